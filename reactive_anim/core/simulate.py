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
from the simulation; joints merged into a body (fingers, toes, clavicles, twist and face bones) and
joints above the pelvis keep their mocap local rotation from the start frame; later stages blend
the result back into mocap and bake it onto the character.

A Ragdoll's MuJoCo model is adjusted per run (body offsets to the start frame's merged bones and
actuator gains) and its MjData buffers are reused across runs (see _RagdollCache), so run one
simulation at a time per Ragdoll.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from . import quat
from .errors import SimulationError, SkeletonError
from .impact import Impact
from .ragdoll import TIMESTEP, Ragdoll, part_of
from .skeleton import Motion

REACTION_WINDOW = 0.25  # seconds, BC: about a human reaction time (paper: ~15 frames)
CD_STIFFNESS = 100.0  # N·m/rad per kg moved (tuned on real walks: tracks within ~1 degree)
CD_DAMPING_TIME = 0.03  # kv / kp, seconds
BC_SERVO_FRACTION = 0.25  # BC servo gains as a fraction of CD's
MAX_JOINT_SPEED = 500.0  # rad/s; muscles reach ~20, a hard hit on a 0.6 kg hand ~150, a numerical blow-up far more
MAX_BODY_SPEED = 30.0  # m/s; a sprinter runs at ~10
FLOOR_TOLERANCE = 0.25  # m a body origin may sink below the floor before it counts as fallen through
GROUND_SPAN = 0.25  # s either side of the start frame in which the stance sole finds the ground
ENERGY_ALLOWANCE_SPEED = 5.0  # m/s: energy beyond 1/2 M v^2 above the start counts as an explosion
_WARNINGS = ("mjWARN_BADQACC", "mjWARN_BADQVEL", "mjWARN_BADQPOS", "mjWARN_CNSTRFULL", "mjWARN_CONTACTFULL")


@dataclass
class HeldPose:
    """The mocap frame whose merged joints (and joints above the pelvis) stay as they are.

    local_rot (J, 4), offsets (J, 3), root_pos (3,): that frame of the input motion.
    """

    local_rot: np.ndarray
    offsets: np.ndarray
    root_pos: np.ndarray
    global_pos: np.ndarray | None = None
    global_rot: np.ndarray | None = None


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
    com, com_velocity: (T, 3) centre of mass and its velocity per sampled frame.
    state: the state at the last sampled frame, to continue from (C for BC).
    """

    motion: Motion
    frames: np.ndarray
    qpos: np.ndarray
    qvel: np.ndarray
    com: np.ndarray
    com_velocity: np.ndarray
    state: SimState


# ---------------------------------------------------------------------------------------------
# Per-ragdoll constants


@dataclass
class _RagdollCache:
    """What every run needs but depends only on the ragdoll: index arrays, masses, sole geoms and two
    reusable MjData. Allocating an MjData costs ~0.5 ms, more than a tenth of a BC window; a reused
    one is put back by mj_resetData, which is what the MjData constructor itself calls, so the
    results are the same bit for bit."""

    model: mujoco.MjModel
    sim_data: mujoco.MjData  # the stepped state of _run
    kin_data: mujoco.MjData  # kinematics only: ground level, samples
    body_ids: np.ndarray  # MuJoCo body id per ragdoll body
    body_joints: np.ndarray  # skeleton joint per ragdoll body
    body_parents: np.ndarray  # parent body per ragdoll body, the root's own index (0) for the root
    child_joints: np.ndarray  # bodies[1:]: their joints
    child_parents: np.ndarray  # bodies[1:]: index of the parent body
    child_parent_joints: np.ndarray  # bodies[1:]: the parent body's joint
    mass_per_actuator: np.ndarray  # mass_moved of each actuator's body
    act_adr: np.ndarray  # qpos address of each actuator's joint
    limit_adr: np.ndarray  # hinge qpos addresses with their limits in radians
    limit_lo: np.ndarray
    limit_hi: np.ndarray
    soles: np.ndarray  # geom ids of the two sole capsules
    total_mass: float
    warnings: np.ndarray  # mjtWarning index per name in _WARNINGS
    dof_body: dict[int, str]


def _cache(ragdoll: Ragdoll) -> _RagdollCache:
    """The ragdoll's constants, built on first use and kept on the Ragdoll (rebuilt if its model changes)."""
    cache = getattr(ragdoll, "_sim_cache", None)
    if cache is not None and cache.model is ragdoll.model:
        return cache
    model = ragdoll.model
    children = ragdoll.bodies[1:]
    limit_adr = [body.qpos_adr for body in children]
    limits = [np.radians(body.ranges) for body in children]
    cache = _RagdollCache(
        model=model,
        sim_data=mujoco.MjData(model),
        kin_data=mujoco.MjData(model),
        body_ids=np.array([b.body_id for b in ragdoll.bodies], dtype=int),
        body_joints=np.array([b.joint for b in ragdoll.bodies], dtype=int),
        body_parents=np.array([max(b.parent, 0) for b in ragdoll.bodies], dtype=int),
        child_joints=np.array([b.joint for b in children], dtype=int),
        child_parents=np.array([b.parent for b in children], dtype=int),
        child_parent_joints=np.array([ragdoll.bodies[b.parent].joint for b in children], dtype=int),
        mass_per_actuator=np.concatenate([np.full(len(b.hinges), mass_moved(ragdoll, b)) for b in children]),
        act_adr=_actuated_qpos(ragdoll),
        limit_adr=np.concatenate(limit_adr).astype(int) if limit_adr else np.zeros(0, dtype=int),
        limit_lo=np.concatenate([r[:, 0] for r in limits]) if limits else np.zeros(0),
        limit_hi=np.concatenate([r[:, 1] for r in limits]) if limits else np.zeros(0),
        soles=np.array([int(model.geom(name).id) for name in ("ankle_l", "ankle_r")], dtype=int),
        total_mass=float(np.sum(model.body_mass)),
        warnings=np.array([int(getattr(mujoco.mjtWarning, name)) for name in _WARNINGS], dtype=int),
        dof_body={int(adr): body.name for body in ragdoll.bodies for adr in body.dof_adr},
    )
    ragdoll._sim_cache = cache
    return cache


