"""Build a character from a BVH file: our reader checks and converts it, our armature builder makes
the bones, the bulk writer keys the motion.

Our reader validates the whole file first, so a malformed file raises BVHError before anything is
created: no half-made armature is left behind. The rig has the bones, rolls and rest pose Blender's
bundled importer (io_anim_bvh, 4.5 and newer) gives the same file, so actions move between the two
(armature_build.py says where they differ), and quaternion keys on every frame.

Blender's importer is no longer called. For a file our reader accepts it would add nothing a user
of this add-on needs (its other options, Euler rotation modes, empties instead of bones, resampling
to the scene's rate, stay in Blender's own File > Import) and it is far slower: it keys every value
from Python (docs/measurements.md).
"""

from __future__ import annotations

from pathlib import Path

import bpy
import numpy as np
from bpy_extras.io_utils import axis_conversion

from ...core.model import bvh
from ..bake import bake
from . import action_io, armature_build


def import_bvh(
    context: bpy.types.Context,
    filepath: str | Path,
    unit: str | float = "auto",
    up: str = "Y",
    name: str = "",
    set_scene_fps: bool = True,
) -> bpy.types.Object:
    """Import `filepath` as an armature with a quaternion action, in metres, Z up.

    Returns the new armature object (named `name`, or after the file). Its action, named after the
    file, starts at frame 1 (file frame 0) and keeps a fake user, so it survives being unassigned
    by a bake. The scene takes the file's frame rate and is lengthened to hold the action.
    """
    data = bvh.parse_bvh(filepath)
    motion = bvh.to_motion(data, unit=unit, up=up)
    title = Path(filepath).stem
    armature = armature_build.build_armature(
        context,
        motion.skeleton,
        name or title,
        file_axes=_file_axes(up),
        file_unit=bvh.unit_scale(data, unit),
        translated_joints={j for j, channels in enumerate(data.channels) if j > 0 and channels.position},
    )
    action = action_io.write_motion(armature, motion, title, frame_start=1)
    action.use_fake_user = True
    bake.assign_action(armature, action)
    scene = context.scene
    if set_scene_fps:  # as Blender's importer does: a whole number of frames per second, fps_base for the rest
        scene.render.fps = round(motion.fps)
        scene.render.fps_base = scene.render.fps / motion.fps
    scene.frame_end = max(scene.frame_end, motion.num_frames)
    scene.frame_set(scene.frame_current)  # show the new rig posed
    return armature


def _file_axes(up: str) -> np.ndarray:
    """(3, 3) rotation from the file's axes to Blender's: the conversion Blender's importer applies."""
    from_forward, from_up = ("-Z", "Y") if up.upper() == "Y" else ("Y", "Z")
    return np.array(axis_conversion(from_forward=from_forward, from_up=from_up))
