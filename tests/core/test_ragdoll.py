"""Ragdoll (core/physics/ragdoll.py) and Impact (core/model/impact.py): real MuJoCo models built from real skeletons.

Masses per body equal the profile (paper Table 1, scaled); every role has a body; the skeletons of
all three shared datasets and the project's sample build; mocap -> joint angles -> pose reproduces
the mocap (so the Euler split of ball joints into hinges is consistent); bad skeletons and bad
impacts raise errors naming what is wrong.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from reactive_anim.core.model import bvh, quat
from reactive_anim.core.model.errors import ImpactError, SimulationError, SkeletonError
from reactive_anim.core.model.impact import Impact
from reactive_anim.core.model.roles import assign_roles, part_of
from reactive_anim.core.model.skeleton import Skeleton
from reactive_anim.core.physics.anatomy import ANATOMICAL_LIMITS, BODY_ROLES, PAPER_LIMITS, TABLE1_MASSES
from reactive_anim.core.physics.joints import _body_local_rotations, mocap_table, to_motion
from reactive_anim.core.physics.ragdoll import build_ragdoll
from reactive_anim.core.physics.simulate import _samples, simulate_impact
from reactive_anim.core.physics.workspace import Workspace, place_bodies
from tests.support.mocap import REPO, require_mocap

SAMPLE_WALK = REPO / "sample_clips" / "walk.bvh"
DATASETS = {
    "bandai": "bandai_namco/dataset-1/dataset-1_walk_normal_001.bvh",
    "cmu": "cmu/91_59.bvh",
    "iclone": "cmu_iclone/007_01.bvh",
}


@pytest.fixture(scope="module")
def sample_walk():
    return bvh.read_bvh(SAMPLE_WALK)


@pytest.mark.parametrize("profile", ["anatomical", "paper"])
@pytest.mark.parametrize("total_mass", [97.6, 70.0])
def test_body_masses_equal_the_profile(sample_walk, profile, total_mass):
    ragdoll = build_ragdoll(sample_walk.skeleton, profile=profile, total_mass=total_mass)
    model = ragdoll.model
    assert len(ragdoll.bodies) == 16
    for role in BODY_ROLES:
        body = next(b for b in ragdoll.bodies if role in b.roles)  # every role has a body
        expected = TABLE1_MASSES[part_of(role)] * total_mass / 97.6
        assert model.body_mass[model.body(body.name).id] == pytest.approx(expected, rel=1e-9)
    assert float(np.sum(model.body_mass)) == pytest.approx(total_mass, rel=1e-9)


@pytest.mark.parametrize("profile, table", [("anatomical", ANATOMICAL_LIMITS), ("paper", PAPER_LIMITS)])
def test_joint_types_and_ranges_follow_the_profile(sample_walk, profile, table):
    """Paper hinges are one hinge, its ball joints three; the compiled ranges are the table's."""
    ragdoll = build_ragdoll(sample_walk.skeleton, profile=profile)
    model = ragdoll.model
    for body in ragdoll.bodies[1:]:
        kinds = table[part_of(body.name)]
        expected = [rng for rng in kinds if rng is not None]
        joints = [j for j in range(model.njnt) if model.jnt_bodyid[j] == body.body_id]
        assert len(joints) == len(expected), body.name
        for j, rng in zip(joints, expected, strict=True):
            assert model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE
            assert np.degrees(model.jnt_range[j]) == pytest.approx(rng)
            assert model.jnt_stiffness[j] > 0 and model.dof_damping[model.jnt_dofadr[j]] > 0
    assert model.nu == sum(len(b.hinges) for b in ragdoll.bodies)
    # The root is free and unactuated.
    assert model.jnt_type[0] == mujoco.mjtJoint.mjJNT_FREE
    assert 0 not in set(model.actuator_trnid[:, 0])


def test_knee_flexes_backward_and_elbow_forward(sample_walk):
    """Positive flexion bends the knee backward and the elbow forward (the sample faces -Y)."""
    ragdoll = build_ragdoll(sample_walk.skeleton)
    model = ragdoll.model
    data = mujoco.MjData(model)
    for joint, forward_sign in (("knee_l_flex", +1.0), ("elbow_l_flex", -1.0)):
        data.qpos[:] = model.qpos0
        data.qpos[model.jnt_qposadr[model.joint(joint).id]] = np.radians(60)
        mujoco.mj_kinematics(model, data)
        child = {"knee_l_flex": "ankle_l", "elbow_l_flex": "wrist_l"}[joint]
        moved = data.xpos[model.body(child).id] - data.xpos[model.body(joint[:-5]).id]
        # Facing -Y: forward is -Y, so a knee swings the shin toward +Y.
        assert forward_sign * moved[1] > 0.1, (joint, moved)


@pytest.mark.parametrize("dataset", sorted(DATASETS))
def test_shared_dataset_skeletons_build(dataset):
    motion = bvh.read_bvh(require_mocap(DATASETS[dataset]))
    for profile in ("anatomical", "paper"):
        ragdoll = build_ragdoll(motion.skeleton, profile=profile, reference=motion)
        assert len(ragdoll.bodies) == 16
        assert float(np.sum(ragdoll.model.body_mass)) == pytest.approx(97.6)
    assert "<freejoint" in ragdoll.mjcf and ragdoll.compile_seconds > 0


def test_a_rest_pose_that_does_not_stand_asks_for_a_reference():
    """Bandai's rest pose lies its bones along X: limits measured from it would mean nothing."""
    motion = bvh.read_bvh(require_mocap(DATASETS["bandai"]))
    with pytest.raises(SkeletonError, match="reference"):
        build_ragdoll(motion.skeleton)