def _fresh(data: mujoco.MjData) -> mujoco.MjData:
    """A cached MjData put back into the state of a newly made one."""
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
    local_m = quat.to_matrix(local_rot[:, joints])
    pos = np.zeros((n, count, 3))
    rot_m = np.zeros((n, count, 3, 3))
    parents = ragdoll.skeleton.parents
    for k, j in enumerate(joints):
        p = parents[j]
        if p < 0:
            pos[:, j] = root_pos
            rot_m[:, j] = local_m[:, k]
        else:
            pos[:, j] = pos[:, p] + np.einsum("nab,nb->na", rot_m[:, p], offsets[:, j])
            rot_m[:, j] = rot_m[:, p] @ local_m[:, k]
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
        """Row k as a HeldPose, with arrays of its own (as _held_pose makes them)."""
        return HeldPose(local_rot=self.local_rot[k].copy(), offsets=np.array(self.offsets[k], dtype=float),
                        root_pos=self.root_pos[k].copy(), global_pos=self.global_pos[k].copy(),
                        global_rot=self.global_rot[k].copy())


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
    cache = _cache(ragdoll)
    joints, parents = cache.body_joints, cache.body_parents
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
    return _MocapPoses(qpos=qpos, local_rot=local_rot, offsets=offsets, root_pos=root_pos, global_pos=pos,
                       global_rot=grot)


def _held_pose(ragdoll: Ragdoll, motion: Motion, frame: int) -> HeldPose:
    local_rot = quat.normalize(motion.local_rot[frame])
    offsets = np.array(motion.joint_offsets()[frame], dtype=float)
    root_pos = motion.root_pos[frame].copy()
    pos, rot = _kinematics(ragdoll, root_pos[None], local_rot[None], offsets[None])
    return HeldPose(local_rot=local_rot, offsets=offsets, root_pos=root_pos, global_pos=pos[0], global_rot=rot[0])


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
    poses: _MocapPoses | None = None

    def at(self, frame: float) -> np.ndarray:
        return _interp_qpos(self.qpos, frame - self.first)

    def held(self, ragdoll: Ragdoll, motion: Motion, frame: int) -> HeldPose:
        """_held_pose(ragdoll, motion, frame), from the table's FK when the frame is in it."""
        k = frame - self.first
        if self.poses is not None and 0 <= k < len(self.qpos):
            return self.poses.held(k)
        return _held_pose(ragdoll, motion, frame)


