#!/bin/sh
# Runs inside the Debian 13 root (tests/gui/run.sh puts it there): a virtual screen, then Debian's
# Blender in a real window running SCRIPT (tests/gui/session.py) with the arguments after it.
# Everything Blender prints goes to OUT/blender.log.
set -eu
out="$1"; script="$2"; shift 2
export HOME=/root DISPLAY=:99 BLENDER_USER_RESOURCES=/tmp/reactive_anim_gui_user
rm -rf "$BLENDER_USER_RESOURCES" /tmp/.X99-lock /tmp/.X11-unix/X99
mkdir -p "$BLENDER_USER_RESOURCES" "$out"
Xvfb :99 -screen 0 1600x900x24 -nolisten tcp > "$out/xvfb.log" 2>&1 &
xvfb=$!
trap 'kill $xvfb 2> /dev/null || true' EXIT
tries=0
until xdotool getdisplaygeometry > /dev/null 2>&1; do
  tries=$((tries + 1)); [ $tries -lt 100 ] || { echo "in_root: Xvfb did not start" >&2; exit 1; }
  sleep 0.1
done
blender --factory-startup --python "$script" -- "$out" "$@" > "$out/blender.log" 2>&1
