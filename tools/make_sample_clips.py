#!/usr/bin/env python3
"""Generate the project's own sample skeleton and clips into sample_clips/.

Why this exists: tests, demos and the reaction library need motion that anyone may redistribute
and that can be rebuilt from code, so the clips are procedural, not captured. Run from anywhere:

    python tools/make_sample_clips.py               # writes sample_clips/*.bvh
    python tools/make_sample_clips.py --out DIR     # writes elsewhere (the tests use a temp dir)
    python tools/make_sample_clips.py --sheets out/contact_sheets   # also draws contact sheet PNGs

tools/ is not a package, so other tools and the tests import this file by path:

    spec = importlib.util.spec_from_file_location("make_sample_clips", REPO / "tools" / "make_sample_clips.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # before exec: dataclasses look their module up there
    spec.loader.exec_module(module)
    skeleton = module.sample_skeleton()

Everything is deterministic (no randomness), so regenerating gives byte-identical files.
To add a clip: write a function returning a Motion on `sample_skeleton()` and list it in CLIPS.
Clip families are parameter tables: a walk or run is a `Gait`, a stepping reaction a `Push` row
of STEPS (a pendulum balance model decides the steps), a get-up a list of key poses in GETUPS.
Falls come from the ragdoll (physics) and sways from the pendulum with planted feet: both in
tools/sample_falls.py, listed in CLIPS here.

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
from reactive_anim.core.skeleton import Motion, Skeleton, forward_kinematics  # noqa: E402

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
    rest_pole: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Global rotations (T, 4) of the upper and lower bone of a limb so its end reaches `target`.

    Analytic (law of cosines), so a planted foot stays exactly where it was planned. root,
    target: (T, 3) world positions; rest_upper, rest_lower: the bones' rest vectors (the child
    offsets); pole: (3,), the direction the middle joint (knee) should point. The hinge
    axis is the pole crossed with the root-to-target line, so the middle joint bends towards the
    pole and the two bones share the hinge. Out-of-reach targets are clamped just short of a
    straight limb. `rest_pole` is where the pole points in the rest pose (default: `pole`); pass
    it when the pole turns with the body (a lying character's knees point at the floor).
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
    rest_hinge = np.cross(pole if rest_pole is None else rest_pole, rest_upper + rest_lower)
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


# A run on the walk's machinery: stance is short (toe off at 30 % of the cycle), so each foot's
# stance is followed by a flight phase with both feet off the floor; the pelvis is lowest in
# mid-stance (bob_low_at near foot_under_pelvis), not in double support; the swing ankle's
# extreme ("lowest_at"/"swing_clearance") becomes a high heel kick; elbows bent near 80 deg.
RUN = Gait(
    speed=3.0,
    cycle_frames=44,  # 0.73 s per cycle, cadence 164 steps/min, stride 2.2 m
    cycles=3,
    step_width=0.08,
    foot_flat=0.05,
    heel_off=0.14,
    ball_off=0.22,
    toe_off=0.30,
    foot_under_pelvis=0.13,
    heel_strike_pitch=-6.0,
    toe_off_pitch=55.0,
    toe_off_toe_pitch=25.0,
    level_pitch=25.0,
    level_at=0.35,
    lowest_at=0.4,
    toe_relax=0.5,
    swing_clearance=0.22,
    pelvis_drop=0.07,
    bob=0.02,
    bob_low_at=0.13,
    sway=0.01,
    surge=0.0,
    pelvis_yaw=7.0,
    pelvis_list=3.0,
    pelvis_tilt=8.0,
    pelvis_tilt_swing=1.0,
    trunk_lean=9.0,
    chest_yaw=8.0,
    list_compensation=0.8,
    arm_swing=30.0,
    arm_mean=5.0,
    arm_abduction=10.0,
    arm_lag=0.03,
    elbow_mean=80.0,
    elbow_swing=15.0,
    wrist_swing=5.0,
    clavicle_swing=5.0,
)


def run_clip() -> Motion:
    """A 2.2 s run at 3 m/s: three seamless cycles with a flight phase after every push-off."""
    return gait_clip(RUN, sample_skeleton())


# ---------------------------------------------------------------------------------------------
# Poses by parameters: the keyframed clips (idle, steps, get-ups) describe a body with a few
# named angles instead of 22 quaternions, so a key pose is a short dict and a variant a row.

SIDE_PARAMS = ("arm_flex", "arm_abd", "elbow", "wrist", "hip_flex", "hip_abd", "knee", "ankle", "toe")
BODY_PARAMS = ("x", "fwd", "z", "pelvis_pitch", "pelvis_roll", "pelvis_yaw", "spine_pitch", "spine_roll",
               "spine_yaw", "neck_pitch")
PARAMS = BODY_PARAMS + tuple(f"{p}_{side}" for side in SIDES for p in SIDE_PARAMS)
STAND_WIDTH = 0.20  # ankle centres apart when standing at rest, m
STAND_DROP = 0.012  # the pelvis sits this far below its rest height: soft knees, not locked
# Pose parameters are degrees, except x, fwd, z: the root in metres (x to the character's left,
# fwd along FORWARD). Signs: pitch and flexion forward, roll to the left, yaw to the left; ankle
# positive points the toes down; toe positive curls them.


def pose(base: dict[str, float] | None = None, **changes: float) -> dict[str, float]:
    """A copy of `base` with `changes`; a side parameter without _L/_R sets both sides."""
    out = dict(STAND if base is None else base)
    for name, value in changes.items():
        if name in SIDE_PARAMS:
            for side in SIDES:
                out[f"{name}_{side}"] = value
        elif name in out:
            out[name] = value
        else:
            raise KeyError(f"unknown pose parameter {name!r}")
    return out


# The standing pose every reaction starts and ends in and the idle breathes around.
STAND = pose(dict.fromkeys(PARAMS, 0.0), z=PELVIS_Z * HEIGHT - STAND_DROP, pelvis_pitch=3.0, spine_pitch=1.0,
             neck_pitch=-4.0, arm_flex=4.0, arm_abd=6.0, elbow=14.0, wrist=4.0)


def _vector(p: dict[str, float]) -> np.ndarray:
    return np.array([p[name] for name in PARAMS])


def _fk_pose(skeleton: Skeleton, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Root position (T, 3) and local rotations (T, J, 4) for parameter rows (T, len(PARAMS)).

    The spine's angles are shared over its three joints and the neck's over neck and head, as a
    real spine bends along its length.
    """
    count = len(values)
    idx = skeleton.index
    col = {name: values[:, k] for k, name in enumerate(PARAMS)}
    rad = {name: np.radians(v) for name, v in col.items()}
    local = quat.identity((count, skeleton.num_joints))
    root = np.stack([col["x"], np.zeros(count), col["z"]], axis=-1) + col["fwd"][:, None] * FORWARD
    local[:, 0] = quat.mul(quat.mul(_rz(rad["pelvis_yaw"]), _ry(rad["pelvis_roll"])), _rx(rad["pelvis_pitch"]))
    for j in ("spine", "spine.001", "chest"):
        local[:, idx(j)] = quat.mul(quat.mul(_rz(rad["spine_yaw"] / 3), _ry(rad["spine_roll"] / 3)),
                                    _rx(rad["spine_pitch"] / 3))
    for j in ("neck", "head"):
        local[:, idx(j)] = _rx(rad["neck_pitch"] / 2)
    for side, s in SIDES.items():
        r = {p: rad[f"{p}_{side}"] for p in SIDE_PARAMS}
        local[:, idx(f"upper_arm.{side}")] = quat.mul(_rx(-r["arm_flex"]), _ry(-s * r["arm_abd"]))
        local[:, idx(f"forearm.{side}")] = _rx(-r["elbow"])
        local[:, idx(f"hand.{side}")] = _rx(-r["wrist"])
        local[:, idx(f"thigh.{side}")] = quat.mul(_rx(-r["hip_flex"]), _ry(-s * r["hip_abd"]))
        local[:, idx(f"shin.{side}")] = _rx(r["knee"])
        local[:, idx(f"foot.{side}")] = _rx(r["ankle"])
        local[:, idx(f"toe.{side}")] = _rx(r["toe"])
    return root, local


