#!/usr/bin/env bash
# Create (or reuse) one pinned virtual environment, built from tools/requirements/<name>.txt with the
# Python that tools/requirements/environments.txt names for it:
#   tools/setup_env.sh bpy-5.2 (or 5.2)  -> .venv/bpy-5.2   (bpy = Blender as a Python module)
#   tools/setup_env.sh core              -> .venv/core      (numpy, mujoco, onnxruntime, pytest; no bpy)
#   tools/setup_env.sh lint              -> .venv/lint      (ruff, pyright, fake-bpy-module + the core packages)
# Prints the venv's python on the last line.
# A venv is rebuilt only when its requirements file (or one it includes) changed (a hash stamp sits inside it).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
table="$root/tools/requirements/environments.txt"
names="$(awk '!/^#/ && NF {printf "%s%s", sep, $1; sep="|"}' "$table")"
usage="usage: setup_env.sh $names (a bare Blender line such as 5.2 means bpy-5.2)"
name="${1:?$usage}"
case "$name" in [0-9]*.[0-9]*) name="bpy-$name" ;; esac
python_version="$(awk -v n="$name" '!/^#/ && $1 == n {print $2}' "$table")"
[ -n "$python_version" ] || { echo "setup_env: unknown environment '$1'; $usage" >&2; exit 2; }
case "$name" in bpy-*) note=" (first run downloads about 1 GB)" ;; *) note="" ;; esac
req="$root/tools/requirements/$name.txt"
[ -f "$req" ] || { echo "setup_env: no requirements for '$name' ($req)" >&2; exit 2; }
venv="$root/.venv/$name"
stamp="$venv/.requirements.sha256"

# The interpreter: pythonX.Y on PATH if it runs (a pyenv shim may not), else pyenv's own copy.
find_python() {
  local candidate
  for candidate in "python$1" "$(pyenv root 2>/dev/null)/versions/$1"*/bin/"python$1" \
    "$HOME/.pyenv/versions/$1"*/bin/"python$1"; do
    if "$candidate" -c 'import venv' > /dev/null 2>&1; then
      command -v "$candidate"
      return 0
    fi
  done
  return 1
}

# The stamp covers the file and the files it includes with `-r` (lint.txt includes core.txt).
inputs=("$req")
while read -r inc; do inputs+=("$(dirname "$req")/$inc"); done < <(sed -n 's/^-r[[:space:]]*//p' "$req")
want="$(cat "${inputs[@]}" | sha256sum | cut -d' ' -f1)"
if [ ! -x "$venv/bin/python" ] || [ "$(cat "$stamp" 2>/dev/null)" != "$want" ]; then
  python="$(find_python "$python_version")" || {
    echo "setup_env: $name needs Python $python_version (python$python_version on PATH or under pyenv); none found" >&2
    exit 1
  }
  echo "setup_env: building $venv with $python$note" >&2
  rm -rf "$venv"
  "$python" -m venv "$venv"
  "$venv/bin/python" -m pip install --quiet --disable-pip-version-check -r "$req" >&2
  echo "$want" > "$stamp"
fi
echo "$venv/bin/python"
