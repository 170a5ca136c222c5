"""armature/action <-> Motion on the real Blender: conventions cross-checked against core FK."""

from __future__ import annotations

import bpy
import numpy as np
import pytest

from reactive_anim.blender import compat
from reactive_anim.blender.character import action_io, bvh_import
from reactive_anim.core.model import bvh, quat
from reactive_anim.core.model.errors import SkeletonError
from reactive_anim.core.model.skeleton import Motion
from tests.support.actions import action_of, keyframes
from tests.support.mocap import require_mocap

# Three skeletons from three datasets: CMU cgspeed (31 joints, ZYX, only the root translated),
# Bandai Namco (22 joints, ZXY, every joint translated), iClone CC rig (101 joints, twist/face bones).
CROSS_CHECK_FILES = [
    "cmu/90_18.bvh",
    "bandai_namco/dataset-2/dataset-2_walk-turn-left_normal_001.bvh",
    "cmu_iclone/007_01.bvh",
]


@pytest.mark.parametrize("relative", CROSS_CHECK_FILES)
def test_core_fk_matches_blender_import(relative):
    """Core FK of the file equals the bone heads Blender evaluates on the imported rig, within 1 mm,
    all frames (the evaluated pose: our reading of the curves is tested against it elsewhere)."""
    path = require_mocap(relative)
    armature = bvh_import.import_bvh(bpy.context, path)
    read = action_io.read_motion(armature, evaluate=True)
    core = bvh.read_bvh(path)
    assert read.num_frames == core.num_frames
    assert read.fps == pytest.approx(core.fps, rel=1e-4)
    order = [read.skeleton.names.index(n) for n in core.skeleton.names]
    error = np.linalg.norm(read.global_positions()[:, order] - core.global_positions(), axis=-1)
    assert error.max() < 1e-3, (
        f"max {error.max() * 1000:.3f} mm at frame {np.unravel_index(error.argmax(), error.shape)}"
    )


def test_write_then_read_round_trip_leaves_source_untouched():
    path = require_mocap("bandai_namco/dataset-1/dataset-1_walk_normal_002.bvh")
    armature = bvh_import.import_bvh(bpy.context, path)
    source = action_of(armature)
    before = keyframes(source)
    motion = action_io.read_motion(armature)
    assert motion.local_pos is not None  # this dataset animates every joint's translation

    written = action_io.write_motion(armature, motion, "walk.copy")
    again = action_io.read_motion(armature, written)

    assert written != source and written.name == "walk.copy"
    assert armature.animation_data.action == source  # reading another action restores the assignment
    assert np.abs(again.global_positions() - motion.global_positions()).max() < 1e-5
    assert quat.angle_between(again.local_rot, motion.local_rot).max() < 1e-5
    assert np.abs(again.joint_offsets() - motion.joint_offsets()).max() < 1e-5
    after = keyframes(source)
    assert after.keys() == before.keys()
    assert all(after[k] == before[k] for k in before)


def _rotated_scaled_rig() -> bpy.types.Object:
    """A hand-built 3-bone armature with rolled bones, under a rotated and scaled object."""
    data = bpy.data.armatures.new("rig")
    rig = bpy.data.objects.new("rig", data)
    bpy.context.scene.collection.objects.link(rig)
    bpy.context.view_layer.objects.active = rig
    bpy.ops.object.mode_set(mode="EDIT")
    specs = [
        ("root", None, (0, 0, 1), (0, 0.1, 1.3), 0.3),
        ("arm", "root", (0, 0.1, 1.3), (0.4, 0.2, 1.4), 1.1),
        ("hand", "arm", (0.45, 0.2, 1.4), (0.6, 0.1, 1.35), -0.7),
    ]
    for name, parent, head, tail, roll in specs:
        bone = data.edit_bones.new(name)
        bone.head, bone.tail, bone.roll = head, tail, roll
        if parent:
            bone.parent = data.edit_bones[parent]
    bpy.ops.object.mode_set(mode="OBJECT")
    rig.rotation_euler = (0.2, -0.3, 1.0)
    rig.scale = (0.5, 0.5, 0.5)
    rig.location = (1.0, -2.0, 0.5)
    bpy.context.view_layer.update()
    return rig


def test_round_trip_on_a_rig_that_is_not_a_bvh_import():
    """Rolled bones, a disconnected child and a rotated, scaled object: no importer layout assumed."""
    rig = _rotated_scaled_rig()
    rng = np.random.default_rng(7)
    frames, joints = 12, 3
    motion_rot = quat.normalize(quat.identity((frames, joints)) + 0.3 * rng.normal(size=(frames, joints, 4)))
    skeleton = action_io.armature_skeleton(rig)
    local_pos = np.broadcast_to(skeleton.offsets, (frames, joints, 3)) + 0.02 * rng.normal(size=(frames, joints, 3))
    root_pos = skeleton.offsets[0] + 0.1 * rng.normal(size=(frames, 3))
    motion = Motion(skeleton, 24.0, root_pos, motion_rot, local_pos)
    action = action_io.write_motion(rig, motion, "random")
    assert rig.animation_data is None  # writing does not assign
    back = action_io.read_motion(rig, action)
    assert rig.animation_data is None  # reading another action leaves no trace on the rig
    assert np.abs(back.global_positions() - motion.global_positions()).max() < 1e-5
    assert quat.angle_between(back.local_rot, motion.local_rot).max() < 1e-5


def test_evaluated_pose_includes_constraints():
    """read_motion sees what Blender shows: a constraint's effect is part of the pose."""
    rig = _rotated_scaled_rig()
    plain = action_io.read_motion(rig, frame_range=(1, 2))
    constraint = rig.pose.bones["hand"].constraints.new("LIMIT_ROTATION")
    assert isinstance(constraint, bpy.types.LimitRotationConstraint)
    constraint.use_limit_x = constraint.use_limit_y = constraint.use_limit_z = True
    constraint.owner_space = "LOCAL"
    rig.pose.bones["hand"].rotation_mode = "XYZ"
    rig.pose.bones["hand"].rotation_euler = (1.0, 0.5, 0.2)
    limited = action_io.read_motion(rig, frame_range=(1, 2))
    rig.pose.bones["hand"].constraints.remove(constraint)
    free = action_io.read_motion(rig, frame_range=(1, 2))
    assert quat.angle_between(limited.local_rot[:, 2], plain.local_rot[:, 2]).max() < 1e-5
    assert quat.angle_between(free.local_rot[:, 2], plain.local_rot[:, 2]).max() > 0.5


def test_write_motion_names_missing_bones():
    rig = _rotated_scaled_rig()
    motion = action_io.read_motion(rig, frame_range=(1, 3))
    motion.skeleton.names[2] = "finger"
    with pytest.raises(SkeletonError, match="lacks bones the motion animates: finger"):
        action_io.write_motion(rig, motion, "bad")
    assert "bad" not in bpy.data.actions


def test_action_api_path_matches_this_blender():
    """The F-curve path chosen by feature detection is the one this Blender version needs."""
    rig = _rotated_scaled_rig()
    action = action_io.write_motion(rig, action_io.read_motion(rig, frame_range=(1, 2)), "api")
    major_minor = bpy.app.version[:2]
    if major_minor < (4, 4):
        assert not hasattr(action, "layers") and len(action.fcurves) == 3 * 4 + 3
    else:
        layered = compat.layered(action)
        bag = layered.layers[0].strips[0].channelbag(layered.slots[0])
        assert len(bag.fcurves) == 3 * 4 + 3
        assert {g.name for g in bag.groups} == {"root", "arm", "hand"}
