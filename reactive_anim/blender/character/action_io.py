"""Armature + action <-> core.Motion, for any armature (not only BVH imports).

Poses are expressed in the core's BVH-like convention: rest pose = identity rotations, rest offsets
in world axes. Positions are measured from the object's origin, not the world's: where the object
stands (raised onto a stage, moved across the set) changes nothing the bake computes (search,
physics, floor), and the keys, which are the bones' own, move with the object.

With B_j the bone's rest orientation in world space (object rotation @ bone rest) and D_j =
R_pose_j @ B_j^-1 its rotation away from rest in world space, the core's local rotation is L_j =
D_parent^-1 @ D_j. Writing inverts this: the pose-bone quaternion is B_j^-1 @ L_j @ B_j, and a
bone's location channel is B_j^-1 (local_pos_j - rest_offset_j) / object_scale.

Reading has two ways. Where the action alone moves the bones (no bone constraints, no drivers,
every bone inheriting its parent's rotation, unit scale), it is writing inverted, straight from the
F-curves in numpy: L_j = B_j @ basis_j @ B_j^-1, basis_j the bone's rotation channels (quaternion,
Euler in the bone's order, or axis-angle), and local_pos_j = rest_offset_j + object_scale B_j
location_j (a connected bone's location ignored, as Blender ignores it). Otherwise Blender evaluates
the armature frame by frame (constraints, drivers and all) and the evaluated pose is read, without
the bones' scale (not part of the motion: a bake carries it). Both give the same motion to float
precision (tests/blender/test_read_motion_fast.py).

Writing a bake's result carries the source action along: every channel the motion does not decide
(object keys, bone custom properties, bone scale, bones outside the skeleton) is copied into the new
action with its keys and settings, so the new action plays exactly like the source wherever the
motion agrees with it (`write_motion`'s carry_from).

Blender's action APIs (4.2 legacy, 4.4+ layered, 5.0 layered only: compat.py) differ in where
F-curves live, which `_fcurve_factory` (writing) and `_slot_fcurves` (reading, for
`_playing_fcurves` and the channels a write carries) hide.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterator
from contextlib import contextmanager, suppress
from typing import Any, cast

import bpy
import numpy as np

from ...core.model import quat
from ...core.model.errors import SkeletonError
from ...core.model.skeleton import Motion, Skeleton
from .. import compat

LOCAL_POS_TOLERANCE = 1e-5  # metres (float32 pose matrices); below this, joint translations equal the rest offsets
# Keyframe interpolation as foreach_get/foreach_set see it: the enum's stored byte (a uint8 buffer
# is copied as is; any other type is converted value by value, several times slower).
_CONSTANT, _LINEAR = 0, 1


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


def _object_transform(armature: bpy.types.Object) -> tuple[np.ndarray, float]:
    """The object's world rotation (quaternion) and uniform scale (its location is left out: see
    the module docstring)."""
    m = np.array(armature.matrix_world)
    scales = np.linalg.norm(m[:3, :3], axis=0)
    if not np.allclose(scales, scales[0], rtol=1e-4):
        raise SkeletonError(
            f"armature '{armature.name}' has a non-uniform object scale {tuple(scales.round(4))}; apply it first"
        )
    return quat.from_matrix(m[:3, :3] / scales[0]), float(scales[0])


def _rest_frames(armature: bpy.types.Object, bones: list[bpy.types.Bone]) -> tuple[np.ndarray, np.ndarray]:
    """Rest head positions (J, 3) from the object's origin and rest orientations B_j (J, 4)."""
    obj_rot, scale = _object_transform(armature)
    local = np.array([np.array(b.matrix_local) for b in bones])  # (J, 4, 4), armature space
    heads = scale * quat.rotate(obj_rot, local[:, :3, 3])
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
    obj_rot, scale = _object_transform(armature)
    leaves = [i for i, b in enumerate(bones) if not b.children]
    tips = np.array([np.array(bones[i].tail_local) - np.array(bones[i].head_local) for i in leaves]).reshape(-1, 3)
    tails = dict(zip(leaves, scale * quat.rotate(obj_rot, tips), strict=True))
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
    saved = (adt.action, compat.assigned_slot(adt), adt.use_nla)
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
            if saved[0] is not None:
                compat.assign_slot(adt, saved[1])
            adt.use_nla = saved[2]
        scene.frame_set(frame[0], subframe=frame[1])


