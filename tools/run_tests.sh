#!/usr/bin/env bash
# Every test: the core once in the bpy-free core environment (so an `import bpy` that slips into
# reactive_anim/core fails), the Blender layer on each supported Blender line (bpy 4.2, 4.5, 5.0).
# Builds the pinned virtual environments first if they are missing (tools/setup_env.sh).
# Extra arguments go to every pytest run (e.g. -x, -k name). Exit status is non-zero if any run fails.
set -uo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
cd "$root"
lines=(4.2 4.5 5.0)
envs=(core "${lines[@]}")
results="$root/out/test-results"
rm -rf "$results" && mkdir -p "$results"

# Environments in parallel (mostly downloads), then check each one.
for env in "${envs[@]}"; do tools/setup_env.sh "$env" > "$results/setup-$env.log" 2>&1 & done
wait
for env in "${envs[@]}"; do
  if ! tail -n 1 "$results/setup-$env.log" | grep -q "/bin/python$"; then
    echo "run_tests: setting up the $env environment failed:" >&2
    cat "$results/setup-$env.log" >&2
    exit 1
  fi
done
python_for() { tail -n 1 "$results/setup-$1.log"; }

status=0
run() {  # run LABEL PYTHON PYTEST-ARGS...
  local label="$1" python="$2"; shift 2
  echo "=== $label ($("$python" -c 'import bpy; print("Blender", bpy.app.version_string)' 2>/dev/null || echo "no bpy"))"
  "$python" -m pytest "$@" --junitxml="$results/$label.xml" || status=1
}
run core "$(python_for core)" tests/core "$@"
for line in "${lines[@]}"; do
  run "blender-$line" "$(python_for "$line")" tests/blender "$@"
done
python3 tools/test_summary.py "$results"/*.xml || status=1
exit $status
