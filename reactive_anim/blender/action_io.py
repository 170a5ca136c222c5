"""Armature + action <-> core.Motion, for any armature (not only BVH imports).

Reading evaluates the armature frame by frame (constraints, drivers and all) and expresses each
bone's pose in the core's BVH-like convention: rest pose = identity rotations, rest offsets in
world axes. With B_j the bone's rest orientation in world space (object rotation @ bone rest) and
D_j = R_pose_j @ B_j^-1 its rotation away from rest in world space, the core's local rotation is
L_j = D_parent^-1 @ D_j. Writing inverts this: the pose-bone quaternion is B_j^-1 @ L_j @ B_j, and a
bone's location channel is B_j^-1 (local_pos_j - rest_offset_j) / object_scale.

Blender has three live action APIs; they differ only in how F-curves are created, which
`_fcurve_factory` hides, chosen by feature detection:
- 4.2: `action.fcurves.new(data_path, index, action_group=...)`;
- 4.4/4.5: layered actions (slot, layer, keyframe strip, channelbag); `fcurves.new` takes no group
  name, so groups are made with `channelbag.groups.new` and assigned;
- 5.0: layered only (`action.fcurves` is gone); `fcurves.new(..., group_name=...)`.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any, cast

import bpy
import numpy as np

from ..core import quat
from ..core.errors import SkeletonError
from ..core.skeleton import Motion, Skeleton

LOCAL_POS_TOLERANCE = 1e-5  # metres (float32 pose matrices); below this, joint translations equal the rest offsets


def _since_4_4(blender_object: object) -> Any:
    """The object untyped, to reach the layered-action API of Blender 4.4+ (slots, layers,
    action_slot): callers detect the feature at run time, and the type stubs describe 4.2."""
    return blender_object


def _armature_data(armature: bpy.types.Object) -> bpy.types.Armature:
    """The object's armature data; any other kind of object is refused by name."""
    if not isinstance(armature.data, bpy.types.Armature):
        raise SkeletonError(f"object '{armature.name}' is not an armature")
    return armature.data


# ---------------------------------------------------------------------------------------------
# Armature rest pose as a core Skeleton


def _root_bone(armature: bpy.types.Object) -> bpy.types.Bone:
    """The root bone with the largest subtree; other root bones (props, IK targets) are ignored."""
    roots = [b for b in _armature_data(armature).bones if b.parent is None]
    if not roots:
        raise SkeletonError(f"armature '{armature.name}' has no bones")
    return max(roots, key=lambda b: len(b.children_recursive))


def _bones_in_order(armature: bpy.types.Object) -> list[bpy.types.Bone]:
    """Bones under the root, parents before children (depth-first, children in Blender's order)."""
    order, stack = [], [_root_bone(armature)]
    while stack:
        bone = stack.pop()
        order.append(bone)
        stack.extend(reversed(bone.children))
    return order


def _object_transform(armature: bpy.types.Object) -> tuple[np.ndarray, float, np.ndarray]:
    """The object's world rotation (quaternion), uniform scale and translation."""
    m = np.array(armature.matrix_world)
    scales = np.linalg.norm(m[:3, :3], axis=0)
    if not np.allclose(scales, scales[0], rtol=1e-4):
        raise SkeletonError(
            f"armature '{armature.name}' has a non-uniform object scale {tuple(scales.round(4))}; apply it first"
        )
    return quat.from_matrix(m[:3, :3] / scales[0]), float(scales[0]), m[:3, 3]


def _rest_frames(armature: bpy.types.Object, bones: list[bpy.types.Bone]) -> tuple[np.ndarray, np.ndarray]:
    """World rest head positions (J, 3) and rest orientations B_j (J, 4)."""
    obj_rot, scale, translation = _object_transform(armature)
    local = np.array([np.array(b.matrix_local) for b in bones])  # (J, 4, 4), armature space
    heads = translation + scale * quat.rotate(obj_rot, local[:, :3, 3])
    rest_rot = quat.mul(obj_rot, quat.from_matrix(_orthonormal(local[:, :3, :3])))
    return heads, rest_rot


def _orthonormal(m: np.ndarray) -> np.ndarray:
    """Strip scale from rotation matrices (columns to unit length)."""
    return m / np.linalg.norm(m, axis=-2, keepdims=True)


def armature_skeleton(armature: bpy.types.Object) -> Skeleton:
    """The armature's rest pose as a core Skeleton (world-axis offsets, metres)."""
    bones = _bones_in_order(armature)
    index = {b.name: i for i, b in enumerate(bones)}
    # _bones_in_order reached every bone after the root through its parent
    parents = np.array([-1] + [index[cast(bpy.types.Bone, b.parent).name] for b in bones[1:]])
    heads, _ = _rest_frames(armature, bones)
    offsets = heads.copy()
    offsets[1:] -= heads[parents[1:]]
    obj_rot, scale, _ = _object_transform(armature)
    tails = {
        i: scale * quat.rotate(obj_rot, np.array(b.tail_local) - np.array(b.head_local))
        for i, b in enumerate(bones)
        if not b.children
    }
    return Skeleton([b.name for b in bones], parents, offsets, tails)


