"""Blender-layer tests: the real bpy module in background mode, reset before every test
(tests/support/blender_session.py)."""

from __future__ import annotations

from tests.support.blender_session import addon_registered, empty_scene

__all__ = ["addon_registered", "empty_scene"]  # the session's fixtures, for pytest to find here
