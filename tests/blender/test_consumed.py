"""Constraints and drivers a bake consumes (blender/bake/consumed.py): the reacted keys hold the pose
Blender evaluated with them, so while the reacted action plays they are muted, not applied twice;
Clear Reactions turns them back on, and a rebake reads the original as it played."""

from __future__ import annotations

import bpy
import numpy as np

from reactive_anim.blender.bake import bake
from tests.support.bake_scene import walk_with_impacts
from tools.devkit.operators import addon_ops

BEFORE_FIRST_IMPACT = range(1, 40, 6)  # walk_with_impacts hits first at frame 41


def _world(rig: bpy.types.Object, bone: str, frames) -> np.ndarray:
    """The bone's world head and world rotation (as a matrix) on each frame, as Blender plays it."""
    rows = []
    for frame in frames:
        bpy.context.scene.frame_set(frame)
        matrix = rig.matrix_world @ rig.pose.bones[bone].matrix
        rows.append([*matrix.translation, *np.array(matrix.to_3x3()).ravel()])
    return np.array(rows)


def _moving_empty() -> bpy.types.Object:
    """A vehicle: an empty travelling 2 m along X and turning while the character rides it."""
    empty = bpy.data.objects.new("vehicle", None)
    bpy.context.scene.collection.objects.link(empty)
    for frame, x, turn in ((1, 0.0, 0.0), (264, 2.0, 0.6)):
        empty.location = (x, 0.0, 0.0)
        empty.rotation_euler = (0.0, 0.0, turn)
        empty.keyframe_insert("location", frame=frame)
        empty.keyframe_insert("rotation_euler", frame=frame)
    return empty


def test_a_child_of_and_an_additive_copy_rotation_are_not_applied_twice(empty_scene):
    rig = walk_with_impacts(empty_scene)
    child_of = rig.pose.bones["pelvis"].constraints.new("CHILD_OF")
    assert isinstance(child_of, bpy.types.ChildOfConstraint)
    child_of.target = _moving_empty()
    copy = rig.pose.bones["head"].constraints.new("COPY_ROTATION")
    assert isinstance(copy, bpy.types.CopyRotationConstraint)
    copy.target, copy.mix_mode = child_of.target, "ADD"
    original = {bone: _world(rig, bone, BEFORE_FIRST_IMPACT) for bone in ("pelvis", "head")}

    assert addon_ops.bake(armature_name="walk") == {"FINISHED"}
    assert child_of.mute and copy.mute
    for bone, expected in original.items():
        assert np.abs(_world(rig, bone, BEFORE_FIRST_IMPACT) - expected).max() < 1e-4, bone

    assert addon_ops.clear_bake(armature_name="walk") == {"FINISHED"}
    assert not child_of.mute and not copy.mute
    for bone, expected in original.items():
        assert np.abs(_world(rig, bone, BEFORE_FIRST_IMPACT) - expected).max() < 1e-6, bone


def test_a_rebake_reads_the_original_with_its_constraints(empty_scene):
    rig = walk_with_impacts(empty_scene)
    child_of = rig.pose.bones["pelvis"].constraints.new("CHILD_OF")
    assert isinstance(child_of, bpy.types.ChildOfConstraint)
    child_of.target = _moving_empty()
    assert addon_ops.bake(armature_name="walk") == {"FINISHED"}
    first = _world(rig, "pelvis", range(1, 264, 7))
    assert addon_ops.bake(armature_name="walk") == {"FINISHED"}
    assert np.array_equal(_world(rig, "pelvis", range(1, 264, 7)), first)
    assert bake.bake_state(rig).muted.count('"constraint"') == 1  # listed once, not again by the rebake


def test_a_driver_on_a_keyed_rotation_is_muted_and_restored(empty_scene):
    rig = walk_with_impacts(empty_scene)
    rig.pose.bones["head"].rotation_mode = "XYZ"
    driver = rig.pose.bones["head"].driver_add("rotation_euler", 2)
    driver.driver.expression = "0.3"
    unrelated = rig.pose.bones["head"].driver_add("scale", 0)  # not a channel the bake keys
    unrelated.driver.expression = "1.0"
    assert addon_ops.bake(armature_name="walk") == {"FINISHED"}
    assert driver.mute and not unrelated.mute
    bpy.context.scene.frame_set(20)
    turned = rig.pose.bones["head"].matrix.to_quaternion()
    assert addon_ops.clear_bake(armature_name="walk") == {"FINISHED"}
    assert not driver.mute
    bpy.context.scene.frame_set(20)
    assert rig.pose.bones["head"].matrix.to_quaternion().rotation_difference(turned).angle < 1e-4
    assert abs(rig.pose.bones["head"].rotation_euler.z - 0.3) < 1e-6  # the driver drives again
