"""Build a character from a BVH file with Blender's bundled importer, after our reader checks it.

Our reader validates the whole file first, so a malformed file raises BVHError before Blender
creates anything: no half-made armature is left behind. The geometry itself comes from
io_anim_bvh (Blender's own importer), called with the unit scale our reader detected.
"""

from __future__ import annotations

from pathlib import Path

import bpy
from bpy_extras.io_utils import axis_conversion

from ..core import bvh
from ..core.errors import BVHError


def import_bvh(
    context: bpy.types.Context,
    filepath: str | Path,
    unit: str | float = "auto",
    up: str = "Y",
    name: str = "",
    set_scene_fps: bool = True,
) -> bpy.types.Object:
    """Import `filepath` as an armature with a quaternion action, in metres, Z up.

    Returns the new armature object. Its action starts at frame 1 (file frame 0) and keeps a fake
    user, so it survives being unassigned by a bake.
    """
    # Blender's bundled BVH add-on (scripts/addons_core); the bpy type stubs do not cover add-ons.
    from io_anim_bvh import import_bvh as blender_importer  # pyright: ignore[reportMissingImports]

    data = bvh.parse_bvh(filepath)
    scale = bvh.unit_scale(data, unit)
    if up.upper() not in ("Y", "Z"):
        raise BVHError(f"up axis must be 'Y' or 'Z', got '{up}'", filepath)
    from_forward, from_up = ("-Z", "Y") if up.upper() == "Y" else ("Y", "Z")
    if context.view_layer.objects.active and context.view_layer.objects.active.mode != "OBJECT":
        bpy.ops.object.mode_set(mode="OBJECT")
    before = set(bpy.data.objects)
    result = blender_importer.load(
        context,
        str(filepath),
        rotate_mode="QUATERNION",
        global_scale=scale,
        global_matrix=axis_conversion(from_forward=from_forward, from_up=from_up).to_4x4(),
        frame_start=1,
        update_scene_fps=set_scene_fps,
        update_scene_duration=True,
        report=lambda *_args: None,
    )
    created = [ob for ob in bpy.data.objects if ob not in before and ob.type == "ARMATURE"]
    if result != {"FINISHED"} or len(created) != 1:
        raise BVHError("Blender's BVH importer did not create an armature", filepath)
    armature = created[0]
    action = armature.animation_data.action if armature.animation_data else None
    if armature.data is None or action is None:
        raise BVHError("Blender's BVH importer did not create an animated armature", filepath)
    if name:
        armature.name = name
        armature.data.name = name
    action.use_fake_user = True
    return armature
