"""Get-ups: keyframed clips from lying face down, lying face up or sitting on the floor to standing.

A get-up is a list of `Key`s (GETUPS). A key is a pose (a few named angles, poses.py) plus, for
hands and feet on the floor, world targets. Keys are joined with minimum-jerk easing; hands and
feet reach their targets by IK, so a hand or foot whose target does not change between two keys
stays planted, and one that moves is lifted on the way.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from reactive_anim.core.model import quat
from reactive_anim.core.model.skeleton import Motion, forward_kinematics

from .curves import key_timeline, lift_bump
from .ik import arm_ik, leg_ik
from .poses import STAND_WIDTH, pose, pose_vector, posed
from .skeleton import ANKLE_HEIGHT, FORWARD, FPS, SIDES, UP, about_x, about_z, clip_motion, sample_skeleton


@dataclass(frozen=True)
class Key:
    """A key pose at time `at` (s).

    hands: world target of a wrist with its hand flat on the floor (x, mirrored per side; fwd; z;
    the fingers' heading in degrees, 0 forward, 90 outwards), or None: the arms keep the pose's
    own angles. feet: world target of an ankle (x mirrored, fwd, z, the foot's world pitch in
    degrees, toes down positive), or None: where the pose's leg angles put it.
    """

    at: float
    body: dict[str, float]
    hands: tuple[float, float, float, float] | None = None
    feet: tuple[float, float, float, float] | None = None


def _side_point(xyz: tuple[float, ...], s: float) -> np.ndarray:
    """A key's world target: x mirrored by the side's sign `s`, fwd along FORWARD, z up."""
    return np.array([s * xyz[0], 0.0, xyz[2]]) + xyz[1] * FORWARD


HAND_DOWN = 0.03  # wrist height of a hand flat on the floor, m
# Face down (head towards FORWARD): hands beside the hips, then under the shoulders, push the
# chest up, draw the knees under the hips (hands and knees), tuck the toes and push back into a
# deep squat, stand up. Lying, the feet are a little up: with the ankles on the floor the legs,
# not quite straight, bent their knees down into it (the knee joints 4 cm under).
PRONE_GETUP = [
    Key(
        0.0,
        pose(z=0.11, pelvis_pitch=88.0, spine_pitch=0.0, neck_pitch=-25.0),
        hands=(0.32, 0.28, HAND_DOWN, 15.0),
        feet=(0.12, -0.86, 0.25, 150.0),
    ),
    Key(
        0.4,
        pose(z=0.11, pelvis_pitch=88.0, spine_pitch=0.0, neck_pitch=-30.0),
        hands=(0.32, 0.28, HAND_DOWN, 15.0),
        feet=(0.12, -0.86, 0.25, 150.0),
    ),
    Key(
        1.2,
        pose(z=0.16, pelvis_pitch=72.0, spine_pitch=-22.0, neck_pitch=-20.0),
        hands=(0.32, 0.28, HAND_DOWN, 15.0),
        feet=(0.12, -0.84, 0.25, 150.0),
    ),
    Key(
        2.1,
        pose(fwd=-0.16, z=0.52, pelvis_pitch=85.0, spine_pitch=0.0, neck_pitch=-25.0),
        hands=(0.32, 0.28, HAND_DOWN, 15.0),
        feet=(0.12, -0.62, 0.075, 150.0),
    ),
    Key(
        2.8,
        pose(fwd=-0.22, z=0.55, pelvis_pitch=85.0, spine_pitch=5.0, neck_pitch=-15.0, toe=-55.0),
        hands=(0.32, 0.28, HAND_DOWN, 15.0),
        feet=(STAND_WIDTH / 2, -0.55, 0.18, 70.0),
    ),
    Key(
        3.7,
        pose(fwd=-0.83, z=0.46, pelvis_pitch=45.0, spine_pitch=25.0, neck_pitch=-30.0, arm_flex=125.0, elbow=20.0),
        feet=(STAND_WIDTH / 2, -0.68, ANKLE_HEIGHT, 0.0),
    ),
    Key(4.6, pose(fwd=-0.68), feet=(STAND_WIDTH / 2, -0.68, ANKLE_HEIGHT, 0.0)),
    Key(5.1, pose(fwd=-0.68), feet=(STAND_WIDTH / 2, -0.68, ANKLE_HEIGHT, 0.0)),
]
# From sitting on the floor (knees bent, feet flat, hands behind): rock forward onto the feet
# into a squat with the arms reaching forward, stand up. The face-up get-up sits up into it.
SIT_KEYS = [
    Key(
        0.0,
        pose(z=0.11, pelvis_pitch=-15.0, spine_pitch=18.0, neck_pitch=5.0),
        hands=(0.22, -0.15, HAND_DOWN, 90.0),
        feet=(STAND_WIDTH / 2, 0.50, ANKLE_HEIGHT, 0.0),
    ),
    Key(
        0.5,
        pose(z=0.11, pelvis_pitch=-5.0, spine_pitch=25.0, neck_pitch=5.0),
        hands=(0.22, -0.15, HAND_DOWN, 90.0),
        feet=(STAND_WIDTH / 2, 0.50, ANKLE_HEIGHT, 0.0),
    ),
    Key(
        1.3,
        pose(fwd=0.35, z=0.45, pelvis_pitch=45.0, spine_pitch=25.0, neck_pitch=-30.0, arm_flex=125.0, elbow=20.0),
        feet=(STAND_WIDTH / 2, 0.50, ANKLE_HEIGHT, 0.0),
    ),
    Key(2.2, pose(fwd=0.50), feet=(STAND_WIDTH / 2, 0.50, ANKLE_HEIGHT, 0.0)),
    Key(2.7, pose(fwd=0.50), feet=(STAND_WIDTH / 2, 0.50, ANKLE_HEIGHT, 0.0)),
]
# Face up (head away from FORWARD): sit up onto the hands, draw the feet in, then as SIT_KEYS.
SUPINE_KEYS = [
    Key(
        0.0,
        pose(z=0.11, pelvis_pitch=-88.0, spine_pitch=0.0, neck_pitch=12.0),
        hands=(0.30, -0.05, HAND_DOWN, 0.0),
        feet=(0.12, 0.86, 0.09, -60.0),
    ),
    Key(
        0.8,
        pose(z=0.11, pelvis_pitch=-35.0, spine_pitch=20.0, neck_pitch=10.0),
        hands=(0.22, -0.15, HAND_DOWN, 90.0),
        feet=(0.12, 0.84, 0.09, -60.0),
    ),
]
GETUPS: dict[str, list[Key]] = {
    "getup_face_down": PRONE_GETUP,
    "getup_face_up": SUPINE_KEYS + [Key(k.at + 1.6, k.body, k.hands, k.feet) for k in SIT_KEYS],
    "getup_sitting": SIT_KEYS,
}


def keyed_clip(keys: list[Key]) -> Motion:
    """Interpolate key poses (minimum-jerk between neighbours) and put hands and feet on their
    targets by IK; unset targets come from the key's own arm and leg angles."""
    skeleton = sample_skeleton()
    idx = skeleton.index
    # Each key's limb targets and foot rotations, filled in from its pose where not given.
    key_values = np.array([pose_vector(k.body) for k in keys])
    key_root, key_local = posed(skeleton, key_values)
    key_pos, key_rot = forward_kinematics(skeleton, key_root, key_local, skeleton.offsets)
    hands, feet, foot_rot, hand_rot = {}, {}, {}, {}
    for side, s in SIDES.items():
        hands[side] = np.array(
            [
                key_pos[i, idx(f"hand.{side}")] if k.hands is None else _side_point(k.hands, s)
                for i, k in enumerate(keys)
            ]
        )
        hand_rot[side] = np.array(
            [
                key_rot[i, idx(f"hand.{side}")]
                if k.hands is None
                else quat.mul(about_z(s * np.radians(k.hands[3])), about_x(-np.pi / 2))
                for i, k in enumerate(keys)
            ]
        )
        feet[side] = np.array(
            [key_pos[i, idx(f"foot.{side}")] if k.feet is None else _side_point(k.feet, s) for i, k in enumerate(keys)]
        )
        foot_rot[side] = np.array(
            [
                key_rot[i, idx(f"foot.{side}")] if k.feet is None else about_x(np.radians(k.feet[3]))
                for i, k in enumerate(keys)
            ]
        )
    times = np.array([k.at for k in keys])
    count = round(times[-1] * FPS) + 1
    timeline = key_timeline(times, np.arange(count) / FPS)
    seg, eased = timeline.segment, timeline.eased
    bump = lift_bump(timeline.progress)

    def carried(a: np.ndarray) -> np.ndarray:
        """A hand or foot moving to a new target lifts off on the way (half the distance, at
        most 15 cm, highest half way), so it neither drags over nor digs into the floor."""
        lift = np.minimum(0.5 * np.linalg.norm(a[seg + 1] - a[seg], axis=-1), 0.15)
        return timeline.between(a) + (lift * bump)[:, None] * UP

    root, local = posed(skeleton, timeline.between(key_values))
    # Arms without a target keep their own angles (IK to where they would be anyway would twist
    # them); between a planted and a free key the two solutions are blended.
    planted = timeline.between(np.array([0.0 if k.hands is None else 1.0 for k in keys]))
    for side in SIDES:
        rot = quat.slerp(foot_rot[side][seg], foot_rot[side][seg + 1], eased)
        leg_ik(skeleton, root, local, side, carried(feet[side]), rot)
        arm = [idx(f"{b}.{side}") for b in ("upper_arm", "forearm", "hand")]
        free = local[:, arm].copy()
        arm_ik(
            skeleton,
            root,
            local,
            side,
            carried(hands[side]),
            quat.slerp(hand_rot[side][seg], hand_rot[side][seg + 1], eased),
        )
        local[:, arm] = quat.slerp(free, local[:, arm], planted[:, None])
    return clip_motion(skeleton, root, local)
