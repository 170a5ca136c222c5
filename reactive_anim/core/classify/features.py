"""The classifier's inputs at time C (paper section 2.3).

The paper feeds its network 9 values at C: the head, chest and pelvis displacement from B to C
along the spine frame's X and Y (6 values) and the centre of mass's 3D displacement (3 values).

THE SPINE FRAME is the trunk's frame at B (the moment the impact lands), with the spine's long axis
taken as world up:
    Z = world up (0, 0, 1);
    Y = the character's left: the horizontal part of (left hip - right hip) + (left shoulder - right
        shoulder), normalised (hip and shoulder lines counter-rotate while walking; their sum is the
        trunk's mean facing);
    X = Y x Z, the character's forward.
Its origin does not matter: only displacements and velocities are expressed in it. Built from the
body alone, it turns with the character, so the features do not depend on which way the character
faces (yaw) or where it stands (ground translation).

B is the first sampled frame of the simulation (simulate_impact samples from ceil(B), at most one
frame after the impact), C its last. The centre of mass is the ragdoll's (Table 1's masses), of the
simulated body and, through the same ragdoll, of the mocap poses.

What differs from the paper, with the reason:
- Lengths are in leg lengths (hip to knee to ankle joint) and speeds in sqrt(g * leg length), i.e.
  dimensionless (Alexander's dynamic similarity): the model is trained on one skeleton and must
  serve characters of any size. The paper's per-feature [0, 1] scaling is the model's input
  normalisation (in the model's metadata), not part of the features.
- EXTENDED adds 18 inputs. The paper trained on one walk, where displacements suffice; ours
  serves standing, walking and running characters, and a walker's 0.3 m of travel in 0.25 s looks
  like a standing character's hard shove unless the model sees the motion it departs from:
    dev_*      the centre of mass at C minus the motion's own at C (what the push did), 3 values;
    dev_v*     the same for its velocity, 3; com_v* its velocity at C, 3;
    xcom_*     the departure of the extrapolated centre of mass (capture.py) from the motion's, 2;
    reach      how far the centre of pressure can still move that way inside the base of support;
    excess     the departure's length beyond that reach;
    speed_along  the centre of mass's speed along the departure;
    height     the centre of mass above the floor at C;
    xcom_cos, xcom_sin  the departure's direction from the facing: cosine and |sine| of its angle;
    down       1 where a body other than the feet touches the floor at C, else 0.
  The last seven are the balance state the outcome rule (outcome.py) reads. A model given the
  departure and the reach but not the excess and the speed along it scored lower on simulated
  pushes (docs/measurements.md): the rule's thresholds lie on those two, and a net
  learns a threshold on one input from far fewer samples than on a norm it must compute. The
  direction's cosine and |sine| are there for the same reason: the rule's forward / side / backward
  sectors (45 degrees either side of the facing axis) are thresholds on them, where on xcom_dx and
  xcom_dy they are the lines |y| = x and |y| = -x. `down` is the rule's one fall criterion that no
  other input shows: a knee or hand on the floor at C with the centre of mass still high.
  For a simulated push the motion is the same BC run without the push (simulate_push; the
  outcome rule's module docstring says why not the mocap); a real reaction capture has no
  unpushed version, so there it is the body at B carried on at its velocity at B.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..model.arrays import AnyFloatArray, FloatArray
from ..model.errors import SkeletonError
from ..model.rig import Rig
from ..model.roles import SIDES
from ..model.skeleton import Motion, forward_kinematics
from ..physics.joints import mocap_qpos
from ..physics.ragdoll import Ragdoll
from ..physics.simulate import SimResult
from . import capture
from .capture import SoleGeometry, Support

UP = np.array([0.0, 0.0, 1.0])
PAPER_FEATURES: tuple[str, ...] = (
    "head_dx",
    "head_dy",
    "chest_dx",
    "chest_dy",
    "pelvis_dx",
    "pelvis_dy",
    "com_dx",
    "com_dy",
    "com_dz",
)
EXTENDED_FEATURES: tuple[str, ...] = PAPER_FEATURES + (
    "dev_x",
    "dev_y",
    "dev_z",
    "dev_vx",
    "dev_vy",
    "dev_vz",
    "com_vx",
    "com_vy",
    "com_vz",
    "xcom_dx",
    "xcom_dy",
    "reach",
    "excess",
    "speed_along",
    "height",
    "xcom_cos",
    "xcom_sin",
    "down",
)
FEATURE_SETS = {"paper": PAPER_FEATURES, "extended": EXTENDED_FEATURES}
_LATERAL = [
    EXTENDED_FEATURES.index(n)
    for n in ("head_dy", "chest_dy", "pelvis_dy", "com_dy", "dev_y", "dev_vy", "com_vy", "xcom_dy")
]
TRACKED_ROLES = ("head", "chest", "pelvis")
FRAME_ROLES = ("hip_l", "hip_r", "shoulder_l", "shoulder_r")
CAPTURE_FLOOR_PERCENTILE = 2.0  # a low percentile, not the minimum: one frame's marker glitch must not sink the floor
KEPT_MOTIONS = 4  # motions whose frames' centres of mass a reader keeps
LEG_ROLES = tuple(f"{part}_{side}" for side in SIDES for part in ("hip", "knee", "ankle"))


def feature_rig(rig: Rig) -> Rig:
    """The rig the features read (its joints and leg length), checked to have the roles they need:
    SkeletonError naming the missing ones."""
    missing = [r for r in TRACKED_ROLES + FRAME_ROLES + LEG_ROLES if r not in rig.roles]
    if missing:
        raise SkeletonError(f"the reaction features need joints for the roles: {', '.join(missing)}")
    return rig


def spine_frame(rig: Rig, positions: FloatArray) -> FloatArray:
    """Rows X (forward), Y (left), Z (up) of the spine frame (see the module docstring), (3, 3),
    from one pose's joint positions (J, 3)."""
    j = rig.joints
    left = positions[j["hip_l"]] - positions[j["hip_r"]] + positions[j["shoulder_l"]] - positions[j["shoulder_r"]]
    left = left - (left @ UP) * UP
    norm = float(np.linalg.norm(left))
    if norm < 1e-6:
        raise SkeletonError("the hips and shoulders are stacked vertically: the character's facing is undefined")
    left /= norm
    return np.stack([np.cross(left, UP), left, UP])