def _solve_limb(
    skeleton: Skeleton, root: np.ndarray, local: np.ndarray, chain: tuple[str, str, str],
    target: np.ndarray, end_world: np.ndarray | None, pole: np.ndarray, rest_pole: np.ndarray,
) -> None:
    """Turn a limb's two bones (in place) so its end joint reaches `target` (T, 3).

    pole: (T, 3) world direction the middle joint points; rest_pole: the same in the rest pose.
    end_world: (T, 4) world rotation to give the end joint (a planted foot stays flat), or None
    to keep its local rotation.
    """
    upper, middle, end = (skeleton.index(n) for n in chain)
    parent = skeleton.parents[upper]
    pos, rot = forward_kinematics(skeleton, root, local, skeleton.offsets)
    upper_rot, lower_rot = two_bone_ik(pos[:, upper], target, skeleton.offsets[middle], skeleton.offsets[end],
                                       pole, rest_pole)
    local[:, upper] = quat.mul(quat.conj(rot[:, parent]), upper_rot)
    local[:, middle] = quat.mul(quat.conj(upper_rot), lower_rot)
    if end_world is not None:
        local[:, end] = quat.mul(quat.conj(lower_rot), end_world)


def _leg_ik(skeleton: Skeleton, root: np.ndarray, local: np.ndarray, side: str, ankle: np.ndarray,
            foot_world: np.ndarray) -> None:
    """Legs by IK, knees pointing where the pelvis faces (so they stay right when it pitches)."""
    pole = quat.rotate(local[:, 0], FORWARD)
    _solve_limb(skeleton, root, local, (f"thigh.{side}", f"shin.{side}", f"foot.{side}"), ankle, foot_world,
                pole, FORWARD)


