#!/usr/bin/env python3
"""Generate the project's own sample skeleton and clips into sample_clips/.

Why this exists: tests, demos and the reaction library need motion that anyone may redistribute
and that can be rebuilt from code, so the clips are procedural, not captured. Run from anywhere:

    python tools/make_sample_clips.py               # writes sample_clips/*.bvh
    python tools/make_sample_clips.py --out DIR     # writes elsewhere (the tests use a temp dir)

tools/ is not a package, so other tools and the tests import this file by path:

    spec = importlib.util.spec_from_file_location("make_sample_clips", REPO / "tools" / "make_sample_clips.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # before exec: dataclasses look their module up there
    spec.loader.exec_module(module)
    skeleton = module.sample_skeleton()

Everything is deterministic (no randomness), so regenerating gives byte-identical files.
To add a clip: write a function returning a Motion on `sample_skeleton()` and list it in CLIPS.

World: metres, Z up; the character faces -Y (Blender's convention: the front view looks along +Y
at the character's face), so its left (.L) is +X. In the written BVH (Y up) it faces +Z.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:  # run as a script: make the reactive_anim package importable
    sys.path.insert(0, str(REPO))

from reactive_anim.core import bvh, quat  # noqa: E402
from reactive_anim.core.skeleton import Motion, Skeleton  # noqa: E402

HEIGHT = 1.75
FPS = 60
FORWARD = np.array([0.0, -1.0, 0.0])  # the direction the character faces and walks
UP = np.array([0.0, 0.0, 1.0])
X_AXIS = np.array([1.0, 0.0, 0.0])
SIDES = {"L": 1.0, "R": -1.0}  # sign of the character's side along +X

# Proportions as fractions of body height H, from the Drillis & Contini (1966) segment-length
# table reproduced in D. A. Winter, "Biomechanics and Motor Control of Human Movement" (4th ed.,
# 2009), Fig. 4.1: shoulder 0.818H, hip 0.530H, knee 0.285H, ankle 0.039H; upper arm 0.186H,
# forearm 0.146H, hand 0.108H, thigh 0.245H, shank 0.246H, foot length 0.152H; crown at 1.0H.
# The spine's subdivision, joint-centre widths and the split of the foot into heel / ball / toe
# are this project's estimates from typical adult anatomy.
SHOULDER_Z = 0.818
HIP_Z = 0.530
UPPER_ARM = 0.186
FOREARM = 0.146
HAND = 0.108
THIGH = 0.245
SHANK = 0.246
ANKLE_Z = HIP_Z - THIGH - SHANK  # 0.039, as in the table
PELVIS_Z = 0.555  # root: mid-pelvis, above the hip joint centres
SPINE_Z = 0.620  # lumbar
SPINE1_Z = 0.690  # lower thoracic
CHEST_Z = 0.760  # upper thoracic
CLAVICLE_Z = 0.805  # sternoclavicular joint, just below the shoulder line
NECK_Z = 0.835  # C7, base of the neck
HEAD_Z = 0.910  # skull base; the crown (End Site) is at 1.0H
HIP_HALF_WIDTH = 0.050  # hip joint centres 0.10H apart
SHOULDER_HALF_WIDTH = 0.100  # shoulder joint centres 0.20H apart (bideltoid width is 0.259H)
CLAVICLE_HALF_WIDTH = 0.012
BALL_FORWARD = 0.080  # ankle to ball of the foot (the toe joint)
BALL_Z = 0.014  # the toe joint's height above the floor
TOE_LENGTH = 0.040  # ball to toe tip; with the heel, foot length is 0.032 + 0.080 + 0.040 = 0.152H
TOE_TIP_Z = 0.006
HEEL_BACK = 0.032  # heel behind the ankle (not a joint: used to roll the foot over the heel)


def sample_skeleton() -> Skeleton:
    """The project's 22-joint, 1.75 m adult, standing with arms hanging, facing -Y (see README).

    Joints are ordered depth-first, the order a BVH file lists them, so reading a written file back
    gives the same indices.
    """
    h = HEIGHT
    names: list[str] = []
    parents: list[int] = []
    rest_h: list[tuple[float, float, float]] = []  # rest positions in units of H
    end_sites: dict[int, np.ndarray] = {}

    def add(name: str, parent: str | None, x: float, y: float, z: float) -> None:
        names.append(name)
        parents.append(-1 if parent is None else names.index(parent))
        rest_h.append((x, y, z))

    add("pelvis", None, 0.0, 0.0, PELVIS_Z)
    add("spine", "pelvis", 0.0, 0.0, SPINE_Z)
    add("spine.001", "spine", 0.0, 0.0, SPINE1_Z)
    add("chest", "spine.001", 0.0, 0.0, CHEST_Z)
    add("neck", "chest", 0.0, 0.0, NECK_Z)
    add("head", "neck", 0.0, 0.0, HEAD_Z)
    end_sites[names.index("head")] = np.array([0.0, 0.0, (1.0 - HEAD_Z) * h])
    for side, s in SIDES.items():
        add(f"shoulder.{side}", "chest", s * CLAVICLE_HALF_WIDTH, 0.0, CLAVICLE_Z)
        add(f"upper_arm.{side}", f"shoulder.{side}", s * SHOULDER_HALF_WIDTH, 0.0, SHOULDER_Z)
        add(f"forearm.{side}", f"upper_arm.{side}", s * SHOULDER_HALF_WIDTH, 0.0, SHOULDER_Z - UPPER_ARM)
        add(f"hand.{side}", f"forearm.{side}", s * SHOULDER_HALF_WIDTH, 0.0, SHOULDER_Z - UPPER_ARM - FOREARM)
        end_sites[names.index(f"hand.{side}")] = np.array([0.0, 0.0, -HAND * h])
    for side, s in SIDES.items():
        add(f"thigh.{side}", "pelvis", s * HIP_HALF_WIDTH, 0.0, HIP_Z)
        add(f"shin.{side}", f"thigh.{side}", s * HIP_HALF_WIDTH, 0.0, HIP_Z - THIGH)
        add(f"foot.{side}", f"shin.{side}", s * HIP_HALF_WIDTH, 0.0, ANKLE_Z)
        add(f"toe.{side}", f"foot.{side}", s * HIP_HALF_WIDTH, -BALL_FORWARD, BALL_Z)
        end_sites[names.index(f"toe.{side}")] = np.array([0.0, -TOE_LENGTH * h, (TOE_TIP_Z - BALL_Z) * h])
    rest = np.array(rest_h) * h
    offsets = rest.copy()
    offsets[1:] -= rest[parents[1:]]
    return Skeleton(names, np.array(parents), offsets, end_sites)


# ---------------------------------------------------------------------------------------------
# Small maths helpers


def _rot(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Quaternions for rotations by `angle` (radians, any shape) about a fixed world axis."""
    return quat.from_axis_angle(axis, np.asarray(angle, dtype=float))


