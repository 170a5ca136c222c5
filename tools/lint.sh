#!/usr/bin/env bash
# Lint and types, configured in pyproject.toml: `ruff check` and `ruff format --check` over
# reactive_anim/, tools/ and tests/, then pyright ([tool.pyright]: the same three, standard mode).
# Builds (or reuses) the pinned .venv/lint first (tools/setup_env.sh lint). Runs every check even
# after a failure; the exit status is non-zero if any of them failed. Needs no network after setup.
set -uo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
cd "$root"
python="$(tools/setup_env.sh lint | tail -n 1)" || { echo "lint: setting up the lint environment failed" >&2; exit 1; }
bin="$(dirname "$python")"

# mujoco's bindings are compiled modules without type stubs; pyright reads stubs generated from the
# installed module (pyproject: stubPath), regenerated when mujoco or the generator changes.
stubs="$root/.venv/lint/typings"
want="$("$python" -c 'from importlib.metadata import version as v; print("mujoco", v("mujoco"), "pybind11-stubgen", v("pybind11-stubgen"))')"
if [ "$(cat "$stubs/.stamp" 2>/dev/null)" != "$want" ]; then
  rm -rf "$stubs"
  if ! "$bin/pybind11-stubgen" mujoco --ignore-all-errors -o "$stubs" > "$root/.venv/lint/stubgen.log" 2>&1; then
    echo "lint: generating the mujoco stubs failed:" >&2
    cat "$root/.venv/lint/stubgen.log" >&2
    exit 1
  fi
  echo "$want" > "$stubs/.stamp"
fi
# Our own hand-written stubs (tools/typings: onnxruntime, which ships none) go beside them, copied
# afresh on every run so that an edit to them counts.
for package in "$root"/tools/typings/*/; do
  name="$(basename "$package")"
  rm -rf "${stubs:?}/$name"
  cp -R "$root/tools/typings/$name" "$stubs/$name"
done

export PYRIGHT_PYTHON_IGNORE_WARNINGS=1  # no "new pyright version" look-up on PyPI
status=0
check() {  # check LABEL COMMAND...
  local label="$1"; shift
  echo "=== $label"
  if "$@"; then echo "$label: ok"; else echo "$label: FAILED"; status=1; fi
}
check "ruff check" "$bin/ruff" check .
check "ruff format" "$bin/ruff" format --check .
check "pyright" "$bin/pyright"
exit $status
