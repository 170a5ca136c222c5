"""Simulation: state from mocap, the impact, forward dynamics (BC) and PD tracking (CD, Eq. 2): the run loop.

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
- We add the target's velocity to Eq. 2: ctrl = theta_target + (kv / kp) theta_dot_target, which
  makes the torque kp (theta_target - theta) + kv (theta_dot_target - theta_dot). Eq. 2 as printed
  damps toward zero velocity and so lags a moving target by (kv / kp) theta_dot.
- The root is not actuated: nothing invisible holds the character up, so pure PD tracking, which
  has no balance feedback, falls over eventually; during CD a capped root assist may help
  (balance.py).
- Fixed timestep and step counts derived from frame numbers only: the same input gives bit-identical
  output. Sampling at the motion's frame times uses round(frame_interval / dt) steps per frame.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import mujoco
import numpy as np

from ..model import quat
from ..model.arrays import BoolArray, FloatArray
from ..model.ease import smootherstep
from ..model.errors import SimulationError
from ..model.impact import Impact
from ..model.skeleton import Motion
from .balance import ASSIST_STEPS, AssistController, RootAssist
from .contacts import GROUND_SPAN, floor_contacts, ground_from_table
from .joints import HeldPose, MocapTable, local_rotations, mocap_qpos, mocap_table, same_turns, to_motion
from .mjcf import TIMESTEP
from .ragdoll import Ragdoll
from .watch import CapturedWarnings, Watch, check_hit_speed
from .workspace import (
    BC_GAINS,
    CD_GAINS,
    ServoGains,
    Workspace,
    forward_passing_overlaps,
    place_bodies,
    reset_data,
    servo_kp,
    set_limits,
    set_servos,
    workspace_for,
)

REACTION_WINDOW = 0.25  # seconds, BC: about a human reaction time (paper: ~15 frames)


@dataclass
class SimState:
    """A ragdoll state to start or continue a simulation from."""

    qpos: FloatArray
    qvel: FloatArray
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
    frames: FloatArray
    qpos: FloatArray
    qvel: FloatArray
    com: FloatArray
    com_velocity: FloatArray
    floor: float
    contacts: BoolArray
    first_contact: dict[str, float]
    state: SimState
    assist_fraction: float = 0.0
    unpushed: SimResult | None = None  # simulate_push: the same BC run without the push

    @property
    def twin(self) -> SimResult:
        """The unpushed run (simulate_push), what a push is measured against; an error on a run
        made without it."""
        if self.unpushed is None:
            raise SimulationError("this BC run was made without its unpushed twin (simulate_push)")
        return self.unpushed

    @property
    def com_height(self) -> FloatArray:
        """(T,) the centre of mass's height above the run's floor."""
        return self.com[:, 2] - self.floor


def state_from_mocap(ragdoll: Ragdoll, motion: Motion, frame: float, workspace: Workspace | None = None) -> SimState:
    """Ragdoll state at a (possibly fractional) frame: pose from the rotations, velocity by central
    differences over one frame either side, so the character keeps the motion's momentum; and the
    ground height the mocap stands on there (see ground_level)."""
    table = _start_table(ragdoll, motion, frame)
    with workspace_for(ragdoll, workspace) as ws:
        return _state_from_table(ws, motion, frame, table)


def _start_table(ragdoll: Ragdoll, motion: Motion, frame: float) -> MocapTable:
    """The pose table a start state at `frame` reads: GROUND_SPAN and one frame either side."""
    if not (np.isfinite(frame) and 0 <= frame <= motion.num_frames - 1):
        raise SimulationError(f"frame {frame} is outside the motion's frames 0..{motion.num_frames - 1}")
    reach = GROUND_SPAN * motion.fps
    return mocap_table(ragdoll, motion, frame - reach - 1, frame + reach + 1)


def _state_from_table(ws: Workspace, motion: Motion, frame: float, table: MocapTable) -> SimState:
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
        qvel[ragdoll.index.hinge_dof] = (after[ragdoll.index.hinge_qpos] - before[ragdoll.index.hinge_qpos]) / span
    held = table.held(round(frame))
    floor = ground_from_table(ws, table, frame, held, GROUND_SPAN * motion.fps)
    return SimState(qpos=qpos, qvel=qvel, held=held, floor=floor)


def _samples(
    ws: Workspace, qpos: FloatArray, qvel: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Body rotations (N, B, 4), pelvis positions (N, 3), centre of mass and its velocity (N, 3)."""
    model = ws.model
    data = reset_data(ws.kin_data)
    ids = ws.ragdoll.index.body_ids
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