def _arm_ik(skeleton: Skeleton, root: np.ndarray, local: np.ndarray, side: str, hand: np.ndarray,
            hand_world: np.ndarray) -> None:
    """Arms by IK, elbows pointing back and a little out from the chest (a push-up's elbows),
    turning outwards when the back faces the floor (lying face up) so they stay above it."""
    _, rot = forward_kinematics(skeleton, root, local, skeleton.offsets)
    chest = rot[:, skeleton.index("chest")]
    back, out = quat.rotate(chest, -FORWARD), quat.rotate(chest, SIDES[side] * X_AXIS)
    pole = back + (0.5 + 3.0 * np.maximum(-back[:, 2:], 0.0)) * out
    _solve_limb(skeleton, root, local, (f"upper_arm.{side}", f"forearm.{side}", f"hand.{side}"), hand, hand_world,
                pole, -FORWARD)


def _ease(s: np.ndarray) -> np.ndarray:
    """Minimum-jerk progress 0 -> 1 (zero speed and acceleration at both ends) for s in [0, 1]."""
    s = np.clip(s, 0.0, 1.0)
    return s * s * s * (10.0 - 15.0 * s + 6.0 * s * s)


def _stand_ankles(count: int) -> dict[str, np.ndarray]:
    """Ankle positions (T, 3) of the standing pose: under the hips, a little wider."""
    ankle_z = ANKLE_Z * HEIGHT
    return {side: np.tile([s * STAND_WIDTH / 2, 0.0, ankle_z], (count, 1)) for side, s in SIDES.items()}


def _motion(skeleton: Skeleton, root: np.ndarray, local: np.ndarray) -> Motion:
    return Motion(skeleton=skeleton, fps=float(FPS), root_pos=root, local_rot=quat.normalize(local))


# ---------------------------------------------------------------------------------------------
# Idle


def idle_clip(seconds: float = 6.0) -> Motion:
    """Standing at rest: a breath every 3 s, the weight shifting from foot to foot every 6 s.

    Every oscillation has a whole number of periods in the clip, so it loops. The feet stay
    where they are (legs by IK), so the weight shift bends the knees, not the floor.
    """
    skeleton = sample_skeleton()
    count = int(round(seconds * FPS))
    t = np.arange(count) / FPS
    breath = np.sin(2 * np.pi * t / 3.0)
    shift = np.sin(2 * np.pi * t / seconds)
    values = np.tile(_vector(STAND), (count, 1))
    changes = {
        "x": 0.018 * shift, "z": -0.004 * (1.0 - np.cos(4 * np.pi * t / seconds)), "pelvis_roll": -1.5 * shift,
        "spine_roll": 2.0 * shift, "spine_pitch": -1.2 * breath, "neck_pitch": 1.0 * breath + 1.5 * shift,
        "arm_flex_L": 1.5 * breath, "arm_flex_R": 1.5 * breath, "elbow_L": 2.0 * shift, "elbow_R": -2.0 * shift,
        "pelvis_yaw": 1.5 * np.sin(2 * np.pi * t / seconds + 1.0),
    }
    for name, delta in changes.items():
        values[:, PARAMS.index(name)] += delta
    root, local = _fk_pose(skeleton, values)
    for side, ankle in _stand_ankles(count).items():
        _leg_ik(skeleton, root, local, side, ankle, quat.identity((count,)))
    return _motion(skeleton, root, local)


# ---------------------------------------------------------------------------------------------
# Stepping reactions: a linear inverted pendulum decides where the feet land


GRAVITY = 9.81
COM_HEIGHT = 0.95  # the pendulum's height: the centre of mass of a 1.75 m adult standing, m
OMEGA = float(np.sqrt(GRAVITY / COM_HEIGHT))
SIM_STEPS = 10  # pendulum steps per frame (dt = 1/600 s)
# The sole as a rectangle around the ankle (x to the left, y along world Y: the toes are at -Y).
SOLE = np.array([[-0.045, -0.19], [0.045, -0.19], [0.045, 0.05], [-0.045, 0.05]])
FOOT_CENTRE = np.array([0.0, -0.07])  # the sole's middle, ankle-relative: where a step aims


@dataclass(frozen=True)
class Push:
    """One stepping reaction: the push and how the character may step to catch itself."""

    direction: float  # degrees from the facing direction, positive to the character's left
    speed: float  # centre-of-mass speed the push leaves, m/s
    max_step: float  # longest step, ankle to ankle over the ground, m
    first: str  # the foot that steps first, "L" or "R"
    react: float = 0.15  # time before the first foot lifts, s
    swing: float = 0.30  # time a foot is in the air, s
    pause: float = 0.06  # double support between steps, s


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
}


def _interval(points: np.ndarray, axis: np.ndarray) -> tuple[float, float]:
    """The extent of 2D points along a unit axis."""
    along = points @ axis
    return float(along.min()), float(along.max())


