"""The Blender session of every folder of bpy tests (tests/blender, tests/farm): the real bpy module
in background mode, the add-on registered once, an empty scene before every test.

BLENDER_USER_RESOURCES points at a temporary folder before bpy is imported, so nothing the tests
do lands in the user's Blender configuration: a conftest imports this module before anything that
imports bpy.
"""

from __future__ import annotations

import os
import tempfile

os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="reactive_anim_test_"))

import bpy  # must come after the environment variable
import pytest

import reactive_anim


@pytest.fixture(scope="session", autouse=True)
def addon_registered():
    """The add-on from this checkout, registered once for the session."""
    reactive_anim.register()
    yield
    reactive_anim.unregister()


@pytest.fixture(autouse=True)
def empty_scene():
    """A fresh empty Blender before each test (add-on classes stay registered)."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    yield bpy.context.scene