def _ensure_slot(adt: bpy.types.AnimData, action: bpy.types.Action) -> None:
    """Layered actions animate nothing until a slot is assigned; pick the first object slot."""
    if compat.has_slots(adt) and compat.assigned_slot(adt) is None:
        compat.assign_slot(adt, compat.object_slot(action))


def read_motion(
    armature: bpy.types.Object,
    action: bpy.types.Action | None = None,
    frame_range: tuple[int, int] | None = None,
    *,
    evaluate: bool = False,
) -> Motion:
    """`action` (default: the assigned one) on `armature` as a core Motion.

    frame_range: inclusive (first, last) Blender frames; default the action's frame range.
    evaluate: let Blender evaluate every frame even where the F-curves alone would do: the reference
      the direct reading is checked against, and the way to see a pose that frame-change handlers
      set (the direct reading runs no handlers).
    The armature's own assignment, NLA state and the scene's current frame are restored.
    """
    bpy.context.view_layer.update()  # the object's transform as it stands now, which both readings use
    skeleton = armature_skeleton(armature)
    bones = _bones_in_order(armature)
    scene = bpy.context.scene
    fps = scene.render.fps / scene.render.fps_base
    with _action_assigned(armature, action) as playing:
        if frame_range is None:
            if playing is None:
                raise SkeletonError(f"armature '{armature.name}' has no action to read")
            frame_range = (round(playing.frame_range[0]), round(playing.frame_range[1]))
        frames = np.arange(frame_range[0], frame_range[1] + 1)
        motion = None if evaluate else _motion_from_fcurves(armature, skeleton, bones, frames, fps)
        if motion is not None:
            return motion
        with _evaluated_while_hidden(armature):
            pose = _evaluated_pose(armature, bones, frames)
    # the evaluated pose is taken to the core's convention with the frame and the object restored
    return _motion_from_pose(armature, skeleton, bones, pose, fps)


@contextmanager
def _evaluated_while_hidden(armature: bpy.types.Object) -> Iterator[None]:
    """Make Blender evaluate the armature for the frame-by-frame read, whatever its visibility.

    The depsgraph skips an object disabled in viewports, or in a collection that is excluded from
    the view layer or disabled or hidden in it: every frame then reads one frozen pose, and the bake
    simulated a statue. For the read, the object and the layer collections that hold it are made
    visible; everything is put back afterwards.
    """
    restore: list[tuple[Any, str, Any]] = [(armature, "hide_viewport", armature.hide_viewport)]
    for path in _layer_collection_paths(bpy.context.view_layer.layer_collection, armature):
        for layer in path:
            restore += [(layer, "exclude", layer.exclude), (layer, "hide_viewport", layer.hide_viewport)]
            restore.append((layer.collection, "hide_viewport", layer.collection.hide_viewport))
    hidden = None  # the eye in the outliner, which Blender asks about only once the object is in the view layer
    try:
        for owner, name, value in restore:
            if value:
                setattr(owner, name, False)
        hidden = armature.hide_get()
        armature.hide_set(False)
        yield
    finally:
        if hidden is not None:
            armature.hide_set(hidden)
        for owner, name, value in reversed(restore):
            if value:
                setattr(owner, name, value)


def _layer_collection_paths(layer: bpy.types.LayerCollection, ob: bpy.types.Object) -> list[list[Any]]:
    """Every chain of layer collections from `layer` down to one whose collection holds `ob`."""
    here = [[layer]] if ob.name in layer.collection.objects else []
    below = [[layer, *path] for child in layer.children for path in _layer_collection_paths(child, ob)]
    return here + below