# ---------------------------------------------------------------------------------------------
# Reading


@contextmanager
def _action_assigned(armature: bpy.types.Object, action: bpy.types.Action | None) -> Iterator[bpy.types.Action | None]:
    """Temporarily play `action` on the armature (NLA off), restoring everything afterwards."""
    scene = bpy.context.scene
    frame = scene.frame_current, scene.frame_subframe
    created = armature.animation_data is None
    if created and action is None:  # nothing plays: read the pose as it is, add nothing
        try:
            yield None
        finally:
            scene.frame_set(frame[0], subframe=frame[1])
        return
    adt = armature.animation_data or armature.animation_data_create()
    saved = (adt.action, getattr(adt, "action_slot", None), adt.use_nla)
    try:
        if action is not None:
            adt.action = action
            _ensure_slot(adt, action)
        adt.use_nla = False
        yield adt.action
    finally:
        if created:
            armature.animation_data_clear()
        else:
            adt.action = saved[0]
            if saved[0] is not None and hasattr(adt, "action_slot") and saved[1] is not None:
                _since_4_4(adt).action_slot = saved[1]
            adt.use_nla = saved[2]
        scene.frame_set(frame[0], subframe=frame[1])


def _ensure_slot(adt: bpy.types.AnimData, action: bpy.types.Action) -> None:
    """Layered actions animate nothing until a slot is assigned; pick the first object slot."""
    if not hasattr(adt, "action_slot") or _since_4_4(adt).action_slot is not None:
        return
    for slot in _since_4_4(action).slots:
        if slot.target_id_type in {"OBJECT", "UNSPECIFIED"}:
            _since_4_4(adt).action_slot = slot
            return


def read_motion(
    armature: bpy.types.Object,
    action: bpy.types.Action | None = None,
    frame_range: tuple[int, int] | None = None,
) -> Motion:
    """Evaluate `action` (default: the assigned one) on `armature` into a core Motion.

    frame_range: inclusive (first, last) Blender frames; default the action's frame range.
    The armature's own assignment, NLA state and the scene's current frame are restored.
    """
    skeleton = armature_skeleton(armature)
    bones = _bones_in_order(armature)
    with _action_assigned(armature, action) as playing:
        if frame_range is None:
            if playing is None:
                raise SkeletonError(f"armature '{armature.name}' has no action to read")
            frame_range = (round(playing.frame_range[0]), round(playing.frame_range[1]))
        matrices = _sample_pose_matrices(armature, bones, frame_range)
    scene = bpy.context.scene
    fps = scene.render.fps / scene.render.fps_base
    return _motion_from_matrices(armature, skeleton, bones, matrices, fps)


def _sample_pose_matrices(
    armature: bpy.types.Object, bones: list[bpy.types.Bone], frame_range: tuple[int, int]
) -> np.ndarray:
    """Armature-space pose matrices (T, J, 4, 4), one bulk read per frame."""
    scene = bpy.context.scene
    pose_bones = armature.pose.bones
    order = np.array([pose_bones.find(b.name) for b in bones])
    first, last = frame_range
    buffer = np.empty(len(pose_bones) * 16, dtype=np.float32)
    out = np.empty((last - first + 1, len(bones), 4, 4))
    for t, frame in enumerate(range(first, last + 1)):
        scene.frame_set(frame)
        # foreach_get returns each matrix column-major (ignore: an ndarray is a buffer, see _set_keys)
        pose_bones.foreach_get("matrix", buffer)  # pyright: ignore[reportArgumentType]
        out[t] = buffer.reshape(-1, 4, 4).transpose(0, 2, 1)[order]
    return out


def _motion_from_matrices(
    armature: bpy.types.Object, skeleton: Skeleton, bones: list[bpy.types.Bone], matrices: np.ndarray, fps: float
) -> Motion:
    obj_rot, scale, translation = _object_transform(armature)
    _, rest_rot = _rest_frames(armature, bones)
    heads = translation + scale * quat.rotate(obj_rot, matrices[..., :3, 3])
    pose_rot = quat.mul(obj_rot, quat.from_matrix(_orthonormal(matrices[..., :3, :3])))
    delta = quat.mul(pose_rot, quat.conj(rest_rot))  # D_j, (T, J, 4)
    parents = skeleton.parents
    parent_delta = delta[:, parents[1:]]
    local_rot = delta.copy()
    local_rot[:, 1:] = quat.mul(quat.conj(parent_delta), delta[:, 1:])
    local_pos = np.broadcast_to(skeleton.offsets, heads.shape).copy()
    local_pos[:, 1:] = quat.rotate(quat.conj(parent_delta), heads[:, 1:] - heads[:, parents[1:]])
    translated = np.abs(local_pos[:, 1:] - skeleton.offsets[1:]).max(initial=0.0) > LOCAL_POS_TOLERANCE
    return Motion(
        skeleton=skeleton,
        fps=fps,
        root_pos=heads[:, 0],
        local_rot=quat.normalize(local_rot),
        local_pos=local_pos if translated else None,
    )


