"""The classifier's inputs (core/classify/features.py) on the project's own clips: no ../shared needed.

- Invariance: the features of a reaction state do not change when the whole state is turned about
  the vertical and moved (any yaw, any ground offset, the floor moving with it); and a simulated
  push on a turned and moved copy of the walk gives the features of the original push.
- Signs: a push from behind and one from the front (left and right) give features of opposite sign
  where they should: the forward (left) displacements and departures.
- Mirror: a state seen in a left-right mirror has the features `mirrored` gives (training uses it).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from reactive_anim.core.classify.capture import Support
from reactive_anim.core.classify.features import (
    EXTENDED_FEATURES,
    PAPER_FEATURES,
    FeatureReader,
    ReactionState,
    feature_rig,
    mirrored,
    reaction_features,
    select,
)
from reactive_anim.core.model import bvh, quat
from reactive_anim.core.model.errors import SkeletonError
from reactive_anim.core.model.impact import Impact
from reactive_anim.core.model.rig import Rig
from reactive_anim.core.model.skeleton import Motion
from reactive_anim.core.physics.ragdoll import build_ragdoll
from reactive_anim.core.physics.simulate import simulate_push

SAMPLE_CLIPS = Path(__file__).resolve().parents[2] / "sample_clips"
IMPACT_FRAME = 60.9
PUSH = 60.0  # N·s, a firm push
EXACT = 1e-9  # the same state turned and moved: only rounding differs
SIMULATED = 2e-3  # a turned and moved simulation: MuJoCo's sums in another order (dimensionless units)


@pytest.fixture(scope="module")
def clips() -> dict[str, tuple[Motion, FeatureReader]]:
    out = {}
    for name in ("walk", "idle"):
        motion = bvh.read_bvh(SAMPLE_CLIPS / f"{name}.bvh")
        out[name] = (motion, FeatureReader(build_ragdoll(motion.skeleton, reference=motion)))
    return out


def pushed(motion: Motion, reader: FeatureReader, role: str, towards: str, strength: float = PUSH) -> ReactionState:
    """The state at C after a push on `role` toward the character's forward/back/left/right at B."""
    frame = reader.facing(motion, IMPACT_FRAME)
    direction = {"forward": frame[0], "back": -frame[0], "left": frame[1], "right": -frame[1]}[towards]
    impact = Impact(IMPACT_FRAME, reader.ragdoll.roles[role], tuple(direction), strength)
    return reader.simulated(motion, simulate_push(reader.ragdoll, motion, impact))


def turned(state: ReactionState, yaw: float, offset: np.ndarray) -> ReactionState:
    """The state turned by `yaw` about the vertical through the origin, then moved by `offset`."""
    c, s = np.cos(yaw), np.sin(yaw)
    rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])

    def point(p: np.ndarray) -> np.ndarray:
        return p @ rot.T + offset

    support = Support(state.support.points @ rot[:2, :2].T + offset[:2], state.support.radius, state.support.down)
    return replace(
        state,
        positions_b=point(state.positions_b),
        com_b=point(state.com_b),
        positions_c=point(state.positions_c),
        com_c=point(state.com_c),
        com_velocity=state.com_velocity @ rot.T,
        motion_com=point(state.motion_com),
        motion_velocity=state.motion_velocity @ rot.T,
        support=support,
        floor=state.floor + offset[2],
    )


def turned_motion(motion: Motion, yaw: float, offset: np.ndarray) -> Motion:
    """The motion turned about the vertical through the origin and moved (root position and rotation)."""
    spin = quat.from_axis_angle(np.array([0.0, 0.0, 1.0]), yaw)
    local = motion.local_rot.copy()
    local[:, 0] = quat.mul(spin, local[:, 0])
    return replace(motion, root_pos=quat.rotate(spin, motion.root_pos) + offset, local_rot=local)


def test_features_do_not_depend_on_yaw_or_ground_offset(clips):
    """Random yaws and offsets (the ground up to 2 m up or down) leave every feature as it was."""
    motion, reader = clips["walk"]
    state = pushed(motion, reader, "chest", "left")
    original = reaction_features(reader.rig, state)
    rng = np.random.default_rng(3)
    for _ in range(20):
        offset = rng.uniform([-50.0, -50.0, -2.0], [50.0, 50.0, 2.0])
        moved = reaction_features(reader.rig, turned(state, rng.uniform(-np.pi, np.pi), offset))
        np.testing.assert_allclose(moved, original, atol=EXACT)


def test_a_turned_and_moved_walk_pushed_the_same_way_gives_the_same_features(clips):
    """End to end: the walk turned 90 degrees and moved 3 m (and 0.4 m up, floor and all), pushed
    on the same bone in the same direction relative to the character."""
    motion, reader = clips["walk"]
    original = reaction_features(reader.rig, pushed(motion, reader, "chest", "forward"))
    copy = turned_motion(motion, np.pi / 2, np.array([3.0, -2.0, 0.4]))
    moved = reaction_features(reader.rig, pushed(copy, reader, "chest", "forward"))
    np.testing.assert_allclose(moved, original, atol=SIMULATED)


