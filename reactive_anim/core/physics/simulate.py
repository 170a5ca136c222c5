"""Simulation: state from mocap, the impact, forward dynamics (BC) and PD tracking (CD, Eq. 2).

Paper section 2, steps 2 and 5, section 2.5 and Eq. 2: at B the impact lands and forward dynamics
runs for about a human reaction time (BC); from C a PD servo per joint,
tau = k_s (theta_target - theta) - k_d theta_dot, drives the ragdoll toward the target clip (CD).

How, and what differs from the paper, with the reason:
- State at B: joint angles from the motion's rotations, velocities by central differences of the
  mocap, so a walking character keeps its momentum (the paper does not say; a standing start
  would stop the walker dead).
- The impact is an impulse J (N·s) applied as the force J / dt for one step at the hit body's
  centre of mass (`mj_applyFT`), so the centre of mass gains exactly J / M whatever the timestep.
- BC is not limp: weak servos (a fraction of CD's gains) pull toward the mocap continuing after B,
  as a person's muscles do not switch off at the instant of a hit.
- Eq. 2 is MuJoCo's position actuator (torque = kp (ctrl - q) - kv q_dot), integrated implicitly
  (`implicitfast`): stable at dt = 1/600 where torques computed in Python were not, and faster.
  We add the target's velocity: ctrl = theta_target + (kv / kp) theta_dot_target, which makes the
  torque kp (theta_target - theta) + kv (theta_dot_target - theta_dot). Eq. 2 as printed damps
  toward zero velocity and so lags a moving target by (kv / kp) theta_dot.
- Gains scale with the mass each joint moves, so one setting, `stiffness` in N·m/rad per kg,
  suits the neck and the hip alike: for the spine, neck and arms that is the body and everything
  below it; for hip, knee and ankle the whole body, which a leg carries while its foot is planted
  (scaled by the leg's own mass, a stance ankle sagged 8 degrees and the walker sank at once).
- The floor is put at the mocap's ground near B (the lowest sole per frame, median over +-0.25 s,
  never above the start frame's lowest sole), not at z = 0: mocap floors drift by centimetres, and
  a character starting 4 cm in the air or in the floor falls or pops before anything else happens.
- The root is not actuated: nothing invisible holds the character up, so pure PD tracking, which
  has no balance feedback, falls over eventually (tests measure after how long).
- Fixed timestep (1/600 s) and step counts derived from frame numbers only: the same input gives
  bit-identical output. Sampling at the motion's frame times uses round(frame_interval / dt) steps
  per frame.
- Explosions (NaN, joint or body speeds beyond physical bounds, bodies through the floor, energy
  growing without input, MuJoCo's own instability warnings) raise SimulationError naming the time
  (on the motion's clock), the body and the quantity; they are never returned as NaN poses. MuJoCo
  still prints its own one-line warning to stderr when it resets an unstable state.

Output is a core Motion on the full input skeleton at the motion's frame times. Role joints come
from the simulation; a spine body's bend is shared by the skeleton joints it spans (waist and back
over the spine joints, neck over the neck joints and the head); joints with no body below them
(toes, fingers, twist and face bones) follow the mocap the servos track; joints between bodies
(clavicles, helper bones) keep the start frame's rotation, as the model does.

Per-run state: a Ragdoll is immutable. What a run changes (body offsets to the start frame's merged
bones, servo gains) lives in a Workspace: a copy of the ragdoll's model and its own MjData. Pass one
Workspace per thread to reuse it (making one costs about 1 ms, a tenth of a BC window); without one,
each call makes its own. MuJoCo's warning text is caught per thread, so simulations on several
threads at once give the same results as one after the other.
"""

from __future__ import annotations

import copy
import math
import sys
import threading
from collections.abc import Callable
from dataclasses import dataclass

import mujoco
import numpy as np

from ..model import quat
from ..model.errors import ImpactError, SimulationError, SkeletonError
from ..model.impact import Impact
from ..model.skeleton import Motion
from .balance import ASSIST_STEPS, AssistController, RootAssist
from .ragdoll import JOINT_GROUPS, TIMESTEP, Ragdoll

REACTION_WINDOW = 0.25  # seconds, BC: about a human reaction time (paper: ~15 frames)
CD_STIFFNESS = 100.0  # N·m/rad per kg moved (tuned on real walks: tracks within ~1 degree)
CD_DAMPING_TIME = 0.03  # kv / kp, seconds
BC_SERVO_FRACTION = 0.25  # BC servo gains as a fraction of CD's
MAX_JOINT_SPEED = 500.0  # rad/s; muscles reach ~20, a hard hit on a 0.6 kg hand ~150, a numerical blow-up far more
MAX_BODY_SPEED = 30.0  # m/s; a sprinter runs at ~10
FLOOR_TOLERANCE = 0.25  # m a body origin may sink below the floor before it counts as fallen through
GROUND_SPAN = 0.25  # s either side of the start frame in which the stance sole finds the ground
# m/s: energy beyond 1/2 M v^2 above the start counts as an explosion. The servos and the root
# assist do work (raising a crouched body to a standing target adds ~500 J of the 1,220 J that 5 m/s
# allowed, and a reaction during a lunge went over it); a numerical blow-up adds far more, and the
# joint and body speed checks catch it too.
ENERGY_ALLOWANCE_SPEED = 10.0
# m/s: the most an impact may set the hit body's centre of mass moving, faster than a batted ball
# (about 45 m/s). Pushes beyond it are refused before simulating: no hit does that to a body part,
# and past 57-86 m/s on the head and upper arms, 95-190 on a hand, the joints spun beyond
# MAX_JOINT_SPEED (measured on five walks; a hand or foot reaches 50 m/s at 50-190 N·s, the head at
# 530-880).
MAX_HIT_SPEED = 50.0
_WARNINGS = ("mjWARN_BADQACC", "mjWARN_BADQVEL", "mjWARN_BADQPOS", "mjWARN_CNSTRFULL", "mjWARN_CONTACTFULL")
_WARNING_IDS = np.array([int(getattr(mujoco.mjtWarning, name)) for name in _WARNINGS], dtype=int)


@dataclass
class HeldPose:
    """The mocap frame whose merged joints (and joints above the pelvis) stay as they are.

    local_rot (J, 4), offsets (J, 3), root_pos (3,): that frame of the input motion; qpos (nq,):
    the ragdoll's joint positions for it (mocap_qpos).
    """

    local_rot: np.ndarray
    offsets: np.ndarray
    root_pos: np.ndarray
    global_pos: np.ndarray
    global_rot: np.ndarray
    qpos: np.ndarray


