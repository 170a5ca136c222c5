"""Reactions from the sample library baked onto characters of other skeletons (issue "any character"):
the shared iClone (CMU-derived CC rig), Bandai Namco and CMU files imported, and an armature made
here in Blender with Mixamo-style names, an A-pose rest and bones rolled a quarter turn."""

from __future__ import annotations

import bpy
import numpy as np
import pytest

from reactive_anim.blender.bake import bake
from reactive_anim.blender.character import action_io, bvh_import
from reactive_anim.blender.impacts import impacts
from reactive_anim.core.model import quat
from reactive_anim.core.model.rig import Rig
from reactive_anim.core.model.roles import RIG_PRESETS, assign_roles
from reactive_anim.core.model.skeleton import Skeleton
from reactive_anim.core.transition import retarget
from reactive_anim.core.transition.casting import _sole
from tests.support.actions import action_of
from tests.support.mocap import require_mocap
from tools.devkit.skeletons import WALK, role_bone_angles, turned_chain

SHARED = ["cmu_iclone/002_01.bvh", "bandai_namco/dataset-1/dataset-1_walk_normal_001.bvh", "cmu/139_16.bvh"]
# Sample bone -> Mixamo bone, role by role.
MIXAMO_NAMES = {RIG_PRESETS["sample"][role]: RIG_PRESETS["mixamo"][role] for role in RIG_PRESETS["sample"]}


def _lowest_feet(motion, roles: dict[str, str]) -> np.ndarray:
    """(T,) the lower of the two feet's lowest points (toes, end sites)."""
    pos, rot = motion.global_transforms()
    sk = motion.skeleton
    feet = [retarget.lowest_foot_point(sk, sk.index(roles[f"ankle_{s}"]), pos, rot) for s in ("l", "r")]
    return np.minimum(*feet)


def _bake_one_push(scene: bpy.types.Scene, rig: bpy.types.Object, frame: int, strength: float) -> bake.BakeResult:
    roles = assign_roles(action_io.armature_skeleton(rig))
    motion = action_io.read_motion(rig)
    pelvis = motion.global_positions()[:, motion.skeleton.index(roles["pelvis"])]
    forward = pelvis[frame + 10] - pelvis[frame - 10]
    forward[2] = 0.0
    impacts.add_impact(scene, rig, roles["chest"], frame + 1, tuple(forward / np.linalg.norm(forward)), strength)
    return bake.bake_armature(scene, rig)


@pytest.mark.parametrize("relative", SHARED)
def test_reactions_bake_onto_shared_skeletons_with_the_feet_on_the_floor(empty_scene, relative):
    rig = bvh_import.import_bvh(bpy.context, require_mocap(relative))
    before = action_io.read_motion(rig)
    roles = assign_roles(before.skeleton)
    frame = min(int(before.fps), before.num_frames // 3)

    result = _bake_one_push(empty_scene, rig, frame, 90.0)

    assert action_of(rig).name == result.reacted_action
    reacted = action_io.read_motion(rig)
    assert reacted.num_frames > frame + before.fps * 0.5
    # The clip after F (its first half: the end is blended into the resumed motion) stands on the
    # character's own floor: no foot goes through it, and a planted foot stands on it. (Where the
    # clip's feet are planted, core/test_retarget.py checks them frame by frame.)
    reaction = result.reactions[0]
    sole = _sole(
        before, Rig(before.skeleton, roles)
    )  # the take's floor, a calibration frame 0 left out (139_16 opens on one)
    lowest = _lowest_feet(reacted, roles)[
        reaction.frame_f : max(reaction.frame_f + 1, (reaction.frame_f + reaction.end_frame) // 2)
    ]
    assert lowest.min() > sole - 0.01, (relative, sole, lowest.min())
    if len(lowest) > 10:
        assert lowest.min() < sole + 0.01, (relative, sole, lowest.min())
    assert "no classifier model" not in result.summary()


def _a_pose_mixamo_rig(scene: bpy.types.Scene) -> tuple[bpy.types.Object, Skeleton]:
    """The sample skeleton in A-pose (arms 45 deg out from hanging) under Mixamo names, built as
    Blender bones rolled a quarter turn about themselves, its walk written by retargeting."""
    skeleton = WALK.skeleton
    for side, sign in (("L", 1.0), ("R", -1.0)):
        skeleton = turned_chain(skeleton, f"upper_arm.{side}", quat.from_axis_angle([0, 1.0, 0], -sign * np.pi / 4))
    data = bpy.data.armatures.new("hero")
    rig = bpy.data.objects.new("hero", data)
    scene.collection.objects.link(rig)
    bpy.context.view_layer.objects.active = rig
    bpy.ops.object.mode_set(mode="EDIT")
    rest = skeleton.rest_positions()
    for j, name in enumerate(skeleton.names):
        bone = data.edit_bones.new(MIXAMO_NAMES[name])
        children = skeleton.children(j)
        tip = rest[children[0]] if children else rest[j] + skeleton.end_sites.get(j, np.array([0.0, 0.0, 0.1]))
        bone.head, bone.tail = rest[j], tip if np.linalg.norm(tip - rest[j]) > 1e-3 else rest[j] + [0, 0, 0.05]
        bone.roll = np.pi / 2
        if skeleton.parents[j] >= 0:
            bone.parent = data.edit_bones[MIXAMO_NAMES[skeleton.names[skeleton.parents[j]]]]
    bpy.ops.object.mode_set(mode="OBJECT")
    return rig, skeleton


def test_an_a_pose_rig_with_rolled_bones_plays_the_clips_role_bones_as_the_source(empty_scene):
    rig, _ = _a_pose_mixamo_rig(empty_scene)
    target = action_io.armature_skeleton(rig)  # the rig as the core reads it from Blender
    mapping = retarget.retarget_map(Rig.of(WALK.skeleton), Rig.of(target))
    assert mapping.scale == pytest.approx(1.0, abs=1e-6) and len(mapping.roles) == 22
    motion = retarget.retarget(WALK, mapping)
    action = action_io.write_motion(rig, motion, "hero_walk", frame_start=1)
    bake.assign_action(rig, action)

    back = action_io.read_motion(rig)  # as Blender evaluates it: rolls, A-pose rest and all
    angles = role_bone_angles(mapping, WALK.global_positions(), back.global_positions())
    assert max(angles.values()) < 5.0, {r: round(v, 1) for r, v in angles.items() if v > 2}

    result = _bake_one_push(empty_scene, rig, 60, 120.0)
    assert action_of(rig).name == "hero_walk.reacted"
    assert "'hit_01' mixamorig:Spine2:" in result.summary()
