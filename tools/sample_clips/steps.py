"""Stepping reactions and sways: a pushed body recovers by the balance model (balance.py), with
steps (step_forward, steps_forward, step_back, steps_back, step_left, step_right) or on planted
feet (sway_balance). The side steps (beyond the paper's classes) step out with the foot on the side
the body is pushed to, the other foot held where it stands: a side step and hold.

A stepping reaction is a `Push` row of STEPS: the balance model decides where and when the feet
land; the root follows the pendulum's centre of mass, the legs reach the planned ankles by IK, and
the upper body blends from the standing pose towards flung key poses by the pendulum's alarm.

SWAYS. Pure PD tracking has no balance feedback: the ragdoll held by PD servos toward the standing
pose topples whatever the push (measured from the idle's first frame, tracking STAND: with no push
the pelvis is below 0.8 m after 2.5 s, after a 15 N·s push on the chest after 1.3 s). So the
sways are made as the stepping clips are, by the same linear inverted pendulum (balance_plan) with
the feet kept planted: the centre of pressure moves within the feet (ankle strategy) by a
capture-point controller, the trunk bends against the push as the body's alarm rises (hip
strategy), and the capture point never leaves the support polygon, so no step.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from reactive_anim.core.model import quat
from reactive_anim.core.model.skeleton import Motion, Skeleton, forward_kinematics

from .balance import Push, StepPlan, balance_plan
from .curves import minimum_jerk
from .ik import leg_ik
from .poses import PARAMS, STAND, pose, pose_vector, posed
from .skeleton import (
    ANKLE_HEIGHT,
    FPS,
    HEIGHT,
    SHANK,
    SIDES,
    THIGH,
    TOE_TIP_Z,
    about_x,
    clip_motion,
    end_site_position,
    sample_skeleton,
)

# Variants: a row each. One-step pushes are caught by a single step to the capture point; the
# several-steps rows push harder and allow only short steps, so the first landing falls short.
STEPS: dict[str, Push] = {
    "step_forward_1": Push(direction=0.0, speed=0.75, max_step=0.75, first="R"),
    "step_forward_2": Push(direction=20.0, speed=0.9, max_step=0.75, first="L", react=0.12),
    "step_forward_3": Push(direction=-15.0, speed=1.0, max_step=0.75, first="R", react=0.2, swing=0.34),
    "steps_forward_1": Push(direction=0.0, speed=1.15, max_step=0.6, first="L", swing=0.32),
    "steps_forward_2": Push(direction=15.0, speed=1.2, max_step=0.5, first="L", swing=0.25, pause=0.04),
    "steps_forward_3": Push(direction=-25.0, speed=1.2, max_step=0.4, first="R", swing=0.22, pause=0.03),
    "step_back_1": Push(direction=180.0, speed=0.45, max_step=0.55, first="L"),
    "step_back_2": Push(direction=160.0, speed=0.5, max_step=0.55, first="L", react=0.12),
    "step_back_3": Push(direction=-165.0, speed=0.4, max_step=0.55, first="R", swing=0.34),
    "steps_back_1": Push(direction=180.0, speed=0.65, max_step=0.55, first="R"),
    "steps_back_2": Push(direction=165.0, speed=0.7, max_step=0.45, first="L", swing=0.25, pause=0.04),
    "steps_back_3": Push(direction=-160.0, speed=0.7, max_step=0.35, first="R", swing=0.22, pause=0.03),
    "step_left_1": Push(direction=90.0, speed=0.6, max_step=0.6, first="L"),
    "step_left_2": Push(direction=70.0, speed=0.75, max_step=0.6, first="L", react=0.12),
    "step_left_3": Push(direction=110.0, speed=0.55, max_step=0.6, first="L", swing=0.34),
    "step_right_1": Push(direction=-90.0, speed=0.6, max_step=0.6, first="R"),
    "step_right_2": Push(direction=-70.0, speed=0.75, max_step=0.6, first="R", react=0.12),
    "step_right_3": Push(direction=-110.0, speed=0.55, max_step=0.6, first="R", swing=0.34),
}


# Key poses the upper body passes through when the push is strong (alarm = 1): the trunk bends
# into the fall's direction for a forward push and against it for a backward one (the hip
# strategy), arms fly up and out to balance. Blended from STAND by the alarm and the direction.
FLUNG_FORWARD = pose(
    pelvis_pitch=8.0, spine_pitch=14.0, neck_pitch=-14.0, arm_flex=50.0, arm_abd=30.0, elbow=40.0, wrist=10.0
)
FLUNG_BACK = pose(
    pelvis_pitch=12.0, spine_pitch=18.0, neck_pitch=-6.0, arm_flex=70.0, arm_abd=35.0, elbow=30.0, wrist=-10.0
)
# Per unit of push to the character's left: bend the trunk right, fling the left arm out; to its
# right, the mirror image.
FLUNG_LEFT = dict.fromkeys(PARAMS, 0.0) | {
    "spine_roll": -10.0,
    "pelvis_roll": 3.0,
    "arm_abd_L": 40.0,
    "arm_abd_R": -15.0,
    "arm_flex_L": 10.0,
}
FLUNG_RIGHT = dict.fromkeys(PARAMS, 0.0) | {
    "spine_roll": 10.0,
    "pelvis_roll": -3.0,
    "arm_abd_R": 40.0,
    "arm_abd_L": -15.0,
    "arm_flex_R": 10.0,
}


def step_clip(push: Push, plan: StepPlan | None = None) -> Motion:
    """A stepping reaction: pendulum root path, legs by IK to the planned feet, upper body blended
    between key poses by the pendulum's alarm. Starts in the standing pose at the push, ends at rest.
    plan: the balance model's plan (default balance_plan(push); the sways pass a planted-feet one)."""
    skeleton = sample_skeleton()
    plan = balance_plan(push) if plan is None else plan
    count = len(plan.com)
    angle = np.radians(push.direction)
    ahead, side = np.cos(angle), np.sin(angle)
    stand = pose_vector(STAND)
    flung = (
        max(ahead, 0.0) * (pose_vector(FLUNG_FORWARD) - stand)
        + max(-ahead, 0.0) * (pose_vector(FLUNG_BACK) - stand)
        + max(side, 0.0) * pose_vector(FLUNG_LEFT)
        + max(-side, 0.0) * pose_vector(FLUNG_RIGHT)
    )
    values = stand + plan.alarm[:, None] * flung
    values[:, PARAMS.index("x")] = plan.com[:, 0]
    values[:, PARAMS.index("fwd")] = -plan.com[:, 1]
    root, local = posed(skeleton, values)
    # Pelvis height: as high as standing allows, lower where the feet are far apart (long legs
    # reach 97 % at most), then smoothed so the body sinks and rises gradually.
    reach = 0.97 * (THIGH + SHANK) * HEIGHT
    limit = np.full(count, root[0, 2])
    for s in SIDES:
        hip = quat.rotate(local[:, 0], skeleton.offsets[skeleton.index(f"thigh.{s}")])
        flat = np.linalg.norm(root[:, :2] + hip[:, :2] - plan.ankles[s][:, :2], axis=1)
        limit = np.minimum(limit, plan.ankles[s][:, 2] - hip[:, 2] + np.sqrt(np.maximum(reach**2 - flat**2, 0.0)))
    window = int(0.15 * FPS)
    padded = np.pad(limit, window, mode="edge")
    low = np.min(np.lib.stride_tricks.sliding_window_view(padded, 2 * window + 1), axis=1)
    kernel = np.exp(-0.5 * (np.arange(-window, window + 1) / (window / 3)) ** 2)
    sunk = np.convolve(np.pad(low, window, mode="edge"), kernel / kernel.sum(), mode="valid")
    # Frame 0 is the standing pose exactly; the sinking starts with the push.
    root[:, 2] += (sunk - root[:, 2]) * minimum_jerk(np.arange(count) / (push.react * FPS))
    for s in SIDES:
        _swing_leg(skeleton, root, local, s, plan.ankles[s].copy(), about_x(plan.pitch[s]))
    return clip_motion(skeleton, root, local)