@dataclass
class SimState:
    """A ragdoll state to start or continue a simulation from."""

    qpos: np.ndarray
    qvel: np.ndarray
    held: HeldPose
    floor: float = 0.0


@dataclass
class SimResult:
    """A simulated stretch sampled at frame times.

    motion: the full skeleton's pose per sampled frame; frames[i] is its frame number on the
      input motion's clock (BC) or the target's (CD).
    com, com_velocity: (T, 3) centre of mass (world) and its velocity per sampled frame.
    floor: the height of the floor the run stood on (the mocap's ground, see ground_level).
    contacts: (T, B) which ragdoll bodies (Ragdoll.bodies order) touch the floor at each sample.
    first_contact: per body name, the time in seconds after the run's start of the first sample at
      which it touches the floor (bodies that never do are absent); the feet usually at 0.
    assist_fraction: the largest root assist used, as a fraction of body weight (balance.py).
    state: the state at the last sampled frame, to continue from (C for BC).
    """

    motion: Motion
    frames: np.ndarray
    qpos: np.ndarray
    qvel: np.ndarray
    com: np.ndarray
    com_velocity: np.ndarray
    floor: float
    contacts: np.ndarray
    first_contact: dict[str, float]
    state: SimState
    assist_fraction: float = 0.0

    @property
    def com_height(self) -> np.ndarray:
        """(T,) the centre of mass's height above the run's floor."""
        return self.com[:, 2] - self.floor


@dataclass(frozen=True)
class ServoGains:
    """Eq. 2's PD gains, per kg the joint moves (see mass_moved): kp = stiffness * group * mass
    (N·m/rad), kv = damping_time * kp (N·m·s/rad); `group` is the factor of the joint's group
    (ragdoll.JOINT_GROUPS: legs = hips, knees, ankles; trunk = waist, back; arms; neck)."""

    stiffness: float = CD_STIFFNESS
    damping_time: float = CD_DAMPING_TIME
    legs: float = 1.0
    trunk: float = 1.0
    arms: float = 1.0
    neck: float = 1.0

    def group_factors(self) -> np.ndarray:
        """Factors in ragdoll.JOINT_GROUPS order."""
        return np.array([getattr(self, group) for group in JOINT_GROUPS])


CD_GAINS = ServoGains()
BC_GAINS = ServoGains(stiffness=CD_STIFFNESS * BC_SERVO_FRACTION)


class Workspace:
    """One simulation's own MuJoCo state: a copy of the ragdoll's model, whose body offsets, servo
    gains and hinge ranges each run sets, and two MjData (the stepped state; kinematics for ground level and samples).

    Reuse one per thread: a reused MjData is put back by mj_resetData, which is what the MjData
    constructor itself calls, so results are the same bit for bit. Two runs cannot share one at
    once (SimulationError)."""

    def __init__(self, ragdoll: Ragdoll):
        self.ragdoll = ragdoll
        self.model = copy.copy(ragdoll.model)
        address = {int(a): j for j, a in enumerate(self.model.jnt_qposadr)}
        self.hinge_joints = np.array([address[int(a)] for a in ragdoll.hinge_qpos], dtype=int)
        self.sim_data = mujoco.MjData(self.model)
        self.kin_data = mujoco.MjData(self.model)
        self._busy = threading.Lock()

    def __enter__(self) -> Workspace:
        if not self._busy.acquire(blocking=False):
            raise SimulationError("this simulation workspace is in use by another run; give each thread its own")
        return self

    def __exit__(self, *exc: object) -> None:
        self._busy.release()


def _workspace(ragdoll: Ragdoll, workspace: Workspace | None) -> Workspace:
    if workspace is None:
        return Workspace(ragdoll)
    if workspace.ragdoll is not ragdoll:
        raise SimulationError("the workspace was made for another ragdoll")
    return workspace


def _fresh(data: mujoco.MjData) -> mujoco.MjData:
    """A reused MjData put back into the state of a newly made one."""
    mujoco.mj_resetData(data.model, data)
    return data


# ---------------------------------------------------------------------------------------------
# Mocap <-> joint angles


def _check_finite(motion: Motion, frames: np.ndarray) -> None:
    rot = motion.local_rot[frames]
    bad = ~np.all(np.isfinite(rot), axis=-1)
    if np.any(bad):
        f, j = np.argwhere(bad)[0]
        raise SimulationError(
            f"the input pose holds NaN or infinite values: frame {frames[f]}, joint '{motion.skeleton.names[j]}'"
        )
    bad_root = ~np.all(np.isfinite(motion.root_pos[frames]), axis=-1)
    if np.any(bad_root):
        frame = frames[np.argmax(bad_root)]
        raise SimulationError(f"the input root position holds NaN or infinite values at frame {frame}")
    if motion.local_pos is not None and not np.all(np.isfinite(motion.local_pos[frames])):
        raise SimulationError("the input joint positions hold NaN or infinite values")