def _rx(angle: np.ndarray) -> np.ndarray:
    return _rot(X_AXIS, angle)


def _ry(angle: np.ndarray) -> np.ndarray:
    return _rot(np.array([0.0, 1.0, 0.0]), angle)


def _rz(angle: np.ndarray) -> np.ndarray:
    return _rot(UP, angle)


def _wave(phase: np.ndarray, peak_at: float) -> np.ndarray:
    """cos(2 pi (phase - peak_at)): one oscillation per cycle, +1 at `peak_at` (a cycle fraction)."""
    return np.cos(2.0 * np.pi * (phase - peak_at))


def _hermite(p0: np.ndarray, m0: np.ndarray, p1: np.ndarray, m1: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Cubic Hermite from p0 (slope m0) to p1 (slope m1) for s in [0, 1]; slopes are per unit s.

    Used for the swing so that position and velocity join the stance phases without a jolt.
    """
    s = s.reshape(s.shape + (1,) * (np.ndim(p0) - 1))
    s2, s3 = s * s, s * s * s
    return (2 * s3 - 3 * s2 + 1) * p0 + (s3 - 2 * s2 + s) * m0 + (-2 * s3 + 3 * s2) * p1 + (s3 - s2) * m1


def _via(
    start: np.ndarray, start_slope: np.ndarray, middle: float, end: np.ndarray, end_slope: np.ndarray,
    s: np.ndarray, at: float,
) -> np.ndarray:
    """Two cubic Hermite pieces, start -> middle (reached at s = `at` with zero slope) -> end.

    Pins a curve's extreme in the middle of an interval while keeping its ends' values and slopes
    (per unit s), e.g. a swing foot that levels out at mid-swing.
    """
    flat = np.zeros_like(start)
    first = _hermite(start, start_slope * at, flat + middle, flat, s / at)
    second = _hermite(flat + middle, flat, end, end_slope * (1.0 - at), (s - at) / (1.0 - at))
    return np.where(s < at, first, second)


def _frame(axis: np.ndarray, lateral: np.ndarray) -> np.ndarray:
    """Orthonormal matrices (..., 3, 3) whose columns are the lateral, the bone axis and their cross."""
    axis = axis / np.linalg.norm(axis, axis=-1, keepdims=True)
    lateral = lateral - np.sum(lateral * axis, axis=-1, keepdims=True) * axis
    lateral = lateral / np.linalg.norm(lateral, axis=-1, keepdims=True)
    return np.stack([lateral, axis, np.cross(lateral, axis)], axis=-1)


def two_bone_ik(
    root: np.ndarray,
    target: np.ndarray,
    rest_upper: np.ndarray,
    rest_lower: np.ndarray,
    pole: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Global rotations (T, 4) of the upper and lower bone of a limb so its end reaches `target`.

    Analytic (law of cosines), so a planted foot stays exactly where it was planned. root,
    target: (T, 3) world positions; rest_upper, rest_lower: the bones' rest vectors (the child
    offsets); pole: (3,), the direction the middle joint (knee) should point. The hinge
    axis is the pole crossed with the root-to-target line, so the middle joint bends towards the
    pole and the two bones share the hinge. Out-of-reach targets are clamped just short of a
    straight limb.
    """
    len1 = float(np.linalg.norm(rest_upper))
    len2 = float(np.linalg.norm(rest_lower))
    reach = target - root
    dist = np.linalg.norm(reach, axis=-1, keepdims=True)
    along = reach / dist
    dist = np.clip(dist, abs(len1 - len2) + 1e-6, (len1 + len2) * (1.0 - 1e-6))
    hinge = np.cross(np.broadcast_to(pole, reach.shape), along)
    hinge /= np.linalg.norm(hinge, axis=-1, keepdims=True)
    bend = np.cross(along, hinge)  # towards the pole, perpendicular to the root-target line
    cos_a = (len1 * len1 + dist * dist - len2 * len2) / (2.0 * len1 * dist)
    middle = root + len1 * (cos_a * along + np.sqrt(1.0 - cos_a * cos_a) * bend)
    end = root + dist * along
    rest_hinge = np.cross(pole, rest_upper + rest_lower)
    upper = _frame(middle - root, hinge) @ np.swapaxes(_frame(rest_upper, rest_hinge), -1, -2)
    lower = _frame(end - middle, hinge) @ np.swapaxes(_frame(rest_lower, rest_hinge), -1, -2)
    return quat.from_matrix(upper), quat.from_matrix(lower)


# ---------------------------------------------------------------------------------------------
# Gait


@dataclass(frozen=True)
class Gait:
    """Parameters of a procedural gait; angles in degrees, phases as fractions of a cycle.

    A cycle starts at the left heel strike; the right foot runs half a cycle behind. Each foot's
    stance rolls over the heel (heel strike to foot flat), stays flat, then rolls over the ball
    (from heel off) and the toe tip (from ball off) until toe off; the swing joins toe off to the
    next heel strike with cubic curves (see foot_track).
    """

    speed: float  # m/s along FORWARD
    cycle_frames: int  # frames per cycle (two steps)
    cycles: int
    step_width: float  # lateral distance between the feet's tracks, m
    foot_flat: float  # phase of foot flat
    heel_off: float  # the heel starts to rise (the foot pitches about the ball)
    ball_off: float  # the ball starts to rise (the toes pitch about their tip)
    toe_off: float
    foot_under_pelvis: float  # phase at which the pelvis passes over the flat foot's ankle
    heel_strike_pitch: float  # toes up at heel strike (negative: rotation about +X)
    toe_off_pitch: float  # the foot's pitch at toe off (heel up)
    toe_off_toe_pitch: float  # the toes' pitch at toe off (ball above the tip)
    level_pitch: float  # the foot's pitch when it levels out in the swing
    level_at: float  # fraction of the swing at which it is level
    lowest_at: float  # fraction of the swing at which the ankle passes lowest (least toe clearance)
    toe_relax: float  # fraction of the swing over which the toes return from bent to straight
    swing_clearance: float  # the swing ankle's height above its standing height at its lowest, m
    pelvis_drop: float  # mean pelvis height below the standing height, m
    bob: float  # vertical amplitude, m (lowest in double support)
    bob_low_at: float  # phase of the lowest point
    sway: float  # lateral amplitude towards the stance leg, m
    surge: float  # forward speed-up in double support, m of amplitude
    pelvis_yaw: float  # the leading leg's hip goes forward
    pelvis_list: float  # the swing side drops
    pelvis_tilt: float  # anterior tilt, mean
    pelvis_tilt_swing: float  # twice-per-cycle tilt amplitude
    trunk_lean: float  # forward lean of the spine over the pelvis
    chest_yaw: float  # counter-rotation of the chest against the pelvis
    list_compensation: float  # fraction of the pelvis's list the spine bends back
    arm_swing: float  # shoulder flexion amplitude
    arm_mean: float  # mean shoulder flexion (forward positive)
    arm_abduction: float  # keeps the hands clear of the hips
    arm_lag: float  # the arms follow the legs by this phase
    elbow_mean: float
    elbow_swing: float
    wrist_swing: float
    clavicle_swing: float


# Tuned by hand and by a parameter search so that the knee follows the typical walking curve
# (about 10 deg at heel strike, 18 in loading, 35 at toe off, 60 in swing), the legs never stretch
# beyond 99.8 % of their length (so the IK always reaches), and the toes clear the floor.
WALK = Gait(
    speed=1.3,
    cycle_frames=66,  # 1.1 s per cycle, cadence 109 steps/min, stride 1.43 m
    cycles=4,
    step_width=0.12,
    foot_flat=0.1,
    heel_off=0.36,
    ball_off=0.52,
    toe_off=0.62,
    foot_under_pelvis=0.22,
    heel_strike_pitch=-12.0,
    toe_off_pitch=70.0,
    toe_off_toe_pitch=35.0,
    level_pitch=-7.0,
    level_at=0.5,
    lowest_at=0.75,
    toe_relax=0.55,
    swing_clearance=0.03,
    pelvis_drop=0.03,
    bob=0.018,
    bob_low_at=-0.01,
    sway=0.022,
    surge=0.006,
    pelvis_yaw=5.0,
    pelvis_list=4.0,
    pelvis_tilt=4.0,
    pelvis_tilt_swing=1.5,
    trunk_lean=2.0,
    chest_yaw=4.0,
    list_compensation=0.8,
    arm_swing=18.0,
    arm_mean=-3.0,
    arm_abduction=7.0,
    arm_lag=0.04,
    elbow_mean=22.0,
    elbow_swing=10.0,
    wrist_swing=6.0,
    clavicle_swing=3.0,
)


@dataclass
class FootTrack:
    """One foot's planned world path: ankle position (T, 3), foot pitch and toe bend (T,), radians."""

    ankle: np.ndarray
    pitch: np.ndarray
    toe: np.ndarray


@dataclass
class _FootState:
    """Ankle position and velocity, foot pitch and toe bend with their rates (per unit phase)."""

    ankle: np.ndarray
    velocity: np.ndarray
    pitch: np.ndarray
    pitch_rate: np.ndarray
    toe: np.ndarray
    toe_rate: np.ndarray


def _ramp(phase: np.ndarray, start: float, stop: float, amount: float) -> tuple[np.ndarray, np.ndarray]:
    """amount * k^2 with k going 0 -> 1 over [start, stop] (clamped), and its rate per unit phase.

    Starts at zero rate, so a rotation leaves the flat foot without a jolt, and ends at its fastest,
    as a push-off or a foot slapping down does.
    """
    k = np.clip((phase - start) / (stop - start), 0.0, 1.0)
    return amount * k * k, 2.0 * amount * k / (stop - start)


def _turn(angle: np.ndarray, rate: np.ndarray, arm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """`arm` rotated about +X by `angle`, and its velocity for the angle's `rate`."""
    turned = quat.rotate(_rx(angle), arm)
    return turned, rate[..., None] * np.cross(X_AXIS, turned)


def foot_track(gait: Gait, skeleton: Skeleton, side: str, frames: np.ndarray) -> FootTrack:
    """Plan one foot in world space so that it never slides while it bears weight.

    Stance: from heel strike the foot rolls down about the planted heel, lies flat, then pushes off:
    the heel rises (the foot pitches about the ball, toes flat), then the ball rises too (the toes
    pitch about their planted tip). Swing: cubic curves join toe off to the next heel strike with
    matching velocities; the foot levels out and passes low but clear of the floor on the way.
    """
    s = SIDES[side]
    ankle_z = skeleton.rest_positions()[skeleton.index(f"foot.{side}")][2]
    toe = skeleton.index(f"toe.{side}")
    ball_arm = -skeleton.offsets[toe]  # ankle relative to the ball, foot flat
    tip_arm = -skeleton.end_sites[toe]  # ball relative to the toe tip, toes flat
    heel_arm = np.array([0.0, 0.0, ankle_z]) + HEEL_BACK * HEIGHT * FORWARD  # ankle relative to the heel
    stride = gait.speed * gait.cycle_frames / FPS
    offset = 0.0 if side == "L" else 0.5
    u = frames / gait.cycle_frames - offset
    cycle = np.floor(u)
    phase = u - cycle

    def stance(c: np.ndarray, ph: np.ndarray) -> _FootState:
        flat = np.array([s * gait.step_width / 2, 0.0, ankle_z]) + (
            stride * (c + offset + gait.foot_under_pelvis)
        )[:, None] * FORWARD
        roll, roll_rate = _ramp(-ph, -gait.foot_flat, 0.0, np.radians(gait.heel_strike_pitch))
        roll_rate = -roll_rate  # the ramp ran backwards in phase
        heel, heel_vel = _turn(roll, roll_rate, heel_arm)
        pitch, pitch_rate = _ramp(ph, gait.heel_off, gait.toe_off, np.radians(gait.toe_off_pitch))
        toes, toes_rate = _ramp(ph, gait.ball_off, gait.toe_off, np.radians(gait.toe_off_toe_pitch))
        ball, ball_vel = _turn(pitch, pitch_rate, ball_arm)
        tip, tip_vel = _turn(toes, toes_rate, tip_arm)
        on_heel = (ph < gait.foot_flat)[:, None]
        return _FootState(
            ankle=np.where(on_heel, flat - heel_arm + heel, flat - ball_arm - tip_arm + tip + ball),
            velocity=np.where(on_heel, heel_vel, tip_vel + ball_vel),
            pitch=roll + pitch,
            pitch_rate=roll_rate + pitch_rate,
            toe=toes - pitch,  # the toes' rotation relative to the foot
            toe_rate=toes_rate - pitch_rate,
        )

    n = len(frames)
    ankle, pitch, toe = np.empty((n, 3)), np.empty(n), np.empty(n)
    part = phase < gait.toe_off
    now = stance(cycle[part], phase[part])
    ankle[part], pitch[part], toe[part] = now.ankle, now.pitch, now.toe

    part = ~part
    c = cycle[part]
    duration = 1.0 - gait.toe_off
    sw = (phase[part] - gait.toe_off) / duration
    lift_off = stance(c, np.full(len(c), gait.toe_off))
    landing = stance(c + 1, np.zeros(len(c)))
    # Forward: one cubic. Height and pitch pass through mid-swing level and just above standing
    # height (zero vertical speed and pitch rate there), so the toes clear the floor.
    ankle[part] = _hermite(lift_off.ankle, lift_off.velocity * duration, landing.ankle, landing.velocity * duration, sw)
    ankle[part, 2] = _via(
        lift_off.ankle[:, 2], lift_off.velocity[:, 2] * duration, ankle_z + gait.swing_clearance,
        landing.ankle[:, 2], landing.velocity[:, 2] * duration, sw, gait.lowest_at,
    )
    pitch[part] = _via(
        lift_off.pitch, lift_off.pitch_rate * duration, np.radians(gait.level_pitch),
        landing.pitch, landing.pitch_rate * duration, sw, gait.level_at,
    )
    relax = np.minimum(sw / gait.toe_relax, 1.0)
    rest = np.zeros(len(c))
    toe[part] = _hermite(lift_off.toe, lift_off.toe_rate * duration * gait.toe_relax, rest, rest, relax)
    return FootTrack(ankle, pitch, toe)


def _pelvis(gait: Gait, skeleton: Skeleton, frames: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Root position (T, 3) and rotation (T, 4): forward travel with bob, sway, surge and the
    pelvis's yaw, list and tilt, each periodic in the cycle."""
    phase = frames / gait.cycle_frames
    t = frames / FPS
    stance_l = _wave(phase, 0.25)  # +1 in the middle of the left stance
    double = _wave(2.0 * phase, 2.0 * gait.bob_low_at)  # +1 in each double support
    height = skeleton.offsets[0, 2] - gait.pelvis_drop - gait.bob * double
    travel = gait.speed * t + gait.surge * np.sin(4.0 * np.pi * (phase - gait.bob_low_at))  # fastest in double support
    pos = (travel[:, None] * FORWARD) + np.stack([gait.sway * stance_l, np.zeros_like(t), height], axis=-1)
    yaw = np.radians(gait.pelvis_yaw) * _wave(phase, 0.0)  # left hip forward at the left heel strike
    lst = np.radians(gait.pelvis_list) * _wave(phase, 0.2)  # right (swing) side lower in left stance
    tilt = np.radians(gait.pelvis_tilt + gait.pelvis_tilt_swing * double)
    rot = quat.mul(quat.mul(_rz(-yaw), _ry(-lst)), _rx(tilt))
    return pos, rot


def gait_clip(gait: Gait, skeleton: Skeleton) -> Motion:
    """A looping locomotion clip: pelvis path, feet planned in world space, legs by analytic IK,
    upper body by periodic curves. Whole cycles, so the last frame runs on into the first."""
    count = gait.cycle_frames * gait.cycles
    frames = np.arange(count, dtype=float)
    phase = frames / gait.cycle_frames
    local = quat.identity((count, skeleton.num_joints))
    idx = skeleton.index
    root_pos, local[:, 0] = _pelvis(gait, skeleton, frames)
    pelvis_rot = local[:, 0]

    for side in SIDES:
        track = foot_track(gait, skeleton, side, frames)
        thigh, shin, foot, toe = (idx(f"{b}.{side}") for b in ("thigh", "shin", "foot", "toe"))
        hip = root_pos + quat.rotate(pelvis_rot, skeleton.offsets[thigh])
        upper, lower = two_bone_ik(hip, track.ankle, skeleton.offsets[shin], skeleton.offsets[foot], FORWARD)
        foot_rot = _rx(track.pitch)
        local[:, thigh] = quat.mul(quat.conj(pelvis_rot), upper)
        local[:, shin] = quat.mul(quat.conj(upper), lower)
        local[:, foot] = quat.mul(quat.conj(lower), foot_rot)
        local[:, toe] = _rx(track.toe)

    # Spine: counter-rotate the chest against the pelvis, undo the list, lean a little forward.
    spine = [idx("spine"), idx("spine.001"), idx("chest")]
    yaw = np.radians(gait.chest_yaw + gait.pelvis_yaw) * _wave(phase, 0.0) / len(spine)
    lst = np.radians(gait.pelvis_list * gait.list_compensation) * _wave(phase, 0.2) / len(spine)
    lean = np.radians(gait.trunk_lean - gait.pelvis_tilt) / len(spine)
    for j in spine:
        local[:, j] = quat.mul(quat.mul(_rz(yaw), _ry(lst)), _rx(np.full(count, lean)))
    # Neck and head: keep the gaze level and forward, the neck taking half of the correction.
    chest_rot = pelvis_rot
    for j in spine:
        chest_rot = quat.mul(chest_rot, local[:, j])
    local[:, idx("neck")] = quat.slerp(quat.identity((count,)), quat.conj(chest_rot), 0.5)
    local[:, idx("head")] = quat.conj(quat.mul(chest_rot, local[:, idx("neck")]))

    # Arms swing opposite to the legs: the left arm is forward when the right leg is.
    for side, s in SIDES.items():
        forward_at = gait.arm_lag + (0.5 if side == "L" else 0.0)
        swing = _wave(phase, forward_at)
        flex = np.radians(gait.arm_mean + gait.arm_swing * swing)
        local[:, idx(f"shoulder.{side}")] = _rz(-s * np.radians(gait.clavicle_swing) * swing)
        abduction = _ry(np.full(count, -s * np.radians(gait.arm_abduction)))
        local[:, idx(f"upper_arm.{side}")] = quat.mul(_rx(-flex), abduction)
        elbow = np.radians(gait.elbow_mean + gait.elbow_swing * _wave(phase, forward_at + 0.03))
        local[:, idx(f"forearm.{side}")] = _rx(-elbow)
        local[:, idx(f"hand.{side}")] = _rx(-np.radians(gait.wrist_swing) * _wave(phase, forward_at + 0.08))

    return Motion(skeleton=skeleton, fps=float(FPS), root_pos=root_pos, local_rot=quat.normalize(local))


def walk_clip() -> Motion:
    """A 4.4 s walk at 1.3 m/s: four seamless cycles, feet planted, arms swinging."""
    return gait_clip(WALK, sample_skeleton())


CLIPS: dict[str, Callable[[], Motion]] = {
    "walk": walk_clip,
}


def write_clips(out_dir: Path) -> list[Path]:
    """Write every clip in CLIPS as <name>.bvh (centimetres, Y up, ZXY: the common dialect)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    written = []
    for name, make in CLIPS.items():
        path = out_dir / f"{name}.bvh"
        bvh.write_bvh(path, make(), rotation_order="ZXY", unit="cm", up="Y")
        written.append(path)
    return written


def main(argv: list[str] | None = None) -> int:
    """Write the clips and say what was written, read back through the BVH reader as a check."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--out", type=Path, default=REPO / "sample_clips", help="output folder (default: sample_clips/)"
    )
    args = parser.parse_args(argv)
    for path in write_clips(args.out):
        motion = bvh.read_bvh(path)
        seconds = motion.num_frames / motion.fps
        distance = np.linalg.norm(motion.root_pos[-1, :2] - motion.root_pos[0, :2])
        print(
            f"wrote {path}: {motion.skeleton.num_joints} joints, {motion.num_frames} frames at "
            f"{motion.fps:g} fps ({seconds:.2f} s), root travels {distance:.2f} m"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