@dataclass(frozen=True)
class ReactionState:
    """The body at B and at C, and the motion it was playing at C (world, metres, m/s).

    positions_b, positions_c: (J, 3) joint positions; com_b, com_c, com_velocity: (3,) the centre
    of mass at B and C and its velocity at C; motion_com, motion_velocity: the motion's own at C;
    support: the base of support at C; floor: the floor's height.
    """

    positions_b: FloatArray
    com_b: FloatArray
    positions_c: FloatArray
    com_c: FloatArray
    com_velocity: FloatArray
    motion_com: FloatArray
    motion_velocity: FloatArray
    support: Support
    floor: float

    def facing(self, rig: Rig) -> FloatArray:
        """The spine frame at B, (3, 3)."""
        return spine_frame(rig, self.positions_b)

    def omega(self) -> float:
        """The inverted pendulum's eigenfrequency at the motion's centre of mass height at C."""
        return capture.eigenfrequency(float(self.motion_com[2] - self.floor))

    def xcom_departure(self) -> FloatArray:
        """XCoM(body at C) - XCoM(motion at C), horizontal, world (2,)."""
        omega = self.omega()
        return capture.xcom(self.com_c, self.com_velocity, omega) - capture.xcom(
            self.motion_com, self.motion_velocity, omega
        )

    def reach(self) -> float:
        """How far the motion's centre of pressure can still move along the XCoM departure (m)."""
        motion_xcom = capture.xcom(self.motion_com, self.motion_velocity, self.omega())
        return self.support.reach(motion_xcom, self.xcom_departure())