def _mocap_table(ragdoll: Ragdoll, motion: Motion, lo: float, hi: float) -> _MocapTable:
    first = int(max(0, np.floor(lo)))
    last = int(min(motion.num_frames - 1, np.ceil(hi)))
    poses = _mocap_poses(ragdoll, motion, np.arange(first, last + 1))
    return _MocapTable(first, poses.qpos, poses)


def state_from_mocap(ragdoll: Ragdoll, motion: Motion, frame: float, _table: _MocapTable | None = None) -> SimState:
    """Ragdoll state at a (possibly fractional) frame: pose from the rotations, velocity by central
    differences over one frame either side, so the character keeps the motion's momentum; and the
    ground height the mocap stands on there (see ground_level)."""
    if not (np.isfinite(frame) and 0 <= frame <= motion.num_frames - 1):
        raise SimulationError(f"frame {frame} is outside the motion's frames 0..{motion.num_frames - 1}")
    reach = GROUND_SPAN * motion.fps
    table = _table or _mocap_table(ragdoll, motion, frame - reach - 1, frame + reach + 1)
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
    held = table.held(ragdoll, motion, int(round(frame)))
    return SimState(qpos=qpos, qvel=qvel, held=held, floor=_ground_level(ragdoll, table, frame, held, reach))


def ground_level(ragdoll: Ragdoll, motion: Motion, frame: float, span: float = GROUND_SPAN) -> float:
    """Height of the ground the mocap walks on near `frame`: the lowest point of the ragdoll's soles,
    per frame, within `span` seconds either side, and of those the median.

    Mocap floors are rarely at exactly z = 0 (and our soles are guesses), so the simulated floor is
    put where the soles touch rather than the character dropped or lifted onto z = 0.
    """
    reach = span * motion.fps
    table = _mocap_table(ragdoll, motion, frame - reach, frame + reach)
    return _ground_level(ragdoll, table, frame, table.held(ragdoll, motion, int(round(frame))), reach)


def _ground_level(ragdoll: Ragdoll, table: _MocapTable, frame: float, held: HeldPose, reach: float) -> float:
    _place_bodies(ragdoll, held)
    model = ragdoll.model
    cache = _cache(ragdoll)
    data = _fresh(cache.kin_data)
    soles = cache.soles
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
    # phases; but never above the start frame's lowest sole, so the start does not pop out of the floor.
    at_start = lowest[int(np.argmin(np.abs(numbers[rows] - round(frame))))]
    return float(min(np.median(lowest), at_start))


# ---------------------------------------------------------------------------------------------
# Model set-up per run


def _place_bodies(ragdoll: Ragdoll, held: HeldPose) -> None:
    """Body offsets from the held frame: merged bones between two bodies (clavicles, helper bones)
    and animated bone lengths keep the start frame's values, so FK of the output matches MuJoCo."""
    cache = _cache(ragdoll)
    joints, parent_joints, ids = cache.child_joints, cache.child_parent_joints, cache.body_ids[1:]
    to_neutral = quat.mul(ragdoll.neutral_global_rot[parent_joints], quat.conj(held.global_rot[parent_joints]))
    ragdoll.model.body_pos[ids] = quat.rotate(to_neutral, held.global_pos[joints] - held.global_pos[parent_joints])


def mass_moved(ragdoll: Ragdoll, body) -> float:
    """The mass a joint's servo moves: its body and everything below, except that a leg joint
    carries the whole body when its foot is planted (the tree hangs from the pelvis, but a
    standing character hangs from its feet)."""
    if part_of(body.name) in ("hip", "knee", "ankle"):
        return float(sum(b.mass for b in ragdoll.bodies))
    return body.subtree_mass


def _set_servos(ragdoll: Ragdoll, stiffness: float, damping_time: float) -> np.ndarray:
    """Position-actuator gains kp = stiffness * mass moved, kv = damping_time * kp; returns kv/kp per actuator."""
    model = ragdoll.model
    kp = stiffness * _cache(ragdoll).mass_per_actuator
    kv = kp * damping_time
    model.actuator_gainprm[:, 0] = kp
    model.actuator_biasprm[:, 0] = 0.0
    model.actuator_biasprm[:, 1] = -kp
    model.actuator_biasprm[:, 2] = -kv
    return np.full(model.nu, damping_time)


