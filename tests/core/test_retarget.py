"""Retargeting (core/transition/retarget.py): the sample walk played by skeletons with other rest poses and
proportions (a T-pose variant of the sample skeleton made here; the shared CMU-derived iClone,
Bandai Namco and CMU skeletons where ../shared is present), and back again."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from reactive_anim.core.model import bvh, quat
from reactive_anim.core.model.errors import SkeletonError
from reactive_anim.core.model.rig import Rig
from reactive_anim.core.model.roles import SIDES, assign_roles
from reactive_anim.core.model.skeleton import Motion, Skeleton
from reactive_anim.core.transition import retarget
from tests.support.mocap import REPO, mocap_files
from tools.devkit.skeletons import WALK, role_bone_angles, t_pose_variant

SHARED = {
    "iclone": "cmu_iclone/002_01.bvh",
    "bandai": "bandai_namco/dataset-1/dataset-1_walk_normal_001.bvh",
    "cmu": "cmu/139_16.bvh",
}


def _targets() -> list[tuple[str, Skeleton]]:
    """The T-pose variant, and the shared skeletons that are present (../shared is test-only data)."""
    found = [("t-pose variant", t_pose_variant())]
    for label, relative in SHARED.items():
        path = next((p for p in mocap_files() if p.as_posix().endswith(relative)), None)
        if path is not None:
            found.append((label, bvh.read_bvh(path).skeleton))
    return found


TARGETS = _targets()


def _role_joint_angles(a: Motion, b: Motion) -> dict[str, float]:
    """Mean angle (degrees) between the two motions' global rotations, per role joint."""
    roles = assign_roles(a.skeleton)
    ra, rb = a.global_rotations(), b.global_rotations()
    return {
        role: float(np.degrees(quat.angle_between(ra[:, a.skeleton.index(n)], rb[:, a.skeleton.index(n)])).mean())
        for role, n in roles.items()
    }


@pytest.mark.parametrize(("label", "target"), TARGETS, ids=[t[0] for t in TARGETS])
def test_there_and_back_returns_the_original_within_2_degrees(label, target):
    """The rotation transfer alone is exact where both skeletons have the joints (the spine loses
    the split of a bend among joints one skeleton lacks); the feet's leg IK then fits the legs to
    the other proportions, a few degrees that a round trip does not undo."""
    for fix_feet, limit in ((False, 2.0), (True, 5.0)):
        there = retarget.retarget(WALK, retarget.retarget_map(Rig.of(WALK.skeleton), Rig.of(target)), fix_feet=fix_feet)
        back = retarget.retarget(there, retarget.retarget_map(Rig.of(target), Rig.of(WALK.skeleton)), fix_feet=fix_feet)
        angles = _role_joint_angles(WALK, back)
        assert max(angles.values()) < limit, (fix_feet, {r: round(v, 2) for r, v in angles.items() if v > 0.5})
    np.testing.assert_allclose(back.root_pos[:, :2], WALK.root_pos[:, :2], atol=0.02)


@pytest.mark.parametrize(("label", "target"), TARGETS, ids=[t[0] for t in TARGETS])
def test_role_bones_point_where_the_sources_do(label, target):
    mapping = retarget.retarget_map(Rig.of(WALK.skeleton), Rig.of(target))
    out = retarget.retarget(WALK, mapping)
    angles = role_bone_angles(mapping, WALK.global_positions(), out.global_positions())
    assert max(angles.values()) < 5.0, {r: round(v, 1) for r, v in angles.items() if v > 2}