def reaction_features(rig: Rig, state: ReactionState) -> FloatArray:
    """EXTENDED_FEATURES (the paper's nine first): lengths in leg lengths, speeds in sqrt(g L)."""
    frame = state.facing(rig)
    moved = state.positions_c - state.positions_b
    departure = state.xcom_departure()
    distance = float(np.linalg.norm(departure))
    along = float(state.com_velocity[:2] @ departure / distance) if distance > 0.0 else 0.0
    reach = state.reach()
    length, speed = rig.leg_length, np.sqrt(capture.GRAVITY * rig.leg_length)
    return np.concatenate(
        [
            np.concatenate([frame[:2] @ moved[rig.joints[r]] for r in TRACKED_ROLES]) / length,
            frame @ (state.com_c - state.com_b) / length,
            frame @ (state.com_c - state.motion_com) / length,
            frame @ (state.com_velocity - state.motion_velocity) / speed,
            frame @ state.com_velocity / speed,
            frame[:2, :2] @ departure / length,
            [reach / length, (distance - reach) / length, along / speed, (state.com_c[2] - state.floor) / length],
            _direction(frame[:2, :2] @ departure, distance),
            [1.0 if state.support.down else 0.0],
        ]
    )


def _direction(local: FloatArray, distance: float) -> list[float]:
    """Cosine and |sine| of a horizontal vector's angle from forward (both 0 for no vector)."""
    if distance <= 0.0:
        return [0.0, 0.0]
    return [float(local[0]) / distance, abs(float(local[1])) / distance]


def select(features: AnyFloatArray, names: tuple[str, ...]) -> AnyFloatArray:
    """The columns `names` of EXTENDED_FEATURES rows (..., 27), e.g. PAPER_FEATURES."""
    unknown = [n for n in names if n not in EXTENDED_FEATURES]
    if unknown:
        raise SkeletonError(f"unknown reaction features: {', '.join(unknown)}")
    return features[..., [EXTENDED_FEATURES.index(n) for n in names]]


def mirrored(features: AnyFloatArray) -> FloatArray:
    """EXTENDED_FEATURES rows (..., 27) of the same pushes seen in a left-right mirror.

    Mirrored, the hips and shoulders swap sides, so the spine frame keeps its axes and every
    value along its Y (left) changes sign; the rest stay, xcom_sin being a |sine|. The outcome rule
    is symmetric too: a mirrored row's label is its class's mirror image (a side step's other side,
    classes.mirror_image; every other class its own), so training on both sides doubles the data
    for free.
    """
    out = np.array(features, dtype=np.float64)
    out[..., _LATERAL] *= -1.0
    return out


# ---------------------------------------------------------------------------------------------
# Reaction states from simulations and from motion capture


