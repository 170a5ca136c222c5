"""Falls, made by physics: the ragdoll pushed, then PD servos toward protective key poses.

The ragdoll (reactive_anim.core.physics.ragdoll, anatomical profile, built on the sample skeleton with the
idle stand as its reference) starts from a frame of the idle stand or of the walk; walk starts use
frames where both feet's toes are flat (24, 56, 88, ...: the ragdoll has no toe joint, so toes bent
at the push stay bent through the fall, and from frame 40 a toe tip went 1.7-4 cm into the floor);
the push lands there (simulate_impact: an impulse at a body's centre of mass, then 0.25 s of
forward dynamics with weak servos toward the motion continuing, a human reaction time); from then
on PD servos (simulate.track) drive the joints toward a keyframed *target* of protective key poses
(arms out to catch, knees bending, a tuck) while gravity and the floor contacts decide where the
body goes. The root is never actuated: nothing holds the character up. A fall ends at rest on the
floor, and its `next` is the get-up that fits how it lies.

What the simulation output needs before it is written, and why:
- Knee and elbow are hinges in the sample skeleton and single hinges in the anatomical ragdoll;
  the ragdoll's hinge axis comes from the neutral pose, a fraction of a degree off the skeleton's
  X axis, so the rotation is projected onto X (the clip tests allow 1 degree off the hinge).
- The simulation shares the trunk's bend over spine.001 and chest and the neck's over neck and
  head (simulate.py). It takes the toes from the servo target, which switches at C from the walk
  to the keyed poses: the toes are written flat. The simulation's floor (contacts.py puts it where
  the start frame's soles are, a few mm off z = 0) is moved to z = 0.
- Every other joint angle is written as the simulation gave it.

MuJoCo gives the same bits for the same input on one machine (fixed step counts), but not
necessarily on another CPU or MuJoCo build: the falls are chaotic, so their later frames may differ
there (tests/core/test_sample_clips.py compares them with tolerances).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from reactive_anim.core.model import quat
from reactive_anim.core.model.impact import Impact
from reactive_anim.core.model.skeleton import Motion
from reactive_anim.core.physics.anatomy import ANATOMICAL_LIMITS, HingeRange
from reactive_anim.core.physics.ragdoll import Ragdoll, build_ragdoll
from reactive_anim.core.physics.simulate import simulate_impact, track
from reactive_anim.core.physics.workspace import ServoGains, Workspace
from reactive_anim.core.transition.soften import soften

from .curves import key_timeline
from .gaits import walk_clip
from .idle import idle_clip
from .poses import pose, pose_vector, posed
from .skeleton import FPS, SIDES, UP, X_AXIS, clip_motion, heading, sample_skeleton


@lru_cache(maxsize=1)
def _start_motions() -> dict[str, Motion]:
    return {"idle": idle_clip(), "walk": walk_clip()}


@lru_cache(maxsize=1)
def sample_ragdoll() -> Ragdoll:
    """The ragdoll of the sample skeleton, neutral pose from the idle stand.

    The clip tests allow no hyperextension; knee and elbow limits are soft (a degree or two past 0
    under load), so on this tool's ragdoll they start a degree into flexion."""
    limits: dict[str, tuple[HingeRange, HingeRange, HingeRange]] = dict(ANATOMICAL_LIMITS)
    for part in ("knee", "elbow"):
        flexion, twist, abduction = limits[part]
        assert flexion is not None  # knees and elbows are hinges that flex
        limits[part] = ((max(flexion[0], 1.0), flexion[1]), twist, abduction)
    return build_ragdoll(sample_skeleton(), profile=limits, reference=_start_motions()["idle"])


@dataclass(frozen=True)
class Fall:
    """One physics fall: where it starts, the push, and the key poses the servos aim at.

    start: "idle" or "walk", from its frame `frame`. direction: degrees from the facing, positive
    to the character's left. keys: (time s after the servos take over, pose) pairs; the target
    eases between them (minimum jerk) and holds the last. duration: seconds of tracking.
    """

    start: str
    frame: int
    bone: str
    direction: float
    strength: float
    keys: tuple[tuple[float, dict[str, float]], ...]
    next: str
    duration: float = 3.0
    stiffness: float = 100.0
    damping_time: float = 0.03
    lift: float = 0.0  # upward share of the push direction


