"""The ragdoll: a MuJoCo model built from any Skeleton and its joint roles (paper section 2.2, Table 1).

`build_ragdoll` is the one entry: the bodies laid out on the skeleton (bodies.py, from the tables in
anatomy.py), written as MJCF and compiled (mjcf.py), and the flat index arrays the joint model
(joints.py) and the run loop (simulate.py) read. The result is immutable; runs change only their own
Workspace (workspace.py).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import mujoco
import numpy as np

from ..model import quat
from ..model.arrays import FloatArray, IndexArray
from ..model.errors import SimulationError, SkeletonError
from ..model.rig import Rig
from ..model.roles import REQUIRED_ROLES, SIDES, part_of
from ..model.skeleton import Motion, Skeleton, forward_kinematics
from .anatomy import (
    GROUP_OF_PART,
    HINGE_NAMES,
    JOINT_GROUPS,
    RADII,
    TABLE1_TOTAL_MASS,
    HingeRange,
    JointLimits,
    resolve_profile,
)
from .bodies import (
    Geometry,
    Pose,
    RagdollBody,
    body_layout,
    find_leaf_joints,
    find_spine_segments,
    foot_point,
    mass_moved,
    neutral_pose,
    read_only,
    reference_pose,
    segment_end,
    with_hinges,
)
from .mjcf import compile_without_touching_pairs


@dataclass(frozen=True)
class JointIndex:
    """A ragdoll's flat index arrays, read-only: vectorised conversions between the skeleton, the
    bodies and MuJoCo's arrays index with them instead of looping over bodies. In body, hinge (the
    bodies' hinges in body order) or actuator order."""

    kinematic_joints: IndexArray  # skeleton joints FK must visit: body joints and their ancestors
    kinematic_levels: tuple[tuple[IndexArray, IndexArray], ...]  # those below the root, (joints, parents) by depth
    frame_quat: FloatArray  # (B, 4) joint frame (e1, e2, e3 as columns) per body
    hinge_body: IndexArray  # per hinge: its body, Euler slot, qpos and dof address, abduction sign
    hinge_slot: IndexArray
    hinge_qpos: IndexArray
    hinge_dof: IndexArray
    hinge_sign: FloatArray
    body_ids: IndexArray  # MuJoCo body id per ragdoll body
    body_joints: IndexArray  # skeleton joint per ragdoll body
    body_parents: IndexArray  # parent body per ragdoll body, the root's own index (0) for the root
    actuator_qpos: IndexArray  # qpos address of each actuator's joint
    actuator_mass: FloatArray  # mass each actuator's servo moves (mass_moved)
    actuator_group: IndexArray  # each actuator's index into JOINT_GROUPS
    limit_lo: FloatArray  # per hinge (hinge order), its range in radians
    limit_hi: FloatArray
    sole_geoms: IndexArray  # geom ids of the two feet's sole capsules
    floor_geom: int  # geom id of the floor plane
    body_of_geom: IndexArray  # per MuJoCo geom, the ragdoll body it belongs to (-1: the floor)
    dof_body: dict[int, str]  # body name per hinge dof address


@dataclass(frozen=True)
class Ragdoll:
    """A compiled ragdoll and its mapping to the skeleton; immutable after build_ragdoll.

    Simulations never write to `model`: each run copies what it changes per run (body offsets,
    servo gains) into its own Workspace (simulate.py), so runs on several threads do not interfere.

    limits: the profile's hinge ranges in degrees (JointLimits), the one source the model's joint
      ranges are made from (a run widens them to take in a start pose beyond them).
    neutral_global_rot (J, 4): the neutral pose, where every MuJoCo joint angle is zero and every
      body frame equals the world frame.
    body_of_joint (J,): the body each skeleton joint belongs to (index into bodies; joints above the
      pelvis, such as a ground root bone, map to the pelvis body).
    index: the flat index arrays the joint model and the run loop read (JointIndex).
    """

    model: mujoco.MjModel
    mjcf: str
    rig: Rig
    profile: str
    limits: dict[str, tuple[HingeRange, HingeRange, HingeRange]]
    total_mass: float
    bodies: tuple[RagdollBody, ...]
    neutral_global_rot: FloatArray
    body_of_joint: IndexArray
    compile_seconds: float
    leaf_joints: IndexArray  # merged joints with no body below them (toes, fingers, head, face)
    spine_segments: tuple[tuple[int, IndexArray, FloatArray], ...]  # (body, joints, weights): see find_spine_segments
    index: JointIndex

    @property
    def root(self) -> RagdollBody:
        return self.bodies[0]

    @property
    def skeleton(self) -> Skeleton:
        return self.rig.skeleton

    @property
    def roles(self) -> dict[str, str]:
        return self.rig.roles

    def body_for_bone(self, bone: str) -> RagdollBody:
        """The body a skeleton bone belongs to (a merged bone belongs to its ancestor's body)."""
        return self.bodies[int(self.body_of_joint[self.skeleton.index(bone)])]