@dataclass
class StepPlan:
    """What the balance model decided, per frame: CoM over the ground (T, 2), each ankle (T, 3)
    and foot pitch (T,), how alarmed the body is (T,, 0..1), and the touch-down frames."""

    com: np.ndarray
    ankles: dict[str, np.ndarray]
    pitch: dict[str, np.ndarray]
    alarm: np.ndarray
    touchdowns: list[tuple[str, int]]


def balance_plan(push: Push) -> StepPlan:
    """Simulate the pushed body as a linear inverted pendulum along the push, stepping to its
    capture point.

    The centre of mass u (along the push) moves as u'' = w^2 (u - p), w = sqrt(g / z0). The centre
    of pressure p stays within the feet on the floor (their soles' extent along the push); there
    it follows a capture-point controller p = xi + k (xi - target), xi = u + u'/w, which brings the
    body to rest over the middle of its feet. When xi is outside the feet (the push is too strong
    to ride out on the ankles), a foot lifts, and it lands where xi will be when it lands (the
    capture point, predicted with p held at the stance foot's edge), or as far as `max_step`
    allows; when that falls short, the other foot steps next. Across the push the pendulum is
    planar; a landing foot keeps at least 14 cm sideways from the other, so the feet never cross.
    """
    dt = 1.0 / (FPS * SIM_STEPS)
    angle = np.radians(push.direction)
    axis = np.cos(angle) * FORWARD[:2] + np.sin(angle) * X_AXIS[:2]
    ankle_z = ANKLE_Z * HEIGHT
    base = {side: np.array([s * STAND_WIDTH / 2, 0.0]) for side, s in SIDES.items()}
    along = {side: 0.0 for side in SIDES}  # each foot's travel along the push
    shift = {side: 0.0 for side in SIDES}  # sideways correction that keeps the feet uncrossed

    def foot(side: str) -> np.ndarray:
        return base[side] + along[side] * axis + shift[side] * X_AXIS[:2]

    def sole(side: str) -> tuple[float, float]:
        return _interval(foot(side) + SOLE, axis)

    u, v = 0.0, push.speed
    planted = {"L": True, "R": True}
    swing: tuple[str, np.ndarray, np.ndarray, float] | None = None  # side, from, to, lift time
    next_lift, mover, touchdowns = push.react, push.first, []
    alarm_state = np.zeros(2)  # a critically damped follower of the alarm signal, and its rate
    com, ankles, pitch, alarm = [], {s: [] for s in SIDES}, {s: [] for s in SIDES}, []
    settled_at, t, frame = None, 0.0, 0
    while settled_at is None or frame < settled_at + int(0.6 * FPS):
        if frame > 6 * FPS or len(touchdowns) > 4:
            raise RuntimeError(f"the balance model does not recover from {push}")
        com.append(u * axis)
        alarm.append(alarm_state[0])
        for side in SIDES:
            if swing is not None and swing[0] == side:
                w = (t - swing[3]) / push.swing
                bump = 16 * w * w * (1 - w) * (1 - w)
                xy = swing[1] + (swing[2] - swing[1]) * _ease(np.array(w))
                clearance = 0.05 + 0.1 * float(np.linalg.norm(swing[2] - swing[1]))  # long steps lift higher
                ankles[side].append([xy[0], xy[1], ankle_z + clearance * bump])
                pitch[side].append(-np.radians(10.0) * bump)
            else:
                ankles[side].append([*foot(side), ankle_z])
                pitch[side].append(0.0)
        for _ in range(SIM_STEPS):
            xi = u + v / OMEGA
            support = [side for side in SIDES if planted[side]]
            lo = min(sole(side)[0] for side in support)
            hi = max(sole(side)[1] for side in support)
            target = float(np.mean([(foot(side) + FOOT_CENTRE) @ axis for side in support]))
            if swing is None and t >= next_lift and (xi < lo - 0.01 or xi > hi + 0.01):
                stance = "R" if mover == "L" else "L"
                edge = float(np.clip(xi, *sole(stance)))
                capture = edge + (xi - edge) * np.exp(OMEGA * push.swing)
                reach = capture - (base[mover] + FOOT_CENTRE) @ axis - along[stance]
                reach = float(np.clip(reach, -push.max_step, push.max_step))
                start = foot(mover)
                along[mover] = along[stance] + reach
                s = SIDES[mover]
                shift[mover] += s * max(0.0, 0.14 - s * (foot(mover)[0] - foot(stance)[0]))
                swing = (mover, start, foot(mover), t)
                planted[mover] = False
            if swing is not None and t >= swing[3] + push.swing - 1e-9:
                planted[swing[0]] = True
                touchdowns.append((swing[0], frame + 1))
                mover = "R" if swing[0] == "L" else "L"
                next_lift = t + push.pause
                swing = None
            p = float(np.clip(xi + 1.5 * (xi - target), lo, hi))
            v += OMEGA * OMEGA * (u - p) * dt
            u += v * dt
            raw = min(abs(v) / 0.8, 1.0)
            alarm_state += dt * np.array([alarm_state[1], 144.0 * (raw - alarm_state[0]) - 24.0 * alarm_state[1]])
            t += dt
        frame += 1
        if settled_at is None and touchdowns and swing is None and abs(v) < 0.003 and abs(xi - target) < 0.003:
            settled_at = frame
    return StepPlan(np.array(com), {s: np.array(a) for s, a in ankles.items()},
                    {s: np.array(a) for s, a in pitch.items()}, np.array(alarm), touchdowns)


