"""Blender data typed as what a test expects it to be, where the bpy type stubs are looser: they give
`Object.data` as any kind of data block (or None) and `Area.spaces.active` as any kind of editor;
these helpers assert the one kind the test works with and return it typed, so a test on the wrong
thing fails there, saying what it got. Imports bpy: only for tests/blender and tests/gui."""

from __future__ import annotations

from typing import TYPE_CHECKING, cast

import bpy
import numpy as np

if TYPE_CHECKING:
    from typing_extensions import Buffer  # collections.abc.Buffer from Python 3.12


def as_buffer(array: np.ndarray) -> Buffer:
    """The array, for `foreach_get`/`foreach_set`, which fill or read any buffer. An ndarray is one,
    but numpy 1.26's stubs say so (`ndarray.__buffer__`, PEP 688) only for Python 3.12 and newer."""
    return cast("Buffer", array)


def armature_data(ob: bpy.types.Object) -> bpy.types.Armature:
    """The armature of an armature object."""
    data = ob.data
    assert isinstance(data, bpy.types.Armature), f"object '{ob.name}' is a {ob.type.lower()}, not an armature"
    return data


def view_3d(area: bpy.types.Area) -> bpy.types.SpaceView3D:
    """The 3D view of an area of the screen."""
    space = area.spaces.active
    assert isinstance(space, bpy.types.SpaceView3D), f"the {area.type} area shows no 3D view"
    return space