def build_ragdoll(
    skeleton: Skeleton,
    roles: dict[str, str] | None = None,
    *,
    profile: str | JointLimits = "anatomical",
    total_mass: float = TABLE1_TOTAL_MASS,
    reference: Motion | None = None,
    reference_frame: int = 0,
) -> Ragdoll:
    """Build and compile the ragdoll of a skeleton.

    roles: role -> joint name; default `skeleton.roles` or `assign_roles(skeleton)`. A missing
      role raises SkeletonError.
    profile: "anatomical" (default), "paper" (Table 1's joint types and limits as printed), or the
      limits themselves (JointLimits, degrees, every joint kind of PROFILES' entries), e.g. a copy
      of ANATOMICAL_LIMITS with some ranges changed.
    total_mass: Table 1's masses scaled to this total (kg).
    reference: a motion of this skeleton whose frame `reference_frame` shows the character roughly
      standing; it fixes the character's forward and the twist of each segment in the neutral pose.
      Default: the skeleton's rest pose, which must then stand (head above pelvis above ankles);
      Bandai Namco and iClone rest poses do not, so pass a motion for them.
    """
    profile_name, limits = resolve_profile(profile)
    if not (np.isfinite(total_mass) and total_mass > 0):
        raise SimulationError(f"total mass must be a positive number of kg, got {total_mass!r}")
    rig = Rig.of(skeleton, roles)
    missing = [r for r in REQUIRED_ROLES if r not in rig.roles]
    if missing:
        raise SkeletonError(f"the ragdoll needs joints for the roles: {', '.join(missing)}")
    index = rig.joints
    bodies, body_of_joint = body_layout(rig)
    scale = total_mass / TABLE1_TOTAL_MASS
    bodies = [replace(b, mass=b.mass * scale) for b in bodies]
    ref = reference_pose(skeleton, index, reference, reference_frame)
    neutral_local = neutral_pose(skeleton, bodies, index, ref)
    npos, ngrot = forward_kinematics(skeleton, ref.root[None], neutral_local[None], ref.offsets[None])
    neutral = Pose(npos[0], ngrot[0])
    ends = [segment_end(skeleton, bodies, k, neutral, index) for k in range(len(bodies))]
    bodies = with_hinges(bodies, ends, neutral.pos, index, limits)
    size = max(ref.height, 0.5) / 1.75
    geometry = Geometry(
        pos=neutral.pos,
        ends=ends,
        radii=[RADII[part_of(b.name)] * size for b in bodies],
        hip_r=index["hip_r"],
        balls={side: foot_point(skeleton, index, side) for side in SIDES},
    )
    start = time.perf_counter()
    text, model = compile_without_touching_pairs(bodies, geometry)
    compile_seconds = time.perf_counter() - start
    bodies = [_with_addresses(b, model) for b in bodies]
    segments = find_spine_segments(skeleton, body_of_joint, index)
    return Ragdoll(
        model=model,
        mjcf=text,
        rig=rig,
        profile=profile_name,
        limits=dict(limits),
        total_mass=float(total_mass),
        bodies=tuple(bodies),
        neutral_global_rot=read_only(neutral.grot),
        body_of_joint=read_only(body_of_joint),
        compile_seconds=compile_seconds,
        leaf_joints=read_only(
            np.setdiff1d(
                find_leaf_joints(skeleton, bodies), np.concatenate([j for _, j, _ in segments] or [np.zeros(0)])
            )
        ),
        spine_segments=segments,
        index=_joint_index(skeleton, bodies, model),
    )


