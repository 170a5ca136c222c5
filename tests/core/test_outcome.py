"""The outcome rule (core/classify/outcome.py) on constructed states, and the support geometry it stands on
(core/classify/capture.py). No simulation: each state is written down, so each case tests one clause.

The constructed character faces +X (its left is +Y), stands on two feet 20 cm apart whose soles run
from 5 cm behind to 15 cm ahead of the centre of mass, legs 0.9 m long, centre of mass 1 m up
(w0 = sqrt(9.81 / 1) = 3.13 /s).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from reactive_anim.core.classify import outcome
from reactive_anim.core.classify.capture import Support, convex_hull, nearest_in_polygon
from reactive_anim.core.classify.features import ReactionState
from reactive_anim.core.classify.outcome import COLLAPSE_HEIGHT, judge
from reactive_anim.core.model.rig import Rig
from reactive_anim.core.model.skeleton import Skeleton

LEG = 0.9
ROLES = ("pelvis", "chest", "head", "hip_l", "hip_r", "shoulder_l", "shoulder_r")  # POSE's rows
POSE = np.array(
    [[0, 0, 0.95], [0, 0, 1.3], [0, 0, 1.6], [0, 0.1, 0.9], [0, -0.1, 0.9], [0, 0.2, 1.4], [0, -0.2, 1.4]], dtype=float
)
FEET = np.array([[-0.05, 0.1], [0.15, 0.1], [-0.05, -0.1], [0.15, -0.1]], dtype=np.float64)
SOLE_RADIUS = 0.04
COM = np.array([0.0, 0.0, 1.0])
# The rig stands in POSE, with a knee and an ankle straight below each hip (the rule reads neither;
# they give the rig its leg length, LEG): joints named by their roles.
PARENTS = np.array([-1, 0, 1, 0, 0, 1, 1, 3, 4, 7, 8], dtype=np.int64)
REST = np.vstack([POSE, POSE[3:5] - [0.0, 0.0, LEG / 2], POSE[3:5] - [0.0, 0.0, LEG]])
NAMES = [*ROLES, "knee_l", "knee_r", "ankle_l", "ankle_r"]
RIG = Rig(Skeleton(NAMES, PARENTS, REST - np.vstack([[0.0, 0.0, 0.0], REST[PARENTS[1:]]])), {n: n for n in NAMES})
OMEGA = math.sqrt(9.81 / 1.0)


def state(
    velocity=(0.0, 0.0, 0.0), moved=(0.0, 0.0, 0.0), motion_velocity=(0.0, 0.0, 0.0), down=False
) -> ReactionState:
    """The character at C with its centre of mass moved and moving; the motion it was playing has
    its centre of mass at COM moving at `motion_velocity`."""
    return ReactionState(
        positions_b=POSE,
        com_b=COM,
        positions_c=POSE + np.asarray(moved, dtype=np.float64),
        com_c=COM + np.asarray(moved, dtype=np.float64),
        com_velocity=np.asarray(velocity, dtype=float),
        motion_com=COM,
        motion_velocity=np.asarray(motion_velocity, dtype=float),
        support=Support(FEET, SOLE_RADIUS, down),
        floor=0.0,
    )


def turned(s: ReactionState, yaw: float) -> ReactionState:
    """Only the push's effect turned: the body keeps facing +X, its centre of mass departs the other way."""
    c, n = math.cos(yaw), math.sin(yaw)
    rot = np.array([[c, -n, 0.0], [n, c, 0.0], [0.0, 0.0, 1.0]])
    return replace(s, com_c=COM + rot @ (s.com_c - COM), com_velocity=rot @ s.com_velocity)


def test_at_rest_the_character_sways():
    assert judge(RIG, state()).reaction == "sway_balance"
    assert judge(RIG, state()).steps == 0


def test_a_fast_forward_centre_of_mass_falls_forward_and_rolls():
    """5 m/s forward: the XCoM is 1.6 m ahead, 1.41 m past the toes, beyond the 1.26 m that any
    number of steps can catch, and faster than sqrt(g L) = 2.97 m/s: thrown over its hands, it rolls.
    (4 m/s, a fast run, is still caught in three long steps.)"""
    result = judge(RIG, state(velocity=(5.0, 0.0, 0.0)))
    assert (result.reaction, result.steps, result.direction) == ("fall_forward_roll", None, "forward")