# Key poses the upper body passes through when the push is strong (alarm = 1): the trunk bends
# into the fall's direction for a forward push and against it for a backward one (the hip
# strategy), arms fly up and out to balance. Blended from STAND by the alarm and the direction.
FLUNG_FORWARD = pose(pelvis_pitch=8.0, spine_pitch=14.0, neck_pitch=-14.0, arm_flex=50.0, arm_abd=30.0,
                     elbow=40.0, wrist=10.0)
FLUNG_BACK = pose(pelvis_pitch=12.0, spine_pitch=18.0, neck_pitch=-6.0, arm_flex=70.0, arm_abd=35.0,
                  elbow=30.0, wrist=-10.0)
# Per unit of push to the character's left: bend the trunk right, fling the left arm out.
FLUNG_LEFT = dict.fromkeys(PARAMS, 0.0) | {"spine_roll": -10.0, "pelvis_roll": 3.0, "arm_abd_L": 40.0,
                                             "arm_abd_R": -15.0, "arm_flex_L": 10.0}


def step_clip(push: Push, plan: StepPlan | None = None) -> Motion:
    """A stepping reaction: pendulum root path, legs by IK to the planned feet, upper body blended
    between key poses by the pendulum's alarm. Starts in the standing pose at the push, ends at rest.
    plan: the balance model's plan (default balance_plan(push); the sways pass a planted-feet one)."""
    skeleton = sample_skeleton()
    plan = balance_plan(push) if plan is None else plan
    count = len(plan.com)
    angle = np.radians(push.direction)
    ahead, side = np.cos(angle), np.sin(angle)
    stand = _vector(STAND)
    flung = (max(ahead, 0.0) * (_vector(FLUNG_FORWARD) - stand) + max(-ahead, 0.0) * (_vector(FLUNG_BACK) - stand)
             + side * _vector(FLUNG_LEFT))
    values = stand + plan.alarm[:, None] * flung
    values[:, PARAMS.index("x")] = plan.com[:, 0]
    values[:, PARAMS.index("fwd")] = -plan.com[:, 1]
    root, local = _fk_pose(skeleton, values)
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
    root[:, 2] += (sunk - root[:, 2]) * _ease(np.arange(count) / (push.react * FPS))
    for s in SIDES:
        _swing_leg(skeleton, root, local, s, plan.ankles[s].copy(), _rx(plan.pitch[s]))
    return _motion(skeleton, root, local)


def _swing_leg(skeleton: Skeleton, root: np.ndarray, local: np.ndarray, side: str, ankle: np.ndarray,
               foot_world: np.ndarray) -> None:
    """Leg IK for a stepping foot. A swinging foot is not held flat: its ankle turns at most 45 deg
    from neutral (a fast long step folds the leg without bending the ankle past its range), so
    its toes hang; where they would scuff the floor the ankle is carried higher (a few passes)."""
    count = len(ankle)
    foot, toe = skeleton.index(f"foot.{side}"), skeleton.index(f"toe.{side}")
    airborne = np.clip((ankle[:, 2] - ANKLE_Z * HEIGHT) / 0.025, 0.0, 1.0)
    for _ in range(4):
        _leg_ik(skeleton, root, local, side, ankle, foot_world)
        angle = quat.angle_between(quat.identity(), local[:, foot])
        keep = 1.0 - airborne * (1.0 - np.minimum(1.0, np.radians(45.0) / np.maximum(angle, 1e-9)))
        local[:, foot] = quat.slerp(quat.identity((count,)), local[:, foot], keep)
        pos, rot = forward_kinematics(skeleton, root, local, skeleton.offsets)
        tip = pos[:, toe] + quat.rotate(rot[:, toe], skeleton.end_sites[toe])
        scuff = np.maximum(TOE_TIP_Z * HEIGHT + 0.02 - tip[:, 2], 0.0) * airborne
        window = int(0.1 * FPS)
        scuff = np.max(np.lib.stride_tricks.sliding_window_view(np.pad(scuff, window), 2 * window + 1), axis=1)
        smooth = np.hanning(2 * window + 1)
        ankle[:, 2] += np.convolve(scuff, smooth / smooth.sum(), "same") * airborne


# ---------------------------------------------------------------------------------------------
# Get-ups: key poses, interpolated with minimum-jerk easing; hands and feet reach world targets
# by IK, so a hand or foot whose target does not change between two keys stays planted.


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
    return np.array([s * xyz[0], 0.0, xyz[2]]) + xyz[1] * FORWARD


