"""The ragdoll as MuJoCo's model text (MJCF), with every solver setting named here, and its compilation.

- The root is a free joint, not Table 1's "Hip" ball joint: it stays unactuated and unconstrained,
  so no invisible force holds the character up.
- Every servoed joint is one to three hinges (joints.py says why), each with a position actuator
  whose gains each run sets (workspace.set_servos).
- The floor is a mocap body, so each run can put it at the mocap's ground height (contacts.py).
- Bodies whose capsules already touch in the neutral pose do not collide with each other (a mocap
  skeleton's capsules are guesses; pairs that overlap standing would shove each other apart).
"""

from __future__ import annotations

import mujoco
import numpy as np
from numpy.typing import ArrayLike

from ..model.arrays import unit
from ..model.errors import SimulationError
from ..model.roles import part_of
from .anatomy import HINGE_NAMES, JOINT_DAMPING_PER_KG, JOINT_STIFFNESS_PER_KG
from .bodies import Geometry, RagdollBody

# The one simulation step. The servo gains and the contact and limit time constants are tuned at it;
# the stiffest servo (an ankle carrying the body, on a light foot) sets how short it must be.
TIMESTEP = 1.0 / 600.0
# Limits are soft constraints in MuJoCo; a time constant of 2.5 steps keeps overshoot to a few degrees.
LIMIT_SOLREF = (2.5 * TIMESTEP, 1.0)
# The rest of the solver's settings, each where MJCF puts it.
GRAVITY = (0.0, 0.0, -9.81)  # m/s², Z up
JOINT_ARMATURE = 0.01  # kg·m², inertia added to every hinge's own
LIMIT_SOLIMP = (0.95, 0.995, 0.001)  # joint limits: impedance 0.95 rising to 0.995 over 0.001 rad
CONTACT_SOLREF = (0.005, 1.0)  # contacts: time constant 5 ms, critically damped
# Sliding, torsional and rolling friction; contacts have 3 dimensions (sliding only), the soles 4.
FRICTION = (1.0, 0.005, 0.0001)
CONTACT_DIMENSIONS = 3
SOLE_FRICTION = (1.0, 0.03, 0.0001)  # torsional 3 cm: see the sole's geom in mjcf_text
SOLE_CONTACT_DIMENSIONS = 4
# Placeholder actuator gains: every run sets its own (workspace.set_servos).
ACTUATOR_KP, ACTUATOR_KV = 1.0, 0.1


def _fmt(v: ArrayLike) -> str:
    return " ".join(f"{float(x):.6g}" for x in np.atleast_1d(v))