@pytest.mark.parametrize(
    "yaw, expected",
    [(math.pi / 2, "fall_side_knees"), (-math.pi / 2, "fall_side_knees"), (math.pi, "fall_backward_hands")],
)
def test_the_same_state_turned_falls_to_the_side_or_back(yaw, expected):
    assert judge(RIG, turned(state(velocity=(5.0, 0.0, 0.0)), yaw)).reaction == expected


def test_a_slow_fall_sits_down_or_catches_itself_on_the_hands():
    """Displaced 1.6 m beyond the motion with no speed: not capturable, and slow."""
    assert judge(RIG, state(moved=(-1.6, 0.0, 0.0))).reaction == "fall_backward_sit"
    assert judge(RIG, state(moved=(1.6, 0.0, 0.0))).reaction == "fall_forward_hands"


@pytest.mark.parametrize(
    "speed, expected", [(1.0, "step_forward"), (3.3, "steps_forward"), (-1.0, "step_back"), (-3.3, "steps_back")]
)
def test_moderate_pushes_are_caught_by_steps(speed, expected):
    """1 m/s: the XCoM is 0.32 m away, past the toes (0.19 m) by 0.13 m, one step of up to a leg
    length catches it until about 3 m/s; 3.3 m/s needs two."""
    assert judge(RIG, state(velocity=(speed, 0.0, 0.0))).reaction == expected


def test_a_sideways_push_caught_by_steps_steps_to_that_side_standing_or_walking():
    """The character's left is +Y: pushed towards it, it steps left, whether it stood or walked (the
    walker's own velocity is the motion's, so the departure is the push's alone)."""
    sideways = judge(RIG, state(velocity=(0.0, 1.0, 0.0)))
    assert (sideways.direction, sideways.steps, sideways.reaction) == ("left", 1, "step_left")
    assert judge(RIG, state(velocity=(0.0, -1.0, 0.0))).reaction == "step_right"
    walking = state(velocity=(1.3, 1.0, 0.0), motion_velocity=(1.3, 0.0, 0.0))
    assert judge(RIG, walking).reaction == "step_left"
    walking_back = state(velocity=(-1.0, -1.0, 0.0), motion_velocity=(-1.0, 0.0, 0.0))
    assert judge(RIG, walking_back).reaction == "step_right"


def test_a_body_already_on_the_floor_has_fallen():
    result = judge(RIG, state(velocity=(0.3, 0.0, 0.0), down=True))
    assert (result.steps, result.reaction) == (None, "fall_forward_hands")


def test_a_body_low_and_sinking_at_c_is_falling_whatever_its_xcom():
    """The pendulum keeps its height; a centre of mass already below COLLAPSE_HEIGHT leg lengths and
    sinking faster than COLLAPSE_SPEED is going down (a push during a deep crouch), even with its
    XCoM where a sway would keep it. Low but still, or sinking but high, it is not."""
    drop = (0.0, 0.0, COLLAPSE_HEIGHT * LEG - 0.05 - COM[2])
    low_and_sinking = judge(RIG, state(velocity=(0.3, 0.0, -1.5), moved=drop))
    assert (low_and_sinking.steps, low_and_sinking.collapsing) == (None, True)
    assert low_and_sinking.reaction.startswith("fall_")
    assert judge(RIG, state(velocity=(0.3, 0.0, -0.2), moved=drop)).reaction == "sway_balance"
    assert judge(RIG, state(velocity=(0.3, 0.0, -1.5))).reaction == "sway_balance"


def test_a_departure_inside_the_feet_sways_and_the_tolerance_is_the_sway_limit():
    """Forward, the support reaches 0.19 m ahead of the centre of mass; up to SWAY_TOLERANCE leg
    lengths beyond that is still a sway."""
    edge = 0.15 + SOLE_RADIUS + outcome.SWAY_TOLERANCE * LEG
    assert judge(RIG, state(velocity=((edge - 0.01) * OMEGA, 0.0, 0.0))).reaction == "sway_balance"
    assert judge(RIG, state(velocity=((edge + 0.01) * OMEGA, 0.0, 0.0))).reaction == "step_forward"


def test_steps_grow_with_the_excess_up_to_the_infinite_step_limit():
    """Koolen's recursion: the number of steps never falls as the excess grows, and the last
    capturable excess is the infinite-step bound (l_max / (e^(w dt) - 1) + l_max) / e^(w t1)."""
    window, reach = 0.25, outcome.MAX_STEP_LENGTH * LEG
    growth = math.exp(OMEGA * outcome.STEP_TIME)
    bound = (reach / (growth - 1.0) + reach) / math.exp(OMEGA * (outcome.FIRST_STEP_DELAY - window))
    excesses = np.linspace(0.0, bound * 0.999, 400)
    steps = [outcome._steps_to_capture(e, OMEGA, LEG, window) for e in excesses]
    assert all(s is not None for s in steps)
    counts = [s for s in steps if s is not None]  # every one of them
    assert counts == sorted(counts) and counts[-1] > 2
    assert outcome._steps_to_capture(bound * 1.01, OMEGA, LEG, window) is None