def _evaluated_pose(
    armature: bpy.types.Object, bones: list[bpy.types.Bone], frames: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Armature-space heads (T, J, 3) and orientations (T, J, 4) as Blender evaluates them, one
    scene update and one bulk read of the pose matrices per frame; without the bones' scale
    (`_without_bone_scale`)."""
    scene = bpy.context.scene
    pose_bones = armature.pose.bones
    order = np.array([pose_bones.find(b.name) for b in bones])
    buffer = np.empty(len(pose_bones) * 16, dtype=np.float32)
    matrices = np.empty((len(frames), len(bones), 4, 4))
    for t, frame in enumerate(frames):
        scene.frame_set(int(frame))
        # foreach_get returns each matrix column-major (ignore: an ndarray is a buffer, see _set_keys)
        pose_bones.foreach_get("matrix", buffer)  # pyright: ignore[reportArgumentType]
        matrices[t] = buffer.reshape(-1, 4, 4).transpose(0, 2, 1)[order]
    heads, rotations = _without_bone_scale(matrices, bones)
    return heads, quat.from_matrix(rotations)


BONE_SCALE_TOLERANCE = 1e-5  # float32 pose matrices: an axis longer or shorter than this is scaled


def _without_bone_scale(matrices: np.ndarray, bones: list[bpy.types.Bone]) -> tuple[np.ndarray, np.ndarray]:
    """Heads (T, J, 3) and orientations (T, J, 3, 3) of armature-space pose matrices (T, J, 4, 4)
    as the bones would have them unscaled: each bone placed and turned in its parent's unscaled axes
    as it is in the parent's scaled ones.

    A bone's scale is not part of the motion: a bake carries its keys into the reacted action
    (write_motion), where Blender applies it again. Left in the pose, the offsets a scaled bone
    stretches would become location keys, and a non-uniform scale would shear its children's
    orientations into the rotation keys: both scaled a second time. The heads and orientations are
    Blender's own where no bone is scaled.
    """
    heads, axes = matrices[..., :3, 3], matrices[..., :3, :3]
    rotations = _orthonormal(axes)  # a bone's own scale lies along its axes: their lengths
    if np.abs(np.linalg.norm(axes, axis=-2) - 1.0).max(initial=0.0) <= BONE_SCALE_TOLERANCE:
        return heads, rotations
    index = {b.name: j for j, b in enumerate(bones)}
    unscaled = heads.copy()
    for j, bone in enumerate(bones[1:], start=1):  # parents first
        p = index[cast(bpy.types.Bone, bone.parent).name]
        inverse = np.linalg.inv(axes[:, p])  # into the parent's scaled axes
        offset = inverse @ (heads[:, j] - heads[:, p])[..., None]
        unscaled[:, j] = unscaled[:, p] + (rotations[:, p] @ offset)[..., 0]
        rotations[:, j] = rotations[:, p] @ _orthonormal(inverse @ axes[:, j])
    return unscaled, rotations


def _motion_from_pose(
    armature: bpy.types.Object,
    skeleton: Skeleton,
    bones: list[bpy.types.Bone],
    pose: tuple[np.ndarray, np.ndarray],
    fps: float,
) -> Motion:
    """The core Motion of armature-space heads (T, J, 3) and orientations (T, J, 4)."""
    obj_rot, scale = _object_transform(armature)
    _, rest_rot = _rest_frames(armature, bones)
    heads = scale * quat.rotate(obj_rot, pose[0])
    pose_rot = quat.mul(obj_rot, pose[1])
    delta = quat.mul(pose_rot, quat.conj(rest_rot))  # D_j, (T, J, 4)
    parents = skeleton.parents
    parent_delta = delta[:, parents[1:]]
    local_rot = delta.copy()
    local_rot[:, 1:] = quat.mul(quat.conj(parent_delta), delta[:, 1:])
    local_pos = heads.copy()  # the root's row: its position
    local_pos[:, 1:] = quat.rotate(quat.conj(parent_delta), heads[:, 1:] - heads[:, parents[1:]])
    return _local_motion(skeleton, fps, local_rot, local_pos)


def _local_motion(skeleton: Skeleton, fps: float, local_rot: np.ndarray, local_pos: np.ndarray) -> Motion:
    """The Motion of local rotations (T, J, 4) and translations (T, J, 3), row 0 the root's position;
    the translations are kept only where some joint moves away from its rest offset."""
    translated = np.abs(local_pos[:, 1:] - skeleton.offsets[1:]).max(initial=0.0) > LOCAL_POS_TOLERANCE
    return Motion(
        skeleton=skeleton,
        fps=fps,
        root_pos=local_pos[:, 0],
        local_rot=quat.normalize(local_rot),
        local_pos=local_pos if translated else None,
    )


# ---------------------------------------------------------------------------------------------
# Reading the action's F-curves without a scene update per frame

# Pose-bone channels the pose depends on, and their widths.
_POSE_CHANNELS = {"location": 3, "rotation_quaternion": 4, "rotation_euler": 3, "rotation_axis_angle": 4, "scale": 3}
UNIT_SCALE_TOLERANCE = 1e-6  # a bone scaled further than this from 1 is evaluated by Blender


def _motion_from_fcurves(
    armature: bpy.types.Object, skeleton: Skeleton, bones: list[bpy.types.Bone], frames: np.ndarray, fps: float
) -> Motion | None:
    """The playing action as a Motion straight from its F-curves (see the module docstring), or None
    where more than the action shapes the pose, the scene remaps time (Blender then reads the
    curves between frames), or a curve needs more than Blender's linear or constant segments
    between the frames asked for."""
    fcurves = _playing_fcurves(armature)
    render = bpy.context.scene.render
    if fcurves is None or render.frame_map_old != render.frame_map_new or not _pose_is_action_only(armature, bones):
        return None
    pose_bones = armature.pose.bones
    order = np.array([pose_bones.find(b.name) for b in bones])
    # Every channel holds the pose bone's own value, what Blender keeps where nothing is keyed (a
    # read-only view over the frames until a curve keys it)...
    channels: dict[str, np.ndarray] = {}
    for prop, width in _POSE_CHANNELS.items():
        values = np.empty(len(pose_bones) * width, dtype=np.float32)
        pose_bones.foreach_get(prop, values)  # pyright: ignore[reportArgumentType]
        channels[prop] = np.broadcast_to(values.reshape(-1, width)[order], (len(frames), len(bones), width))
    # ... and a keyed channel holds its curve, evaluated at every frame.
    joint_of = {f'pose.bones["{bpy.utils.escape_identifier(b.name)}"]': j for j, b in enumerate(bones)}
    for fcurve in fcurves:
        bone_path, _, prop = fcurve.data_path.rpartition(".")
        j = joint_of.get(bone_path)
        if j is None or prop not in channels or fcurve.array_index >= _POSE_CHANNELS[prop]:
            continue  # another bone, or a property that does not move the bone (custom, B-Bone...)
        if not len(fcurve.keyframe_points):
            continue  # Blender skips an empty curve
        values = _fcurve_values(fcurve, frames)
        if values is None:
            return None
        if not channels[prop].flags.writeable:
            channels[prop] = channels[prop].astype(float)
        channels[prop][:, j, fcurve.array_index] = values
    if np.abs(channels["scale"] - 1.0).max(initial=0.0) > UNIT_SCALE_TOLERANCE:
        return None
    # Writing inverted: L_j = B_j basis_j B_j^-1, local_pos_j = rest_offset_j + s B_j location_j.
    _, rest_rot = _rest_frames(armature, bones)
    _, scale = _object_transform(armature)
    basis = _basis_rotations([pose_bones[i].rotation_mode for i in order], channels)
    local_rot = quat.sandwich(rest_rot, basis)
    connected = np.array([b.use_connect for b in bones])
    location = np.where(connected[:, None], 0.0, channels["location"])
    local_pos = skeleton.offsets + scale * quat.rotate(rest_rot, location)
    return _local_motion(skeleton, fps, local_rot, local_pos)


def has_keyframes(action: bpy.types.Action) -> bool:
    """Whether any F-curve of the action (of any slot, in Blender 4.4+) has a key."""
    if compat.has_layers(action) and (compat.layered(action).layers or not hasattr(action, "fcurves")):
        bags = [bag for layer in compat.layered(action).layers for strip in layer.strips for bag in strip.channelbags]
        curves = [fcurve for bag in bags for fcurve in bag.fcurves]
    else:  # 4.2, or a legacy action in 4.4/4.5
        curves = list(action.fcurves)
    return any(len(fcurve.keyframe_points) for fcurve in curves)


def _playing_fcurves(armature: bpy.types.Object) -> list[bpy.types.FCurve] | None:
    """The F-curves the assigned action plays on the armature (its slot's, in Blender 4.4+), or
    None where its layers could blend (more than one layer or strip)."""
    adt = armature.animation_data
    action = adt.action if adt is not None else None
    if adt is None or action is None:
        return []
    if not compat.has_layers(action):  # 4.2: legacy actions
        return list(action.fcurves)
    layers = compat.layered(action).layers
    if len(layers) > 1 or any(len(layer.strips) > 1 for layer in layers):
        return None
    return _slot_fcurves(action, compat.assigned_slot(adt))


def _slot_fcurves(action: bpy.types.Action, slot: Any) -> list[bpy.types.FCurve]:
    """The F-curves of `action` for `slot` (Blender 4.4+; None: none), or all of a 4.2 action."""
    if not compat.has_layers(action):  # 4.2: legacy actions
        return list(action.fcurves)
    layers = compat.layered(action).layers
    bags = [strip.channelbag(slot) for layer in layers for strip in layer.strips] if slot is not None else []
    return [fcurve for bag in bags if bag is not None for fcurve in bag.fcurves]


def _pose_is_action_only(armature: bpy.types.Object, bones: list[bpy.types.Bone]) -> bool:
    """True where only the action moves these bones: the pose position shown, no drivers on the
    object or its armature, no bone constraints, every bone inheriting its parent's rotation and
    keying its location in its own axes."""
    data = _armature_data(armature)
    if data.pose_position != "POSE":
        return False
    if any(adt is not None and len(adt.drivers) for adt in (armature.animation_data, data.animation_data)):
        return False
    pose_bones = armature.pose.bones
    return all(
        b.use_inherit_rotation and b.use_local_location and not len(pose_bones[b.name].constraints) for b in bones
    )


def _fcurve_values(fcurve: bpy.types.FCurve, frames: np.ndarray) -> np.ndarray | None:
    """The curve at the given whole frames (T,), as Blender evaluates it: a key's own value on its
    frame, constant before the first key and after the last, linear or constant segments between
    keys. None where that is not enough (muted, modifiers, extrapolated linearly, or a frame
    between two keys joined by a Bézier or easing segment)."""
    if fcurve.mute or (fcurve.group is not None and fcurve.group.mute) or len(fcurve.modifiers):
        return None
    points = fcurve.keyframe_points
    co = np.empty(2 * len(points), dtype=np.float32)
    points.foreach_get("co", co)  # pyright: ignore[reportArgumentType]
    keys, values = co[0::2].astype(float), co[1::2].astype(float)
    if len(keys) == len(frames) and (keys == frames).all():  # a key on every frame asked for: the common case
        return values
    outside = (frames < keys[0]) | (frames > keys[-1])
    if fcurve.extrapolation != "CONSTANT" and outside.any():
        return None
    left = np.clip(np.searchsorted(keys, frames, side="right") - 1, 0, len(keys) - 1)  # the key at or before
    out = values[left]
    between = ~outside & (keys[left] != frames)
    if between.any():
        interpolation = np.empty(len(points), dtype=np.uint8)
        points.foreach_get("interpolation", interpolation)  # pyright: ignore[reportArgumentType]
        segment = left[between]
        kind = interpolation[segment]
        if not np.isin(kind, (_CONSTANT, _LINEAR)).all():
            return None
        weight = (frames[between] - keys[segment]) / (keys[segment + 1] - keys[segment])
        linear = values[segment] + weight * (values[segment + 1] - values[segment])
        out[between] = np.where(kind == _LINEAR, linear, values[segment])
    return out


def _basis_rotations(modes: list[str], channels: dict[str, np.ndarray]) -> np.ndarray:
    """Each bone's rotation channels as quaternions (T, J, 4), by its rotation mode.

    Blender's Euler mode 'XYZ' applies X first: R = Rz Ry Rx, which is quat.from_euler with the
    order reversed. Blender normalises quaternions and axes before use: the axes are normalised
    here, the quaternions by _local_motion (conjugating by a unit B_j keeps their length).
    """
    rotations = channels["rotation_quaternion"].copy()
    for mode in set(modes) - {"QUATERNION"}:
        joints = [j for j, m in enumerate(modes) if m == mode]
        if mode == "AXIS_ANGLE":
            angle_axis = channels["rotation_axis_angle"][:, joints]
            axis = angle_axis[..., 1:] / np.maximum(np.linalg.norm(angle_axis[..., 1:], axis=-1, keepdims=True), 1e-12)
            rotations[:, joints] = quat.from_axis_angle(axis, angle_axis[..., 0])
        else:
            order = mode[::-1]
            euler = channels["rotation_euler"][:, joints]
            rotations[:, joints] = quat.from_euler(euler[..., [quat.AXES.index(a) for a in order]], order)
    return rotations


# ---------------------------------------------------------------------------------------------
# Writing


def write_motion(
    armature: bpy.types.Object,
    motion: Motion,
    name: str,
    frame_start: int = 1,
    *,
    carry_from: bpy.types.Action | None = None,
    carry_slot: str = "",
) -> bpy.types.Action:
    """Write `motion` into a NEW action called `name` (keys at frame_start, frame_start + 1, ...).

    The armature's current action is not touched and the new one is not assigned (the caller
    decides). Bones are switched to quaternion rotation mode, since the new
    action keys quaternions. Every motion joint must be a bone with the same parent.

    carry_from: the action the motion was read from. Every channel of it the motion does not
    decide is copied into the new action, keys and settings as they are (see `_carry_fcurves`):
    object keys, custom properties, bone scale, bones outside the motion. The motion decides the
    rotation (in any rotation mode) and location of its joints' bones. carry_slot (Blender 4.4+):
    identifier of the slot whose channels are carried, the one the armature plays carry_from
    through ("": its first object slot); they go into the new action's one slot.
    On failure nothing is left behind: the new action is removed.
    """
    bones = _bones_in_order(armature)
    joints = _joint_bones(armature, motion.skeleton, bones)
    heads, rest_rot = _rest_frames(armature, bones)
    _, scale = _object_transform(armature)
    b = rest_rot[joints]  # (J, 4)
    basis_rot = quat.make_continuous(quat.sandwich(quat.conj(b), motion.local_rot))
    rest_offsets = heads[joints].copy()
    rest_offsets[1:] -= heads[joints][motion.skeleton.parents[1:]]
    translation = motion.joint_offsets().copy()
    translation[:, 0] = motion.root_pos
    keyed_loc = [0] + (
        [j for j in range(1, len(joints)) if not bones[joints[j]].use_connect] if motion.local_pos is not None else []
    )
    basis_loc = quat.rotate(quat.conj(b[keyed_loc]), translation[:, keyed_loc] - rest_offsets[keyed_loc]) / scale

    action = bpy.data.actions.new(name)
    frames = frame_start + np.arange(motion.num_frames, dtype=np.float64)
    loc_keys, rot_keys = _key_points(frames, basis_loc), _key_points(frames, basis_rot)
    linear = np.full(motion.num_frames, _LINEAR, dtype=np.uint8)
    names = motion.skeleton.names
    try:
        new_fcurve = _fcurve_factory(action, armature)
        for j, bone_name in enumerate(names):
            path = f'pose.bones["{bpy.utils.escape_identifier(bone_name)}"]'
            if j in keyed_loc:
                k = keyed_loc.index(j)
                for axis in range(3):
                    _set_keys(new_fcurve(path + ".location", axis, bone_name), loc_keys[k, axis], linear)
            for axis in range(4):
                _set_keys(new_fcurve(path + ".rotation_quaternion", axis, bone_name), rot_keys[j, axis], linear)
        if carry_from is not None:
            _carry_fcurves(armature, carry_from, carry_slot, new_fcurve, set(names))
    except BaseException:
        bpy.data.actions.remove(action)
        raise
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


def _key_points(frames: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Keyframe coordinates of every curve at once, (J, axes, 2 T) float32, each row the (frame,
    value) pairs `foreach_set("co")` takes: one conversion for all curves, not one per curve."""
    co = np.empty((values.shape[1], values.shape[2], len(frames), 2), dtype=np.float32)
    co[..., 0] = frames
    co[..., 1] = values.transpose(1, 2, 0)
    return co.reshape(values.shape[1], values.shape[2], -1)


def _set_keys(fcurve: bpy.types.FCurve, co: np.ndarray, interpolation: np.ndarray) -> None:
    """All keys of one curve in bulk calls (co: _key_points' row; interpolation: linear, one key per frame).

    The keys come in frame order, so nothing needs sorting, and their Bézier handles are left where
    `keyframe_points.add` puts them, as Blender's own BVH importer leaves them: linear segments never
    use them, and Blender's editors compute them when a key is moved or made Bézier. Computing them
    here (fcurve.update) would take longer than writing the keys.
    """
    points = fcurve.keyframe_points
    points.add(len(interpolation))
    # An ndarray is a buffer, but numpy 1.26's stubs declare __buffer__ only for Python 3.12+.
    points.foreach_set("co", co)  # pyright: ignore[reportArgumentType]
    points.foreach_set("interpolation", interpolation)  # pyright: ignore[reportArgumentType]


def _fcurve_factory(
    action: bpy.types.Action, armature: bpy.types.Object
) -> Callable[[str, int, str], bpy.types.FCurve]:
    """new_fcurve(data_path, index, group) for whichever action API this Blender has."""
    if not compat.has_layers(action):  # 4.2: legacy actions
        return lambda path, index, group: action.fcurves.new(path, index=index, action_group=group)
    layered = compat.layered(action)
    slot = layered.slots.new(id_type="OBJECT", name=armature.name)
    strip = layered.layers.new("Layer").strips.new(type="KEYFRAME")
    channelbag = strip.channelbag(slot, ensure=True)
    if compat.fcurves_new_takes_group(channelbag):  # 5.0 and newer
        return lambda path, index, group: channelbag.fcurves.new(path, index=index, group_name=group)

    def new_fcurve(path: str, index: int, group: str) -> bpy.types.FCurve:  # 4.4 / 4.5
        fcurve = channelbag.fcurves.new(path, index=index)
        if group:  # "" leaves it ungrouped, as the other two APIs do
            fcurve.group = channelbag.groups.get(group) or channelbag.groups.new(group)
        return fcurve

    return new_fcurve


# ---------------------------------------------------------------------------------------------
# Carrying the source action's other channels into a written action

# A pose bone's channel: its name (quoted either way, escaped) and the property.
_BONE_CHANNEL = re.compile(r"""^pose\.bones\[(["'])((?:\\.|(?!\1).)*)\1\]\.(\w+)$""")
# The channels of a motion joint's bone that the written motion decides, at any array index (a
# rotation mode the bone leaves for quaternions, a location the motion leaves at rest included).
_DECIDED = frozenset({"location", "rotation_quaternion", "rotation_euler", "rotation_axis_angle"})
# Keyframe fields a carried curve copies, with the buffer type foreach_get/foreach_set copy as is
# (an enum as its stored byte).
_KEY_FIELDS = (
    ("co", 2, np.float32),
    ("handle_left", 2, np.float32),
    ("handle_right", 2, np.float32),
    ("interpolation", 1, np.uint8),
    ("easing", 1, np.uint8),
    ("handle_left_type", 1, np.uint8),
    ("handle_right_type", 1, np.uint8),
    ("type", 1, np.uint8),
    ("back", 1, np.float32),
    ("amplitude", 1, np.float32),
    ("period", 1, np.float32),
)
_FCURVE_FIELDS = ("extrapolation", "mute", "hide", "lock", "color_mode", "color", "auto_smoothing")


def _carry_fcurves(
    armature: bpy.types.Object,
    source: bpy.types.Action,
    slot_identifier: str,
    new_fcurve: Callable[[str, int, str], bpy.types.FCurve],
    joints: set[str],
) -> None:
    """Copy every F-curve `source` plays on the armature through the slot `slot_identifier` (4.4+),
    except the channels the motion decides (`_DECIDED` of the `joints`' bones), with new_fcurve,
    into the same group. A copy is the curve as it is: keys in bulk (frame, value, handles and
    their types, interpolation, easing and its parameters, key type), extrapolation, mute and
    display settings, modifiers; its integer or on/off evaluation is set as Blender sets it for
    the property the path names on the armature."""
    for fcurve in _slot_fcurves(source, compat.object_slot(source, slot_identifier)):
        match = _BONE_CHANNEL.match(fcurve.data_path)
        if match and match[3] in _DECIDED and re.sub(r"\\(.)", r"\1", match[2]) in joints:
            continue
        copy = new_fcurve(fcurve.data_path, fcurve.array_index, fcurve.group.name if fcurve.group else "")
        _copy_fcurve(fcurve, copy)
        with suppress(RuntimeError):  # a path the armature lacks (a property removed since): flags as made
            copy.update_autoflags(armature)


def _copy_fcurve(source: bpy.types.FCurve, target: bpy.types.FCurve) -> None:
    """The keys (or samples), settings and modifiers of `source` onto the new, empty `target`.

    Keys go in last: adding a Cycles modifier makes Blender recompute the handles of the keys a
    curve has, which must stay as the source has them. Samples go in before the modifiers, which
    sampling would bake into them."""
    for field in _FCURVE_FIELDS:
        setattr(target, field, getattr(source, field))
    count = len(source.keyframe_points)
    if not count and len(source.sampled_points):  # baked samples, one per frame: sampled from linear keys
        samples = np.empty(2 * len(source.sampled_points), dtype=np.float32)
        source.sampled_points.foreach_get("co", samples)  # pyright: ignore[reportArgumentType]
        _set_keys(target, samples, np.full(len(samples) // 2, _LINEAR, dtype=np.uint8))
        target.convert_to_samples(round(samples[0]), round(samples[-2]) + 1)  # the end frame is not sampled
    copies = [(modifier, target.modifiers.new(modifier.type)) for modifier in source.modifiers]
    for modifier, copy in copies:
        _copy_settings(modifier, copy)
    for modifier, copy in sorted(copies, key=lambda pair: bool(pair[0].active)):  # each new one took it: active last
        copy.active = modifier.active
    if count:
        target.keyframe_points.add(count)
        for field, width, dtype in _KEY_FIELDS:
            values = np.empty(count * width, dtype=dtype)
            source.keyframe_points.foreach_get(field, values)  # pyright: ignore[reportArgumentType]
            target.keyframe_points.foreach_set(field, values)  # pyright: ignore[reportArgumentType]


def _copy_settings(source: Any, target: Any) -> None:
    """An F-curve modifier's settings onto a new one of its type (in RNA order, which sets a
    generator's order before its coefficients), and an envelope's control points."""
    for prop in source.bl_rna.properties:
        if not prop.is_readonly and prop.type not in {"POINTER", "COLLECTION"}:
            setattr(target, prop.identifier, getattr(source, prop.identifier))
    points = list(getattr(source, "control_points", ()))
    for point in points:
        target.control_points.add(point.frame)
    # Set in bulk: assigned one by one, each value runs the modifier's update on the control point,
    # which Blender reads as a whole modifier past the point's 16 bytes (a segfault, seen on 5.1).
    for field in ("min", "max") if points else ():
        target.control_points.foreach_set(field, [getattr(point, field) for point in points])
