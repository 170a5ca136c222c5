"""read_motion straight from the F-curves equals Blender's evaluated pose, and rigs whose pose
depends on more than the action (constraints, drivers, scale, curves it cannot evaluate) are still
evaluated frame by frame. Which way was taken shows in the frame changes a read makes: the direct
reading makes one (restoring the scene's frame), the evaluated one one per frame read and one more."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

import bpy
import numpy as np
import pytest

from reactive_anim.blender import compat
from reactive_anim.blender.character import action_io, armature_build, bvh_import
from reactive_anim.core.model import quat
from reactive_anim.core.model.skeleton import Skeleton
from tests.support.actions import action_of, fcurves
from tests.support.mocap import require_mocap
from tools.devkit.blender_types import armature_data

if TYPE_CHECKING:
    from bpy._typing.rna_enums import ObjectRotationModeItems

WALK = Path(__file__).resolve().parents[2] / "sample_clips" / "walk.bvh"
FRAMES = (0, 12)  # one frame before the first key, three after the last (constant extrapolation)
MODES: list[ObjectRotationModeItems] = [
    "XYZ",
    "ZXY",
    "YZX",
    "AXIS_ANGLE",
    "QUATERNION",
    "ZYX",
]  # one per bone of the test rig


@contextmanager
def frame_changes() -> Iterator[list[int]]:
    """The frames the scene is set to while the block runs."""
    seen: list[int] = []

    def note(scene: bpy.types.Scene, *_args: object) -> None:
        seen.append(scene.frame_current)

    bpy.app.handlers.frame_change_post.append(note)
    try:
        yield seen
    finally:
        bpy.app.handlers.frame_change_post.remove(note)


def read_both_ways(rig: bpy.types.Object, **options) -> tuple[list[int], list[int]]:
    """Read directly and evaluated; assert they agree; return the frame changes of each read."""
    with frame_changes() as direct_frames:
        direct = action_io.read_motion(rig, **options)
    with frame_changes() as evaluated_frames:
        evaluated = action_io.read_motion(rig, evaluate=True, **options)
    assert direct.num_frames == evaluated.num_frames
    assert np.abs(direct.global_positions() - evaluated.global_positions()).max() < 1e-5
    assert quat.angle_between(direct.local_rot, evaluated.local_rot).max() < 1e-5
    assert (direct.local_pos is None) == (evaluated.local_pos is None)
    return direct_frames, evaluated_frames


def took_the_direct_way(frames: tuple[list[int], list[int]]) -> bool:
    direct, evaluated = frames
    assert len(evaluated) > 2  # the reference always evaluates every frame
    return len(direct) == 1


@pytest.mark.parametrize(
    "relative",
    [
        "walk",
        "cmu/90_18.bvh",
        "bandai_namco/dataset-2/dataset-2_walk-turn-left_normal_001.bvh",  # every joint translated
        "cmu_iclone/007_01.bvh",
    ],
)
def test_imported_bvh_reads_directly_and_equals_the_evaluated_pose(relative):
    path = WALK if relative == "walk" else require_mocap(relative)
    rig = bvh_import.import_bvh(bpy.context, path)
    assert took_the_direct_way(read_both_ways(rig))


def euler_rig() -> bpy.types.Object:
    """Six bones in six rotation modes (Euler orders, axis-angle, quaternion), a branch, a child off
    its parent's tail, rolled bones, a rotated and scaled object; keys on frames 1, 4, 5, 9 with
    linear and constant segments, location keyed on the root and the loose child."""
    offsets = [(0, 0, 1), (0, 0.1, 0.3), (0.2, 0, 0.2), (0.1, 0.1, 0), (0, 0, 0.2), (-0.2, 0, 0.1)]
    skeleton = Skeleton(
        [f"b{j}" for j in range(6)], np.array([-1, 0, 1, 2, 1, 4]), np.array(offsets), {3: np.array([0, 0.1, 0])}
    )
    tilted = quat.to_matrix(quat.normalize(np.array([0.9, 0.2, -0.3, 0.25])))
    rig = armature_build.build_armature(
        bpy.context, skeleton, "euler", file_axes=tilted, file_unit=1.0, translated_joints={5}
    )
    rig.rotation_euler = (0.2, -0.3, 1.0)
    rig.scale = (0.5, 0.5, 0.5)
    rig.location = (1.0, -2.0, 0.5)
    rng = np.random.default_rng(3)
    for pose_bone, mode in zip(rig.pose.bones, MODES, strict=True):
        pose_bone.rotation_mode = mode
        for frame in (1, 4, 5, 9):
            if mode == "QUATERNION":
                pose_bone.rotation_quaternion = rng.normal(size=4).tolist()  # not unit: Blender normalises
            elif mode == "AXIS_ANGLE":
                pose_bone.rotation_axis_angle = rng.normal(size=4)
            else:
                pose_bone.rotation_euler = rng.uniform(-2, 2, size=3).tolist()
            pose_bone.keyframe_insert({"QUATERNION": "rotation_quaternion", "AXIS_ANGLE": "rotation_axis_angle"}.get(
                mode, "rotation_euler"), frame=frame)  # fmt: skip
            if pose_bone.name in ("b0", "b5"):
                pose_bone.location = rng.normal(scale=0.1, size=3).tolist()
                pose_bone.keyframe_insert("location", frame=frame)
    for k, fcurve in enumerate(fcurves(action_of(rig))):
        for point in fcurve.keyframe_points:
            point.interpolation = "CONSTANT" if k % 3 == 0 else "LINEAR"
    return rig


def test_euler_and_axis_angle_rig_reads_directly():
    rig = euler_rig()
    bones = armature_data(rig).bones
    assert not bones["b5"].use_connect and bones["b1"].use_connect
    assert took_the_direct_way(read_both_ways(rig, frame_range=FRAMES))


def test_a_connected_bones_location_is_ignored_both_ways():
    rig = euler_rig()
    rig.pose.bones["b1"].location = (0.3, 0.2, 0.1)  # connected: Blender ignores it
    assert took_the_direct_way(read_both_ways(rig, frame_range=FRAMES))


def test_bezier_keys_read_directly_on_their_frames_and_evaluated_between():
    rig = euler_rig()
    for fcurve in fcurves(action_of(rig)):
        for point in fcurve.keyframe_points:
            point.interpolation = "BEZIER"
        fcurve.update()
    assert took_the_direct_way(read_both_ways(rig, frame_range=(4, 5)))  # keys on both frames
    assert not took_the_direct_way(read_both_ways(rig, frame_range=FRAMES))


def test_a_rig_with_a_constraint_is_evaluated():
    rig = euler_rig()
    constraint = rig.pose.bones["b2"].constraints.new("LIMIT_ROTATION")
    assert isinstance(constraint, bpy.types.LimitRotationConstraint)
    constraint.use_limit_x = constraint.use_limit_z = True
    constraint.owner_space = "LOCAL"
    assert not took_the_direct_way(read_both_ways(rig, frame_range=FRAMES))


def test_a_rig_with_a_driver_is_evaluated():
    rig = euler_rig()
    driver = rig.pose.bones["b3"].driver_add("rotation_euler", 0).driver
    driver.expression = "frame / 10"
    assert not took_the_direct_way(read_both_ways(rig, frame_range=FRAMES))


def test_a_scaled_bone_is_evaluated():
    rig = euler_rig()
    rig.pose.bones["b1"].scale = (1.2, 1.0, 1.0)
    assert not took_the_direct_way(read_both_ways(rig, frame_range=FRAMES))


def test_a_scene_that_remaps_time_is_evaluated():
    rig = euler_rig()
    bpy.context.scene.render.frame_map_old, bpy.context.scene.render.frame_map_new = 100, 150
    assert not took_the_direct_way(read_both_ways(rig, frame_range=FRAMES))


@pytest.mark.parametrize("change", ["linear extrapolation", "muted curve", "modifier"])
def test_curves_it_cannot_evaluate_are_evaluated_by_blender(change):
    rig = euler_rig()
    fcurve = next(fc for fc in fcurves(action_of(rig)) if fc.data_path.endswith(".location"))
    if change == "linear extrapolation":
        fcurve.extrapolation = "LINEAR"
    elif change == "muted curve":
        fcurve.mute = True
    else:
        fcurve.modifiers.new("NOISE")
    assert not took_the_direct_way(read_both_ways(rig, frame_range=FRAMES))


@pytest.mark.skipif(bpy.app.version < (4, 4), reason="action slots came with Blender 4.4")
def test_only_the_playing_slots_curves_are_read():
    rig = euler_rig()
    action = action_of(rig)
    layered = compat.layered(action)
    other = layered.slots.new(id_type="OBJECT", name="other")
    bag = layered.layers[0].strips[0].channelbag(other, ensure=True)
    points = bag.fcurves.new('pose.bones["b2"].rotation_euler', index=0).keyframe_points
    points.insert(1, 2.5)
    assert took_the_direct_way(read_both_ways(rig, frame_range=FRAMES))


def _hide_in_every_way(rig: bpy.types.Object, how: str) -> None:
    """Hide the rig the ways a scene does, each of which Blender's depsgraph then skips."""
    if how == "object disabled in viewports":
        rig.hide_viewport = True
    elif how == "object hidden":
        rig.hide_set(True)
    else:
        collection = bpy.data.collections.new("chars")
        bpy.context.scene.collection.children.link(collection)
        for owner in list(rig.users_collection):
            owner.objects.unlink(rig)
        collection.objects.link(rig)
        layer = bpy.context.view_layer.layer_collection.children["chars"]
        if how == "collection excluded":
            layer.exclude = True
        elif how == "collection disabled in viewports":
            collection.hide_viewport = True
        else:
            layer.hide_viewport = True


@pytest.mark.parametrize(
    "how",
    [
        "object disabled in viewports",
        "object hidden",
        "collection excluded",
        "collection disabled in viewports",
        "collection hidden",
    ],
)
def test_a_hidden_character_is_read_as_it_moves_and_left_hidden(how):
    """A rig that needs Blender's evaluation (a constraint) read while hidden: every frame read one
    frozen pose (a bake then simulated a statue and reported success)."""
    rig = bvh_import.import_bvh(bpy.context, WALK)
    rig.pose.bones["head"].constraints.new("LIMIT_ROTATION")  # the evaluated path, nothing limited
    shown = action_io.read_motion(rig, frame_range=(1, 40))
    _hide_in_every_way(rig, how)
    layer = bpy.context.view_layer.layer_collection.children.get("chars")
    before = (rig.hide_viewport, layer and (layer.exclude, layer.hide_viewport, layer.collection.hide_viewport))
    hidden = action_io.read_motion(rig, frame_range=(1, 40))
    assert np.abs(hidden.global_positions() - shown.global_positions()).max() < 1e-5
    after = (rig.hide_viewport, layer and (layer.exclude, layer.hide_viewport, layer.collection.hide_viewport))
    assert after == before
    if how == "object hidden":
        assert rig.hide_get()
