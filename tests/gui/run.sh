#!/usr/bin/env bash
# Run tests/gui/in_root.sh inside the Debian 13 root of tools/setup_gui_root.sh, with this
# repository bound at /repo, in a private mount namespace (the mounts vanish with the process).
#   tests/gui/run.sh ROOT OUT SCRIPT [ARGS...]   (OUT and SCRIPT relative to the repository)
set -euo pipefail
repo="$(cd "$(dirname "$0")/../.." && pwd)"
root="$1"; shift
exec unshare --mount --fork sh -c '
  set -e
  root="$1" repo="$2"; shift 2
  mount --make-rprivate /
  mkdir -p "$root/repo"
  mount -t proc proc "$root/proc"
  mount --rbind /dev "$root/dev"
  mount --bind "$repo" "$root/repo"
  exec chroot "$root" /bin/sh /repo/tests/gui/in_root.sh "$@"
' sh "$root" "$repo" "$@"