def _actuated_qpos(ragdoll: Ragdoll) -> np.ndarray:
    """qpos address of each actuator's joint, in actuator order."""
    return ragdoll.model.jnt_qposadr[ragdoll.model.actuator_trnid[:, 0]]


def _clamp_to_limits(ragdoll: Ragdoll, qpos: np.ndarray) -> np.ndarray:
    """Mocap beyond a profile's limits starts at the limit, so the first step does not snap it back."""
    cache = _cache(ragdoll)
    qpos = qpos.copy()
    qpos[cache.limit_adr] = np.clip(qpos[cache.limit_adr], cache.limit_lo, cache.limit_hi)
    return qpos


class _CapturedWarnings:
    """MuJoCo's warning text, caught for the duration of a run instead of printed and appended to
    MUJOCO_LOG.TXT in the working folder; the previous handler is restored afterwards. (The handler
    is process-wide: run simulations from one thread at a time.)"""

    def __enter__(self) -> list[str]:
        self.previous = mujoco.get_mju_user_warning()
        self.messages: list[str] = []
        mujoco.set_mju_user_warning(self.messages.append)
        return self.messages

    def __exit__(self, *exc) -> None:
        mujoco.set_mju_user_warning(self.previous)


class _Watch:
    """Explosion detection after each sampled frame; raises SimulationError naming time, body, quantity."""

    def __init__(self, ragdoll: Ragdoll, data: mujoco.MjData, t0: float, messages: list[str]):
        self.messages = messages
        self.ragdoll = ragdoll
        self.model = ragdoll.model
        self.data = data
        self.t0 = t0
        self.energy_limit = None
        self.floor = float(data.mocap_pos[0, 2])
        cache = _cache(ragdoll)
        self.body_ids = cache.body_ids
        self.dof_body = cache.dof_body
        self.warnings = cache.warnings
        self.mass = cache.total_mass

    def energy(self) -> float:
        """Kinetic + potential energy, computed on demand (cheaper than MuJoCo's per-step flag)."""
        mujoco.mj_energyPos(self.model, self.data)
        mujoco.mj_energyVel(self.model, self.data)
        return float(np.sum(self.data.energy))

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
        if hinge.size and hinge.max() > MAX_JOINT_SPEED:
            i = int(np.argmax(hinge)) + 6
            raise SimulationError(
                f"simulation exploded at t = {t:.4f} s: body '{self._dof_name(i)}' joint speed "
                f"{hinge.max():.1f} rad/s exceeds {MAX_JOINT_SPEED:g}"
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
        for name in _WARNINGS:
            w = d.warning[int(getattr(mujoco.mjtWarning, name))]
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
    ragdoll: Ragdoll, qpos: np.ndarray, qvel: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Body rotations (N, B, 4), pelvis positions (N, 3), centre of mass and its velocity (N, 3)."""
    model = ragdoll.model
    cache = _cache(ragdoll)
    data = _fresh(cache.kin_data)
    ids, root = cache.body_ids, int(cache.body_ids[0])
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


def _to_motion(ragdoll: Ragdoll, held: HeldPose, body_rot: np.ndarray, pelvis_pos: np.ndarray, fps: float) -> Motion:
    """Full-skeleton Motion from simulated body rotations; merged joints keep the held frame."""
    skeleton = ragdoll.skeleton
    n = len(body_rot)
    hpos, hrot = held.global_pos, held.global_rot
    local = np.broadcast_to(held.local_rot, (n,) + held.local_rot.shape).copy()
    cache = _cache(ragdoll)
    joints = cache.body_joints
    glob = quat.mul(body_rot, ragdoll.neutral_global_rot[joints])  # (N, B, 4)
    root = ragdoll.root
    parent = skeleton.parents[root.joint]
    if parent < 0:
        local[:, root.joint] = glob[:, 0]
        root_pos = pelvis_pos.copy()
    else:
        # Joints above the pelvis (a ground root bone) hold; the root moves so the pelvis lands right.
        local[:, root.joint] = quat.mul(quat.conj(hrot[parent]), glob[:, 0])
        root_pos = held.root_pos + (pelvis_pos - hpos[root.joint])
    # Every other body at once: its parent joint's rotation is the parent body's, carried through
    # the held merged bones between them.
    body_parent, parent_body_joint = cache.child_parents, cache.child_parent_joints
    parent_joint = skeleton.parents[joints[1:]]
    carry = quat.mul(quat.conj(hrot[parent_body_joint]), hrot[parent_joint])
    parent_rot = quat.mul(glob[:, body_parent], carry)
    local[:, joints[1:]] = quat.mul(quat.conj(parent_rot), glob[:, 1:])
    local = quat.make_continuous(quat.normalize(local))
    local_pos = np.broadcast_to(held.offsets, (n,) + held.offsets.shape).copy()
    return Motion(skeleton=skeleton, fps=fps, root_pos=root_pos, local_rot=local, local_pos=local_pos)


# ---------------------------------------------------------------------------------------------
# The run loop


def _run(
    ragdoll: Ragdoll,
    start: SimState,
    targets: np.ndarray,
    fps: float,
    sample_offsets: np.ndarray,
    start_offset: float,
    stiffness: float,
    damping_time: float,
    impulse: tuple[int, np.ndarray] | None,
    clock: float,
) -> SimResult:
    """Step from `start` and sample at frame times.

    targets: (K, nq) mocap qpos per target frame, target frame 0 at time 0 of the targets' clock;
    the simulation starts at `start_offset` frames on that clock and samples at `sample_offsets`
    (frames on that clock, >= start_offset). Step counts depend only on these numbers.
    """
    model = ragdoll.model
    _place_bodies(ragdoll, start.held)
    ratio = _set_servos(ragdoll, stiffness, damping_time)
    model.opt.timestep = TIMESTEP
    data = _fresh(_cache(ragdoll).sim_data)
    data.qpos[:] = _clamp_to_limits(ragdoll, start.qpos)
    data.qvel[:] = start.qvel
    data.mocap_pos[0] = (0.0, 0.0, start.floor)
    if not (np.all(np.isfinite(data.qpos)) and np.all(np.isfinite(data.qvel))):
        raise SimulationError("the start state holds NaN or infinite values")
    mujoco.mj_forward(model, data)
    with _CapturedWarnings() as messages:
        return _step_and_sample(ragdoll, data, start, targets, fps, sample_offsets, start_offset, ratio,
                                impulse, _Watch(ragdoll, data, clock, messages))


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


def _step_and_sample(
    ragdoll: Ragdoll,
    data: mujoco.MjData,
    start: SimState,
    targets: np.ndarray,
    fps: float,
    sample_offsets: np.ndarray,
    start_offset: float,
    ratio: np.ndarray,
    impulse: tuple[int, np.ndarray] | None,
    watch: _Watch,
) -> SimResult:
    """The stepping loop of _run: fixed step counts to each sample, explosion checks per sample."""
    model = ragdoll.model
    act_adr = _cache(ragdoll).act_adr
    # Servo set-points for every step, computed at once: the target's hinge angles interpolated at
    # the step's time plus (kv / kp) times its velocity (see the module docstring).
    frame_steps = 1.0 / fps / TIMESTEP
    goals = [int(round((sample - start_offset) * frame_steps)) for sample in sample_offsets]
    hinges = targets[:, act_adr]
    velocity = np.gradient(hinges, axis=0) * fps if len(hinges) > 1 else np.zeros_like(hinges)
    step_frames = start_offset + np.arange(max(goals[-1], 1)) / frame_steps
    ctrl = _interp_rows(step_frames, hinges) + ratio * _interp_rows(step_frames, velocity)
    step = 0
    data_ctrl = data.ctrl  # one view on MjData's buffer, not a new wrapper per step
    qpos_arr, qvel_arr = np.empty((len(goals), model.nq)), np.empty((len(goals), model.nv))
    for n, goal in enumerate(goals):
        while step < goal:
            data_ctrl[:] = ctrl[step]
            if step == 0:
                # The impulse: force J / dt for this one step, at the hit body's centre of mass.
                if impulse is not None:
                    body_id, force = impulse
                    point = data.xipos[body_id].copy()
                    mujoco.mj_applyFT(model, data, force, np.zeros(3), point, body_id, data.qfrc_applied)
                mujoco.mj_step(model, data)
                data.qfrc_applied[:] = 0.0
                watch.check()
                # Energy after the impulse is the reference: from here on nothing adds energy but the servos.
                mujoco.mj_forward(model, data)
                watch.arm_energy()
            else:
                mujoco.mj_step(model, data)
            step += 1
        watch.check()
        qpos_arr[n] = data.qpos
        qvel_arr[n] = data.qvel
    rots, pelvis, com, com_vel = _samples(ragdoll, qpos_arr, qvel_arr)
    motion = _to_motion(ragdoll, start.held, rots, pelvis, fps)
    end = SimState(qpos=qpos_arr[-1].copy(), qvel=qvel_arr[-1].copy(), held=start.held, floor=start.floor)
    return SimResult(motion=motion, frames=np.asarray(sample_offsets, dtype=float), qpos=qpos_arr, qvel=qvel_arr,
                     com=com, com_velocity=com_vel, state=end)


# ---------------------------------------------------------------------------------------------
# Public API


def simulate_impact(
    ragdoll: Ragdoll,
    motion: Motion,
    impact: Impact,
    window: float = REACTION_WINDOW,
    servo_fraction: float = BC_SERVO_FRACTION,
    stiffness: float = CD_STIFFNESS,
    damping_time: float = CD_DAMPING_TIME,
) -> SimResult:
    """BC: the impact lands at B = impact.frame; forward dynamics for `window` seconds.

    Weak servos (servo_fraction of CD's gains) pull toward the motion continuing after B. The
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
    c = int(round(b + window * motion.fps))
    reach = GROUND_SPAN * motion.fps
    table = _mocap_table(ragdoll, motion, b - reach - 1, max(b + reach + 1, c + 2))
    start = state_from_mocap(ragdoll, motion, b, _table=table)
    # Servo targets: the motion continuing after B (its last pose held past its end), on a clock
    # whose frame 0 is the table's first frame.
    extra = max(0, c + 2 - (table.first + len(table.qpos) - 1))
    targets = np.concatenate([table.qpos, np.repeat(table.qpos[-1:], extra, axis=0)])
    force = np.asarray(impact.impulse) / TIMESTEP
    result = _run(
        ragdoll,
        start,
        targets,
        motion.fps,
        np.arange(int(np.ceil(b)), c + 1, dtype=float) - table.first,
        b - table.first,
        stiffness * servo_fraction,
        damping_time,
        (body.body_id, force),
        clock=b / motion.fps,
    )
    result.frames = result.frames + table.first
    return result


def track(
    ragdoll: Ragdoll,
    start: SimState | Motion,
    target: Motion,
    duration: float,
    target_start: int = 0,
    start_frame: float = 0.0,
    stiffness: float = CD_STIFFNESS,
    damping_time: float = CD_DAMPING_TIME,
) -> SimResult:
    """CD: PD tracking (Eq. 2) of `target` from frame `target_start` for `duration` seconds.

    start: a SimState (e.g. BC's end state) or a Motion, whose frame `start_frame` gives the state.
    Sampled at the target's frame times target_start .. target_start + round(duration * fps); the
    output's frames are numbered on the target's clock.
    """
    if isinstance(start, Motion):
        start = state_from_mocap(ragdoll, start, start_frame)
    if not (np.isfinite(duration) and duration > 0):
        raise SimulationError(f"tracking duration must be a positive number of seconds, got {duration!r}")
    if not 0 <= target_start < target.num_frames:
        raise SimulationError(f"target start frame {target_start} is outside the target's {target.num_frames} frames")
    n = int(round(duration * target.fps))
    frames = np.clip(np.arange(target_start, target_start + n + 3), 0, target.num_frames - 1)
    targets = mocap_qpos(ragdoll, target, frames)
    result = _run(
        ragdoll,
        start,
        targets,
        target.fps,
        np.arange(0, n + 1, dtype=float),
        0.0,
        stiffness,
        damping_time,
        None,
        clock=target_start / target.fps,
    )
    result.frames = result.frames + target_start
    return result