class FeatureReader:
    """Reads reaction states on one ragdoll: mocap poses go through the ragdoll's masses for their
    centre of mass, kept per motion frame (training reads the same frames for 30 pushes; a bake
    reads a new motion per impact, so the keep is bounded). Holds an MjData: one reader per thread."""

    def __init__(self, ragdoll: Ragdoll):
        self.ragdoll = ragdoll
        self.rig = feature_rig(ragdoll.rig)
        self.soles = SoleGeometry(ragdoll)
        self._kept: dict[int, tuple[Motion, dict[int, FloatArray]]] = {}

    def facing(self, motion: Motion, frame: float) -> FloatArray:
        """The spine frame of the motion at a frame (nearest), (3, 3)."""
        return spine_frame(self.rig, _positions((motion, _clamp_frame(frame, motion)))[0])

    def simulated(self, motion: Motion, bc: SimResult) -> ReactionState:
        """The state of a BC simulation of `motion` with its unpushed twin (simulate_push), which
        is the motion at C."""
        b = _clamp_frame(bc.frames[0], motion)
        positions = _positions((motion, b), (bc.motion, bc.motion.num_frames - 1))
        return ReactionState(
            positions_b=positions[0],
            com_b=self._com(motion, [b])[0],
            positions_c=positions[1],
            com_c=bc.com[-1],
            com_velocity=bc.com_velocity[-1],
            motion_com=bc.twin.com[-1],
            motion_velocity=bc.twin.com_velocity[-1],
            support=self.soles.support(bc.state.qpos, bc.floor, bc.contacts[-1]),
            floor=bc.floor,
        )

    def captured(self, motion: Motion, frame_b: int, window: float) -> ReactionState:
        """The state of a motion capture's own reaction: B at frame_b, C `window` seconds later; the
        motion at C is the body at B carried on at its velocity; the floor is the capture's floor
        (capture_floor)."""
        c = round(frame_b + window * motion.fps)
        if not 0 < frame_b < c < motion.num_frames - 1:
            raise SkeletonError(f"frames {frame_b}..{c} are outside the motion's frames 1..{motion.num_frames - 2}")
        positions = _positions((motion, frame_b), (motion, c))
        com = self._com(motion, [frame_b - 1, frame_b, frame_b + 1, c - 1, c, c + 1])
        velocity_b = _velocity(com[0], com[2], 2, motion.fps)
        floor = self.capture_floor(motion)
        qpos_c = mocap_qpos(self.ragdoll, motion, np.array([c]))[0]
        return ReactionState(
            positions_b=positions[0],
            com_b=com[1],
            positions_c=positions[1],
            com_c=com[4],
            com_velocity=_velocity(com[3], com[5], 2, motion.fps),
            motion_com=com[1] + velocity_b * (c - frame_b) / motion.fps,
            motion_velocity=velocity_b,
            support=self.soles.support(qpos_c, floor),
            floor=floor,
        )

    def capture_floor(self, motion: Motion) -> float:
        """The floor of a whole capture: the 2nd percentile over its frames of the lowest sole point.
        (contacts.ground_level looks only near one frame, which in a jump or a fall has no foot on the
        floor.)"""
        qpos = mocap_qpos(self.ragdoll, motion, np.arange(motion.num_frames))
        return float(np.percentile([self.soles.lowest_sole(q) for q in qpos], CAPTURE_FLOOR_PERCENTILE))

    def _com(self, motion: Motion, frames: list[int]) -> FloatArray:
        """The ragdoll's centre of mass (n, 3) in some mocap frames."""
        kept = self._kept_for(motion)
        missing = [f for f in dict.fromkeys(frames) if f not in kept]
        if missing:
            for frame, qpos in zip(missing, mocap_qpos(self.ragdoll, motion, np.asarray(missing)), strict=True):
                kept[frame] = self.soles.probe.centre_of_mass(qpos)
        return np.array([kept[f] for f in frames])

    def _kept_for(self, motion: Motion) -> dict[int, FloatArray]:
        """The centres of mass kept for this motion (the object, not just its id); the oldest motion
        is dropped past KEPT_MOTIONS."""
        entry = self._kept.get(id(motion))
        if entry is None or entry[0] is not motion:
            if len(self._kept) >= KEPT_MOTIONS:
                del self._kept[next(iter(self._kept))]
            entry = self._kept[id(motion)] = (motion, {})
        return entry[1]


def _positions(*frames: tuple[Motion, int]) -> FloatArray:
    """Joint positions (n, J, 3) of (motion, frame) pairs on one skeleton, in one pass of forward
    kinematics (its cost is per joint, not per frame)."""
    skeleton = frames[0][0].skeleton
    root = np.array([m.root_pos[f] for m, f in frames])
    local = np.array([m.local_rot[f] for m, f in frames])
    offsets = np.array([m.joint_offsets()[f] for m, f in frames])
    return forward_kinematics(skeleton, root, local, offsets)[0]


def _velocity(earlier: FloatArray, later: FloatArray, frames: int, fps: float) -> FloatArray:
    """Central (or one-sided, at a motion's ends) difference; zero over no frames."""
    return (later - earlier) * fps / frames if frames > 0 else np.zeros(3)


def _clamp_frame(frame: float, motion: Motion) -> int:
    return int(min(max(round(float(frame)), 0), motion.num_frames - 1))
