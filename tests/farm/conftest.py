"""Farm tests: `python -m reactive_anim bake` on a Dask cluster on the loopback interface, and the
whole, resumable outputs every bake writes. Run in the `farm` environment (bpy 4.5 + Dask).

The inputs are made here with the Blender layer (the sample walk, two impact markers per file,
each file its own frames so that every output differs), once per session, with their one-process
bake: the reference every farm run must reproduce key for key. Blender does not write .blend files
byte for byte the same twice (pointers are saved), so outputs are compared by what the bake wrote:
every key of every reacted action.
"""

from __future__ import annotations

import pytest

from tests.support.blender_session import addon_registered, empty_scene

__all__ = ["addon_registered", "empty_scene"]  # the session's fixtures, for pytest to find here


@pytest.fixture(scope="session")
def inputs(tmp_path_factory: pytest.TempPathFactory) -> list:
    """Six .blend files with impact markers, in a folder of their own."""
    from tests.farm.support import INPUTS, scene_file  # bpy is imported once the session is set up

    folder = tmp_path_factory.mktemp("inputs")
    return [scene_file(folder / f"shot_{k}.blend", first_frame=31 + 12 * k) for k in range(INPUTS)]


@pytest.fixture(scope="session")
def reference(inputs: list, tmp_path_factory: pytest.TempPathFactory) -> dict:
    """The inputs baked one after another in one process: output name -> its reacted keys."""
    from tests.farm.support import bake_here, reacted_keys

    out = tmp_path_factory.mktemp("reference")
    done = bake_here(*map(str, inputs), "--out-dir", str(out))
    assert done.returncode == 0, done.stderr
    return {p.name: reacted_keys(p) for p in sorted(out.glob("*.reacted.blend"))}
