#!/usr/bin/env bash
# Every test: the core in bpy-free environments (so an `import bpy` that slips into reactive_anim/core
# fails) on numpy 1.26 and numpy 2, the Blender layer on each supported Blender line, then the real
# Blender window (tests/gui, its own Debian 13 root). The environments and the lines come from
# tools/requirements/environments.txt; tools/setup_env.sh builds any that is missing.
# Extra arguments go to every pytest run (e.g. -x, -k name). Exit status is non-zero if any run fails.
set -uo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
cd "$root"
mapfile -t rows < <(awk '!/^#/ && NF && $3 != "-" {print $1, $3}' tools/requirements/environments.txt)
results="$root/out/test-results"
rm -rf "$results" && mkdir -p "$results"

# Environments in parallel (mostly downloads), then check each one.
for row in "${rows[@]}"; do env="${row%% *}"; tools/setup_env.sh "$env" > "$results/setup-$env.log" 2>&1 & done
wait
for row in "${rows[@]}"; do
  env="${row%% *}"
  if ! tail -n 1 "$results/setup-$env.log" | grep -q "/bin/python$"; then
    echo "run_tests: setting up the $env environment failed:" >&2
    cat "$results/setup-$env.log" >&2
    exit 1
  fi
done

status=0
for row in "${rows[@]}"; do
  env="${row%% *}" tests="${row#* }"
  python="$(tail -n 1 "$results/setup-$env.log")"
  echo "=== $env ($("$python" -c 'import sys, numpy; v = sys.version_info
try:
    import bpy; b = "Blender " + bpy.app.version_string
except ImportError:
    b = "no bpy"
print(f"{b}, Python {v[0]}.{v[1]}, numpy {numpy.__version__}")'))"
  "$python" -m pytest $tests "$@" --junitxml="$results/$env.xml" || status=1
done
echo "=== gui (a real Blender window: Debian's Blender under Xvfb, tests/gui)"
"$(tail -n 1 "$results/setup-core.log")" -m pytest tests/gui "$@" --junitxml="$results/gui.xml" || status=1
python3 tools/test_summary.py "$results"/*.xml || status=1
exit $status