HAND_DOWN = 0.03  # wrist height of a hand flat on the floor, m
ANKLE_UP = ANKLE_Z * HEIGHT
# Face down (head towards FORWARD): hands beside the hips, then under the shoulders, push the
# chest up, draw the knees under the hips (hands and knees), tuck the toes and push back into a
# deep squat, stand up.
PRONE_GETUP = [
    Key(0.0, pose(z=0.11, pelvis_pitch=88.0, spine_pitch=0.0, neck_pitch=-25.0),
        hands=(0.32, 0.28, HAND_DOWN, 15.0), feet=(0.12, -0.86, 0.075, 150.0)),
    Key(0.4, pose(z=0.11, pelvis_pitch=88.0, spine_pitch=0.0, neck_pitch=-30.0),
        hands=(0.32, 0.28, HAND_DOWN, 15.0), feet=(0.12, -0.86, 0.075, 150.0)),
    Key(1.2, pose(z=0.16, pelvis_pitch=72.0, spine_pitch=-22.0, neck_pitch=-20.0),
        hands=(0.32, 0.28, HAND_DOWN, 15.0), feet=(0.12, -0.84, 0.075, 150.0)),
    Key(2.1, pose(fwd=-0.16, z=0.52, pelvis_pitch=85.0, spine_pitch=0.0, neck_pitch=-25.0),
        hands=(0.32, 0.28, HAND_DOWN, 15.0), feet=(0.12, -0.62, 0.075, 150.0)),
    Key(2.8, pose(fwd=-0.22, z=0.55, pelvis_pitch=85.0, spine_pitch=5.0, neck_pitch=-15.0, toe=-55.0),
        hands=(0.32, 0.28, HAND_DOWN, 15.0), feet=(STAND_WIDTH / 2, -0.55, 0.17, 70.0)),
    Key(3.7, pose(fwd=-0.83, z=0.46, pelvis_pitch=45.0, spine_pitch=25.0, neck_pitch=-30.0, arm_flex=125.0,
                  elbow=20.0), feet=(STAND_WIDTH / 2, -0.68, ANKLE_UP, 0.0)),
    Key(4.6, pose(fwd=-0.68), feet=(STAND_WIDTH / 2, -0.68, ANKLE_UP, 0.0)),
    Key(5.1, pose(fwd=-0.68), feet=(STAND_WIDTH / 2, -0.68, ANKLE_UP, 0.0)),
]
# From sitting on the floor (knees bent, feet flat, hands behind): rock forward onto the feet
# into a squat with the arms reaching forward, stand up. The face-up get-up sits up into it.
SIT_KEYS = [
    Key(0.0, pose(z=0.11, pelvis_pitch=-15.0, spine_pitch=18.0, neck_pitch=5.0),
        hands=(0.22, -0.15, HAND_DOWN, 90.0), feet=(STAND_WIDTH / 2, 0.50, ANKLE_UP, 0.0)),
    Key(0.5, pose(z=0.11, pelvis_pitch=-5.0, spine_pitch=25.0, neck_pitch=5.0),
        hands=(0.22, -0.15, HAND_DOWN, 90.0), feet=(STAND_WIDTH / 2, 0.50, ANKLE_UP, 0.0)),
    Key(1.3, pose(fwd=0.35, z=0.45, pelvis_pitch=45.0, spine_pitch=25.0, neck_pitch=-30.0, arm_flex=125.0,
                  elbow=20.0), feet=(STAND_WIDTH / 2, 0.50, ANKLE_UP, 0.0)),
    Key(2.2, pose(fwd=0.50), feet=(STAND_WIDTH / 2, 0.50, ANKLE_UP, 0.0)),
    Key(2.7, pose(fwd=0.50), feet=(STAND_WIDTH / 2, 0.50, ANKLE_UP, 0.0)),
]
# Face up (head away from FORWARD): sit up onto the hands, draw the feet in, then as SIT_KEYS.
SUPINE_KEYS = [
    Key(0.0, pose(z=0.11, pelvis_pitch=-88.0, spine_pitch=0.0, neck_pitch=12.0),
        hands=(0.30, -0.05, HAND_DOWN, 0.0), feet=(0.12, 0.86, 0.09, -60.0)),
    Key(0.8, pose(z=0.11, pelvis_pitch=-35.0, spine_pitch=20.0, neck_pitch=10.0),
        hands=(0.22, -0.15, HAND_DOWN, 90.0), feet=(0.12, 0.84, 0.09, -60.0)),
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
    key_values = np.array([_vector(k.body) for k in keys])
    key_root, key_local = _fk_pose(skeleton, key_values)
    key_pos, key_rot = forward_kinematics(skeleton, key_root, key_local, skeleton.offsets)
    hands, feet, foot_rot, hand_rot = {}, {}, {}, {}
    for side, s in SIDES.items():
        hands[side] = np.array([key_pos[i, idx(f"hand.{side}")] if k.hands is None else _side_point(k.hands, s)
                                for i, k in enumerate(keys)])
        hand_rot[side] = np.array([key_rot[i, idx(f"hand.{side}")] if k.hands is None
                                   else quat.mul(_rz(s * np.radians(k.hands[3])), _rx(-np.pi / 2))
                                   for i, k in enumerate(keys)])
        feet[side] = np.array([key_pos[i, idx(f"foot.{side}")] if k.feet is None else _side_point(k.feet, s)
                               for i, k in enumerate(keys)])
        foot_rot[side] = np.array([key_rot[i, idx(f"foot.{side}")] if k.feet is None
                                   else _rx(np.radians(k.feet[3])) for i, k in enumerate(keys)])
    times = np.array([k.at for k in keys])
    count = int(round(times[-1] * FPS)) + 1
    t = np.arange(count) / FPS
    seg = np.clip(np.searchsorted(times, t, side="right") - 1, 0, len(keys) - 2)
    e = _ease((t - times[seg]) / (times[seg + 1] - times[seg]))

    def between(a: np.ndarray) -> np.ndarray:
        w = e.reshape(-1, *([1] * (a.ndim - 1)))
        return a[seg] + (a[seg + 1] - a[seg]) * w

    u = np.clip((t - times[seg]) / (times[seg + 1] - times[seg]), 0.0, 1.0)
    bump = 16.0 * u * u * (1.0 - u) * (1.0 - u)

    def carried(a: np.ndarray) -> np.ndarray:
        """A hand or foot moving to a new target lifts off on the way (half the distance, at
        most 15 cm, highest half way), so it neither drags over nor digs into the floor."""
        lift = np.minimum(0.5 * np.linalg.norm(a[seg + 1] - a[seg], axis=-1), 0.15)
        return between(a) + (lift * bump)[:, None] * UP

    root, local = _fk_pose(skeleton, between(key_values))
    # Arms without a target keep their own angles (IK to where they would be anyway would twist
    # them); between a planted and a free key the two solutions are blended.
    planted = between(np.array([0.0 if k.hands is None else 1.0 for k in keys]))
    for side in SIDES:
        rot = quat.slerp(foot_rot[side][seg], foot_rot[side][seg + 1], e)
        _leg_ik(skeleton, root, local, side, carried(feet[side]), rot)
        arm = [idx(f"{b}.{side}") for b in ("upper_arm", "forearm", "hand")]
        free = local[:, arm].copy()
        _arm_ik(skeleton, root, local, side, carried(hands[side]),
                quat.slerp(hand_rot[side][seg], hand_rot[side][seg + 1], e))
        local[:, arm] = quat.slerp(free, local[:, arm], planted[:, None])
    return _motion(skeleton, root, local)


LOCOMOTION = ("walk", "run", "idle")  # not reactions: kept out of the library


def clip_maker(build: Callable[[object], Motion], params: object, what: str) -> Callable[[], Motion]:
    """A CLIPS entry (a clip function without arguments) for one row of a parameter table."""

    def make() -> Motion:
        return build(params)

    make.__doc__ = what
    return make


# The physics-made reactions (falls by the ragdoll, sways by the pendulum) live in sample_falls.py
# next to this file; it imports this module by name, so register it under that name when run as a script.
sys.modules.setdefault("make_sample_clips", sys.modules[__name__])
if str(Path(__file__).resolve().parent) not in sys.path:
    sys.path.insert(0, str(Path(__file__).resolve().parent))
import sample_falls  # noqa: E402

CLIPS: dict[str, Callable[[], Motion]] = {
    "walk": walk_clip,
    "run": run_clip,
    "idle": idle_clip,
    **{name: clip_maker(step_clip, push, f"The stepping reaction {name}: {push}") for name, push in STEPS.items()},
    **sample_falls.CLIPS,
    **{name: clip_maker(keyed_clip, keys, f"The keyframed get-up {name}.") for name, keys in GETUPS.items()},
}
REACTIONS = [name for name in CLIPS if name not in LOCOMOTION and name not in GETUPS]


def reaction_class(name: str) -> str:
    """The class slug of a reaction clip: its name without the variant number."""
    return name.rsplit("_", 1)[0]


def library_toml() -> str:
    """The reaction library's clip list (read by reactive_anim's library module)."""
    lines = [
        "# The reaction library over the clips in this folder, written by tools/make_sample_clips.py.",
        "# One [[clip]] per reaction clip: file, class (a DESIGN.md slug), optional frames = [start, end]",
        "# and optional next = the clip that follows it (a get-up after a fall).",
        "# [[chain]] tables list clips reached only through `next` (the get-ups); they are no class.",
        "",
    ]
    for name in REACTIONS:
        lines += ["[[clip]]", f'file = "{name}.bvh"', f'class = "{reaction_class(name)}"']
        if name in sample_falls.NEXT:
            lines.append(f'next = "{sample_falls.NEXT[name]}"')
        lines.append("")
    for name in GETUPS:
        lines += ["[[chain]]", f'file = "{name}.bvh"', ""]
    return "\n".join(lines)


# ---------------------------------------------------------------------------------------------
# Contact sheets: a stick figure per sampled frame, side and front view, as a PNG (no plotting
# library needed: numpy draws, zlib packs).

SHEET_CELL = (150, 200)  # width, height in pixels of one view
SHEET_SCALE = 95.0  # pixels per metre


def _png(image: np.ndarray) -> bytes:
    """An RGB uint8 image (H, W, 3) as PNG bytes."""
    import struct
    import zlib

    def chunk(kind: bytes, data: bytes) -> bytes:
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body) & 0xFFFFFFFF)

    h, w, _ = image.shape
    raw = b"".join(b"\x00" + image[row].tobytes() for row in range(h))
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b""))


