"""Farm tests: `python -m reactive_anim bake` on a Dask cluster on the loopback interface, and the
whole, resumable outputs every bake writes. Run in the `farm` environment (bpy 4.5 + Dask).

The inputs are made here with the Blender layer (the sample walk, two impact markers per file,
each file its own frames so that every output differs), once per session, with their one-process
bake: the reference every farm run must reproduce key for key. Blender does not write .blend files
byte for byte the same twice (pointers are saved), so outputs are compared by what the bake wrote:
every key of every reacted action.
"""

from __future__ import annotations

import os
import tempfile

os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="reactive_anim_test_farm_"))

import bpy  # must come after the environment variable
import pytest

import reactive_anim
from tests.farm.support import INPUTS, bake_here, reacted_keys, scene_file


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


@pytest.fixture(scope="session")
def inputs(tmp_path_factory: pytest.TempPathFactory) -> list:
    """Six .blend files with impact markers, in a folder of their own."""
    folder = tmp_path_factory.mktemp("inputs")
    return [scene_file(folder / f"shot_{k}.blend", first_frame=31 + 12 * k) for k in range(INPUTS)]


@pytest.fixture(scope="session")
def reference(inputs: list, tmp_path_factory: pytest.TempPathFactory) -> dict:
    """The inputs baked one after another in one process: output name -> its reacted keys."""
    out = tmp_path_factory.mktemp("reference")
    done = bake_here(*map(str, inputs), "--out-dir", str(out))
    assert done.returncode == 0, done.stderr
    return {p.name: reacted_keys(p) for p in sorted(out.glob("*.reacted.blend"))}
