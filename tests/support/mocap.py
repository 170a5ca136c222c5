"""The real motion capture (tools.devkit.mocap) and a skip when a file of it is absent."""

from __future__ import annotations

from pathlib import Path

import pytest

from tools.devkit.mocap import MOCAP, REPO, mocap_files

__all__ = ["MOCAP", "REPO", "mocap_files", "require_mocap"]


def require_mocap(relative: str) -> Path:
    """Path of one shared mocap file, or skip the test with the reason."""
    path = MOCAP / relative
    if not path.is_file():
        pytest.skip(f"real mocap not available: {path} is absent (../shared/mocap is test-only data)")
    return path
