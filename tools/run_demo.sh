#!/usr/bin/env bash
# The main job, headless (python -m tools.demo): the sample walk imported onto a mannequin in a new
# scene, four impact markers, the bake, out/demo.blend saved, out/demo_filmstrip.png rendered.
# Builds the pinned bpy 5.0 environment first if it is missing (tools/setup_env.sh).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
cd "$root"
python="$(tools/setup_env.sh 5.0)"
# Headless Blender prints an EGL error line for each GPU configuration it probes before it finds one
# that renders; they mean nothing here, so they are left out of the output (any other stderr stays).
"$python" -m tools.demo "$@" 2> >(grep -v '^EGL Error (0x3009)' >&2)