def _body_rotations(ws: Workspace, qpos: FloatArray) -> FloatArray:
    """(B, 4) the ragdoll bodies' rotations in the pose qpos (on the workspace's placed bodies)."""
    data = reset_data(ws.kin_data)
    data.qpos[:] = qpos
    mujoco.mj_kinematics(ws.model, data)
    return data.xquat[ws.ragdoll.index.body_ids].copy()


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
    ramp: (gains, seconds): the servos start with these gains' stiffness and reach `gains`' over that time.
    """

    targets: FloatArray
    fps: float
    sample_offsets: FloatArray
    start_offset: float
    gains: ServoGains
    hit: tuple[int, Impact] | None
    clock: float
    follow: FloatArray
    assist: RootAssist | None = None
    ramp: tuple[ServoGains, float] | None = None


def _run(ws: Workspace, start: SimState, plan: _Plan) -> SimResult:
    """Step from `start` and sample at frame times."""
    model = ws.model
    place_bodies(ws, start.held)
    set_servos(ws, plan.gains)
    set_limits(ws, start.qpos)
    model.opt.timestep = TIMESTEP
    data = reset_data(ws.sim_data)
    data.qpos[:] = start.qpos
    data.qvel[:] = start.qvel
    data.mocap_pos[0] = (0.0, 0.0, start.floor)
    if not (np.all(np.isfinite(data.qpos)) and np.all(np.isfinite(data.qvel))):
        raise SimulationError("the start state holds NaN or infinite values")
    forward_passing_overlaps(ws, data)
    if plan.hit is not None:
        check_hit_speed(model, data, *plan.hit)
    with CapturedWarnings() as messages:
        return _step_and_sample(ws, start, plan, Watch(ws, data, plan.clock, messages))


def _interp_rows(x: FloatArray, table: FloatArray) -> FloatArray:
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


def _servo_setpoints(ws: Workspace, plan: _Plan, steps: int) -> FloatArray:
    """Servo set-points for every step, (steps, nu): the target's hinge angles interpolated at the
    step's time plus (kv / kp) times its velocity (see the module docstring)."""
    hinges = plan.targets[:, ws.ragdoll.index.actuator_qpos]
    velocity = np.gradient(hinges, axis=0) * plan.fps if len(hinges) > 1 else np.zeros_like(hinges)
    step_frames = plan.start_offset + np.arange(steps) / (1.0 / plan.fps / TIMESTEP)
    ratio = np.full(ws.model.nu, plan.gains.damping_time)
    return _interp_rows(step_frames, hinges) + ratio * _interp_rows(step_frames, velocity)


def _step_and_sample(ws: Workspace, start: SimState, plan: _Plan, watch: Watch) -> SimResult:
    """The stepping loop of _run: fixed step counts to each sample, explosion checks per sample."""
    model, data = ws.model, ws.sim_data
    frame_steps = 1.0 / plan.fps / TIMESTEP
    goals = [round((sample - plan.start_offset) * frame_steps) for sample in plan.sample_offsets]
    ctrl = _servo_setpoints(ws, plan, max(goals[-1], 1))
    step = 0
    data_ctrl = data.ctrl  # one view on MjData's buffer, not a new wrapper per step
    qpos_arr, qvel_arr = np.empty((len(goals), model.nq)), np.empty((len(goals), model.nv))
    contacts = np.zeros((len(goals), len(ws.ragdoll.bodies)), dtype=bool)
    ramp = _GainRamp(ws, plan)
    helper = None
    if plan.assist is not None:
        helper = AssistController(plan.assist, model, int(ws.ragdoll.index.body_ids[0]), plan.targets[:, 0:7])
    for n, goal in enumerate(goals):
        while step < goal:
            data_ctrl[:] = ctrl[step]
            if step < ramp.end and step % ASSIST_STEPS == 0:
                ramp.apply(step)
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
        contacts[n] = floor_contacts(ws, data)
    rots, pelvis, com, com_vel = _samples(ws, qpos_arr, qvel_arr)
    held_rot = _body_rotations(ws, start.held.qpos)
    motion = to_motion(ws.ragdoll, start.held, plan.follow, rots, pelvis, held_rot, fps=plan.fps)
    end = SimState(qpos=qpos_arr[-1].copy(), qvel=qvel_arr[-1].copy(), held=start.held, floor=start.floor)
    times = (np.asarray(plan.sample_offsets, dtype=np.float64) - plan.start_offset) / plan.fps
    first = {body.name: float(times[np.argmax(contacts[:, k])])
             for k, body in enumerate(ws.ragdoll.bodies) if contacts[:, k].any()}  # fmt: skip
    return SimResult(motion=motion, frames=np.asarray(plan.sample_offsets, dtype=np.float64), qpos=qpos_arr,
                     qvel=qvel_arr, com=com, com_velocity=com_vel, floor=start.floor, contacts=contacts,
                     first_contact=first, state=end,
                     assist_fraction=0.0 if helper is None else helper.largest_fraction)  # fmt: skip