def _kinematics(
    ragdoll: Ragdoll, root_pos: np.ndarray, local_rot: np.ndarray, offsets: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Forward kinematics (N, J, 3) and (N, J, 4) of only the joints the ragdoll needs (body joints
    and their ancestors; fingers and face bones are left at zero), vectorised over frames.
    Rotation matrices inside: a 3x3 product per joint is far cheaper than quaternion helpers on
    small arrays, and this runs once per impact on the critical path."""
    n, count = local_rot.shape[:2]
    joints = ragdoll.kinematic_joints
    local_m = np.zeros((n, count, 3, 3))
    local_m[:, joints] = quat.to_matrix(local_rot[:, joints])
    pos = np.zeros((n, count, 3))
    rot_m = np.zeros((n, count, 3, 3))
    root = joints[0]
    pos[:, root] = root_pos
    rot_m[:, root] = local_m[:, root]
    # A level of the hierarchy at a time: each joint's arithmetic is the same as joint by joint.
    for level, parents in ragdoll.kinematic_levels:
        pos[:, level] = pos[:, parents] + np.einsum("njab,njb->nja", rot_m[:, parents], offsets[:, level])
        rot_m[:, level] = rot_m[:, parents] @ local_m[:, level]
    rot = np.zeros((n, count, 4))
    rot[:, joints] = quat.from_matrix(rot_m[:, joints])
    return pos, rot


@dataclass
class _MocapPoses:
    """mocap_qpos of some frames together with the forward kinematics it was computed from, so a
    held pose of one of those frames needs no second FK pass (row k of the batched FK is bitwise the
    FK of that frame alone)."""

    qpos: np.ndarray  # (N, nq)
    local_rot: np.ndarray  # (N, J, 4) normalised
    offsets: np.ndarray  # (N, J, 3)
    root_pos: np.ndarray  # (N, 3)
    global_pos: np.ndarray  # (N, J, 3), kinematic joints only
    global_rot: np.ndarray  # (N, J, 4), kinematic joints only

    def held(self, k: int) -> HeldPose:
        """Row k as a HeldPose, with arrays of its own."""
        return HeldPose(
            local_rot=self.local_rot[k].copy(),
            offsets=np.array(self.offsets[k], dtype=float),
            root_pos=self.root_pos[k].copy(),
            global_pos=self.global_pos[k].copy(),
            global_rot=self.global_rot[k].copy(),
            qpos=self.qpos[k].copy(),
        )


def mocap_qpos(ragdoll: Ragdoll, motion: Motion, frames: np.ndarray) -> np.ndarray:
    """Ragdoll joint positions (N, nq) of the given frames of a motion of the ragdoll's skeleton.

    Root: pelvis position and the pelvis body's rotation away from the neutral pose. Each hinge
    triple: the body's rotation relative to its parent body, split into flexion, twist and
    abduction angles (ragdoll.py, JOINT LIMITS). Angles are unwrapped along the frames.
    """
    return _mocap_poses(ragdoll, motion, frames).qpos


def _mocap_poses(ragdoll: Ragdoll, motion: Motion, frames: np.ndarray) -> _MocapPoses:
    """mocap_qpos, keeping the FK on the way (see _MocapPoses)."""
    if motion.skeleton.names != ragdoll.skeleton.names:
        raise SkeletonError("the motion's skeleton is not the ragdoll's skeleton (joint names differ)")
    frames = np.asarray(frames, dtype=int)
    _check_finite(motion, frames)
    offsets = np.broadcast_to(motion.joint_offsets()[frames], (len(frames),) + motion.skeleton.offsets.shape)
    root_pos = motion.root_pos[frames]
    local_rot = quat.normalize(motion.local_rot[frames])
    pos, grot = _kinematics(ragdoll, root_pos, local_rot, offsets)
    joints, parents = ragdoll.body_joints, ragdoll.body_parents
    # Body rotation in MuJoCo = global rotation relative to the neutral pose.
    x = quat.make_continuous(quat.mul(grot[:, joints], quat.conj(ragdoll.neutral_global_rot[joints])))
    qpos = np.zeros((len(frames), ragdoll.model.nq))
    qpos[:, 0:3] = pos[:, ragdoll.root.joint]
    qpos[:, 3:7] = x[:, 0]
    # All bodies at once: rotation relative to the parent body, in the joint frame, as Euler angles.
    rel = quat.mul(quat.conj(x[:, parents]), x)
    fq = ragdoll.frame_quat
    angles = quat.to_euler(quat.mul(quat.conj(fq), quat.mul(rel, fq)), "XYZ")  # (N, B, 3)
    hinge = angles[:, ragdoll.hinge_body, ragdoll.hinge_slot] * ragdoll.hinge_sign
    qpos[:, ragdoll.hinge_qpos] = np.unwrap(hinge, axis=0)
    return _MocapPoses(
        qpos=qpos, local_rot=local_rot, offsets=offsets, root_pos=root_pos, global_pos=pos, global_rot=grot
    )


def _interp_qpos(table: np.ndarray, t: float) -> np.ndarray:
    """Row-interpolate a per-frame qpos table at fractional index t (root rotation by slerp)."""
    i = int(np.clip(np.floor(t), 0, len(table) - 1))
    j = min(i + 1, len(table) - 1)
    s = float(np.clip(t - i, 0.0, 1.0))
    q = table[i] + (table[j] - table[i]) * s
    q[3:7] = quat.slerp(table[i, 3:7], table[j, 3:7], s)
    return q


@dataclass
class _MocapTable:
    """Ragdoll joint positions of the motion's frames first .. first + len(qpos) - 1 (one FK pass)."""

    first: int
    qpos: np.ndarray
    poses: _MocapPoses

    def at(self, frame: float) -> np.ndarray:
        return _interp_qpos(self.qpos, frame - self.first)

    def held(self, frame: int) -> HeldPose:
        """The held pose of a frame of the table."""
        k = frame - self.first
        if not 0 <= k < len(self.qpos):
            raise SimulationError(
                f"frame {frame} is outside the pose table's frames {self.first}..{self.first + len(self.qpos) - 1}"
            )
        return self.poses.held(k)


def _mocap_table(ragdoll: Ragdoll, motion: Motion, lo: float, hi: float) -> _MocapTable:
    first = int(max(0, np.floor(lo)))
    last = int(min(motion.num_frames - 1, np.ceil(hi)))
    poses = _mocap_poses(ragdoll, motion, np.arange(first, last + 1))
    return _MocapTable(first, poses.qpos, poses)


def state_from_mocap(ragdoll: Ragdoll, motion: Motion, frame: float, workspace: Workspace | None = None) -> SimState:
    """Ragdoll state at a (possibly fractional) frame: pose from the rotations, velocity by central
    differences over one frame either side, so the character keeps the motion's momentum; and the
    ground height the mocap stands on there (see ground_level)."""
    table = _start_table(ragdoll, motion, frame)
    with _workspace(ragdoll, workspace) as ws:
        return _state_from_table(ws, motion, frame, table)


def _start_table(ragdoll: Ragdoll, motion: Motion, frame: float) -> _MocapTable:
    """The pose table a start state at `frame` reads: GROUND_SPAN and one frame either side."""
    if not (np.isfinite(frame) and 0 <= frame <= motion.num_frames - 1):
        raise SimulationError(f"frame {frame} is outside the motion's frames 0..{motion.num_frames - 1}")
    reach = GROUND_SPAN * motion.fps
    return _mocap_table(ragdoll, motion, frame - reach - 1, frame + reach + 1)


def _state_from_table(ws: Workspace, motion: Motion, frame: float, table: _MocapTable) -> SimState:
    """state_from_mocap from a table that covers GROUND_SPAN and one frame either side of `frame`."""
    ragdoll = ws.ragdoll
    last = motion.num_frames - 1
    before_f, after_f = max(frame - 1.0, 0.0), min(frame + 1.0, float(last))
    before, qpos, after = table.at(before_f), table.at(frame), table.at(after_f)
    qvel = np.zeros(ragdoll.model.nv)
    span = (after_f - before_f) / motion.fps
    if span > 0:
        qvel[0:3] = (after[0:3] - before[0:3]) / span
        # Free joint angular velocity is in the body's local frame: log of q(t-)^-1 q(t+).
        d = quat.mul(quat.conj(before[3:7]), after[3:7])
        d = d if d[0] >= 0 else -d
        angle = 2.0 * np.arctan2(np.linalg.norm(d[1:]), d[0])
        qvel[3:6] = d[1:] / max(np.linalg.norm(d[1:]), 1e-12) * angle / span
        qvel[ragdoll.hinge_dof] = (after[ragdoll.hinge_qpos] - before[ragdoll.hinge_qpos]) / span
    held = table.held(round(frame))
    floor = _ground_level(ws, table, frame, held, GROUND_SPAN * motion.fps)
    return SimState(qpos=qpos, qvel=qvel, held=held, floor=floor)


def ground_level(
    ragdoll: Ragdoll, motion: Motion, frame: float, span: float = GROUND_SPAN, workspace: Workspace | None = None
) -> float:
    """Height of the ground the mocap walks on near `frame`: the lowest point of the ragdoll's soles,
    per frame, within `span` seconds either side, and of those the median.

    Mocap floors are rarely at exactly z = 0 (and our soles are guesses), so the simulated floor is
    put where the soles touch rather than the character dropped or lifted onto z = 0.
    """
    reach = span * motion.fps
    table = _mocap_table(ragdoll, motion, frame - reach, frame + reach)
    with _workspace(ragdoll, workspace) as ws:
        return _ground_level(ws, table, frame, table.held(round(frame)), reach)


def _ground_level(ws: Workspace, table: _MocapTable, frame: float, held: HeldPose, reach: float) -> float:
    _place_bodies(ws, held)
    model = ws.model
    data = _fresh(ws.kin_data)
    soles = ws.ragdoll.sole_geoms
    numbers = table.first + np.arange(len(table.qpos))
    rows = np.flatnonzero(np.abs(numbers - frame) <= reach)
    # Per frame only the kinematics; the sole heights of all frames at once afterwards.
    sole_z = np.empty((len(rows), len(soles)))
    sole_axis_z = np.empty((len(rows), len(soles)))
    for n, i in enumerate(rows):
        data.qpos[:] = table.qpos[i]
        mujoco.mj_kinematics(model, data)
        sole_z[n] = data.geom_xpos[soles, 2]
        sole_axis_z[n] = data.geom_xmat[soles, 8]  # the capsule axis' z: row-major (3, 3), [2, 2]
    size = model.geom_size[soles]
    heights = sole_z - np.abs(sole_axis_z * size[:, 1]) - size[:, 0]
    lowest = heights.min(axis=1)
    # The median frame's lowest sole: the standing foot, robust to heel-strike dips and flight
    # phases; but never above the start frame's lowest sole, so the start does not pop out of the
    # floor, nor above any body at the start (a character lying or kneeling with its feet up).
    start = int(np.argmin(np.abs(numbers[rows] - round(frame))))
    return float(min(np.median(lowest), lowest[start], _lowest_body_point(ws, data, table.qpos[rows[start]])))


def _lowest_body_point(ws: Workspace, data: mujoco.MjData, qpos: np.ndarray) -> float:
    """The lowest point of any ragdoll geom (capsules and spheres) in the pose `qpos`."""
    model = ws.model
    data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    geoms = np.flatnonzero(ws.ragdoll.body_of_geom >= 0)
    size = model.geom_size[geoms]
    half = np.where(model.geom_type[geoms] == mujoco.mjtGeom.mjGEOM_CAPSULE, size[:, 1], 0.0)
    return float(np.min(data.geom_xpos[geoms, 2] - np.abs(data.geom_xmat[geoms, 8] * half) - size[:, 0]))


# ---------------------------------------------------------------------------------------------
# Model set-up per run (on the workspace's copy of the model)


def _place_bodies(ws: Workspace, held: HeldPose) -> None:
    """Body offsets from the held frame: merged bones between two bodies (clavicles, helper bones)
    and animated bone lengths keep the start frame's values, so FK of the output matches MuJoCo."""
    ragdoll = ws.ragdoll
    joints = ragdoll.body_joints[1:]
    parent_joints = ragdoll.body_joints[ragdoll.body_parents[1:]]
    to_neutral = quat.mul(ragdoll.neutral_global_rot[parent_joints], quat.conj(held.global_rot[parent_joints]))
    ws.model.body_pos[ragdoll.body_ids[1:]] = quat.rotate(
        to_neutral, held.global_pos[joints] - held.global_pos[parent_joints]
    )


def _set_servos(ws: Workspace, gains: ServoGains) -> None:
    """Position-actuator gains kp = stiffness * mass moved, kv = damping_time * kp."""
    model = ws.model
    kp = gains.stiffness * gains.group_factors()[ws.ragdoll.actuator_group] * ws.ragdoll.actuator_mass
    kv = kp * gains.damping_time
    model.actuator_gainprm[:, 0] = kp
    model.actuator_biasprm[:, 0] = 0.0
    model.actuator_biasprm[:, 1] = -kp
    model.actuator_biasprm[:, 2] = -kv


def _same_turns(ragdoll: Ragdoll, targets: np.ndarray, start: np.ndarray) -> None:
    """Shift each hinge's target angles (K, nq) by whole turns, in place, so that the first lies
    within half a turn of the start's. Angles are unwrapped along one motion's frames, so a start
    from another motion (the end of BC, tracking a clip) can sit a whole turn from its target: a
    shoulder raised overhead in a sword slash was 6.1 rad from the target it then tried to reach
    (a 5,400 J jump in one frame, SimulationError)."""
    hinges = ragdoll.hinge_qpos
    turns = np.round((start[hinges] - targets[0, hinges]) / (2.0 * np.pi))
    if np.any(turns):
        targets[:, hinges] += 2.0 * np.pi * turns


def _set_limits(ws: Workspace, qpos: np.ndarray) -> None:
    """Hinge ranges for one run: the profile's, widened where the start pose lies beyond them, so
    the run starts in the mocap's pose. Clamped to the range instead, a limb swung away from where
    the mocap put it: a get-up's sitting hips, flexed 154 degrees, clamped to 120, put the legs 30 cm
    into the floor, and the contacts threw the body a metre up."""
    hinges = ws.ragdoll.hinge_qpos
    ws.model.jnt_range[ws.hinge_joints, 0] = np.minimum(ws.ragdoll.limit_lo, qpos[hinges])
    ws.model.jnt_range[ws.hinge_joints, 1] = np.maximum(ws.ragdoll.limit_hi, qpos[hinges])


# MuJoCo's warning handler is one per process; this one hands the text to the run on the calling
# thread (MuJoCo warns from the thread that steps), and to the previous handler, or stderr, otherwise.
_warning_sink = threading.local()
_handler_lock = threading.Lock()
_handler_installed = False


def _install_warning_handler() -> None:
    global _handler_installed
    with _handler_lock:
        if _handler_installed:
            return
        previous: Callable[[str], None] | None = mujoco.get_mju_user_warning()

        def handle(message: str) -> None:
            messages = getattr(_warning_sink, "messages", None)
            if messages is not None:
                messages.append(message)
            elif previous is not None:
                previous(message)
            else:
                sys.stderr.write(f"MuJoCo warning: {message}\n")

        mujoco.set_mju_user_warning(handle)
        _handler_installed = True


class _CapturedWarnings:
    """MuJoCo's warning text of this thread's run, caught instead of printed and appended to
    MUJOCO_LOG.TXT in the working folder."""

    def __enter__(self) -> list[str]:
        _install_warning_handler()
        self.messages: list[str] = []
        _warning_sink.messages = self.messages
        return self.messages

    def __exit__(self, *exc: object) -> None:
        _warning_sink.messages = None


class _Watch:
    """Explosion detection after each sampled frame; raises SimulationError naming time, body, quantity."""

    def __init__(self, ws: Workspace, data: mujoco.MjData, t0: float, messages: list[str]):
        self.messages = messages
        self.ragdoll = ws.ragdoll
        self.model = ws.model
        self.data = data
        self.t0 = t0
        self.energy_limit: float | None = None
        self.floor = float(data.mocap_pos[0, 2])
        self.body_ids = ws.ragdoll.body_ids
        self.dof_body = ws.ragdoll.dof_body
        self.warnings = _WARNING_IDS
        self.mass = float(np.sum(ws.model.body_mass))

    def energy(self) -> float:
        """Kinetic + potential energy, computed on demand (cheaper than MuJoCo's per-step flag)."""
        mujoco.mj_energyPos(self.model, self.data)
        mujoco.mj_energyVel(self.model, self.data)
        potential, kinetic = self.data.energy
        return float(potential + kinetic)

    def arm_energy(self) -> None:
        self.energy_limit = self.energy() + 0.5 * self.mass * ENERGY_ALLOWANCE_SPEED**2

    def check(self) -> None:
        """Runs once per sampled frame, so each test is one or two numpy calls on cached indices."""
        d, m = self.data, self.model
        t = self.t0 + d.time
        if d.warning.number[self.warnings].any():
            self._raise_warning(t)
        qpos, qvel = d.qpos, d.qvel
        if not (np.isfinite(qpos).all() and np.isfinite(qvel).all()):
            bad = int(np.argmax(~np.isfinite(qvel))) if not np.isfinite(qvel).all() else 0
            raise SimulationError(
                f"simulation produced NaN at t = {t:.4f} s: body '{self._dof_name(bad)}', quantity qvel"
            )
        hinge = np.abs(qvel[6:])
        fastest = float(hinge.max()) if hinge.size else 0.0
        if fastest > MAX_JOINT_SPEED:
            i = int(np.argmax(hinge)) + 6
            raise SimulationError(
                f"simulation exploded at t = {t:.4f} s: body '{self._dof_name(i)}' joint speed "
                f"{fastest:.1f} rad/s exceeds {MAX_JOINT_SPEED:g}"
            )
        speed = math.hypot(qvel[0], qvel[1], qvel[2])
        if speed > MAX_BODY_SPEED:
            raise SimulationError(
                f"simulation exploded at t = {t:.4f} s: body '{self.ragdoll.root.name}' speed {speed:.1f} m/s "
                f"exceeds {MAX_BODY_SPEED:g}"
            )
        heights = d.xpos[self.body_ids, 2] - self.floor
        if heights.min() < -FLOOR_TOLERANCE:
            b = self.body_ids[int(np.argmin(heights))]
            raise SimulationError(
                f"simulation failed at t = {t:.4f} s: body '{m.body(b).name}' fell through the floor "
                f"(height {heights.min():.2f} m)"
            )
        if self.energy_limit is not None:
            energy = self.energy()
            if energy > self.energy_limit:
                raise SimulationError(
                    f"simulation exploded at t = {t:.4f} s: body '{self.ragdoll.root.name}' (whole ragdoll) energy "
                    f"{energy:.0f} J exceeds {self.energy_limit:.0f} J without input"
                )

    def _raise_warning(self, t: float) -> None:
        """The first of _WARNINGS MuJoCo raised, with its message and the degree of freedom it names."""
        d = self.data
        for name, index in zip(_WARNINGS, _WARNING_IDS, strict=True):
            w = d.warning[int(index)]
            if w.number:
                said = f": {self.messages[-1].split(' The simulation')[0]}" if self.messages else ""
                raise SimulationError(
                    f"simulation unstable at t = {t:.4f} s: MuJoCo warning {name}{said} "
                    f"(degree of freedom {w.lastinfo}, body '{self._dof_name(w.lastinfo)}')"
                )

    def _dof_name(self, dof: int) -> str:
        if 0 <= dof < 6:
            return self.ragdoll.root.name
        return self.dof_body.get(int(dof), "?")


def _samples(
    ws: Workspace, qpos: np.ndarray, qvel: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Body rotations (N, B, 4), pelvis positions (N, 3), centre of mass and its velocity (N, 3)."""
    model = ws.model
    data = _fresh(ws.kin_data)
    ids = ws.ragdoll.body_ids
    root = int(ids[0])
    # Whole rows are copied per frame (plain memcpy); the bodies are picked out once at the end.
    xquat = np.empty((len(qpos), model.nbody, 4))
    pelvis = np.empty((len(qpos), 3))
    com = np.empty((len(qpos), 3))
    com_vel = np.empty((len(qpos), 3))
    for i in range(len(qpos)):
        data.qpos[:] = qpos[i]
        data.qvel[:] = qvel[i]
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        mujoco.mj_comVel(model, data)
        mujoco.mj_subtreeVel(model, data)
        xquat[i] = data.xquat
        pelvis[i] = data.xpos[root]
        com[i] = data.subtree_com[root]
        com_vel[i] = data.subtree_linvel[root]
    return xquat[:, ids], pelvis, com, com_vel


def _body_rotations(ws: Workspace, qpos: np.ndarray) -> np.ndarray:
    """(B, 4) the ragdoll bodies' rotations in the pose qpos (on the workspace's placed bodies)."""
    data = _fresh(ws.kin_data)
    data.qpos[:] = qpos
    mujoco.mj_kinematics(ws.model, data)
    return data.xquat[ws.ragdoll.body_ids].copy()


def _to_motion(
    ragdoll: Ragdoll,
    held: HeldPose,
    follow: np.ndarray,
    body_rot: np.ndarray,
    pelvis_pos: np.ndarray,
    held_body_rot: np.ndarray,
    *,
    fps: float,
) -> Motion:
    """Full-skeleton Motion from simulated body rotations (N, B, 4) and pelvis positions (N, 3).

    Joints between bodies (clavicles, helper bones) keep the held frame, as in the model; joints with
    no body below (toes, fingers, head) take their rotation from `follow` (N, J, 4), the mocap the
    servos track; a spine body's bend is shared by the skeleton's joints it spans (_share_bends).
    What a body's joints cannot hold of the held frame (a single-hinge elbow or knee drops the
    forearm's twist and carrying angle) is kept as it is there, on top of the simulated rotation:
    `held_body_rot` (B, 4), the bodies of the held frame's qpos, rebuilt the same way, says how much,
    so the output starts on the mocap's pose instead of jumping away from it at the impact (docs/method.md)."""
    skeleton = ragdoll.skeleton
    n = len(body_rot)
    local = np.broadcast_to(held.local_rot, (n,) + held.local_rot.shape).copy()
    local[:, ragdoll.leaf_joints] = follow[:, ragdoll.leaf_joints]
    joints = ragdoll.body_joints
    # The held frame's bodies as one more row, last.
    body_local = _body_local_rotations(ragdoll, held, np.concatenate([body_rot, held_body_rot[None]]))
    kept = quat.mul(quat.conj(body_local[-1]), held.local_rot[joints])
    local[:, joints] = quat.mul(body_local[:-1], kept)
    root = ragdoll.root
    if skeleton.parents[root.joint] < 0:
        root_pos = pelvis_pos.copy()
    else:  # joints above the pelvis (a ground root bone) hold; the root moves so the pelvis lands right
        root_pos = held.root_pos + (pelvis_pos - held.global_pos[root.joint])
    _share_bends(ragdoll, local, held.local_rot)
    local = quat.make_continuous(quat.normalize(local))
    local_pos = np.broadcast_to(held.offsets, (n,) + held.offsets.shape).copy()
    return Motion(skeleton=skeleton, fps=fps, root_pos=root_pos, local_rot=local, local_pos=local_pos)


def _body_local_rotations(ragdoll: Ragdoll, held: HeldPose, body_rot: np.ndarray) -> np.ndarray:
    """(N, B, 4) the local rotations of the body joints for body rotations (N, B, 4): each body's
    joint turns from its parent body, carried through the held merged bones between them (a ground
    root bone above the pelvis holds)."""
    skeleton, joints, hrot = ragdoll.skeleton, ragdoll.body_joints, held.global_rot
    glob = quat.mul(body_rot, ragdoll.neutral_global_rot[joints])
    body_local = np.empty_like(glob)
    parent = skeleton.parents[ragdoll.root.joint]
    body_local[:, 0] = glob[:, 0] if parent < 0 else quat.mul(quat.conj(hrot[parent]), glob[:, 0])
    body_parent = ragdoll.body_parents[1:]
    carry = quat.mul(quat.conj(hrot[joints[body_parent]]), hrot[skeleton.parents[joints[1:]]])
    parent_rot = quat.mul(glob[:, body_parent], carry)
    body_local[:, 1:] = quat.mul(quat.conj(parent_rot), glob[:, 1:])
    return body_local


def _share_bends(ragdoll: Ragdoll, local: np.ndarray, held: np.ndarray) -> None:
    """Spread each spine body's bend over the skeleton joints it spans, in place.

    The rigid body turns its first joint s0 by D (local[s0] = D held[s0], D in s0's parent frame) and
    carries the held chain s1..sk. Shared, the chain's cumulative rotation up to joint i is
    D^w_i H_i (H_i the held chain's, w_i the cumulative share, w_k = 1), so the segment curves
    instead of kinking at s0 and its end, where the next body hangs, turns exactly as simulated."""
    for _, joints, weights in ragdoll.spine_segments:
        bend = quat.make_continuous(quat.mul(local[:, joints[0]], quat.conj(held[joints[0]])))
        bend = np.where(bend[..., :1] < 0, -bend, bend)
        cumulative_held = [held[joints[0]]]
        for joint in joints[1:]:
            cumulative_held.append(quat.mul(cumulative_held[-1], held[joint]))
        # Every joint of the segment at once (N, k, 4): the same elementwise arithmetic per joint.
        share = quat.slerp(quat.identity(bend.shape[:1])[:, None], bend[:, None], weights)
        cumulative = quat.mul(share, np.array(cumulative_held))
        previous = np.concatenate([quat.identity(bend.shape[:1])[:, None], cumulative[:, :-1]], axis=1)
        local[:, joints] = quat.mul(quat.conj(previous), cumulative)


# ---------------------------------------------------------------------------------------------
# The run loop


@dataclass(frozen=True)
class _Plan:
    """What one run steps through, all on the targets' clock (target frame 0 at time 0).

    targets: (K, nq) mocap qpos per target frame. The simulation starts at `start_offset` frames and
    samples at `sample_offsets` (frames, >= start_offset); step counts depend only on these numbers.
    hit: (MuJoCo body id, the impact) whose impulse the first step applies, or None.
    clock: the start's time in seconds on the caller's clock, for error messages.
    follow: (S, J, 4) the target's local rotations at the samples, for the joints the output takes
      from the mocap (Ragdoll.leaf_joints).
    assist: the root assist toward the targets' pelvis (balance.py), or None for pure PD.
    """

    targets: np.ndarray
    fps: float
    sample_offsets: np.ndarray
    start_offset: float
    gains: ServoGains
    hit: tuple[int, Impact] | None
    clock: float
    follow: np.ndarray
    assist: RootAssist | None = None


def _run(ws: Workspace, start: SimState, plan: _Plan) -> SimResult:
    """Step from `start` and sample at frame times."""
    model = ws.model
    _place_bodies(ws, start.held)
    _set_servos(ws, plan.gains)
    _set_limits(ws, start.qpos)
    model.opt.timestep = TIMESTEP
    data = _fresh(ws.sim_data)
    data.qpos[:] = start.qpos
    data.qvel[:] = start.qvel
    data.mocap_pos[0] = (0.0, 0.0, start.floor)
    if not (np.all(np.isfinite(data.qpos)) and np.all(np.isfinite(data.qvel))):
        raise SimulationError("the start state holds NaN or infinite values")
    mujoco.mj_forward(model, data)
    if plan.hit is not None:
        _check_hit_speed(model, data, *plan.hit)
    with _CapturedWarnings() as messages:
        return _step_and_sample(ws, start, plan, _Watch(ws, data, plan.clock, messages))


def _interp_rows(x: np.ndarray, table: np.ndarray) -> np.ndarray:
    """np.interp(x, arange(K), table[:, a]) for every column a at once, (len(x), A).

    The same arithmetic as numpy's interp (slope (y[j+1] - y[j]) / 1 times (x - j) plus y[j]; the end
    values outside 0..K-1 and at a sample point exactly), so the servo set-points stay bit-identical.
    """
    last = len(table) - 1
    if last < 1:
        return np.repeat(table[:1], len(x), axis=0)
    j = np.clip(np.floor(x), 0, last - 1).astype(int)
    out = (table[j + 1] - table[j]) * (x - j)[:, None] + table[j]
    exact = x == j
    out[exact] = table[j[exact]]
    out[x < 0] = table[0]
    out[x >= last] = table[last]
    return out


def _servo_setpoints(ws: Workspace, plan: _Plan, steps: int) -> np.ndarray:
    """Servo set-points for every step, (steps, nu): the target's hinge angles interpolated at the
    step's time plus (kv / kp) times its velocity (see the module docstring)."""
    hinges = plan.targets[:, ws.ragdoll.actuator_qpos]
    velocity = np.gradient(hinges, axis=0) * plan.fps if len(hinges) > 1 else np.zeros_like(hinges)
    step_frames = plan.start_offset + np.arange(steps) / (1.0 / plan.fps / TIMESTEP)
    ratio = np.full(ws.model.nu, plan.gains.damping_time)
    return _interp_rows(step_frames, hinges) + ratio * _interp_rows(step_frames, velocity)


def _step_and_sample(ws: Workspace, start: SimState, plan: _Plan, watch: _Watch) -> SimResult:
    """The stepping loop of _run: fixed step counts to each sample, explosion checks per sample."""
    model, data = ws.model, ws.sim_data
    frame_steps = 1.0 / plan.fps / TIMESTEP
    goals = [round((sample - plan.start_offset) * frame_steps) for sample in plan.sample_offsets]
    ctrl = _servo_setpoints(ws, plan, max(goals[-1], 1))
    step = 0
    data_ctrl = data.ctrl  # one view on MjData's buffer, not a new wrapper per step
    qpos_arr, qvel_arr = np.empty((len(goals), model.nq)), np.empty((len(goals), model.nv))
    contacts = np.zeros((len(goals), len(ws.ragdoll.bodies)), dtype=bool)
    helper = None
    if plan.assist is not None:
        helper = AssistController(plan.assist, model, int(ws.ragdoll.body_ids[0]), plan.targets[:, 0:7])
    for n, goal in enumerate(goals):
        while step < goal:
            data_ctrl[:] = ctrl[step]
            if helper is not None and step % ASSIST_STEPS == 0:
                helper.apply(data, plan.start_offset + step / frame_steps, plan.fps, start.floor)
            if step == 0:
                _first_step(model, data, plan.hit, watch)
            else:
                mujoco.mj_step(model, data)
            step += 1
        watch.check()
        qpos_arr[n] = data.qpos
        qvel_arr[n] = data.qvel
        contacts[n] = _floor_contacts(ws, data)
    rots, pelvis, com, com_vel = _samples(ws, qpos_arr, qvel_arr)
    held_rot = _body_rotations(ws, start.held.qpos)
    motion = _to_motion(ws.ragdoll, start.held, plan.follow, rots, pelvis, held_rot, fps=plan.fps)
    end = SimState(qpos=qpos_arr[-1].copy(), qvel=qvel_arr[-1].copy(), held=start.held, floor=start.floor)
    times = (np.asarray(plan.sample_offsets, dtype=float) - plan.start_offset) / plan.fps
    first = {body.name: float(times[np.argmax(contacts[:, k])])
             for k, body in enumerate(ws.ragdoll.bodies) if contacts[:, k].any()}  # fmt: skip
    return SimResult(motion=motion, frames=np.asarray(plan.sample_offsets, dtype=float), qpos=qpos_arr,
                     qvel=qvel_arr, com=com, com_velocity=com_vel, floor=start.floor, contacts=contacts,
                     first_contact=first, state=end,
                     assist_fraction=0.0 if helper is None else helper.largest_fraction)  # fmt: skip


def _floor_contacts(ws: Workspace, data: mujoco.MjData) -> np.ndarray:
    """(B,) which ragdoll bodies touch the floor now (a contact between the floor and their geom)."""
    touching = np.zeros(len(ws.ragdoll.bodies), dtype=bool)
    if data.ncon:
        geoms = data.contact.geom[: data.ncon]
        floor = ws.ragdoll.floor_geom
        other = np.where(geoms[:, 0] == floor, geoms[:, 1], geoms[:, 0])[np.any(geoms == floor, axis=1)]
        touching[ws.ragdoll.body_of_geom[other]] = True
    return touching


def _first_step(model: mujoco.MjModel, data: mujoco.MjData, hit: tuple[int, Impact] | None, watch: _Watch) -> None:
    """The impulse: force J / dt for this one step, at the hit body's centre of mass; the energy
    after it is the reference, since from here on nothing adds energy but the servos."""
    if hit is not None:
        body_id, impact = hit
        point = data.xipos[body_id].copy()
        force = np.asarray(impact.impulse) / TIMESTEP
        mujoco.mj_applyFT(model, data, force, np.zeros(3), point, body_id, data.qfrc_applied)
    mujoco.mj_step(model, data)
    data.qfrc_applied[:] = 0.0
    watch.check()
    mujoco.mj_forward(model, data)
    watch.arm_energy()


def _local_rotations(motion: Motion, frames: np.ndarray) -> np.ndarray:
    """(len(frames), J, 4) normalised local rotations; frames past the end hold the last."""
    return quat.normalize(motion.local_rot[np.clip(frames, 0, motion.num_frames - 1)])


# ---------------------------------------------------------------------------------------------
# Public API


def simulate_impact(
    ragdoll: Ragdoll,
    motion: Motion,
    impact: Impact,
    *,
    window: float = REACTION_WINDOW,
    gains: ServoGains = BC_GAINS,
    workspace: Workspace | None = None,
) -> SimResult:
    """BC: the impact lands at B = impact.frame; forward dynamics for `window` seconds.

    Weak servos (BC_GAINS: a fraction of CD's) pull toward the motion continuing after B. The
    result is sampled at the motion's frames ceil(B) .. C with C = round(B + window * fps); frames
    past the motion's end hold its last pose as the servo target. result.state is the state at C.
    """
    if not (np.isfinite(window) and window > 0):
        raise SimulationError(f"reaction window must be a positive number of seconds, got {window!r}")
    if not 0 <= impact.frame <= motion.num_frames - 1:
        raise SimulationError(
            f"impact on '{impact.bone}' at frame {impact.frame:g} is outside the motion's frames "
            f"0..{motion.num_frames - 1}"
        )
    body = ragdoll.body_for_bone(impact.bone)
    b = impact.frame
    c = round(b + window * motion.fps)
    reach = GROUND_SPAN * motion.fps
    table = _mocap_table(ragdoll, motion, b - reach - 1, max(b + reach + 1, c + 2))
    # Servo targets: the motion continuing after B (its last pose held past its end), on a clock
    # whose frame 0 is the table's first frame.
    extra = max(0, c + 2 - (table.first + len(table.qpos) - 1))
    plan = _Plan(
        targets=np.concatenate([table.qpos, np.repeat(table.qpos[-1:], extra, axis=0)]),
        fps=motion.fps,
        sample_offsets=np.arange(int(np.ceil(b)), c + 1, dtype=float) - table.first,
        start_offset=b - table.first,
        gains=gains,
        hit=(body.body_id, impact),
        clock=b / motion.fps,
        follow=_local_rotations(motion, np.arange(int(np.ceil(b)), c + 1)),
    )
    with _workspace(ragdoll, workspace) as ws:
        start = _state_from_table(ws, motion, b, table)
        result = _run(ws, start, plan)
    result.frames = result.frames + table.first
    return result


def _check_hit_speed(model: mujoco.MjModel, data: mujoco.MjData, body_id: int, impact: Impact) -> None:
    """Refuse an impact that would start the hit body faster than MAX_HIT_SPEED, naming the most
    this bone takes here. The speed is the impulse through the inverse mass matrix at the start
    pose (the whole ragdoll answers, so a hand weighs 1-2 kg, the head 11-18); `data` holds the start
    state after mj_forward, which factored that matrix."""
    jacobian = np.zeros((3, model.nv))
    mujoco.mj_jacBodyCom(model, data, jacobian, None, body_id)
    response = np.zeros((1, model.nv))
    mujoco.mj_solveM(model, data, response, (jacobian.T @ np.asarray(impact.impulse))[None])
    speed = float(np.linalg.norm(jacobian @ response[0]))
    if speed > MAX_HIT_SPEED:
        most = math.floor(impact.strength * MAX_HIT_SPEED / speed)  # rounded down: the figure named passes
        raise ImpactError(
            f"impact on '{impact.bone}' at frame {impact.frame:g}: {impact.strength:g} N·s would start that "
            f"body part at {speed:.1f} m/s; this bone takes at most {most:d} N·s here ({MAX_HIT_SPEED:g} m/s, "
            f"faster than a batted ball). Hit a heavier bone (chest, pelvis) for a harder push.",
            impact,
        )


def track(
    ragdoll: Ragdoll,
    start: SimState | Motion,
    target: Motion,
    duration: float,
    *,
    target_start: int = 0,
    start_frame: float = 0.0,
    gains: ServoGains = CD_GAINS,
    assist: RootAssist | None = None,
    workspace: Workspace | None = None,
) -> SimResult:
    """CD: PD tracking (Eq. 2) of `target` from frame `target_start` for `duration` seconds.

    assist: a root assist toward the target's pelvis that keeps the body up (balance.py); None
    (default) is the paper's pure PD tracking.

    start: a SimState (e.g. BC's end state) or a Motion, whose frame `start_frame` gives the state.
    Sampled at the target's frame times target_start .. target_start + round(duration * fps); the
    output's frames are numbered on the target's clock.
    """
    if not (np.isfinite(duration) and duration > 0):
        raise SimulationError(f"tracking duration must be a positive number of seconds, got {duration!r}")
    if not 0 <= target_start < target.num_frames:
        raise SimulationError(f"target start frame {target_start} is outside the target's {target.num_frames} frames")
    n = round(duration * target.fps)
    frames = np.clip(np.arange(target_start, target_start + n + 3), 0, target.num_frames - 1)
    plan = _Plan(
        targets=mocap_qpos(ragdoll, target, frames),
        fps=target.fps,
        sample_offsets=np.arange(0, n + 1, dtype=float),
        start_offset=0.0,
        gains=gains,
        hit=None,
        clock=target_start / target.fps,
        follow=_local_rotations(target, np.arange(target_start, target_start + n + 1)),
        assist=assist,
    )
    with _workspace(ragdoll, workspace) as ws:
        if isinstance(start, Motion):
            start = _state_from_table(ws, start, start_frame, _start_table(ragdoll, start, start_frame))
        _same_turns(ragdoll, plan.targets, start.qpos)
        result = _run(ws, start, plan)
    result.frames = result.frames + target_start
    return result
