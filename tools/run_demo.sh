#!/usr/bin/env bash
# The main job, headless: import the sample walk into a new scene and save out/demo.blend.
# Builds the pinned bpy 5.0 environment first if it is missing (tools/setup_env.sh).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
cd "$root"
python="$(tools/setup_env.sh 5.0)"
"$python" -m reactive_anim import sample_clips/walk.bvh --out out/demo.blend
