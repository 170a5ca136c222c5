"""Where the real motion capture lives (../shared/mocap, test-only data) and a skip when it is absent."""

from __future__ import annotations

from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
MOCAP = REPO.parent / "shared" / "mocap"


def mocap_files(pattern: str = "**/*.bvh") -> list[Path]:
    """Real BVH files under ../shared/mocap (empty where ../shared is absent)."""
    return sorted(MOCAP.glob(pattern)) if MOCAP.is_dir() else []


def require_mocap(relative: str) -> Path:
    """Path of one shared mocap file, or skip the test with the reason."""
    path = MOCAP / relative
    if not path.is_file():
        pytest.skip(f"real mocap not available: {path} is absent (../shared/mocap is test-only data)")
    return path