# ---------------------------------------------------------------------------------------------
# Writing


def write_motion(armature: bpy.types.Object, motion: Motion, name: str, frame_start: int = 1) -> bpy.types.Action:
    """Write `motion` into a NEW action called `name` (keys at frame_start, frame_start + 1, ...).

    The armature's current action is not touched and the new one is not assigned (the caller
    decides). Bones are switched to quaternion rotation mode, since the new
    action keys quaternions. Every motion joint must be a bone with the same parent.
    """
    bones = _bones_in_order(armature)
    joints = _joint_bones(armature, motion.skeleton, bones)
    heads, rest_rot = _rest_frames(armature, bones)
    _, scale, _ = _object_transform(armature)
    b = rest_rot[joints]  # (J, 4)
    basis_rot = quat.make_continuous(quat.mul(quat.mul(quat.conj(b), motion.local_rot), b))
    rest_offsets = heads[joints].copy()
    rest_offsets[1:] -= heads[joints][motion.skeleton.parents[1:]]
    translation = motion.joint_offsets().copy()
    translation[:, 0] = motion.root_pos
    keyed_loc = [0] + (
        [j for j in range(1, len(joints)) if not bones[joints[j]].use_connect] if motion.local_pos is not None else []
    )
    basis_loc = quat.rotate(quat.conj(b[keyed_loc]), translation[:, keyed_loc] - rest_offsets[keyed_loc]) / scale

    action = bpy.data.actions.new(name)
    new_fcurve = _fcurve_factory(action, armature)
    frames = frame_start + np.arange(motion.num_frames, dtype=np.float64)
    names = motion.skeleton.names
    for j, bone_name in enumerate(names):
        path = f'pose.bones["{bpy.utils.escape_identifier(bone_name)}"]'
        if j in keyed_loc:
            k = keyed_loc.index(j)
            for axis in range(3):
                _set_keys(new_fcurve(path + ".location", axis, bone_name), frames, basis_loc[:, k, axis])
        for axis in range(4):
            _set_keys(new_fcurve(path + ".rotation_quaternion", axis, bone_name), frames, basis_rot[:, j, axis])
    for bone_name in names:
        armature.pose.bones[bone_name].rotation_mode = "QUATERNION"
    return action


def _joint_bones(armature: bpy.types.Object, skeleton: Skeleton, bones: list[bpy.types.Bone]) -> list[int]:
    """Index into `bones` of every motion joint; parents must agree."""
    index = {b.name: i for i, b in enumerate(bones)}
    missing = [n for n in skeleton.names if n not in index]
    if missing:
        raise SkeletonError(f"armature '{armature.name}' lacks bones the motion animates: {', '.join(missing)}")
    for j in range(1, skeleton.num_joints):
        bone = bones[index[skeleton.names[j]]]
        expected = skeleton.names[skeleton.parents[j]]
        if bone.parent is None or bone.parent.name != expected:
            raise SkeletonError(
                f"bone '{bone.name}' has parent '{bone.parent.name if bone.parent else None}' in armature "
                f"'{armature.name}' but '{expected}' in the motion"
            )
    return [index[n] for n in skeleton.names]


def _set_keys(fcurve: bpy.types.FCurve, frames: np.ndarray, values: np.ndarray) -> None:
    """All keys of one curve in two bulk calls; linear interpolation (one key per frame)."""
    points = fcurve.keyframe_points
    points.add(len(frames))
    co = np.column_stack([frames, values]).astype(np.float32).ravel()
    linear = np.ones(len(frames), dtype=np.int32)  # 1 = LINEAR
    # An ndarray is a buffer, but numpy 1.26's stubs declare __buffer__ only for Python 3.12+.
    points.foreach_set("co", co)  # pyright: ignore[reportArgumentType]
    points.foreach_set("interpolation", linear)  # pyright: ignore[reportArgumentType]
    fcurve.update()


def _fcurve_factory(
    action: bpy.types.Action, armature: bpy.types.Object
) -> Callable[[str, int, str], bpy.types.FCurve]:
    """new_fcurve(data_path, index, group) for whichever action API this Blender has."""
    if not hasattr(action, "layers"):  # 4.2: legacy actions
        return lambda path, index, group: action.fcurves.new(path, index=index, action_group=group)
    layered = _since_4_4(action)
    slot = layered.slots.new(id_type="OBJECT", name=armature.name)
    strip = layered.layers.new("Layer").strips.new(type="KEYFRAME")
    channelbag = strip.channelbag(slot, ensure=True)
    if "group_name" in channelbag.fcurves.bl_rna.functions["new"].parameters:  # 5.0 and newer
        return lambda path, index, group: channelbag.fcurves.new(path, index=index, group_name=group)

    def new_fcurve(path: str, index: int, group: str) -> bpy.types.FCurve:  # 4.4 / 4.5
        fcurve = channelbag.fcurves.new(path, index=index)
        fcurve.group = channelbag.groups.get(group) or channelbag.groups.new(group)
        return fcurve

    return new_fcurve
