"""Gaits: the looping walk and run, made by one procedural gait on the sample skeleton.

A walk or run is a `Gait`, a row of parameters. Feet are planned in world space (`foot_track`:
stance rolls over the heel, lies flat, pushes off over the ball and the toe tip; swing joins toe
off to the next heel strike with cubic curves); the legs reach the planned ankles by analytic
two-bone IK, so planted feet never slide; pelvis, spine, neck and arms follow periodic curves of
the cycle. Whole cycles only, so the clips loop.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from reactive_anim.core.model import quat
from reactive_anim.core.model.skeleton import Motion, Skeleton, forward_kinematics

from .curves import hermite, hermite_via, wave
from .ik import two_bone_ik
from .skeleton import (
    FORWARD,
    FPS,
    HEEL_BACK,
    HEIGHT,
    SIDES,
    X_AXIS,
    about_x,
    about_y,
    about_z,
    clip_motion,
    sample_skeleton,
)


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
    turned = quat.rotate(about_x(angle), arm)
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
        flat = (
            np.array([s * gait.step_width / 2, 0.0, ankle_z])
            + (stride * (c + offset + gait.foot_under_pelvis))[:, None] * FORWARD
        )
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
    ankle[part] = hermite(lift_off.ankle, lift_off.velocity * duration, landing.ankle, landing.velocity * duration, sw)
    ankle[part, 2] = hermite_via(
        lift_off.ankle[:, 2],
        lift_off.velocity[:, 2] * duration,
        ankle_z + gait.swing_clearance,
        landing.ankle[:, 2],
        landing.velocity[:, 2] * duration,
        sw,
        gait.lowest_at,
    )
    pitch[part] = hermite_via(
        lift_off.pitch,
        lift_off.pitch_rate * duration,
        np.radians(gait.level_pitch),
        landing.pitch,
        landing.pitch_rate * duration,
        sw,
        gait.level_at,
    )
    relax = np.minimum(sw / gait.toe_relax, 1.0)
    rest = np.zeros(len(c))
    toe[part] = hermite(lift_off.toe, lift_off.toe_rate * duration * gait.toe_relax, rest, rest, relax)
    return FootTrack(ankle, pitch, toe)


def _pelvis(gait: Gait, skeleton: Skeleton, frames: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Root position (T, 3) and rotation (T, 4): forward travel with bob, sway, surge and the
    pelvis's yaw, list and tilt, each periodic in the cycle."""
    phase = frames / gait.cycle_frames
    t = frames / FPS
    stance_l = wave(phase, 0.25)  # +1 in the middle of the left stance
    double = wave(2.0 * phase, 2.0 * gait.bob_low_at)  # +1 in each double support
    height = skeleton.offsets[0, 2] - gait.pelvis_drop - gait.bob * double
    travel = gait.speed * t + gait.surge * np.sin(4.0 * np.pi * (phase - gait.bob_low_at))  # fastest in double support
    pos = (travel[:, None] * FORWARD) + np.stack([gait.sway * stance_l, np.zeros_like(t), height], axis=-1)
    yaw = np.radians(gait.pelvis_yaw) * wave(phase, 0.0)  # left hip forward at the left heel strike
    lst = np.radians(gait.pelvis_list) * wave(phase, 0.2)  # right (swing) side lower in left stance
    tilt = np.radians(gait.pelvis_tilt + gait.pelvis_tilt_swing * double)
    rot = quat.mul(quat.mul(about_z(-yaw), about_y(-lst)), about_x(tilt))
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
    joints, _ = forward_kinematics(skeleton, root_pos, local, skeleton.offsets)  # where the hips ride

    for side in SIDES:
        track = foot_track(gait, skeleton, side, frames)
        thigh, shin, foot, toe = (idx(f"{b}.{side}") for b in ("thigh", "shin", "foot", "toe"))
        upper, lower = two_bone_ik(
            joints[:, thigh], track.ankle, skeleton.offsets[shin], skeleton.offsets[foot], FORWARD
        )
        foot_rot = about_x(track.pitch)
        local[:, thigh] = quat.mul(quat.conj(pelvis_rot), upper)
        local[:, shin] = quat.mul(quat.conj(upper), lower)
        local[:, foot] = quat.mul(quat.conj(lower), foot_rot)
        local[:, toe] = about_x(track.toe)

    # Spine: counter-rotate the chest against the pelvis, undo the list, lean a little forward.
    spine = [idx("spine"), idx("spine.001"), idx("chest")]
    yaw = np.radians(gait.chest_yaw + gait.pelvis_yaw) * wave(phase, 0.0) / len(spine)
    lst = np.radians(gait.pelvis_list * gait.list_compensation) * wave(phase, 0.2) / len(spine)
    lean = np.radians(gait.trunk_lean - gait.pelvis_tilt) / len(spine)
    for j in spine:
        local[:, j] = quat.mul(quat.mul(about_z(yaw), about_y(lst)), about_x(np.full(count, lean)))
    # Neck and head: keep the gaze level and forward, the neck taking half of the correction.
    chest_rot = forward_kinematics(skeleton, root_pos, local, skeleton.offsets)[1][:, idx("chest")]
    local[:, idx("neck")] = quat.slerp(quat.identity((count,)), quat.conj(chest_rot), 0.5)
    local[:, idx("head")] = quat.conj(quat.mul(chest_rot, local[:, idx("neck")]))

    # Arms swing opposite to the legs: the left arm is forward when the right leg is.
    for side, s in SIDES.items():
        forward_at = gait.arm_lag + (0.5 if side == "L" else 0.0)
        swing = wave(phase, forward_at)
        flex = np.radians(gait.arm_mean + gait.arm_swing * swing)
        local[:, idx(f"shoulder.{side}")] = about_z(-s * np.radians(gait.clavicle_swing) * swing)
        abduction = about_y(np.full(count, -s * np.radians(gait.arm_abduction)))
        local[:, idx(f"upper_arm.{side}")] = quat.mul(about_x(-flex), abduction)
        elbow = np.radians(gait.elbow_mean + gait.elbow_swing * wave(phase, forward_at + 0.03))
        local[:, idx(f"forearm.{side}")] = about_x(-elbow)
        local[:, idx(f"hand.{side}")] = about_x(-np.radians(gait.wrist_swing) * wave(phase, forward_at + 0.08))

    return clip_motion(skeleton, root_pos, local)


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
