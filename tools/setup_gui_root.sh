#!/usr/bin/env bash
# Build (or reuse) a Debian 13 root that runs a real, interactive Blender window for the GUI test
# (tests/gui): Debian's Blender 4.3 (Python 3.13) under Xvfb on Mesa's software OpenGL, with xdotool
# to send keys and clicks and ImageMagick's `import` for screenshots (Blender's own screenshot is
# black under Xvfb). It lives outside the repository (default /var/cache/reactive_anim/debian13,
# or $REACTIVE_ANIM_GUI_ROOT) and is reused by later runs; a cold build takes about 10 minutes.
# Needs root and Debian's package mirror. Prints the root's path on the last line; on failure
# prints the reason and exits 3 (the GUI test then skips locally and fails in CI).
set -euo pipefail
dir="${REACTIVE_ANIM_GUI_ROOT:-/var/cache/reactive_anim/debian13}"
packages=(blender python3-numpy xvfb xauth libgl1-mesa-dri xdotool imagemagick ca-certificates)
want="${packages[*]}"
stamp="$dir/.reactive_anim-packages"
if [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$want" ] && [ -x "$dir/usr/bin/blender" ]; then
  echo "$dir"
  exit 0
fi
fail() { echo "setup_gui_root: $*" >&2; exit 3; }
[ "$(id -u)" = 0 ] || fail "needs root (debootstrap and chroot)"
if ! command -v debootstrap > /dev/null; then
  { apt-get update -qq && apt-get install -y -qq debootstrap; } > /dev/null 2>&1 \
    || fail "cannot install debootstrap from Debian's packages"
fi
# The host's own Debian mirror (deb822 sources first, then the one-line format).
mirror="$(sed -n 's/^URIs:[[:space:]]*\([^[:space:]]*\).*/\1/p' /etc/apt/sources.list.d/*.sources 2>/dev/null \
  | grep -v security | head -n 1)"
[ -n "$mirror" ] || mirror="$(awk '$1 == "deb" && $2 !~ /security/ {print $2; exit}' /etc/apt/sources.list 2>/dev/null)"
[ -n "$mirror" ] || fail "no Debian mirror found in /etc/apt/sources.list.d or /etc/apt/sources.list"

work="$dir.partial"
log="$dir.log"
mkdir -p "$(dirname "$dir")"
if [ ! -x "$dir/usr/bin/apt-get" ]; then
  echo "setup_gui_root: building $dir from $mirror (about 10 minutes)" >&2
  rm -rf "$work"
  debootstrap --variant=minbase trixie "$work" "$mirror" > "$log" 2>&1 \
    || fail "debootstrap failed (last lines of $log: $(tail -n 3 "$log" | tr '\n' ' '))"
  cp /etc/resolv.conf "$work/etc/resolv.conf" 2>/dev/null || true
  rm -rf "$dir"
  mv "$work" "$dir"
fi
# Blender (whose Debian package leaves numpy a recommendation) and the tools the test drives it with.
unshare --mount --fork sh -c '
  set -e
  mount -t proc proc "$1/proc"
  mount --rbind /dev "$1/dev"
  chroot "$1" apt-get update -qq
  DEBIAN_FRONTEND=noninteractive chroot "$1" apt-get install -y -qq --no-install-recommends $2
' sh "$dir" "$want" >> "$log" 2>&1 \
  || fail "installing Blender in the Debian 13 root failed (see $log)"
echo "$want" > "$stamp"
echo "$dir"