class _GainRamp:
    """The servos' stiffness raised from plan.ramp's gains' to plan.gains' along the smootherstep,
    set every ASSIST_STEPS steps (the assist's cadence: a few steps apart, the change per set is
    small) before `end`, 0 without a ramp; the last set is plan.gains' own. The damping stays
    plan.gains' damping_time times the stiffness throughout."""

    def __init__(self, ws: Workspace, plan: _Plan) -> None:
        self.ws, self.gains = ws, plan.gains
        self.steps = 0 if plan.ramp is None else max(1, round(plan.ramp[1] / TIMESTEP))
        self.end = 0 if plan.ramp is None else self.steps + ASSIST_STEPS
        if plan.ramp is not None:
            self.kp0, self.kp1 = servo_kp(ws, plan.ramp[0]), servo_kp(ws, plan.gains)

    def apply(self, step: int) -> None:
        if step >= self.steps:
            set_servos(self.ws, self.gains)
        else:
            set_servos(self.ws, self.gains, self.kp0 + (self.kp1 - self.kp0) * smootherstep(step / self.steps))


def _first_step(model: mujoco.MjModel, data: mujoco.MjData, hit: tuple[int, Impact] | None, watch: Watch) -> None:
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
    return _simulate_bc(ragdoll, motion, (impact,), window, gains, workspace)[0]


def simulate_push(
    ragdoll: Ragdoll,
    motion: Motion,
    impact: Impact,
    *,
    window: float = REACTION_WINDOW,
    workspace: Workspace | None = None,
) -> SimResult:
    """BC (simulate_impact) with its unpushed twin in result.unpushed: the same run from the same
    state with a push of no strength. The outcome rule measures a push's effect against the twin
    rather than against the mocap: BC's weak servos do not follow the mocap, so an unpushed body
    drifts from it by about as much as a 40 N·s push moves it (docs/measurements.md)."""
    bc, unpushed = _simulate_bc(ragdoll, motion, (impact, replace(impact, strength=0.0)), window, BC_GAINS, workspace)
    bc.unpushed = unpushed
    return bc


def _simulate_bc(
    ragdoll: Ragdoll,
    motion: Motion,
    impacts: tuple[Impact, ...],
    window: float,
    gains: ServoGains,
    workspace: Workspace | None,
) -> list[SimResult]:
    """simulate_impact for impacts on the same bone at the same frame: one start state and one
    table of targets."""
    impact = impacts[0]
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
    table = mocap_table(ragdoll, motion, b - reach - 1, max(b + reach + 1, c + 2))
    # Servo targets: the motion continuing after B (its last pose held past its end), on a clock
    # whose frame 0 is the table's first frame.
    extra = max(0, c + 2 - (table.first + len(table.qpos) - 1))
    follow = local_rotations(motion, np.arange(int(np.ceil(b)), c + 1))
    plans = [_Plan(
        targets=np.concatenate([table.qpos, np.repeat(table.qpos[-1:], extra, axis=0)]),
        fps=motion.fps,
        sample_offsets=np.arange(int(np.ceil(b)), c + 1, dtype=np.float64) - table.first,
        start_offset=b - table.first,
        gains=gains,
        hit=(body.body_id, hit),
        clock=b / motion.fps,
        follow=follow,
    ) for hit in impacts]  # fmt: skip
    with workspace_for(ragdoll, workspace) as ws:
        start = _state_from_table(ws, motion, b, table)
        results = [_run(ws, start, plan) for plan in plans]
    for result in results:
        result.frames = result.frames + table.first
    return results


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
    ramp: tuple[ServoGains, float] | None = None,
    workspace: Workspace | None = None,
) -> SimResult:
    """CD: PD tracking (Eq. 2) of `target` from frame `target_start` for `duration` seconds.

    assist: a root assist toward the target's pelvis that keeps the body up (balance.py); None
    (default) is the paper's pure PD tracking.
    ramp: (start gains, seconds): the servos stiffen from the start gains' stiffness to `gains`' over
    that time (None: `gains` from the first step, the paper's). From BC's weak servos, CD's stiff ones
    switched on at once catch a body landing on a foot in a frame (react.CD_RAMP).

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
        sample_offsets=np.arange(0, n + 1, dtype=np.float64),
        start_offset=0.0,
        gains=gains,
        hit=None,
        clock=target_start / target.fps,
        follow=local_rotations(target, np.arange(target_start, target_start + n + 1)),
        assist=assist,
        ramp=ramp,
    )
    with workspace_for(ragdoll, workspace) as ws:
        if isinstance(start, Motion):
            start = _state_from_table(ws, start, start_frame, _start_table(ragdoll, start, start_frame))
        same_turns(ragdoll, plan.targets, start.qpos)
        result = _run(ws, start, plan)
    result.frames = result.frames + target_start
    return result