def test_missing_role_raises_skeleton_error(sample_walk):
    skeleton = sample_walk.skeleton
    roles = assign_roles(skeleton)
    del roles["elbow_l"]
    with pytest.raises(SkeletonError, match="elbow_l"):
        build_ragdoll(skeleton, roles=roles)
    # A skeleton without arms at all: the role finder names the missing roles.
    keep = [j for j, n in enumerate(skeleton.names) if not any(k in n for k in ("arm", "hand", "shoulder"))]
    remap = {old: new for new, old in enumerate(keep)}
    armless = Skeleton(
        names=[skeleton.names[j] for j in keep],
        parents=np.asarray([remap.get(int(skeleton.parents[j]), -1) for j in keep]),
        offsets=skeleton.offsets[keep],
    )
    with pytest.raises(SkeletonError, match="shoulder_l"):
        build_ragdoll(armless)


@pytest.mark.parametrize("dataset", ["sample", "bandai", "iclone"])
def test_mocap_to_joint_angles_and_back_reproduces_the_pose(sample_walk, dataset):
    """Every joint lands where the mocap has it, merged bones held at the frame included: a ball
    joint's three hinges lose nothing, and what a single-hinge knee or elbow cannot hold of the
    held frame (a twist, a carrying angle) is kept from it. Without that, on the real rigs a hand
    or foot moved a few cm, a finger more."""
    motion = sample_walk if dataset == "sample" else bvh.read_bvh(require_mocap(DATASETS[dataset]))
    ragdoll = build_ragdoll(motion.skeleton, reference=None if dataset == "sample" else motion)
    frame = min(40, motion.num_frames - 1)
    table = mocap_table(ragdoll, motion, frame, frame)
    held = table.held(frame)
    workspace = Workspace(ragdoll)
    place_bodies(workspace, held)
    rots, pelvis, _, _ = _samples(workspace, table.qpos, np.zeros((1, ragdoll.model.nv)))
    out = to_motion(ragdoll, held, held.local_rot[None], rots, pelvis, rots[0], fps=motion.fps)
    error = np.linalg.norm(out.global_positions()[0] - motion.global_positions()[frame], axis=-1)
    assert error.max() < 1e-6
    assert quat.angle_between(out.local_rot[0], quat.normalize(motion.local_rot[frame])).max() < 1e-6
    # What is kept of the held frame is nothing but at the single hinges.
    rebuilt = _body_local_rotations(ragdoll, held, rots)[0]
    lost = quat.angle_between(rebuilt, quat.normalize(held.local_rot[ragdoll.index.body_joints]))
    hinged = np.array([b.name[:-2] in ("knee", "elbow") for b in ragdoll.bodies])
    assert lost[~hinged].max() < 1e-6
    if dataset == "bandai":
        assert lost[hinged].max() > np.radians(5.0)  # a real rig's elbow does more than flex


@pytest.mark.parametrize("relative", [DATASETS["bandai"], "bandai_namco/dataset-1/dataset-1_punch_normal_002.bvh"])
def test_the_simulation_starts_on_the_mocaps_pose(relative):
    """At the impact frame, before any step, the output is the mocap's pose: on a Bandai Namco
    punch a single-hinge elbow dropped 116 degrees of the forearm's rotation and the hand jumped
    37 cm at the hit; the knees are single hinges too."""
    motion = bvh.read_bvh(require_mocap(relative))
    ragdoll = build_ragdoll(motion.skeleton, reference=motion)
    roles = assign_roles(motion.skeleton)
    for frame in (64, motion.num_frames // 2):
        bc = simulate_impact(ragdoll, motion, Impact(frame, roles["pelvis"], (1.0, 0.0, 0.0), 1e-6))
        moved = np.linalg.norm(bc.motion.global_positions()[0] - motion.global_positions()[frame], axis=-1)
        assert moved.max() < 1e-6, (frame, motion.skeleton.names[int(np.argmax(moved))], moved.max())


# ---------------------------------------------------------------------------------------------
# Impact


def test_impact_normalises_its_direction():
    impact = Impact(frame=12.5, bone="chest", direction=(0.0, 3.0, 4.0), strength=50)
    assert impact.direction == pytest.approx((0.0, 0.6, 0.8))
    assert impact.impulse == pytest.approx([0.0, 30.0, 40.0])
    assert impact.frame == 12.5 and impact.reaction is None


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"direction": (0, 0, 0)}, "no length"),
        ({"direction": (float("nan"), 1, 0)}, "finite"),
        ({"direction": (1, 0)}, "three"),
        ({"strength": -1.0}, ">= 0"),
        ({"strength": float("inf")}, "finite"),
        ({"strength": float("nan")}, "finite"),
        ({"frame": float("nan")}, "frame"),
        ({"frame": -2}, "frame"),
        ({"bone": ""}, "bone"),
        ({"reaction": ""}, "reaction"),
    ],
)
def test_impact_rejects_bad_values(kwargs, message):
    args = {"frame": 10, "bone": "chest", "direction": (1, 0, 0), "strength": 50.0, **kwargs}
    with pytest.raises(ImpactError, match=message):
        Impact(**args)


def test_profiles_and_masses_are_checked(sample_walk):
    with pytest.raises(SimulationError, match="profile"):
        build_ragdoll(sample_walk.skeleton, profile="cartoon")
    with pytest.raises(SimulationError, match="mass"):
        build_ragdoll(sample_walk.skeleton, total_mass=-5)