def _sector(degrees: float) -> str:
    return outcome.way(np.array([math.cos(math.radians(degrees)), math.sin(math.radians(degrees))]))


def test_the_direction_sectors_are_45_degrees_either_side_of_the_facing_axis():
    angles = (0, 44, 46, 90, 134, 136, 180, -60)
    expected = ["forward", "forward", "left", "left", "left", "backward", "backward", "right"]
    assert [_sector(a) for a in angles] == expected


# ---------------------------------------------------------------------------------------------
# The support geometry


SQUARE = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])


def test_the_hull_drops_inner_points_and_runs_counter_clockwise():
    hull = convex_hull(np.vstack([SQUARE, [[0.5, 0.5], [0.2, 0.7]]]))
    assert len(hull) == 4 and {tuple(p) for p in hull} == {tuple(p) for p in SQUARE}
    area = 0.5 * np.sum(hull[:, 0] * np.roll(hull[:, 1], -1) - np.roll(hull[:, 0], -1) * hull[:, 1])
    assert area == pytest.approx(1.0)  # positive: counter-clockwise


def test_the_nearest_point_is_the_point_itself_inside_and_on_the_edge_outside():
    np.testing.assert_allclose(nearest_in_polygon(SQUARE, np.array([0.3, 0.4])), [0.3, 0.4])
    np.testing.assert_allclose(nearest_in_polygon(SQUARE, np.array([2.0, 0.5])), [1.0, 0.5])
    np.testing.assert_allclose(nearest_in_polygon(SQUARE, np.array([-1.0, -1.0])), [0.0, 0.0])


def test_the_reach_runs_to_the_edge_of_the_grown_hull():
    """Two sole points 2 m apart grown by 1 m: a capsule. Along it the reach ends on the end disc,
    across it on the straight side, diagonally on the arc."""
    support = Support(np.array([[0.0, 0.0], [2.0, 0.0]]), 1.0)
    assert support.reach(np.array([1.0, 0.0]), np.array([1.0, 0.0])) == pytest.approx(2.0)
    assert support.reach(np.array([1.0, 0.0]), np.array([0.0, -1.0])) == pytest.approx(1.0)
    assert support.reach(np.array([1.0, 0.5]), np.array([0.0, 1.0])) == pytest.approx(0.5)
    assert support.reach(np.array([2.0, 0.0]), np.array([1.0, 1.0])) == pytest.approx(1.0)
    assert Support(np.zeros((1, 2)), 0.5).reach(np.zeros(2), np.array([0.0, 3.0])) == pytest.approx(0.5)


def test_the_reach_does_not_depend_on_the_heading():
    rng = np.random.default_rng(1)
    for _ in range(20):
        c, n = np.cos(yaw := rng.uniform(-np.pi, np.pi)), np.sin(yaw)
        rot = np.array([[c, -n], [n, c]])
        target, direction = rng.normal(size=2) * 0.2, rng.normal(size=2)
        plain = Support(FEET, SOLE_RADIUS).reach(target, direction)
        turned_support = Support(FEET @ rot.T, SOLE_RADIUS)
        assert turned_support.reach(rot @ target, rot @ direction) == pytest.approx(plain, abs=1e-9)


def test_the_reach_starts_from_the_support_point_nearest_the_target():
    support = Support(FEET, SOLE_RADIUS)
    assert support.reach(np.zeros(2), np.array([1.0, 0.0])) == pytest.approx(0.15 + SOLE_RADIUS, abs=2e-3)
    assert support.reach(np.array([1.0, 0.0]), np.array([1.0, 0.0])) == pytest.approx(
        0.0, abs=1e-9
    )  # a walker's XCoM ahead
    assert support.reach(np.array([1.0, 0.0]), np.array([-1.0, 0.0])) == pytest.approx(0.2 + 2 * SOLE_RADIUS, abs=2e-3)
    assert Support(np.zeros((0, 2)), SOLE_RADIUS).reach(np.zeros(2), np.array([1.0, 0.0])) == 0.0
