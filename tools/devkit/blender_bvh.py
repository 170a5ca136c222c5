"""Blender's bundled BVH importer (io_anim_bvh), called as our import called it before it built its
own rigs: the reference the armature tests compare with and the figure the benchmark compares to.
Imports bpy: only for tests/blender and the Blender benchmark."""

from __future__ import annotations

import contextlib
import importlib
import io
from pathlib import Path

import bpy
from bpy_extras.io_utils import axis_conversion

from reactive_anim.core.model import bvh


def import_with_blender(context: bpy.types.Context, path: Path, unit: str = "auto", up: str = "Y") -> bpy.types.Object:
    """The armature Blender's importer makes from `path` (our reader's check first, quaternion
    rotations, metres, Z up, frame 1 = file frame 0, the scene at the file's rate), as before."""
    import_bvh = importlib.import_module("io_anim_bvh.import_bvh")  # Blender's bundled add-on: no type stubs

    scale = bvh.unit_scale(bvh.parse_bvh(path), unit)
    from_forward, from_up = ("-Z", "Y") if up == "Y" else ("Y", "Z")
    before = set(bpy.data.objects)
    with contextlib.redirect_stdout(io.StringIO()):  # it prints its progress and every short bone
        import_bvh.load(
            context,
            str(path),
            rotate_mode="QUATERNION",
            global_scale=scale,
            global_matrix=axis_conversion(from_forward=from_forward, from_up=from_up).to_4x4(),
            frame_start=1,
            update_scene_fps=True,
            update_scene_duration=True,
            report=lambda *_args: None,
        )
    (armature,) = [ob for ob in bpy.data.objects if ob not in before]
    return armature