@pytest.mark.parametrize(("label", "target"), TARGETS, ids=[t[0] for t in TARGETS])
def test_planted_feet_neither_float_sink_nor_slide(label, target):
    mapping = retarget.retarget_map(Rig.of(WALK.skeleton), Rig.of(target))
    out = retarget.retarget(WALK, mapping)
    src_pos, src_rot = WALK.global_transforms()
    pos, rot = out.global_transforms()
    legs = Rig.of(WALK.skeleton).leg_length
    for side in SIDES:
        k = mapping.roles.index(f"ankle_{side}")
        ankle_s, ankle_t = mapping.source_joints[k], mapping.target_joints[k]
        down = retarget.planted(WALK, ankle_s, src_pos, legs)
        assert down.sum() > 40  # the walk plants each foot for a good part of the clip
        height = retarget.lowest_foot_point(target, ankle_t, pos, rot)
        wanted = retarget.lowest_foot_point(WALK.skeleton, ankle_s, src_pos, src_rot) * mapping.scale
        assert np.abs(height - wanted)[down].max() < 0.01, (side, np.abs(height - wanted)[down].max())
        for run in np.split(np.flatnonzero(down), np.flatnonzero(np.diff(np.flatnonzero(down)) > 1) + 1):
            slide = np.linalg.norm(pos[run, ankle_t, :2] - pos[run[0], ankle_t, :2], axis=-1).max()
            assert slide < 0.02, (side, run[0], slide)


@pytest.mark.parametrize("clip", ["walk", "getup_face_down"])
@pytest.mark.parametrize(("label", "target"), TARGETS, ids=[t[0] for t in TARGETS])
def test_no_foot_goes_through_the_floor_off_its_plants(label, target, clip):
    """Other proportions swing a foot lower than the source's; where that takes it under the floor
    (a get-up's sliding feet on the CMU skeleton went 1.4 cm through), it is lifted onto it."""
    source = WALK if clip == "walk" else bvh.read_bvh(REPO / "sample_clips" / f"{clip}.bvh")
    mapping = retarget.retarget_map(Rig.of(source.skeleton), Rig.of(target))
    out = retarget.retarget(source, mapping)
    src_pos, src_rot = source.global_transforms()
    pos, rot = out.global_transforms()
    legs = Rig.of(source.skeleton).leg_length
    feet = [mapping.roles.index(f"ankle_{side}") for side in SIDES]
    src_low = {k: retarget.lowest_foot_point(source.skeleton, mapping.source_joints[k], src_pos, src_rot) for k in feet}
    planted = [src_low[k][retarget.planted(source, mapping.source_joints[k], src_pos, legs)] for k in feet]
    floor = float(np.min(np.concatenate(planted))) * mapping.scale
    for k in feet:
        height = retarget.lowest_foot_point(target, mapping.target_joints[k], pos, rot)
        allowed = np.minimum(src_low[k] * mapping.scale, floor) - 0.002
        assert (height >= allowed).all(), (mapping.roles[k], float((allowed - height).max()))


def test_a_rest_pose_plays_as_the_sources_rest_pose_not_the_targets():
    """The sample skeleton stands arms down; its rest pose on the T-pose variant has the arms down
    too: the rest alignment carries the pose, not the rest pose's rotations (identity)."""
    still = Motion(WALK.skeleton, 60.0, WALK.root_pos[:1], quat.identity((1, WALK.skeleton.num_joints)))
    target = t_pose_variant()
    out = retarget.retarget(still, retarget.retarget_map(Rig.of(WALK.skeleton), Rig.of(target)), fix_feet=False)
    pos = out.global_positions()[0]
    for side in SIDES:
        upper, lower = (target.index(f"{part}.{side.upper()}") for part in ("upper_arm", "forearm"))
        arm = (pos[lower] - pos[upper]) / np.linalg.norm(pos[lower] - pos[upper])
        assert arm[2] < -0.99, arm  # straight down, as the source stands


