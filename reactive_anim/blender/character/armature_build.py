"""A new armature whose rest pose is a core Skeleton (metres, Z up, rest rotations = identity).

The bones are those Blender's bundled BVH importer (io_anim_bvh, as of Blender 4.5) makes from the
same file, so the two rigs have the same rest matrices and play the same actions:
- a bone's head is its joint's rest position; its tail is the End Site, else its only child's head,
  else the mean of its children's heads;
- a bone shorter than a thousandth of a file unit is lengthened a tenth of a file unit along the
  file's Y; one still shorter than 1 mm (files in millimetres) continues its parent's bone, or for
  a root, points along the file's Y with the mean bone length;
- roll is zero in the file's axes: the bones are made there and the armature is then turned into
  Blender's axes, as Blender's importer does with its axis conversion.
Where we differ: in a centimetre file the lengthening makes exactly 1 mm, which Blender's float
arithmetic counts as shorter than 1 mm or not bone by bone; we count it as long enough, so such a
leaf may point elsewhere than Blender's (nothing else moves). And a child whose head is its parent's
tail is connected unless the file translates it; Blender's importer means to do the same but
compares a local offset with a position, so it connects only the children of bones whose OFFSET is
zero. Connection does not change how a rig plays. (Blender 4.2's importer also measured a bone with
several children from the wrong point, which 4.5 fixed.)
"""

from __future__ import annotations

from collections.abc import Collection

import bpy
import numpy as np
from mathutils import Matrix

from ...core.model.errors import SkeletonError
from ...core.model.skeleton import Skeleton

# Blender's BVH importer's lengths for bones the file gives no length: below SHORT (file units) a
# bone is lengthened by NUDGE (file units) along the file's Y; below MIN_BONE_LENGTH (metres, less
# float rounding: see the module docstring) by its parent's bone. Blender drops zero-length bones.
SHORT_IN_FILE_UNITS = 1e-3
NUDGE_IN_FILE_UNITS = 0.1
MIN_BONE_LENGTH = 1e-3
LENGTH_ROUNDING = 1e-9
MAX_BONE_NAME_BYTES = 63  # Blender's bone names (MAXBONENAME, 64 bytes with the terminating NUL)


def build_armature(
    context: bpy.types.Context,
    skeleton: Skeleton,
    name: str,
    *,
    file_axes: np.ndarray,
    file_unit: float,
    translated_joints: Collection[int] = (),
) -> bpy.types.Object:
    """A new armature object `name` in the active collection, selected and active, in object mode.

    file_axes: (3, 3) rotation from the file's axes to Blender's (every bone has zero roll there).
    file_unit: metres per file unit (Blender's importer measures short bones in file units).
    translated_joints: joints the file translates (BVH position channels); never connected.
    Bone names must fit Blender's limit; they are checked before anything is created.
    """
    too_long = [n for n in skeleton.names if len(n.encode()) > MAX_BONE_NAME_BYTES]
    if too_long:
        raise SkeletonError(
            f"joint name '{too_long[0]}' is longer than the {MAX_BONE_NAME_BYTES} bytes a Blender bone name holds"
        )
    heads = skeleton.rest_positions()
    tails = _bone_tails(skeleton, heads, file_y=file_axes[:, 1], file_unit=file_unit)
    connected = [
        j > 0 and j not in translated_joints and bool(np.array_equal(tails[skeleton.parents[j]], heads[j]))
        for j in range(skeleton.num_joints)
    ]

    active = context.view_layer.objects.active
    if active is not None and active.mode != "OBJECT":
        bpy.ops.object.mode_set(mode="OBJECT")
    data = bpy.data.armatures.new(name)
    armature = bpy.data.objects.new(name, data)
    context.collection.objects.link(armature)
    for ob in context.view_layer.objects:
        ob.select_set(False)
    armature.select_set(True)
    context.view_layer.objects.active = armature
    # Make the bones in the file's axes (a row vector times the rotation: its inverse applied)...
    bpy.ops.object.mode_set(mode="EDIT")
    edit_bones = data.edit_bones
    for j, bone_name in enumerate(skeleton.names):
        bone = edit_bones.new(bone_name)
        bone.head, bone.tail, bone.roll = heads[j] @ file_axes, tails[j] @ file_axes, 0.0
        if j > 0:
            bone.parent = edit_bones[skeleton.names[skeleton.parents[j]]]
            bone.use_connect = connected[j]
    bpy.ops.object.mode_set(mode="OBJECT")
    # ... then turn them into Blender's axes; Blender carries each roll along.
    data.transform(Matrix(file_axes.tolist()).to_4x4())
    return armature


def _bone_tails(skeleton: Skeleton, heads: np.ndarray, *, file_y: np.ndarray, file_unit: float) -> np.ndarray:
    """Each bone's tail (J, 3), as Blender's BVH importer places it (see the module docstring)."""
    tails = heads.copy()
    for j in range(skeleton.num_joints):
        children = skeleton.children(j)
        if j in skeleton.end_sites:
            tails[j] = heads[j] + skeleton.end_sites[j]
        elif children:
            tails[j] = heads[children].mean(axis=0)
    # A bone of next to no length in the file is lengthened along the file's Y...
    short = np.linalg.norm(tails - heads, axis=1) <= SHORT_IN_FILE_UNITS * file_unit
    tails[short] += NUDGE_IN_FILE_UNITS * file_unit * file_y
    # ... and one still under 1 mm by its parent's bone (a root, or a child of a bone of no length:
    # the mean bone length along the file's Y; 0.1 m if no bone has a length, Blender's choice).
    vectors = tails - heads
    lengths = np.linalg.norm(vectors, axis=1)
    mean_length = float(lengths[lengths > 0].mean()) if (lengths > 0).any() else 0.1
    for j in np.flatnonzero(lengths < MIN_BONE_LENGTH - LENGTH_ROUNDING):
        parent = skeleton.parents[j]
        tails[j] += vectors[parent] if parent >= 0 and lengths[parent] > 0 else mean_length * file_y
    return tails
