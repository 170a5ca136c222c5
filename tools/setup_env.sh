#!/usr/bin/env bash
# Create (or reuse) the pinned virtual environment for one Blender line: .venv/bpy-<line>.
# Usage: tools/setup_env.sh 4.2|4.5|5.0   -> prints the venv's python on the last line.
# A venv is rebuilt only when its requirements file changed (a hash stamp sits inside it).
set -euo pipefail
line="${1:?usage: setup_env.sh 4.2|4.5|5.0}"
root="$(cd "$(dirname "$0")/.." && pwd)"
req="$root/tools/requirements/bpy-$line.txt"
[ -f "$req" ] || { echo "setup_env: no requirements for Blender line '$line' ($req)" >&2; exit 2; }
venv="$root/.venv/bpy-$line"
stamp="$venv/.requirements.sha256"
want="$(sha256sum "$req" | cut -d' ' -f1)"
if [ ! -x "$venv/bin/python" ] || [ "$(cat "$stamp" 2>/dev/null)" != "$want" ]; then
  echo "setup_env: building $venv (first run downloads about 1 GB)" >&2
  rm -rf "$venv"
  python3.11 -m venv "$venv" 2>/dev/null || python3 -m venv "$venv"
  "$venv/bin/python" -c 'import sys; assert sys.version_info[:2] == (3, 11), "Python 3.11 is required (bpy wheels are cp311)"'
  "$venv/bin/python" -m pip install --quiet --disable-pip-version-check -r "$req" >&2
  echo "$want" > "$stamp"
fi
echo "$venv/bin/python"