def test_joints_without_a_role_keep_the_base_motion_or_the_rest_pose():
    target = t_pose_variant()
    mapping = retarget.retarget_map(Rig.of(WALK.skeleton), Rig.of(target))
    turns = quat.from_axis_angle([1.0, 0, 0], np.linspace(0, 1, WALK.num_frames))[:, None]
    base_rot = np.concatenate([np.roll(WALK.local_rot, 5, axis=0), turns], axis=1)
    base = Motion(target, WALK.fps, WALK.root_pos, base_rot)
    roleless = [j for j in range(target.num_joints) if j not in mapping.target_joints]
    kept = retarget.retarget(WALK, mapping, base=base, fix_feet=False)
    rested = retarget.retarget(WALK, mapping, fix_feet=False)
    for j in roleless:
        if any(j == joint for chain in mapping.between for joint, _ in chain):
            continue  # on a role's bone: shares the turn
        same = np.abs(np.sum(kept.local_rot[:, j] * quat.normalize(base.local_rot[:, j]), -1))
        np.testing.assert_allclose(same, 1, atol=1e-6)
        np.testing.assert_allclose(np.abs(rested.local_rot[:, j, 0]), 1, atol=1e-6)
    assert [target.names[j] for j in roleless] == ["finger.L"]


def test_a_motion_of_another_skeleton_is_refused():
    mapping = retarget.retarget_map(Rig.of(WALK.skeleton), Rig.of(t_pose_variant()))
    renamed = replace(WALK, skeleton=replace(WALK.skeleton, names=[n + "_x" for n in WALK.skeleton.names]))
    with pytest.raises(SkeletonError, match="not the retarget map's source skeleton"):
        retarget.retarget(renamed, mapping)
    with pytest.raises(SkeletonError, match="base motion must be on the target skeleton"):
        retarget.retarget(WALK, mapping, base=WALK)


def _backward_knee_degrees(motion: Motion) -> float:
    """The most any knee of the motion bends backwards (shin in front of the thigh's line), degrees."""
    roles = assign_roles(motion.skeleton)
    pos = motion.global_positions()
    idx = {r: motion.skeleton.index(n) for r, n in roles.items()}
    left = pos[:, idx["hip_l"]] - pos[:, idx["hip_r"]]
    worst = 0.0
    for side in ("l", "r"):
        h, k, a = (pos[:, idx[f"{p}_{side}"]] for p in ("hip", "knee", "ankle"))
        plane = np.cross(h - k, a - k)
        cos = np.sum((h - k) * (a - k), -1) / np.linalg.norm(h - k, axis=-1) / np.linalg.norm(a - k, axis=-1)
        bend = 180.0 - np.degrees(np.arccos(np.clip(cos, -1, 1)))
        backward = np.sum(plane * left, -1) > 0
        worst = max(worst, float(bend[backward].max(initial=0.0)))
    return worst


@pytest.mark.parametrize(("label", "target"), TARGETS, ids=[t[0] for t in TARGETS])
def test_the_feet_ik_never_bends_a_knee_backwards(label, target):
    """A straight leg's bend plane is float noise: the IK must bend it forward, as a knee does."""
    sources = [WALK] + [bvh.read_bvh(p) for p in mocap_files("cmu/90_18.bvh")]  # legs straight in places
    for source in sources:
        out = retarget.retarget(source, retarget.retarget_map(Rig.of(source.skeleton), Rig.of(target)))
        assert _backward_knee_degrees(out) <= max(2.0, _backward_knee_degrees(source) + 0.5), source.skeleton.names[0]


def test_an_end_site_at_zero_lines_up_as_its_bone():
    """BVH exporters that write `End Site 0 0 0`: the hand lines up along its forearm, not at random."""
    target = t_pose_variant()
    hand = target.index("hand.R")
    flat = replace(target, end_sites={**target.end_sites, hand: np.zeros(3)})
    normal = retarget.retarget(WALK, retarget.retarget_map(Rig.of(WALK.skeleton), Rig.of(target)), fix_feet=False)
    zero = retarget.retarget(WALK, retarget.retarget_map(Rig.of(WALK.skeleton), Rig.of(flat)), fix_feet=False)
    turned = np.degrees(quat.angle_between(normal.global_rotations()[:, hand], zero.global_rotations()[:, hand]))
    assert turned.max() < 1.0, turned.max()  # the hand's end site runs along the forearm in this rig