def _draw_line(image: np.ndarray, a: np.ndarray, b: np.ndarray, colour: tuple[int, int, int]) -> None:
    n = int(np.max(np.abs(b - a))) * 2 + 2
    pts = np.round(a + (b - a) * np.linspace(0, 1, n)[:, None]).astype(int)
    for dx in (0, 1):
        for dy in (0, 1):
            x, y = pts[:, 0] + dx, pts[:, 1] + dy
            ok = (x >= 0) & (x < image.shape[1]) & (y >= 0) & (y < image.shape[0])
            image[y[ok], x[ok]] = colour


def contact_sheet(motions: dict[str, Motion], columns: int = 8) -> np.ndarray:
    """Rows of clips, `columns` evenly spaced frames each; per frame a side view (facing right)
    and a front view. Left limbs blue, right red, trunk black, floor grey."""
    cw, ch = SHEET_CELL
    image = np.full((ch * len(motions), 2 * cw * columns, 3), 255, dtype=np.uint8)
    for row, motion in enumerate(motions.values()):
        sk = motion.skeleton
        pos, rot = motion.global_transforms()
        tips = {j: pos[:, j] + quat.rotate(rot[:, j], off) for j, off in sk.end_sites.items()}
        for col, frame in enumerate(np.linspace(0, motion.num_frames - 1, columns).round().astype(int)):
            for view in range(2):
                ox, oy = (2 * col + view) * cw, row * ch
                floor_y = oy + ch - 12
                image[floor_y, ox + 4:ox + cw - 4] = (170, 170, 170)
                image[oy:oy + ch, ox + cw - 1] = (220, 220, 220) if view == 0 else (120, 120, 120)
                centre = pos[frame, 0]

                def px(p: np.ndarray) -> np.ndarray:
                    h = -(p[1] - centre[1]) if view == 0 else (p[0] - centre[0])
                    return np.array([ox + cw / 2 + SHEET_SCALE * h, floor_y - SHEET_SCALE * p[2]])

                for j in range(1, sk.num_joints):
                    name = sk.names[j]
                    colour = {".L": (40, 90, 220), ".R": (220, 50, 40)}.get(name[-2:], (0, 0, 0))
                    _draw_line(image, px(pos[frame, sk.parents[j]]), px(pos[frame, j]), colour)
                    if j in tips:
                        _draw_line(image, px(pos[frame, j]), px(tips[j][frame]), colour)
    return image