def _with_addresses(body: RagdollBody, model: mujoco.MjModel) -> RagdollBody:
    ids = [int(model.joint(f"{body.name}_{HINGE_NAMES[s]}").id) for s in body.hinges]
    return replace(
        body,
        body_id=int(model.body(body.name).id),
        qpos_adr=np.array([model.jnt_qposadr[i] for i in ids], dtype=int),
        dof_adr=np.array([model.jnt_dofadr[i] for i in ids], dtype=int),
    )


def _body_of_geom(bodies: list[RagdollBody], model: mujoco.MjModel) -> IndexArray:
    slot = {b.body_id: k for k, b in enumerate(bodies)}
    return np.array([slot.get(int(model.geom_bodyid[g]), -1) for g in range(model.ngeom)], dtype=int)


def _joint_index(skeleton: Skeleton, bodies: list[RagdollBody], model: mujoco.MjModel) -> JointIndex:
    needed: set[int] = set()
    for b in bodies:
        j = b.joint
        while j >= 0 and j not in needed:
            needed.add(j)
            j = int(skeleton.parents[j])
    rows = [
        (k, slot, adr, dof, b.hinge_sign[slot])
        for k, b in enumerate(bodies)
        for slot, adr, dof in zip(b.hinges, b.qpos_adr, b.dof_adr, strict=True)
    ]
    ranges = np.radians(np.concatenate([b.ranges for b in bodies[1:]])) if len(bodies) > 1 else np.zeros((0, 2))
    children = tuple(bodies)
    kinematic_joints = read_only(np.array(sorted(needed), dtype=int))
    return JointIndex(
        kinematic_joints=kinematic_joints,
        kinematic_levels=tuple(
            (read_only(level), read_only(skeleton.parents[level]))
            for level in (np.intersect1d(joints, kinematic_joints) for joints in skeleton.levels[1:])
            if len(level)
        ),
        frame_quat=read_only(np.array([quat.from_matrix(b.axes.T) for b in bodies])),
        hinge_body=read_only(np.array([r[0] for r in rows], dtype=int)),
        hinge_slot=read_only(np.array([r[1] for r in rows], dtype=int)),
        hinge_qpos=read_only(np.array([r[2] for r in rows], dtype=int)),
        hinge_dof=read_only(np.array([r[3] for r in rows], dtype=int)),
        hinge_sign=read_only(np.array([r[4] for r in rows], dtype=float)),
        body_ids=read_only(np.array([b.body_id for b in bodies], dtype=int)),
        body_joints=read_only(np.array([b.joint for b in bodies], dtype=int)),
        body_parents=read_only(np.array([max(b.parent, 0) for b in bodies], dtype=int)),
        actuator_qpos=read_only(model.jnt_qposadr[model.actuator_trnid[:, 0]].astype(int)),
        actuator_mass=read_only(
            np.concatenate([np.full(len(b.hinges), mass_moved(children, b)) for b in bodies[1:]] or [np.zeros(0)])
        ),
        actuator_group=read_only(
            np.concatenate(
                [np.full(len(b.hinges), JOINT_GROUPS.index(GROUP_OF_PART[part_of(b.name)])) for b in bodies[1:]]
                or [np.zeros(0)]
            ).astype(int)
        ),
        body_of_geom=read_only(_body_of_geom(bodies, model)),
        limit_lo=read_only(ranges[:, 0]),
        limit_hi=read_only(ranges[:, 1]),
        sole_geoms=read_only(np.array([int(model.geom(name).id) for name in ("ankle_l", "ankle_r")], dtype=int)),
        floor_geom=int(model.geom("floor").id),
        dof_body={int(adr): b.name for b in bodies for adr in b.dof_adr},
    )