def _mjcf(ragdoll_bodies: list[RagdollBody], geometry: Geometry, excludes: list[tuple[str, str]]) -> str:
    """MJCF text of the ragdoll in its neutral pose (body frames = world axes)."""
    pos, ends, radii = geometry.pos, geometry.ends, geometry.radii
    pelvis_hip_r, ball_joints = geometry.hip_r, geometry.balls
    children: dict[int, list[int]] = {}
    for k, b in enumerate(ragdoll_bodies):
        children.setdefault(b.parent, []).append(k)

    def body_xml(k: int, indent: str) -> list[str]:
        b = ragdoll_bodies[k]
        origin = pos[b.joint] if b.parent < 0 else pos[b.joint] - pos[ragdoll_bodies[b.parent].joint]
        lines = [f'{indent}<body name="{b.name}" pos="{_fmt(origin)}">']
        if b.parent < 0:
            lines.append(f'{indent}  <freejoint name="root"/>')
        for slot, sign, rng in zip(b.hinges, b.hinge_sign[list(b.hinges)], b.ranges, strict=True):
            axis = b.axes[slot] * sign
            damping = JOINT_DAMPING_PER_KG * b.subtree_mass
            stiffness = JOINT_STIFFNESS_PER_KG * b.subtree_mass
            lines.append(
                f'{indent}  <joint name="{b.name}_{HINGE_NAMES[slot]}" type="hinge" axis="{_fmt(axis)}" '
                f'range="{_fmt(rng)}" damping="{damping:.6g}" stiffness="{stiffness:.6g}" springref="0"/>'
            )
        seg = ends[k] - pos[b.joint]
        if part_of(b.name) == "pelvis":
            hip_r = pos[pelvis_hip_r] - pos[b.joint]
            lines.append(
                f'{indent}  <geom name="{b.name}" type="capsule" fromto="{_fmt(hip_r)} {_fmt(seg)}" '
                f'size="{radii[k]:.6g}" mass="{b.mass:.17g}"/>'
            )
        elif part_of(b.name) == "ankle":
            # A flat sole from under the heel to the toe tip: a capsule from the ankle to the toe
            # alone would stand on its tip and rock. Torsional friction (condim 4, 3 cm): a capsule
            # touches a plane at one or two points, about which it would spin freely, and a
            # tracked walker turned far off its heading within seconds (balance.py).
            ball_z = pos[ball_joints[b.name[-1]], 2] - pos[b.joint, 2]
            flat = np.array([seg[0], seg[1], 0.0])
            heel = np.array([0.0, 0.0, ball_z]) - unit(flat) * radii[k]
            toe = np.array([seg[0], seg[1], ball_z])
            lines.append(
                f'{indent}  <geom name="{b.name}" type="capsule" fromto="{_fmt(heel)} {_fmt(toe)}" '
                f'size="{radii[k]:.6g}" mass="{b.mass:.17g}" '
                f'condim="{SOLE_CONTACT_DIMENSIONS}" friction="{_fmt(SOLE_FRICTION)}"/>'
            )
        elif np.linalg.norm(seg) < 2 * radii[k]:
            lines.append(
                f'{indent}  <geom name="{b.name}" type="sphere" pos="{_fmt(seg / 2)}" size="{radii[k]:.6g}" '
                f'mass="{b.mass:.17g}"/>'
            )
        else:
            # Pull the capsule's ends in by its radius so neighbours meet rather than overlap.
            inset = unit(seg) * min(radii[k], 0.25 * np.linalg.norm(seg))
            start = inset
            stop = seg - inset * (1.0 if part_of(b.name) in ("wrist", "neck") else 0.5)
            lines.append(
                f'{indent}  <geom name="{b.name}" type="capsule" fromto="{_fmt(start)} {_fmt(stop)}" '
                f'size="{radii[k]:.6g}" mass="{b.mass:.17g}"/>'
            )
        for c in children.get(k, []):
            lines += body_xml(c, indent + "  ")
        lines.append(f"{indent}</body>")
        return lines

    actuators = [
        f'    <position name="{b.name}_{HINGE_NAMES[slot]}" joint="{b.name}_{HINGE_NAMES[slot]}" '
        f'kp="{_fmt(ACTUATOR_KP)}" kv="{_fmt(ACTUATOR_KV)}"/>'
        for b in ragdoll_bodies
        for slot in b.hinges
    ]
    exclude_xml = [f'    <exclude body1="{a}" body2="{b}"/>' for a, b in excludes]
    return "\n".join(
        [
            '<mujoco model="reactive_anim_ragdoll">',
            '  <compiler angle="degree" autolimits="true"/>',
            f'  <option timestep="{TIMESTEP:.17g}" integrator="implicitfast" gravity="{_fmt(GRAVITY)}"/>',
            "  <default>",
            f'    <joint armature="{_fmt(JOINT_ARMATURE)}" solreflimit="{_fmt(LIMIT_SOLREF)}" '
            f'solimplimit="{_fmt(LIMIT_SOLIMP)}"/>',
            f'    <geom condim="{CONTACT_DIMENSIONS}" friction="{_fmt(FRICTION)}" solref="{_fmt(CONTACT_SOLREF)}"/>',
            "  </default>",
            "  <worldbody>",
            # The floor is a mocap body so each run can put it at the mocap's ground height.
            '    <body name="ground" mocap="true">',
            f'      <geom name="floor" type="plane" size="0 0 1" friction="{_fmt(FRICTION)}"/>',
            "    </body>",
            *body_xml(0, "    "),
            "  </worldbody>",
            "  <contact>",
            *exclude_xml,
            "  </contact>",
            "  <actuator>",
            *actuators,
            "  </actuator>",
            "</mujoco>",
            "",
        ]
    )


def _compile(text: str) -> mujoco.MjModel:
    try:
        return mujoco.MjModel.from_xml_string(text)
    except ValueError as exc:  # MuJoCo reports XML and compile errors as ValueError
        raise SimulationError(f"MuJoCo could not compile the ragdoll: {exc}") from None


def compile_without_touching_pairs(bodies: list[RagdollBody], geometry: Geometry) -> tuple[str, mujoco.MjModel]:
    """Compile once, find body pairs already touching in the neutral pose, exclude them, compile again."""
    model = _compile(_mjcf(bodies, geometry, []))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    excludes: set[tuple[str, str]] = set()
    for c in data.contact[: data.ncon]:
        b1, b2 = int(model.geom_bodyid[c.geom1]), int(model.geom_bodyid[c.geom2])
        if model.body_mocapid[b1] < 0 and model.body_mocapid[b2] < 0 and b1 > 0 and b2 > 0:
            excludes.add(tuple(sorted((model.body(b1).name, model.body(b2).name))))
    text = _mjcf(bodies, geometry, sorted(excludes))
    return text, _compile(text)
