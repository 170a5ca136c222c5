"""Where the real motion capture lives (../shared/mocap, test-only data: its licences forbid copying
it into the repository or a release)."""

from __future__ import annotations

from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
MOCAP = REPO.parent / "shared" / "mocap"


def mocap_files(pattern: str = "**/*.bvh") -> list[Path]:
    """Real BVH files under ../shared/mocap (empty where ../shared is absent)."""
    return sorted(MOCAP.glob(pattern)) if MOCAP.is_dir() else []
