#!/usr/bin/env bash
# Create (or reuse) one pinned virtual environment, built from tools/requirements/<file>.txt:
#   tools/setup_env.sh 4.2|4.5|5.0   -> .venv/bpy-<line>  (bpy = Blender as a Python module)
#   tools/setup_env.sh core          -> .venv/core        (numpy, mujoco, onnxruntime, pytest; no bpy)
#   tools/setup_env.sh lint          -> .venv/lint        (ruff, pyright, fake-bpy-module + the core packages)
# Prints the venv's python on the last line.
# A venv is rebuilt only when its requirements file (or one it includes) changed (a hash stamp sits inside it).
set -euo pipefail
usage="usage: setup_env.sh 4.2|4.5|5.0|core|lint"
name="${1:?$usage}"
root="$(cd "$(dirname "$0")/.." && pwd)"
case "$name" in
  core|lint) env="$name"; note="" ;;
  [0-9]*.[0-9]*) env="bpy-$name"; note=" (first run downloads about 1 GB)" ;;
  *) echo "setup_env: unknown environment '$name'; $usage" >&2; exit 2 ;;
esac
req="$root/tools/requirements/$env.txt"
[ -f "$req" ] || { echo "setup_env: no requirements for '$name' ($req)" >&2; exit 2; }
venv="$root/.venv/$env"
stamp="$venv/.requirements.sha256"
# The stamp covers the file and the files it includes with `-r` (lint.txt includes core.txt).
inputs=("$req")
while read -r inc; do inputs+=("$(dirname "$req")/$inc"); done < <(sed -n 's/^-r[[:space:]]*//p' "$req")
want="$(cat "${inputs[@]}" | sha256sum | cut -d' ' -f1)"
if [ ! -x "$venv/bin/python" ] || [ "$(cat "$stamp" 2>/dev/null)" != "$want" ]; then
  echo "setup_env: building $venv$note" >&2
  rm -rf "$venv"
  python3.11 -m venv "$venv" 2>/dev/null || python3 -m venv "$venv"
  "$venv/bin/python" -c 'import sys; assert sys.version_info[:2] == (3, 11), "Python 3.11 is required (bpy wheels are cp311)"'
  "$venv/bin/python" -m pip install --quiet --disable-pip-version-check -r "$req" >&2
  echo "$want" > "$stamp"
fi
echo "$venv/bin/python"