def _swing_leg(
    skeleton: Skeleton, root: np.ndarray, local: np.ndarray, side: str, ankle: np.ndarray, foot_world: np.ndarray
) -> None:
    """Leg IK for a stepping foot. A swinging foot is not held flat: its ankle turns at most 45 deg
    from neutral (a fast long step folds the leg without bending the ankle past its range), so
    its toes hang; where they would scuff the floor the ankle is carried higher (a few passes)."""
    count = len(ankle)
    foot, toe = skeleton.index(f"foot.{side}"), skeleton.index(f"toe.{side}")
    airborne = np.clip((ankle[:, 2] - ANKLE_HEIGHT) / 0.025, 0.0, 1.0)
    for _ in range(4):
        leg_ik(skeleton, root, local, side, ankle, foot_world)
        angle = quat.angle_between(quat.identity(), local[:, foot])
        keep = 1.0 - airborne * (1.0 - np.minimum(1.0, np.radians(45.0) / np.maximum(angle, 1e-9)))
        local[:, foot] = quat.slerp(quat.identity((count,)), local[:, foot], keep)
        pos, rot = forward_kinematics(skeleton, root, local, skeleton.offsets)
        tip = end_site_position(skeleton, pos, rot, toe)
        scuff = np.maximum(TOE_TIP_Z * HEIGHT + 0.02 - tip[:, 2], 0.0) * airborne
        window = int(0.1 * FPS)
        scuff = np.max(np.lib.stride_tricks.sliding_window_view(np.pad(scuff, window), 2 * window + 1), axis=1)
        smooth = np.hanning(2 * window + 1)
        ankle[:, 2] += np.convolve(scuff, smooth / smooth.sum(), "same") * airborne


# ---------------------------------------------------------------------------------------------
# Sways: the pendulum with both feet planted


@dataclass(frozen=True)
class Sway:
    """One sway: a push small enough to ride out on planted feet."""

    direction: float  # degrees from the facing, positive to the character's left
    speed: float  # centre-of-mass speed the push leaves, m/s


SWAYS: dict[str, Sway] = {
    "sway_balance_1": Sway(direction=0.0, speed=0.36),
    "sway_balance_2": Sway(direction=180.0, speed=0.34),
    "sway_balance_3": Sway(direction=90.0, speed=0.42),
}


def sway_clip(sway: Sway) -> Motion:
    """A sway: the stepping clip's body (pendulum root path, trunk and arms by the alarm, legs by IK
    to the planted feet) on the balance model's planted-feet plan. The alarm (speed / 0.8 m/s,
    smoothed) sets how far the trunk bends and the arms rise (the hip strategy); a sway's speeds
    are small, so it counts double here to be visible."""
    push = Push(direction=sway.direction, speed=sway.speed, max_step=0.0, first="L")
    plan = balance_plan(push, planted=True)
    return step_clip(push, plan=replace(plan, alarm=np.minimum(2.0 * plan.alarm, 1.0)))
