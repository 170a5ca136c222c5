"""One run's own copy of the engine model, and what each run sets on it: body offsets, Eq. 2's servo
gains, hinge ranges.

A Ragdoll is immutable. What a run changes lives in a Workspace: a copy of the ragdoll's model and
its own MjData. Pass one Workspace per thread to reuse it; without one, each call makes its own.

Eq. 2 is MuJoCo's position actuator (torque = kp (ctrl - q) - kv q_dot), integrated implicitly
(`implicitfast`): stable at the model's timestep where torques computed in Python were not, and
faster. Gains scale with the mass each joint moves, so one setting, `stiffness` in N·m/rad per kg,
suits the neck and the hip alike: for the spine, neck and arms that is the body and everything below
it; for hip, knee and ankle the whole body, which a leg carries while its foot is planted (scaled by
the leg's own mass, a stance ankle sagged and the walker sank at once).
"""

from __future__ import annotations

import copy
import threading
from dataclasses import dataclass

import mujoco
import numpy as np

from ..model import quat
from ..model.arrays import FloatArray
from ..model.errors import SimulationError
from .anatomy import JOINT_GROUPS
from .joints import HeldPose
from .ragdoll import Ragdoll

CD_STIFFNESS = 100.0  # N·m/rad per kg moved (tuned on real walks: tracks within ~1 degree)


CD_DAMPING_TIME = 0.03  # kv / kp, seconds


BC_SERVO_FRACTION = 0.25  # BC servo gains as a fraction of CD's


START_OVERLAP = (
    0.01  # m: limbs starting further inside each other than this pass through the body (forward_passing_overlaps)
)
PASSING = 2  # the contact type bit of a geom let through the body: only the floor meets it


@dataclass(frozen=True)
class ServoGains:
    """Eq. 2's PD gains, per kg the joint moves (see mass_moved): kp = stiffness * group * mass
    (N·m/rad), kv = damping_time * kp (N·m·s/rad); `group` is the factor of the joint's group
    (anatomy.JOINT_GROUPS: legs = hips, knees, ankles; trunk = waist, back; arms; neck)."""

    stiffness: float = CD_STIFFNESS
    damping_time: float = CD_DAMPING_TIME
    legs: float = 1.0
    trunk: float = 1.0
    arms: float = 1.0
    neck: float = 1.0

    def group_factors(self) -> FloatArray:
        """Factors in anatomy.JOINT_GROUPS order."""
        return np.array([getattr(self, group) for group in JOINT_GROUPS], dtype=np.float64)


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
        self.hinge_joints = np.array([address[int(a)] for a in ragdoll.index.hinge_qpos], dtype=int)
        # the floor also meets limbs let through the body (forward_passing_overlaps), whose type bit is PASSING
        self.model.geom_conaffinity[ragdoll.index.floor_geom] |= PASSING
        self.sim_data = mujoco.MjData(self.model)
        self.kin_data = mujoco.MjData(self.model)
        self._busy = threading.Lock()

    def __enter__(self) -> Workspace:
        if not self._busy.acquire(blocking=False):
            raise SimulationError("this simulation workspace is in use by another run; give each thread its own")
        return self

    def __exit__(self, *exc: object) -> None:
        self._busy.release()


def workspace_for(ragdoll: Ragdoll, workspace: Workspace | None) -> Workspace:
    if workspace is None:
        return Workspace(ragdoll)
    if workspace.ragdoll is not ragdoll:
        raise SimulationError("the workspace was made for another ragdoll")
    return workspace


def reset_data(data: mujoco.MjData) -> mujoco.MjData:
    """A reused MjData put back into the state of a newly made one."""
    mujoco.mj_resetData(data.model, data)
    return data


def place_bodies(ws: Workspace, held: HeldPose) -> None:
    """Body offsets from the held frame: merged bones between two bodies (clavicles, helper bones)
    and animated bone lengths keep the start frame's values, so FK of the output matches MuJoCo."""
    ragdoll = ws.ragdoll
    joints = ragdoll.index.body_joints[1:]
    parent_joints = ragdoll.index.body_joints[ragdoll.index.body_parents[1:]]
    to_neutral = quat.mul(ragdoll.neutral_global_rot[parent_joints], quat.conj(held.global_rot[parent_joints]))
    ws.model.body_pos[ragdoll.index.body_ids[1:]] = quat.rotate(
        to_neutral, held.global_pos[joints] - held.global_pos[parent_joints]
    )


def servo_kp(ws: Workspace, gains: ServoGains) -> FloatArray:
    """(nu,) position-actuator stiffness kp = stiffness * group factor * mass moved."""
    return gains.stiffness * gains.group_factors()[ws.ragdoll.index.actuator_group] * ws.ragdoll.index.actuator_mass


def set_servos(ws: Workspace, gains: ServoGains, kp: FloatArray | None = None) -> None:
    """Position-actuator gains kp = stiffness * mass moved (or the given kp), kv = damping_time * kp."""
    model = ws.model
    kp = servo_kp(ws, gains) if kp is None else kp
    kv = kp * gains.damping_time
    model.actuator_gainprm[:, 0] = kp
    model.actuator_biasprm[:, 0] = 0.0
    model.actuator_biasprm[:, 1] = -kp
    model.actuator_biasprm[:, 2] = -kv


def forward_passing_overlaps(ws: Workspace, data: mujoco.MjData) -> None:
    """mj_forward on a run's start state, with limbs that start inside each other (contacts deeper
    than START_OVERLAP) let through the body for the run, the floor still under them: of each such
    pair, the second geom meets the floor and nothing else. A sitting body whose thighs the capture
    crosses deeper than the capsules allow was thrown half a metre up by them at a nudge. Every
    geom meets all as compiled before the contacts are read, so no run inherits an earlier one's."""
    model, floor = ws.model, ws.ragdoll.index.floor_geom
    body = np.arange(model.ngeom) != floor
    model.geom_contype[body], model.geom_conaffinity[body] = 1, 1
    mujoco.mj_forward(model, data)
    deep = [
        int(c.geom2) for c in data.contact[: data.ncon] if c.dist < -START_OVERLAP and floor not in (c.geom1, c.geom2)
    ]
    if deep:
        model.geom_contype[deep], model.geom_conaffinity[deep] = PASSING, 0
        mujoco.mj_forward(model, data)


def set_limits(ws: Workspace, qpos: FloatArray) -> None:
    """Hinge ranges for one run: the profile's, widened where the start pose lies beyond them, so
    the run starts in the mocap's pose. Clamped to the range instead, a limb swung away from where
    the mocap put it: a get-up's sitting hips, flexed 154 degrees, clamped to 120, put the legs 30 cm
    into the floor, and the contacts threw the body a metre up."""
    hinges = ws.ragdoll.index.hinge_qpos
    ws.model.jnt_range[ws.hinge_joints, 0] = np.minimum(ws.ragdoll.index.limit_lo, qpos[hinges])
    ws.model.jnt_range[ws.hinge_joints, 1] = np.maximum(ws.ragdoll.index.limit_hi, qpos[hinges])
