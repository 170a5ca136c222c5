"""The ragdoll: a MuJoCo model built from any Skeleton and its joint roles (paper section 2.2, Table 1).

One body per Table 1 segment, found through the joint roles (roles.py):

    pelvis  "Root" (10.3 kg), free joint          waist  "Lower body" (11.4), Waist joint
    back    "Upper body" (11.7), Back joint       neck   "Head" (8.4), Neck joint (head merged in)
    hip     "Thigh" (10.2), Femur joint           knee   "Calf" (6.0), Knee joint
    ankle   "Foot" (0.9), Ankle joint             shoulder "Upper arm" (8.1), Shoulder joint
    elbow   "Lower arm" (2.1), Elbow joint        wrist  "Hand" (0.6), Wrist joint

16 bodies, 97.6 kg. Every other bone (chest, clavicles, toes, fingers, twist, face and helper bones)
is merged into the body of its nearest ancestor that has one. On a short spine where `back` shares
the waist's joint, the two bodies are one with both masses.

Two joint profiles:
- "paper": Table 1 as printed: ball joints (waist, back, neck, ankle) with a swing cone and a twist
  range, hinges (femur, knee, shoulder, elbow, wrist) with a range. The printed femur range -85..0
  is read with flexion negative, i.e. our flexion 0..85 (the thigh swings forward, not back).
- "anatomical" (default): Table 1's masses and joint types with human ranges of motion (AAOS,
  see ANATOMICAL_LIMITS): knees and elbows single hinges, the ball joints three hinges each (the
  printed knee of -25..25 cannot walk).
A paper hinge follows only the flexion angle of the mocap's rotation (the Euler split below). Every
hinge carries a spring-damper (MuJoCo `stiffness` toward `springref` = the neutral pose, and
`damping`), scaled by the mass it moves, as the paper adds at the knee.

What we do differently, and why:
- The paper's Table 1 "Hip" ball joint belongs to the Root body, which is free here: the root stays
  unactuated and unconstrained so no invisible force holds the character up.
- Joint-angle zero is a *neutral standing pose*, not the BVH rest pose: Bandai Namco and iClone
  rest poses lie bones along arbitrary axes, where limits measured from rest would mean nothing.
  The neutral pose is a reference frame (the rest pose by default, or a frame of a motion) with
  every segment swung by its smallest rotation to stand straight: spine and head up, legs and arms
  down, feet forward. Each body's frame is the world frame in that pose.
- A ball joint is three hinges, not MuJoCo's `ball`: see JOINT LIMITS below.
- Capsules are sized from the skeleton's own bone lengths (radii scale with its height); the foot is
  a flat sole from under the heel to the toe tip, pitched as the mocap's standing foot is (median
  ankle -> ball-of-foot angle over the reference motion's stance frames), so a planted foot lies
  flat instead of rocking on its toe.
- Bodies whose capsules already touch in the neutral pose do not collide with each other (a mocap
  skeleton's capsules are guesses; pairs that overlap standing would shove each other apart).

JOINT LIMITS. MuJoCo's ball joint takes one `range`: a cone on the total rotation angle, with no
separate twist, and position actuators cannot drive a ball joint at all. So every servoed ball joint
is three hinges in the body frame, applied in the order flexion (axis e1), twist (e2 = the bone),
abduction (e3); intrinsically, local = R(e1, a) R(e2, b) R(e3, c). A swing cone of S degrees maps to
flexion and abduction ranges of +-S (a square around the cone, slightly more permissive on the
diagonals), a twist range maps to the twist hinge's range as is. Mocap rotations are split into
the three angles by this Euler decomposition, which is singular at a twist of +-90 degrees (only the
shoulder's and forearm's anatomical ranges come near it; there the flexion and abduction angles
swap freedom but the rotation is still rebuilt exactly).
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass, field, replace

import mujoco
import numpy as np

from ..model import quat
from ..model.errors import SimulationError, SkeletonError
from ..model.roles import REQUIRED_ROLES, assign_roles
from ..model.skeleton import Motion, Skeleton, forward_kinematics

# 1/600 s: the stiffest servo (an ankle carrying the body, kp ~ 10^4 N·m/rad on a foot of ~0.02
# kg·m²) has omega * dt ~ 1.2; MuJoCo integrates kp explicitly, so 1/300 s would blow up.
TIMESTEP = 1.0 / 600.0
TABLE1_TOTAL_MASS = 97.6
# Table 1 masses per body role (kg); left and right limbs each.
TABLE1_MASSES = {
    "pelvis": 10.3, "waist": 11.4, "back": 11.7, "neck": 8.4,
    "hip": 10.2, "knee": 6.0, "ankle": 0.9, "shoulder": 8.1, "elbow": 2.1, "wrist": 0.6,
}  # fmt: skip
BODY_ROLES = ("pelvis", "waist", "back", "neck") + tuple(
    f"{part}_{side}" for side in ("l", "r") for part in ("hip", "knee", "ankle", "shoulder", "elbow", "wrist")
)
# Hinge ranges in degrees per profile and joint kind: (flexion, twist, abduction); None = no hinge.
# Positive flexion moves the segment toward FLEX_TOWARD, positive abduction away from the body's
# midline (for the spine and neck: toward the character's left).
PAPER_LIMITS = {
    "waist": ((-45, 45), (-15, 15), (-45, 45)),
    "back": ((-5, 5), (-5, 5), (-5, 5)),
    "neck": ((-30, 30), (-8, 8), (-30, 30)),
    "hip": ((0, 85), None, None),
    "knee": ((-25, 25), None, None),
    "ankle": ((-85, 85), (-10, 10), (-85, 85)),
    "shoulder": ((-80, 85), None, None),
    "elbow": ((-15, 45), None, None),
    "wrist": ((-60, 60), None, None),
}
# Normal active ranges of motion of adults, American Academy of Orthopaedic Surgeons, "Joint Motion:
# Method of Measuring and Recording" (1965), as tabulated in Norkin & White, "Measurement of Joint
# Motion" (5th ed., 2016), table of AAOS values. Rounded outward by up to 10 degrees where mocap
# routinely goes there (a run whose start pose lies beyond a limit widens that range for the run,
# simulate._set_limits). Per joint:
# - waist + back share the thoracolumbar spine (AAOS: flexion 80, extension 25, lateral bending 35,
#   rotation 45): lumbar-heavy flexion in the waist, most rotation in the back (White & Panjabi,
#   "Clinical Biomechanics of the Spine", 2nd ed. 1990: lumbar axial rotation is a few degrees).
# - neck: cervical spine flexion 45, extension 45, lateral bending 45, rotation 60 (+10, the head is
#   merged into the neck body, so its nod on the atlas is in this joint too).
# - hip: flexion 120, extension 30, abduction 45, adduction 30, internal and external rotation 45.
# - knee and elbow: single hinges, flexion 0-150 (AAOS knee 135, elbow 150; 150 for a deep squat),
#   no hyperextension (the limits are soft: a degree or two past 0 under load).
# - ankle: plantar flexion 50, inversion/eversion 35/15 about the foot's long axis (symmetric here,
#   35). Dorsiflexion (AAOS 20 from the foot square to the shin) and forefoot abduction (10) are
#   opened to 50 and 35: our zero is the standing foot, a crouch or a lunge in mocap reaches 40-50
#   there, and a start pose clamped 30 degrees short (as starts were then) put a toe 4 cm into
#   the floor and threw the body up (the demo's push from the front, during a lunge).
# - shoulder: flexion 180, extension 60, abduction 180, adduction 50 (cross-body), rotation 70/90
#   (symmetric here, 90: the twist hinge has no side-specific sign).
# - wrist: flexion 80, extension 70, radial/ulnar deviation 20/30; the forearm's pronation and
#   supination (80/80) happen here as the wrist's twist, the elbow being a single hinge.
ANATOMICAL_LIMITS = {
    "waist": ((-25, 55), (-20, 20), (-20, 20)),
    "back": ((-15, 35), (-30, 30), (-20, 20)),
    "neck": ((-50, 50), (-70, 70), (-45, 45)),
    "hip": ((-30, 120), (-45, 45), (-30, 45)),
    "knee": ((0, 150), None, None),
    "ankle": ((-55, 50), (-35, 35), (-35, 35)),
    "shoulder": ((-60, 180), (-90, 90), (-50, 180)),
    "elbow": ((0, 150), None, None),
    "wrist": ((-70, 80), (-80, 80), (-30, 30)),
}
PROFILES = {"paper": PAPER_LIMITS, "anatomical": ANATOMICAL_LIMITS}
# A profile's limits: per joint kind (Table 1 row, e.g. "knee"), the (flexion, twist, abduction)
# hinge ranges in degrees, None where the joint has no such hinge.
HingeRange = tuple[float, float] | None
JointLimits = Mapping[str, tuple[HingeRange, HingeRange, HingeRange]]
# Direction a segment moves on positive flexion, in the character's (forward, left, up) frame.
FLEX_TOWARD = {
    "waist": "forward", "back": "forward", "neck": "forward", "hip": "forward", "knee": "back",
    "ankle": "up", "shoulder": "forward", "elbow": "forward", "wrist": "forward",
}  # fmt: skip
# Capsule radius per body at 1.75 m tall (scaled with the skeleton's height).
RADII = {
    "pelvis": 0.09, "waist": 0.11, "back": 0.12, "neck": 0.085, "hip": 0.065, "knee": 0.05,
    "ankle": 0.035, "shoulder": 0.045, "elbow": 0.038, "wrist": 0.03,
}  # fmt: skip
# Passive spring-damper on every hinge (the paper adds them e.g. at the knee), per kg moved:
# damping N·m·s/rad/kg and stiffness N·m/rad/kg toward the neutral pose.
JOINT_DAMPING_PER_KG = 0.08
JOINT_STIFFNESS_PER_KG = 0.5
# Limits are soft constraints in MuJoCo; a time constant of 2.5 steps keeps overshoot to a few degrees.
LIMIT_SOLREF = (2.5 * TIMESTEP, 1.0)
HINGE_NAMES = ("flex", "twist", "abd")
# Servo stiffness groups (simulate.ServoGains), by Table 1 joint kind.
JOINT_GROUPS = ("legs", "trunk", "arms", "neck")
GROUP_OF_PART = {
    "hip": "legs", "knee": "legs", "ankle": "legs", "waist": "trunk", "back": "trunk",
    "shoulder": "arms", "elbow": "arms", "wrist": "arms", "neck": "neck",
}  # fmt: skip


def part_of(role: str) -> str:
    """'knee_l' -> 'knee'; centre roles are their own part."""
    return role[:-2] if role[-2:] in ("_l", "_r") else role


@dataclass(frozen=True)
class RagdollBody:
    """One ragdoll body and how it maps to the skeleton.

    joint: skeleton index of the joint whose rotation moves this body (the role's joint).
    parent: index into Ragdoll.bodies, -1 for the root (pelvis).
    roles: the roles whose segments this body carries (e.g. ("back",) or ("waist", "back")).
    members: skeleton joints merged into this body (the joint itself and descendants without a body).
    axes: (3, 3) rows e1 (flexion), e2 (twist, along the bone), e3 (abduction), right-handed, in the
      body frame (= world axes in the neutral pose).
    hinges: per hinge kept by the profile, its Euler slot 0/1/2; hinge_sign flips abduction so that
      positive means away from the midline.
    """

    name: str
    joint: int
    parent: int
    roles: tuple[str, ...]
    members: list[int]
    mass: float
    axes: np.ndarray
    hinges: tuple[int, ...] = ()
    hinge_sign: np.ndarray = field(default_factory=lambda: np.ones(3))
    ranges: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    body_id: int = -1
    qpos_adr: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    dof_adr: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    subtree_mass: float = 0.0


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
    The remaining arrays are flat indices for vectorised conversions, in body or actuator order.
    """

    model: mujoco.MjModel
    mjcf: str
    skeleton: Skeleton
    roles: dict[str, str]
    profile: str
    limits: dict[str, tuple[HingeRange, HingeRange, HingeRange]]
    total_mass: float
    bodies: tuple[RagdollBody, ...]
    neutral_global_rot: np.ndarray
    body_of_joint: np.ndarray
    compile_seconds: float
    kinematic_joints: np.ndarray  # skeleton joints FK must visit: body joints and their ancestors
    kinematic_levels: tuple[tuple[np.ndarray, np.ndarray], ...]  # those below the root, (joints, parents) by depth
    frame_quat: np.ndarray  # (B, 4) joint frame (e1, e2, e3 as columns) per body
    hinge_body: np.ndarray  # per hinge: its body, Euler slot, qpos and dof address, abduction sign
    hinge_slot: np.ndarray
    hinge_qpos: np.ndarray
    hinge_dof: np.ndarray
    hinge_sign: np.ndarray
    body_ids: np.ndarray  # MuJoCo body id per ragdoll body
    body_joints: np.ndarray  # skeleton joint per ragdoll body
    body_parents: np.ndarray  # parent body per ragdoll body, the root's own index (0) for the root
    actuator_qpos: np.ndarray  # qpos address of each actuator's joint
    actuator_mass: np.ndarray  # mass each actuator's servo moves (mass_moved)
    actuator_group: np.ndarray  # each actuator's index into JOINT_GROUPS
    limit_lo: np.ndarray  # per hinge (hinge order), its range in radians
    limit_hi: np.ndarray
    sole_geoms: np.ndarray  # geom ids of the two feet's sole capsules
    floor_geom: int  # geom id of the floor plane
    body_of_geom: np.ndarray  # per MuJoCo geom, the ragdoll body it belongs to (-1: the floor)
    dof_body: dict[int, str]  # body name per hinge dof address
    leaf_joints: np.ndarray  # merged joints with no body below them (toes, fingers, head, face)
    spine_segments: tuple[tuple[int, np.ndarray, np.ndarray], ...]  # (body, joints, weights): see _spine_segments

    @property
    def root(self) -> RagdollBody:
        return self.bodies[0]

    def body_for_bone(self, bone: str) -> RagdollBody:
        """The body a skeleton bone belongs to (a merged bone belongs to its ancestor's body)."""
        return self.bodies[int(self.body_of_joint[self.skeleton.index(bone)])]


def mass_moved(bodies: tuple[RagdollBody, ...], body: RagdollBody) -> float:
    """The mass a joint's servo moves: its body and everything below, except that a leg joint
    carries the whole body when its foot is planted (the tree hangs from the pelvis, but a
    standing character hangs from its feet)."""
    if part_of(body.name) in ("hip", "knee", "ankle"):
        return float(sum(b.mass for b in bodies))
    return body.subtree_mass


# ---------------------------------------------------------------------------------------------
# Geometry helpers


def _unit(v: np.ndarray) -> np.ndarray:
    return v / max(float(np.linalg.norm(v)), 1e-12)


def _rotation_between(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Smallest rotation (quaternion) taking direction u to direction v."""
    u, v = _unit(u), _unit(v)
    axis = np.cross(u, v)
    s = float(np.linalg.norm(axis))
    c = float(np.dot(u, v))
    if s < 1e-9:
        if c > 0:
            return quat.identity()
        # Opposite: any axis perpendicular to u.
        perp = np.cross(u, [1.0, 0.0, 0.0]) if abs(u[0]) < 0.9 else np.cross(u, [0.0, 1.0, 0.0])
        return quat.from_axis_angle(_unit(perp), np.pi)
    return quat.from_axis_angle(axis / s, np.arctan2(s, c))


def _tips(skeleton: Skeleton, joints: list[int], pos: np.ndarray, grot: np.ndarray) -> np.ndarray:
    """World positions of the joints and of their End Sites, (N, 3)."""
    pts = [pos[j] for j in joints]
    for j in joints:
        if j in skeleton.end_sites:
            pts.append(pos[j] + quat.rotate(grot[j], skeleton.end_sites[j]))
    return np.array(pts)


# ---------------------------------------------------------------------------------------------
# Body layout


def _body_layout(skeleton: Skeleton, roles: dict[str, str]) -> tuple[list[RagdollBody], np.ndarray]:
    """Bodies in parent-first order, and the body each skeleton joint belongs to."""
    index = {role: skeleton.index(name) for role, name in roles.items()}
    owner: dict[int, list[str]] = {}
    for role in BODY_ROLES:
        owner.setdefault(index[role], []).append(role)
    if index["pelvis"] not in owner or owner[index["pelvis"]][0] != "pelvis":
        raise SkeletonError("the pelvis role must have its own joint")
    body_joints = sorted(owner)  # skeleton order is parents first
    body_joints.remove(index["pelvis"])
    body_joints.insert(0, index["pelvis"])
    # Each joint belongs to the body of its nearest ancestor-or-self that has one.
    body_of_joint = np.zeros(skeleton.num_joints, dtype=int)
    slot = {j: k for k, j in enumerate(body_joints)}
    for j in range(skeleton.num_joints):
        a = j
        while a >= 0 and a not in slot:
            a = int(skeleton.parents[a])
        body_of_joint[j] = slot[a] if a >= 0 else 0
    bodies = []
    for k, j in enumerate(body_joints):
        names = tuple(owner[j])
        parent = -1 if k == 0 else int(body_of_joint[skeleton.parents[j]])
        if k > 0 and parent == k:
            raise SkeletonError(f"body '{names[0]}' ({skeleton.names[j]}) has no parent body")
        mass = sum(TABLE1_MASSES[part_of(r)] for r in names)
        members = [int(m) for m in np.flatnonzero(body_of_joint == k)]
        bodies.append(RagdollBody(names[0], j, parent, names, members, mass, np.eye(3)))
    # The pelvis sits below the waist: the other bodies must hang from the expected ones.
    for child, parent in (
        ("waist", "pelvis"),
        ("hip_l", "pelvis"),
        ("hip_r", "pelvis"),
        ("knee_l", "hip_l"),
        ("knee_r", "hip_r"),
        ("elbow_l", "shoulder_l"),
        ("elbow_r", "shoulder_r"),
    ):
        c = next(b for b in bodies if child in b.roles)
        p = next(b for b in bodies if parent in b.roles)
        if bodies[c.parent] is not p:
            raise SkeletonError(
                f"role '{child}' ({skeleton.names[c.joint]}) does not hang from role '{parent}' "
                f"({skeleton.names[p.joint]}); check the role overrides"
            )
    return bodies, body_of_joint


@dataclass(frozen=True)
class _Pose:
    """World joint positions (J, 3) and rotations (J, 4) of one pose."""

    pos: np.ndarray
    grot: np.ndarray


@dataclass(frozen=True)
class _Reference:
    """The reference pose (root position, local rotations, joint offsets), the stance foot pitch
    (radians) and the character's height (m)."""

    root: np.ndarray
    local: np.ndarray
    offsets: np.ndarray
    foot_pitch: float
    height: float


@dataclass(frozen=True)
class _Geometry:
    """Where the neutral pose puts the bodies: joint positions (J, 3), each body's segment end and
    capsule radius, the pelvis capsule's right-hip joint, and the ball-of-foot joint per side."""

    pos: np.ndarray
    ends: list[np.ndarray]
    radii: list[float]
    hip_r: int
    balls: dict[str, int]


# The character's (forward, left, up) unit vectors in a standing pose.
CharacterFrame = tuple[np.ndarray, np.ndarray, np.ndarray]


def _segment_end(
    skeleton: Skeleton, bodies: list[RagdollBody], k: int, pose: _Pose, index: dict[str, int]
) -> np.ndarray:
    """Where body k's capsule ends (world, in the given pose)."""
    pos, grot = pose.pos, pose.grot
    body = bodies[k]
    children = [b for b in bodies if b.parent == k]
    part = part_of(body.name)
    if part == "pelvis":
        return pos[index["hip_l"]]  # a capsule across the hips (its start is the right hip)
    if len(children) == 1 and part != "back":
        return pos[children[0].joint]
    if part == "back" or ("neck" in [c.name for c in children]):
        return pos[index["neck"]]
    # Leaf bodies (head, foot, hand): the farthest merged point (end sites included).
    tips = _tips(skeleton, body.members, pos, grot)
    far = tips[np.argmax(np.linalg.norm(tips - pos[body.joint], axis=1))]
    if np.linalg.norm(far - pos[body.joint]) > 1e-3:
        return far
    parent_dir = _unit(pos[body.joint] - pos[bodies[body.parent].joint])
    return pos[body.joint] + 0.08 * parent_dir


def _character_frame(pos: np.ndarray, index: dict[str, int]) -> CharacterFrame:
    """forward, left, up of a standing pose (world Z up; left from the right hip to the left hip)."""
    up = np.array([0.0, 0.0, 1.0])
    left = pos[index["hip_l"]] - pos[index["hip_r"]]
    left = left - np.dot(left, up) * up
    if np.linalg.norm(left) < 1e-6:
        left = pos[index["shoulder_l"]] - pos[index["shoulder_r"]]
        left = left - np.dot(left, up) * up
    left = _unit(left)
    forward = np.cross(left, up)
    return forward, left, up


def _foot_point(skeleton: Skeleton, index: dict[str, int], side: str) -> int:
    """The joint that marks the ball of the foot: the toe role, else the ankle's first child."""
    toe = index.get(f"toe_{side}")
    if toe is not None:
        return toe
    children = skeleton.children(index[f"ankle_{side}"])
    return children[0] if children else index[f"ankle_{side}"]


def _stance_pitch(skeleton: Skeleton, index: dict[str, int], positions: np.ndarray) -> float:
    """Angle below horizontal of the ankle -> ball-of-foot line while the foot stands, radians.

    positions: (T, J, 3) world joint positions of a standing or walking motion (or the rest pose);
    the stance frames are those where the ankle is within 1 cm of its lowest.
    """
    pitches = []
    for side in ("l", "r"):
        ankle, ball = index[f"ankle_{side}"], _foot_point(skeleton, index, side)
        if ball == ankle:
            continue
        a, b = positions[:, ankle], positions[:, ball]
        stance = a[:, 2] <= a[:, 2].min() + 0.01
        d = b[stance] - a[stance]
        pitches.append(np.arctan2(-d[:, 2], np.linalg.norm(d[:, :2], axis=1)))
    if not pitches:
        return np.radians(20.0)
    return float(np.clip(np.median(np.concatenate(pitches)), 0.0, np.radians(60.0)))


def _neutral_pose(skeleton: Skeleton, bodies: list[RagdollBody], index: dict[str, int], ref: _Reference) -> np.ndarray:
    """Local rotations (J, 4) of the reference pose with every segment swung to stand straight.

    Each body, parents first, turns by the smallest rotation that points its segment at its neutral
    direction (spine and head up, limbs down, feet forward and a little down); its twist stays.
    """
    local_rot = ref.local.copy()
    foot_pitch = ref.foot_pitch

    def fk() -> tuple[np.ndarray, np.ndarray]:
        p, r = forward_kinematics(skeleton, ref.root[None], local_rot[None], ref.offsets[None])
        return p[0], r[0]

    pos, grot = fk()
    forward, _, up = _character_frame(pos, index)
    down = -up
    foot = _unit(forward * np.cos(foot_pitch) - up * np.sin(foot_pitch))
    aim = {"pelvis": up, "waist": up, "back": up, "neck": up, "hip": down, "knee": down,
           "ankle": foot, "shoulder": down, "elbow": down, "wrist": down}  # fmt: skip
    for k, body in enumerate(bodies):
        pos, grot = fk()
        end = _segment_end(skeleton, bodies, k, _Pose(pos, grot), index)
        if part_of(body.name) in ("pelvis", "waist"):
            end = pos[index["neck"]]  # upright torso: the spine from here to the neck points up
        if part_of(body.name) == "ankle":
            end = pos[_foot_point(skeleton, index, body.name[-1])]  # flat foot: ankle -> ball at stance pitch
        seg = end - pos[body.joint]
        if np.linalg.norm(seg) < 1e-6:
            continue
        turn = _rotation_between(seg, aim[part_of(body.name)])
        j = body.joint
        parent = skeleton.parents[j]
        new_global = quat.mul(turn, grot[j])
        parent_rot = grot[parent] if parent >= 0 else quat.identity()
        local_rot[j] = quat.normalize(quat.mul(quat.conj(parent_rot), new_global))
    return local_rot


def _joint_axes(part: str, side: str | None, bone: np.ndarray, frame: CharacterFrame) -> tuple[np.ndarray, float]:
    """Rows e1 (flexion), e2 (twist), e3 (abduction) and the abduction sign for one joint."""
    forward, left, up = frame
    toward = {"forward": forward, "back": -forward, "up": up}[FLEX_TOWARD[part]]
    e2 = _unit(bone)
    e1 = np.cross(e2, toward)
    if np.linalg.norm(e1) < 0.3:
        e1 = np.cross(e2, left)
    e1 = _unit(e1)
    e3 = np.cross(e1, e2)
    # Rotating the bone about e3 moves it toward -e1; positive abduction must move it outward.
    outward = -left if side == "r" else left
    sign = 1.0 if np.dot(-e1, outward) >= 0 else -1.0
    return np.stack([e1, e2, e3]), sign


# ---------------------------------------------------------------------------------------------
# MJCF


def _fmt(v) -> str:
    return " ".join(f"{float(x):.6g}" for x in np.atleast_1d(v))


def _mjcf(ragdoll_bodies: list[RagdollBody], geometry: _Geometry, excludes: list[tuple[str, str]]) -> str:
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
            # tracked walker turned up to 130 degrees within 2 s (balance.py).
            ball_z = pos[ball_joints[b.name[-1]], 2] - pos[b.joint, 2]
            flat = np.array([seg[0], seg[1], 0.0])
            heel = np.array([0.0, 0.0, ball_z]) - _unit(flat) * radii[k]
            toe = np.array([seg[0], seg[1], ball_z])
            lines.append(
                f'{indent}  <geom name="{b.name}" type="capsule" fromto="{_fmt(heel)} {_fmt(toe)}" '
                f'size="{radii[k]:.6g}" mass="{b.mass:.17g}" condim="4" friction="1 0.03 0.0001"/>'
            )
        elif np.linalg.norm(seg) < 2 * radii[k]:
            lines.append(
                f'{indent}  <geom name="{b.name}" type="sphere" pos="{_fmt(seg / 2)}" size="{radii[k]:.6g}" '
                f'mass="{b.mass:.17g}"/>'
            )
        else:
            # Pull the capsule's ends in by its radius so neighbours meet rather than overlap.
            inset = _unit(seg) * min(radii[k], 0.25 * np.linalg.norm(seg))
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
        f'    <position name="{b.name}_{HINGE_NAMES[slot]}" joint="{b.name}_{HINGE_NAMES[slot]}" kp="1" kv="0.1"/>'
        for b in ragdoll_bodies
        for slot in b.hinges
    ]
    exclude_xml = [f'    <exclude body1="{a}" body2="{b}"/>' for a, b in excludes]
    return "\n".join(
        [
            '<mujoco model="reactive_anim_ragdoll">',
            '  <compiler angle="degree" autolimits="true"/>',
            f'  <option timestep="{TIMESTEP:.17g}" integrator="implicitfast" gravity="0 0 -9.81"/>',
            "  <default>",
            f'    <joint armature="0.01" solreflimit="{_fmt(LIMIT_SOLREF)}" solimplimit="0.95 0.995 0.001"/>',
            '    <geom condim="3" friction="1 0.005 0.0001" solref="0.005 1"/>',
            "  </default>",
            "  <worldbody>",
            # The floor is a mocap body so each run can put it at the mocap's ground height.
            '    <body name="ground" mocap="true">',
            '      <geom name="floor" type="plane" size="0 0 1" friction="1 0.005 0.0001"/>',
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


# ---------------------------------------------------------------------------------------------
# Public API


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
    profile_name, limits = _resolve_profile(profile)
    if not (np.isfinite(total_mass) and total_mass > 0):
        raise SimulationError(f"total mass must be a positive number of kg, got {total_mass!r}")
    if roles is None:
        roles = dict(skeleton.roles) if skeleton.roles else assign_roles(skeleton)
    missing = [r for r in REQUIRED_ROLES if r not in roles]
    if missing:
        raise SkeletonError(f"the ragdoll needs joints for the roles: {', '.join(missing)}")
    index = {role: skeleton.index(name) for role, name in roles.items()}
    bodies, body_of_joint = _body_layout(skeleton, roles)
    scale = total_mass / TABLE1_TOTAL_MASS
    bodies = [replace(b, mass=b.mass * scale) for b in bodies]
    ref = _reference_pose(skeleton, index, reference, reference_frame)
    neutral_local = _neutral_pose(skeleton, bodies, index, ref)
    npos, ngrot = forward_kinematics(skeleton, ref.root[None], neutral_local[None], ref.offsets[None])
    neutral = _Pose(npos[0], ngrot[0])
    ends = [_segment_end(skeleton, bodies, k, neutral, index) for k in range(len(bodies))]
    bodies = _with_hinges(bodies, ends, neutral.pos, index, limits)
    size = max(ref.height, 0.5) / 1.75
    geometry = _Geometry(
        pos=neutral.pos,
        ends=ends,
        radii=[RADII[part_of(b.name)] * size for b in bodies],
        hip_r=index["hip_r"],
        balls={side: _foot_point(skeleton, index, side) for side in ("l", "r")},
    )
    start = time.perf_counter()
    text, model = _compile_without_touching_pairs(bodies, geometry)
    compile_seconds = time.perf_counter() - start
    bodies = [_with_addresses(b, model) for b in bodies]
    segments = _spine_segments(skeleton, body_of_joint, index)
    return Ragdoll(
        model=model,
        mjcf=text,
        skeleton=skeleton,
        roles=dict(roles),
        profile=profile_name,
        limits=dict(limits),
        total_mass=float(total_mass),
        bodies=tuple(bodies),
        neutral_global_rot=_frozen(neutral.grot),
        body_of_joint=_frozen(body_of_joint),
        compile_seconds=compile_seconds,
        leaf_joints=_frozen(
            np.setdiff1d(_leaf_joints(skeleton, bodies), np.concatenate([j for _, j, _ in segments] or [[]]))
        ),
        spine_segments=segments,
        **_index_arrays(skeleton, bodies, model),
    )


def _parent(skeleton: Skeleton, joint: int) -> int:
    return int(skeleton.parents[joint])


def _leaf_joints(skeleton: Skeleton, bodies: list[RagdollBody]) -> np.ndarray:
    """Joints without a body that have no body below them: they move nothing the simulation sees, so
    the output takes their rotations from the mocap (toes, fingers, head, face)."""
    body_joints = {b.joint for b in bodies}
    carries = set()  # joints on the way to a body: their rotation places the bodies below
    for j in body_joints:
        p = int(skeleton.parents[j])
        while p >= 0 and p not in carries:
            carries.add(p)
            p = int(skeleton.parents[p])
    return np.array([j for j in range(skeleton.num_joints) if j not in body_joints | carries], dtype=int)


def _spine_segments(
    skeleton: Skeleton, body_of_joint: np.ndarray, index: dict[str, int]
) -> tuple[tuple[int, np.ndarray, np.ndarray], ...]:
    """How the trunk's and the neck's bends are shared among the skeleton's joints.

    The ragdoll bends the trunk at the waist and back bodies and the neck at one, while skeletons
    have two to four spine joints (pelvis to neck) and one to three neck joints, plus the head's own
    nod (neck to head, the head merged into the neck body). Per spine body: its joints along that
    path and the cumulative share of the body's bend each joint carries, by bone length (a longer
    bone bends more, as vertebrae add up; the head counts as long as the neck).
    """
    segments = []
    for first, last, after in (
        (index["waist"], _parent(skeleton, index["neck"]), index["neck"]),
        (index["neck"], index["head"], None),
    ):
        path = [last]
        while path[-1] != first and path[-1] >= 0:
            path.append(int(skeleton.parents[path[-1]]))
        if path[-1] != first:
            continue  # the head or neck is not below: nothing to share
        joints = np.array(path[::-1])  # first ... last
        ends = [*joints[1:], after] if after is not None else list(joints[1:])
        lengths = np.array([np.linalg.norm(skeleton.offsets[c]) for c in ends])
        if after is None:  # the head: as long as the neck before it
            lengths = np.append(lengths, lengths[-1] if len(lengths) else 1.0)
        owner = body_of_joint[joints]
        for k in dict.fromkeys(owner.tolist()):
            mine = owner == k
            share = lengths[mine]
            total = float(share.sum())
            weights = np.cumsum(share) / total if total > 0 else np.arange(1, mine.sum() + 1) / mine.sum()
            if mine.sum() > 1:
                segments.append((int(k), _frozen(joints[mine]), _frozen(weights)))
    return tuple(segments)


def _resolve_profile(profile: str | JointLimits) -> tuple[str, JointLimits]:
    """(name, limits) of a profile given by name or as limits; limits must name every joint kind."""
    if isinstance(profile, str):
        if profile not in PROFILES:
            raise SimulationError(f"unknown ragdoll profile '{profile}'; profiles are: {', '.join(PROFILES)}")
        return profile, PROFILES[profile]
    missing = [part for part in TABLE1_MASSES if part != "pelvis" and part not in profile]
    if missing:
        raise SimulationError(f"the ragdoll's joint limits lack the joints: {', '.join(missing)}")
    for part, ranges in profile.items():
        if len(ranges) != 3 or any(r is not None and not r[0] <= r[1] for r in ranges):
            raise SimulationError(f"joint limits for '{part}' must be three (low, high) ranges or None, got {ranges!r}")
    return "custom", profile


def _reference_pose(
    skeleton: Skeleton, index: dict[str, int], reference: Motion | None, reference_frame: int
) -> _Reference:
    """Root position, local rotations and offsets of the reference pose, the stance foot pitch and
    the character's height (head over ankles); errors when the pose does not stand."""
    if reference is None:
        ref_root = skeleton.offsets[0].copy()
        ref_local = quat.identity((skeleton.num_joints,))
        ref_offsets = skeleton.offsets.copy()
    else:
        if reference.skeleton.names != skeleton.names:
            raise SkeletonError("the reference motion belongs to a different skeleton")
        if not 0 <= reference_frame < reference.num_frames:
            raise SimulationError(
                f"reference frame {reference_frame} is outside the motion's {reference.num_frames} frames"
            )
        ref_root = reference.root_pos[reference_frame].copy()
        ref_local = quat.normalize(reference.local_rot[reference_frame])
        ref_offsets = np.array(reference.joint_offsets()[reference_frame])
    if not (np.all(np.isfinite(ref_local)) and np.all(np.isfinite(ref_root))):
        raise SimulationError("the reference pose holds NaN or infinite values")
    pos, _ = forward_kinematics(skeleton, ref_root[None], ref_local[None], ref_offsets[None])
    pos = pos[0]
    height = pos[index["head"], 2] - min(pos[index["ankle_l"], 2], pos[index["ankle_r"], 2])
    if not (pos[index["head"], 2] > pos[index["pelvis"], 2] > max(pos[index["knee_l"], 2], pos[index["knee_r"], 2])):
        raise SkeletonError(
            "the reference pose does not stand (head above pelvis above knees, Z up); this skeleton's rest "
            "pose is not a standing pose, so pass a motion of it as `reference`"
        )
    stance = pos[None] if reference is None else reference.global_positions()
    return _Reference(ref_root, ref_local, ref_offsets, _stance_pitch(skeleton, index, stance), float(height))


def _with_hinges(
    bodies: list[RagdollBody], ends: list[np.ndarray], npos: np.ndarray, index: dict[str, int], limits: JointLimits
) -> list[RagdollBody]:
    """Bodies with their joint frames, the hinges the limits give them, and the mass each moves."""
    frame = _character_frame(npos, index)
    up = frame[2]
    out = [bodies[0]]
    for k, b in enumerate(bodies[1:], 1):
        part = part_of(b.name)
        side = b.name[-1] if b.name[-2:] in ("_l", "_r") else None
        bone = up if part in ("waist", "back", "neck") else ends[k] - npos[b.joint]
        axes, sign = _joint_axes(part, side, bone, frame)
        kinds = limits[part]
        hinges = tuple(slot for slot in range(3) if kinds[slot] is not None)
        ranges = np.array([kinds[slot] for slot in hinges], dtype=float).reshape(-1, 2)
        out.append(replace(b, axes=axes, hinge_sign=np.array([1.0, 1.0, sign]), hinges=hinges, ranges=ranges))
    # Mass each joint moves: its body and everything below (children come after their parents).
    subtree = [0.0] * len(out)
    for k in reversed(range(len(out))):
        subtree[k] += out[k].mass
        if out[k].parent >= 0:
            subtree[out[k].parent] += subtree[k]
    return [replace(b, subtree_mass=m) for b, m in zip(out, subtree, strict=True)]


def _compile_without_touching_pairs(bodies: list[RagdollBody], geometry: _Geometry) -> tuple[str, mujoco.MjModel]:
    """Compile once, find body pairs already touching in the neutral pose, exclude them, compile again."""
    model = _compile(_mjcf(bodies, geometry, []))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    excludes = set()
    for c in data.contact[: data.ncon]:
        b1, b2 = int(model.geom_bodyid[c.geom1]), int(model.geom_bodyid[c.geom2])
        if model.body_mocapid[b1] < 0 and model.body_mocapid[b2] < 0 and b1 > 0 and b2 > 0:
            excludes.add(tuple(sorted((model.body(b1).name, model.body(b2).name))))
    text = _mjcf(bodies, geometry, sorted(excludes))
    return text, _compile(text)


def _with_addresses(body: RagdollBody, model: mujoco.MjModel) -> RagdollBody:
    ids = [int(model.joint(f"{body.name}_{HINGE_NAMES[s]}").id) for s in body.hinges]
    return replace(
        body,
        body_id=int(model.body(body.name).id),
        qpos_adr=np.array([model.jnt_qposadr[i] for i in ids], dtype=int),
        dof_adr=np.array([model.jnt_dofadr[i] for i in ids], dtype=int),
    )


def _body_of_geom(bodies: list[RagdollBody], model: mujoco.MjModel) -> np.ndarray:
    slot = {b.body_id: k for k, b in enumerate(bodies)}
    return np.array([slot.get(int(model.geom_bodyid[g]), -1) for g in range(model.ngeom)], dtype=int)


def _frozen(array: np.ndarray) -> np.ndarray:
    array = np.array(array)
    array.flags.writeable = False
    return array


def _index_arrays(skeleton: Skeleton, bodies: list[RagdollBody], model: mujoco.MjModel) -> dict:
    """Ragdoll's flat index arrays (see its docstring), read-only."""
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
    arrays = {
        "kinematic_joints": np.array(sorted(needed), dtype=int),
        "frame_quat": np.array([quat.from_matrix(b.axes.T) for b in bodies]),
        "hinge_body": np.array([r[0] for r in rows], dtype=int),
        "hinge_slot": np.array([r[1] for r in rows], dtype=int),
        "hinge_qpos": np.array([r[2] for r in rows], dtype=int),
        "hinge_dof": np.array([r[3] for r in rows], dtype=int),
        "hinge_sign": np.array([r[4] for r in rows], dtype=float),
        "body_ids": np.array([b.body_id for b in bodies], dtype=int),
        "body_joints": np.array([b.joint for b in bodies], dtype=int),
        "body_parents": np.array([max(b.parent, 0) for b in bodies], dtype=int),
        "actuator_qpos": model.jnt_qposadr[model.actuator_trnid[:, 0]].astype(int),
        "actuator_mass": np.concatenate(
            [np.full(len(b.hinges), mass_moved(children, b)) for b in bodies[1:]] or [np.zeros(0)]
        ),
        "actuator_group": np.concatenate(
            [np.full(len(b.hinges), JOINT_GROUPS.index(GROUP_OF_PART[part_of(b.name)])) for b in bodies[1:]]
            or [np.zeros(0)]
        ).astype(int),
        "body_of_geom": _body_of_geom(bodies, model),
        "limit_lo": ranges[:, 0],
        "limit_hi": ranges[:, 1],
        "sole_geoms": np.array([int(model.geom(name).id) for name in ("ankle_l", "ankle_r")], dtype=int),
    }
    frozen: dict = {name: _frozen(a) for name, a in arrays.items()}
    frozen["dof_body"] = {int(adr): b.name for b in bodies for adr in b.dof_adr}
    frozen["floor_geom"] = int(model.geom("floor").id)
    frozen["kinematic_levels"] = tuple(
        (_frozen(level), _frozen(skeleton.parents[level]))
        for level in (np.intersect1d(joints, arrays["kinematic_joints"]) for joints in skeleton.levels[1:])
        if len(level)
    )
    return frozen