@pytest.mark.parametrize("clip", ["walk", "idle"])
def test_pushes_from_behind_and_from_the_front_give_opposite_forward_features(clips, clip):
    """From behind the chest (pushed forward) moves forward relative to the unpushed motion, from the
    front backward: the departure of the centre of mass and of the XCoM changes sign (the paper's
    displacements too on the standing idle, where the body does not walk on)."""
    motion, reader = clips[clip]
    ahead = dict(
        zip(EXTENDED_FEATURES, reaction_features(reader.rig, pushed(motion, reader, "chest", "forward")), strict=True)
    )
    behind = dict(
        zip(EXTENDED_FEATURES, reaction_features(reader.rig, pushed(motion, reader, "chest", "back")), strict=True)
    )
    for name in ("dev_x", "dev_vx", "xcom_dx", "xcom_cos"):
        assert ahead[name] > 0 > behind[name], (name, ahead[name], behind[name])
    assert ahead["xcom_cos"] ** 2 + ahead["xcom_sin"] ** 2 == pytest.approx(1.0)
    if clip == "idle":
        for name in ("chest_dx", "com_dx", "com_vx"):
            assert ahead[name] > 0 > behind[name], (name, ahead[name], behind[name])


@pytest.mark.parametrize("clip", ["walk", "idle"])
def test_pushes_to_the_left_and_to_the_right_give_opposite_sideways_features(clips, clip):
    motion, reader = clips[clip]
    left = dict(
        zip(EXTENDED_FEATURES, reaction_features(reader.rig, pushed(motion, reader, "pelvis", "left")), strict=True)
    )
    right = dict(
        zip(EXTENDED_FEATURES, reaction_features(reader.rig, pushed(motion, reader, "pelvis", "right")), strict=True)
    )
    for name in ("pelvis_dy", "com_dy", "dev_y", "dev_vy", "xcom_dy"):
        assert left[name] > 0 > right[name], (name, left[name], right[name])
    # |sine|: the side is in xcom_dy; the sector the rule reads is the same both ways.
    assert left["xcom_sin"] > abs(left["xcom_cos"]) and right["xcom_sin"] > abs(right["xcom_cos"])


def mirror_of(state: ReactionState, rig: Rig) -> ReactionState:
    """The state in a left-right mirror: every point's y negated, each left joint swapped with its right."""
    flip = np.array([1.0, -1.0, 1.0])
    swap = np.arange(len(state.positions_b))
    for role, j in rig.joints.items():
        if role.endswith("_l") and role[:-2] + "_r" in rig.joints:
            k = rig.joints[role[:-2] + "_r"]
            swap[j], swap[k] = k, j
    support = Support(state.support.points * flip[:2], state.support.radius, state.support.down)
    return replace(
        state,
        positions_b=(state.positions_b * flip)[swap],
        com_b=state.com_b * flip,
        positions_c=(state.positions_c * flip)[swap],
        com_c=state.com_c * flip,
        com_velocity=state.com_velocity * flip,
        motion_com=state.motion_com * flip,
        motion_velocity=state.motion_velocity * flip,
        support=support,
    )


@pytest.mark.parametrize(("clip", "role", "towards"), [("walk", "pelvis", "left"), ("idle", "chest", "forward")])
def test_a_mirrored_push_has_the_mirrored_features(clips, clip, role, towards):
    """What lets training add every push's mirror image (labelled with its class's mirror image): the mirrored state's
    features are exactly `mirrored` of the original's (and they differ: the push has a side)."""
    motion, reader = clips[clip]
    state = pushed(motion, reader, role, towards)
    features = reaction_features(reader.rig, state)
    np.testing.assert_allclose(
        reaction_features(reader.rig, mirror_of(state, reader.rig)), mirrored(features), atol=EXACT
    )
    assert np.abs(mirrored(features) - features).max() > 1e-3


def test_down_says_whether_a_body_other_than_the_feet_is_on_the_floor(clips):
    motion, reader = clips["walk"]
    state = pushed(motion, reader, "chest", "forward")
    down = EXTENDED_FEATURES.index("down")
    for touching in (False, True):
        support = Support(state.support.points, state.support.radius, touching)
        assert reaction_features(reader.rig, replace(state, support=support))[down] == float(touching)


def test_a_motion_that_carries_on_has_no_departure(clips):
    """The idle read as a capture of its own reaction: nothing happened, so the centre of mass is
    where the body at B carried on would be (within 2 % of a leg length), the XCoM too."""
    motion, reader = clips["idle"]
    features = dict(
        zip(EXTENDED_FEATURES, reaction_features(reader.rig, reader.captured(motion, 100, 0.25)), strict=True)
    )
    for name in ("dev_x", "dev_y", "dev_z", "xcom_dx", "xcom_dy"):
        assert abs(features[name]) < 0.02, (name, features[name])
    assert features["reach"] > 0.0  # standing on both feet


def test_the_paper_features_come_first_and_select_picks_by_name():
    assert EXTENDED_FEATURES[: len(PAPER_FEATURES)] == PAPER_FEATURES
    rows = np.arange(2 * len(EXTENDED_FEATURES), dtype=float).reshape(2, -1)
    np.testing.assert_array_equal(select(rows, PAPER_FEATURES), rows[:, : len(PAPER_FEATURES)])
    np.testing.assert_array_equal(select(rows[0], ("excess", "head_dx")), [EXTENDED_FEATURES.index("excess"), 0.0])
    with pytest.raises(SkeletonError, match="unknown reaction features: elbow_dx"):
        select(rows, ("elbow_dx",))


def test_a_skeleton_without_the_roles_is_refused(clips):
    motion, reader = clips["walk"]
    roles = dict(reader.ragdoll.roles)
    del roles["chest"]
    with pytest.raises(SkeletonError, match="chest"):
        feature_rig(Rig(motion.skeleton, roles))