def write_contact_sheets(out_dir: Path) -> list[Path]:
    """One PNG per reaction class, one for the get-ups and one for locomotion, into out_dir."""
    out_dir.mkdir(parents=True, exist_ok=True)
    groups: dict[str, list[str]] = {"locomotion": list(LOCOMOTION), "getups": list(GETUPS)}
    for name in REACTIONS:
        groups.setdefault(reaction_class(name), []).append(name)
    written = []
    for group, names in groups.items():
        path = out_dir / f"{group}.png"
        path.write_bytes(_png(contact_sheet({n: CLIPS[n]() for n in names})))
        written.append(path)
    return written


def write_clips(out_dir: Path) -> list[Path]:
    """Write every clip in CLIPS as <name>.bvh (centimetres to 4 decimals, i.e. 1 um, Y up, ZXY: the
    common dialect; 4 rather than 6 decimals keep the folder a fifth smaller) and
    the reaction library's library.toml."""
    out_dir.mkdir(parents=True, exist_ok=True)
    written = []
    for name, make in CLIPS.items():
        path = out_dir / f"{name}.bvh"
        bvh.write_bvh(path, make(), rotation_order="ZXY", unit="cm", up="Y", decimals=4)
        written.append(path)
    library = out_dir / "library.toml"
    library.write_text(library_toml(), encoding="utf-8", newline="\n")
    written.append(library)
    return written


def main(argv: list[str] | None = None) -> int:
    """Write the clips and say what was written, read back through the BVH reader as a check."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--out", type=Path, default=REPO / "sample_clips", help="output folder (default: sample_clips/)"
    )
    parser.add_argument("--sheets", type=Path, help="also draw contact sheet PNGs into this folder (e.g. out/)")
    args = parser.parse_args(argv)
    if args.sheets:
        for path in write_contact_sheets(args.sheets):
            print(f"drew {path}")
    for path in write_clips(args.out):
        if path.suffix != ".bvh":
            print(f"wrote {path}")
            continue
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