def servo_target(keys: tuple[tuple[float, dict[str, float]], ...], duration: float) -> Motion:
    """The keyed target as a Motion: pose parameters eased between the keys (minimum jerk), the last
    held (root is irrelevant: the servos follow joint angles only)."""
    skeleton = sample_skeleton()
    times = np.array([k[0] for k in keys])
    values = np.array([pose_vector(k[1]) for k in keys])
    count = round(duration * FPS) + 4
    t = np.arange(count) / FPS
    rows = np.tile(values[0], (count, 1)) if len(keys) == 1 else key_timeline(times, t).between(values)
    root, local = posed(skeleton, rows)
    return clip_motion(skeleton, root, local)


def _project_hinge(q: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """The rotation about `axis` closest to q (its twist part about the axis)."""
    along = q[..., 1:] @ axis
    twist = np.concatenate([q[..., :1], along[..., None] * axis], axis=-1)
    return quat.normalize(twist)


def _clean(motion: Motion, floor: float) -> Motion:
    """The simulation's output made fit for the sample skeleton (see the module docstring)."""
    sk = motion.skeleton
    local = quat.normalize(motion.local_rot.copy())
    for side in SIDES:  # the toes follow the servo target, the walk's in BC, the keys' after: flat here
        local[:, sk.index(f"toe.{side}")] = quat.identity((len(local),))
    for side in SIDES:
        local[:, sk.index(f"shin.{side}")] = _project_hinge(local[:, sk.index(f"shin.{side}")], X_AXIS)
        local[:, sk.index(f"forearm.{side}")] = _project_hinge(local[:, sk.index(f"forearm.{side}")], X_AXIS)
    root = motion.root_pos - np.array([0.0, 0.0, floor])  # the simulated floor is z = 0 in the clip
    return Motion(skeleton=sk, fps=float(FPS), root_pos=root, local_rot=local)


def push_direction(fall: Fall) -> tuple[float, float, float]:
    """The fall's push direction in the world: its heading, plus `lift` of up."""
    x, y, z = (float(v) for v in heading(fall.direction) + fall.lift * UP)
    return x, y, z


@dataclass
class FallRun:
    """A simulated fall: the cleaned motion (clip frame 0 = the push), the ragdoll's centre of
    mass per frame (floor at z = 0), and per ragdoll body the time (s after the push) of its first
    floor contact, as the simulation reports it."""

    motion: Motion
    com: np.ndarray
    first_contact: dict[str, float]


def simulate_fall(fall: Fall) -> FallRun:
    """Push, BC window, then PD tracking of the fall's keyed target; BC and CD joined at C (one
    simulation workspace for both)."""
    ragdoll = sample_ragdoll()
    workspace = Workspace(ragdoll)
    source = _start_motions()[fall.start]
    impact = Impact(frame=fall.frame, bone=fall.bone, direction=push_direction(fall), strength=fall.strength)
    bc = simulate_impact(ragdoll, source, impact, workspace=workspace)
    target = servo_target(fall.keys, fall.duration)
    cd = track(
        ragdoll,
        bc.state,
        target,
        fall.duration,
        gains=ServoGains(stiffness=fall.stiffness, damping_time=fall.damping_time),
        workspace=workspace,
    )
    root = np.concatenate([bc.motion.root_pos, cd.motion.root_pos[1:]])
    local = np.concatenate([bc.motion.local_rot, cd.motion.local_rot[1:]])
    motion = _clean(Motion(skeleton=bc.motion.skeleton, fps=float(FPS), root_pos=root, local_rot=local), bc.state.floor)
    com = np.concatenate([bc.com, cd.com[1:]]) - np.array([0.0, 0.0, bc.state.floor])
    bc_seconds = (bc.frames[-1] - bc.frames[0]) / FPS
    first = {name: bc_seconds + t for name, t in cd.first_contact.items()} | bc.first_contact
    return FallRun(motion, com, first)


SETTLED_SPEED = 0.01  # m/s: a body whose joints all move slower than this has settled
SETTLED_TURN = 0.05  # rad/s, likewise for every joint's rotation
SETTLED_TAIL = 0.3  # s kept after the body has settled


def _trim_settled(motion: Motion) -> Motion:
    """Cut the still tail: keep SETTLED_TAIL seconds after the last frame at which any joint still
    moves faster than SETTLED_SPEED (or turns faster than SETTLED_TURN), so the folder stays small.
    Lying bodies creep by a millimetre or two per second on the simulated floor for a while."""
    pos = motion.global_positions()
    speed = np.linalg.norm(np.diff(pos, axis=0), axis=-1).max(axis=1) * motion.fps
    turn = quat.angle_between(motion.local_rot[1:], motion.local_rot[:-1]).max(axis=1) * motion.fps
    moving = (speed > SETTLED_SPEED) | (turn > SETTLED_TURN)
    last = int(np.flatnonzero(moving)[-1]) + 1 if moving.any() else 0
    end = min(motion.num_frames, last + 1 + round(SETTLED_TAIL * FPS))
    return Motion(
        skeleton=motion.skeleton, fps=motion.fps, root_pos=motion.root_pos[:end], local_rot=motion.local_rot[:end]
    )


# m/s^2: a fall's clip is softened where a joint's acceleration passes the first, fully from the
# second (core/transition/soften.py): the physics that makes it stops a limb within a 2 ms step, and
# the clip, cast onto a taller character, accelerates in proportion to its size. Real falls (CMU)
# reach 166 at most; the rolls' heads struck the floor at 135-153 on the sample skeleton, 172 cast.
FALL_SPIKE = (100.0, 130.0)


def fall_clip(fall: Fall) -> Motion:
    """The clip of a fall: its simulation softened where it spikes (the push's own frame kept), the
    still tail cut."""
    return _trim_settled(soften(simulate_fall(fall).motion, 1, FALL_SPIKE))


# ---------------------------------------------------------------------------------------------
# The falls: key poses per class, variants as rows


# The pose every face-down fall ends in: lying on the front, hands beside the chest, head up.
LYING_FACE_DOWN = pose(arm_flex=40.0, arm_abd=45.0, elbow=100.0, hip_flex=0.0, knee=10.0, neck_pitch=-25.0, ankle=40.0)

# Key-pose tables: one (time, pose) row per line.
# fmt: off


def _catch_forward(start: str, frame: int, direction: float, strength: float) -> Fall:
    """Arms thrown forward with the wrists bent back to catch, knees giving a little; the elbows
    yield once the hands are down and the body ends lying face down, head up."""
    return Fall(start=start, frame=frame, bone="chest", direction=direction, strength=strength, keys=(
        (0.0, pose(arm_flex=50.0, elbow=20.0, knee=10.0, hip_flex=5.0)),
        (0.25, pose(arm_flex=95.0, arm_abd=15.0, elbow=15.0, wrist=-30.0, hip_flex=20.0, knee=25.0, spine_pitch=10.0,
                    neck_pitch=-30.0)),
        (0.9, pose(arm_flex=95.0, arm_abd=25.0, elbow=70.0, wrist=-30.0, hip_flex=5.0, knee=15.0, neck_pitch=-35.0)),
        (1.6, pose(LYING_FACE_DOWN, wrist=-30.0)),
    ), next="getup_face_down.bvh")


def _catch_backward(start: str, frame: int, direction: float, strength: float) -> Fall:
    """Arms reaching back and down with the wrists bent back, knees and hips bending to lower the
    body; the hands land first and the body ends sitting, propped on them."""
    return Fall(start=start, frame=frame, bone="chest", direction=direction, strength=strength, keys=(
        (0.0, pose(arm_flex=-40.0, arm_abd=25.0, elbow=10.0, wrist=-50.0, hip_flex=40.0, knee=60.0, spine_pitch=25.0)),
        (0.4, pose(arm_flex=-60.0, arm_abd=25.0, elbow=10.0, wrist=-60.0, hip_flex=60.0, knee=80.0, spine_pitch=25.0,
                   neck_pitch=15.0)),
        (1.5, pose(arm_flex=-50.0, arm_abd=25.0, elbow=15.0, wrist=-60.0, hip_flex=70.0, knee=70.0, spine_pitch=15.0)),
    ), next="getup_sitting.bvh")


def _roll(start: str, frame: int, direction: float, strength: float) -> Fall:
    """A hard shove low on the back: chin to chest, arms forward, hips and knees pulled into a tuck
    so the body rolls over its rounded back; after a second the tuck opens and the body lies face up."""
    tuck = pose(arm_flex=90.0, elbow=60.0, knee=130.0, hip_flex=110.0, spine_pitch=70.0, neck_pitch=60.0)
    return Fall(start=start, frame=frame, bone="spine", direction=direction, strength=strength, keys=(
        (0.0, pose(arm_flex=80.0, elbow=30.0, knee=30.0, hip_flex=30.0, spine_pitch=30.0, neck_pitch=30.0)),
        (0.3, tuck),
        (1.0, tuck),
        (1.6, pose(arm_flex=5.0, arm_abd=35.0, elbow=20.0, knee=20.0, hip_flex=20.0, spine_pitch=5.0, neck_pitch=10.0,
                   ankle=30.0)),
    ), next="getup_face_up.bvh", duration=4.5)


def _sit(direction: float, strength: float, hip: float, knee: float, trunk: float, arms: float) -> Fall:
    """A light push back: a squat over half a second (hips `hip`, knees `knee` degrees) with the
    trunk (`trunk`) and arms (`arms`) forward, so the pelvis drops onto the floor close behind the
    heels; then the legs slide out straight into a long sit, arms forward."""
    return Fall(start="idle", frame=0, bone="chest", direction=direction, strength=strength, keys=(
        (0.0, pose(hip_flex=20.0, knee=30.0, spine_pitch=15.0, arm_flex=40.0, elbow=20.0)),
        (0.5, pose(hip_flex=hip, knee=knee, ankle=-20.0, spine_pitch=trunk, neck_pitch=25.0, arm_flex=arms,
                   elbow=15.0)),
        (1.1, pose(hip_flex=95.0, knee=20.0, ankle=10.0, spine_pitch=45.0, neck_pitch=20.0, arm_flex=70.0, elbow=20.0)),
        (1.7, pose(hip_flex=90.0, knee=20.0, ankle=20.0, spine_pitch=35.0, neck_pitch=10.0, arm_flex=40.0, arm_abd=10.0,
                   elbow=30.0)),
    ), next="getup_sitting.bvh", duration=3.5)


def _side_knees(direction: float, strength: float, knee: float) -> Fall:
    """A push at the hips from the side: the knees give (knees `knee` degrees over ankles bent up
    50, hips straight) so they travel forward and down; on the knees, shins on the floor, the body is
    carried over sideways by the push onto the hip and the hand thrown out to that side, the knees
    still bent, and ends lying face down. (Keyed to sit back over the heels, knees 130 degrees,
    before lying down, the body knelt up instead as the legs straightened and swung the feet 1.2 m
    into the air.)"""
    return Fall(start="idle", frame=0, bone="pelvis", direction=direction, strength=strength, keys=(
        (0.0, pose(hip_flex=0.0, knee=20.0, ankle=-15.0, arm_abd=20.0, elbow=20.0)),
        (0.4, pose(hip_flex=0.0, knee=knee, ankle=-50.0, spine_pitch=0.0, arm_abd=20.0, arm_flex=30.0, elbow=70.0)),
        (0.75, pose(hip_flex=-15.0, knee=100.0, ankle=35.0, spine_pitch=-15.0, arm_abd=30.0, arm_flex=30.0,
                    elbow=70.0)),
        (1.3, pose(hip_flex=20.0, knee=95.0, ankle=35.0, spine_roll=-30.0, arm_abd=60.0, arm_flex=30.0, elbow=30.0)),
        (2.2, pose(LYING_FACE_DOWN, wrist=0.0, knee=60.0, hip_flex=10.0)),
        (3.0, pose(LYING_FACE_DOWN, wrist=0.0)),
    ), next="getup_face_down.bvh", duration=8.5)


FALLS: dict[str, Fall] = {
    "fall_forward_roll_1": _roll("idle", 0, 0.0, 170.0),
    "fall_forward_roll_2": _roll("idle", 0, 15.0, 190.0),
    "fall_forward_roll_3": _roll("walk", 56, 0.0, 120.0),
    "fall_forward_hands_1": _catch_forward("idle", 0, 0.0, 80.0),
    "fall_forward_hands_2": _catch_forward("idle", 0, 20.0, 90.0),
    "fall_forward_hands_3": _catch_forward("walk", 88, 0.0, 100.0),
    "fall_backward_hands_1": _catch_backward("idle", 0, 180.0, 80.0),
    "fall_backward_hands_2": _catch_backward("idle", 0, 160.0, 70.0),
    "fall_backward_hands_3": _catch_backward("idle", 0, -150.0, 85.0),
    "fall_backward_sit_1": _sit(180.0, 10.0, 100.0, 125.0, 50.0, 90.0),
    "fall_backward_sit_2": _sit(160.0, 10.0, 80.0, 110.0, 50.0, 90.0),
    "fall_backward_sit_3": _sit(-160.0, 10.0, 110.0, 135.0, 60.0, 110.0),
    "fall_side_knees_1": _side_knees(90.0, 40.0, 45.0),
    "fall_side_knees_2": _side_knees(80.0, 45.0, 40.0),
    "fall_side_knees_3": _side_knees(80.0, 45.0, 35.0),
}
# fmt: on
NEXT: dict[str, str] = {name: fall.next for name, fall in FALLS.items()}
