"""The ragdoll's bodies laid out on a skeleton, before any physics engine (paper section 2.2, Table 1).

One body per Table 1 segment, found through the joint roles (model/roles.py): pelvis (free), waist,
back, neck (head merged in), and per side hip, knee, ankle, shoulder, elbow, wrist. Every other bone
(chest, clavicles, toes, fingers, twist, face and helper bones) is merged into the body of its
nearest ancestor that has one. On a short spine where `back` shares the waist's joint, the two
bodies are one with both masses.

What we do differently, and why:
- Joint-angle zero is a *neutral standing pose*, not the BVH rest pose: Bandai Namco and iClone rest
  poses lie bones along arbitrary axes, where limits measured from rest would mean nothing. The
  neutral pose is a reference frame (the rest pose by default, or a frame of a motion) with every
  segment swung by its smallest rotation to stand straight: spine and head up, legs and arms down,
  feet forward. Each body's frame is the world frame in that pose.
- Each joint's frame (flexion, twist along the bone, abduction) comes from the character's own
  forward, left and up in that pose, so a limit means the same on every rig.
- Capsules are sized from the skeleton's own bone lengths (radii scale with its height); the foot is
  a flat sole from under the heel to the toe tip, pitched as the mocap's standing foot is (median
  ankle -> ball-of-foot angle over the reference motion's stance frames), so a planted foot lies
  flat instead of rocking on its toe.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import TypeVar

import numpy as np
import numpy.typing as npt

from ..model import quat
from ..model.arrays import FloatArray, IndexArray, unit
from ..model.errors import SimulationError, SkeletonError
from ..model.rig import Rig
from ..model.roles import SIDES, part_of, side_of
from ..model.skeleton import Motion, Skeleton, forward_kinematics
from .anatomy import BODY_ROLES, FLEX_TOWARD, TABLE1_MASSES, JointLimits


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
    axes: FloatArray
    hinges: tuple[int, ...] = ()
    hinge_sign: FloatArray = field(default_factory=lambda: np.ones(3))
    ranges: FloatArray = field(default_factory=lambda: np.zeros((0, 2)))
    body_id: int = -1
    qpos_adr: IndexArray = field(default_factory=lambda: np.zeros(0, dtype=int))
    dof_adr: IndexArray = field(default_factory=lambda: np.zeros(0, dtype=int))
    subtree_mass: float = 0.0


def mass_moved(bodies: tuple[RagdollBody, ...], body: RagdollBody) -> float:
    """The mass a joint's servo moves: its body and everything below, except that a leg joint
    carries the whole body when its foot is planted (the tree hangs from the pelvis, but a
    standing character hangs from its feet)."""
    if part_of(body.name) in ("hip", "knee", "ankle"):
        return float(sum(b.mass for b in bodies))
    return body.subtree_mass


def _rotation_between(u: FloatArray, v: FloatArray) -> FloatArray:
    """Smallest rotation (quaternion) taking direction u to direction v."""
    u, v = unit(u), unit(v)
    axis = np.cross(u, v)
    s = float(np.linalg.norm(axis))
    c = float(np.dot(u, v))
    if s < 1e-9:
        if c > 0:
            return quat.identity()
        # Opposite: any axis perpendicular to u.
        perp = np.cross(u, [1.0, 0.0, 0.0]) if abs(u[0]) < 0.9 else np.cross(u, [0.0, 1.0, 0.0])
        return quat.from_axis_angle(unit(perp), np.pi)
    return quat.from_axis_angle(axis / s, np.arctan2(s, c))


def _tips(skeleton: Skeleton, joints: list[int], pos: FloatArray, grot: FloatArray) -> FloatArray:
    """World positions of the joints and of their End Sites, (N, 3)."""
    pts = [pos[j] for j in joints]
    for j in joints:
        if j in skeleton.end_sites:
            pts.append(pos[j] + quat.rotate(grot[j], skeleton.end_sites[j]))
    return np.array(pts)


def body_layout(rig: Rig) -> tuple[list[RagdollBody], IndexArray]:
    """Bodies in parent-first order, and the body each skeleton joint belongs to."""
    skeleton, index = rig.skeleton, rig.joints
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
    bodies: list[RagdollBody] = []
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
class Pose:
    """World joint positions (J, 3) and rotations (J, 4) of one pose."""

    pos: FloatArray
    grot: FloatArray


@dataclass(frozen=True)
class _Reference:
    """The reference pose (root position, local rotations, joint offsets), the stance foot pitch
    (radians) and the character's height (m)."""

    root: FloatArray
    local: FloatArray
    offsets: FloatArray
    foot_pitch: float
    height: float


@dataclass(frozen=True)
class Geometry:
    """Where the neutral pose puts the bodies: joint positions (J, 3), each body's segment end and
    capsule radius, the pelvis capsule's right-hip joint, and the ball-of-foot joint per side."""

    pos: FloatArray
    ends: list[FloatArray]
    radii: list[float]
    hip_r: int
    balls: dict[str, int]


# The character's (forward, left, up) unit vectors in a standing pose.
CharacterFrame = tuple[FloatArray, FloatArray, FloatArray]


def segment_end(skeleton: Skeleton, bodies: list[RagdollBody], k: int, pose: Pose, index: dict[str, int]) -> FloatArray:
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
    parent_dir = unit(pos[body.joint] - pos[bodies[body.parent].joint])
    return pos[body.joint] + 0.08 * parent_dir


def _character_frame(pos: FloatArray, index: dict[str, int]) -> CharacterFrame:
    """forward, left, up of a standing pose (world Z up; left from the right hip to the left hip)."""
    up = np.array([0.0, 0.0, 1.0])
    left = pos[index["hip_l"]] - pos[index["hip_r"]]
    left = left - np.dot(left, up) * up
    if np.linalg.norm(left) < 1e-6:
        left = pos[index["shoulder_l"]] - pos[index["shoulder_r"]]
        left = left - np.dot(left, up) * up
    left = unit(left)
    forward = np.cross(left, up)
    return forward, left, up


def foot_point(skeleton: Skeleton, index: dict[str, int], side: str) -> int:
    """The joint that marks the ball of the foot: the toe role, else the ankle's first child."""
    toe = index.get(f"toe_{side}")
    if toe is not None:
        return toe
    children = skeleton.children(index[f"ankle_{side}"])
    return children[0] if children else index[f"ankle_{side}"]


def _stance_pitch(skeleton: Skeleton, index: dict[str, int], positions: FloatArray) -> float:
    """Angle below horizontal of the ankle -> ball-of-foot line while the foot stands, radians.

    positions: (T, J, 3) world joint positions of a standing or walking motion (or the rest pose);
    the stance frames are those where the ankle is within 1 cm of its lowest.
    """
    pitches: list[FloatArray] = []
    for side in SIDES:
        ankle, ball = index[f"ankle_{side}"], foot_point(skeleton, index, side)
        if ball == ankle:
            continue
        a, b = positions[:, ankle], positions[:, ball]
        stance = a[:, 2] <= a[:, 2].min() + 0.01
        d = b[stance] - a[stance]
        pitches.append(np.arctan2(-d[:, 2], np.linalg.norm(d[:, :2], axis=1)))
    if not pitches:
        return np.radians(20.0)
    return float(np.clip(np.median(np.concatenate(pitches)), 0.0, np.radians(60.0)))


def neutral_pose(skeleton: Skeleton, bodies: list[RagdollBody], index: dict[str, int], ref: _Reference) -> FloatArray:
    """Local rotations (J, 4) of the reference pose with every segment swung to stand straight.

    Each body, parents first, turns by the smallest rotation that points its segment at its neutral
    direction (spine and head up, limbs down, feet forward and a little down); its twist stays.
    """
    local_rot = ref.local.copy()
    foot_pitch = ref.foot_pitch

    def fk() -> tuple[FloatArray, FloatArray]:
        p, r = forward_kinematics(skeleton, ref.root[None], local_rot[None], ref.offsets[None])
        return p[0], r[0]

    pos, grot = fk()
    forward, _, up = _character_frame(pos, index)
    down = -up
    foot = unit(forward * np.cos(foot_pitch) - up * np.sin(foot_pitch))
    aim = {"pelvis": up, "waist": up, "back": up, "neck": up, "hip": down, "knee": down,
           "ankle": foot, "shoulder": down, "elbow": down, "wrist": down}  # fmt: skip
    for k, body in enumerate(bodies):
        pos, grot = fk()
        end = segment_end(skeleton, bodies, k, Pose(pos, grot), index)
        if part_of(body.name) in ("pelvis", "waist"):
            end = pos[index["neck"]]  # upright torso: the spine from here to the neck points up
        if part_of(body.name) == "ankle":
            end = pos[foot_point(skeleton, index, body.name[-1])]  # flat foot: ankle -> ball at stance pitch
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


def _joint_axes(part: str, side: str | None, bone: FloatArray, frame: CharacterFrame) -> tuple[FloatArray, float]:
    """Rows e1 (flexion), e2 (twist), e3 (abduction) and the abduction sign for one joint."""
    forward, left, up = frame
    toward = {"forward": forward, "back": -forward, "up": up}[FLEX_TOWARD[part]]
    e2 = unit(bone)
    e1 = np.cross(e2, toward)
    if np.linalg.norm(e1) < 0.3:
        e1 = np.cross(e2, left)
    e1 = unit(e1)
    e3 = np.cross(e1, e2)
    # Rotating the bone about e3 moves it toward -e1; positive abduction must move it outward.
    outward = -left if side == "r" else left
    sign = 1.0 if np.dot(-e1, outward) >= 0 else -1.0
    return np.stack([e1, e2, e3]), sign


def _parent(skeleton: Skeleton, joint: int) -> int:
    return int(skeleton.parents[joint])


def find_leaf_joints(skeleton: Skeleton, bodies: list[RagdollBody]) -> IndexArray:
    """Joints without a body that have no body below them: they move nothing the simulation sees, so
    the output takes their rotations from the mocap (toes, fingers, head, face)."""
    body_joints = {b.joint for b in bodies}
    carries: set[int] = set()  # joints on the way to a body: their rotation places the bodies below
    for j in body_joints:
        p = int(skeleton.parents[j])
        while p >= 0 and p not in carries:
            carries.add(p)
            p = int(skeleton.parents[p])
    return np.array([j for j in range(skeleton.num_joints) if j not in body_joints | carries], dtype=int)


def find_spine_segments(
    skeleton: Skeleton, body_of_joint: IndexArray, index: dict[str, int]
) -> tuple[tuple[int, IndexArray, FloatArray], ...]:
    """How the trunk's and the neck's bends are shared among the skeleton's joints.

    The ragdoll bends the trunk at the waist and back bodies and the neck at one, while skeletons
    have two to four spine joints (pelvis to neck) and one to three neck joints, plus the head's own
    nod (neck to head, the head merged into the neck body). Per spine body: its joints along that
    path and the cumulative share of the body's bend each joint carries, by bone length (a longer
    bone bends more, as vertebrae add up; the head counts as long as the neck).
    """
    segments: list[tuple[int, IndexArray, FloatArray]] = []
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
            count = int(mine.sum())
            weights = np.cumsum(share) / total if total > 0 else np.arange(1, count + 1) / count
            if count > 1:
                segments.append((int(k), read_only(joints[mine]), read_only(weights)))
    return tuple(segments)


def reference_pose(
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


def with_hinges(
    bodies: list[RagdollBody], ends: list[FloatArray], npos: FloatArray, index: dict[str, int], limits: JointLimits
) -> list[RagdollBody]:
    """Bodies with their joint frames, the hinges the limits give them, and the mass each moves."""
    frame = _character_frame(npos, index)
    up = frame[2]
    out = [bodies[0]]
    for k, b in enumerate(bodies[1:], 1):
        part = part_of(b.name)
        side = side_of(b.name)
        bone = up if part in ("waist", "back", "neck") else ends[k] - npos[b.joint]
        axes, sign = _joint_axes(part, side, bone, frame)
        kinds = limits[part]
        hinges = tuple(slot for slot in range(3) if kinds[slot] is not None)
        ranges = np.array([kinds[slot] for slot in hinges], dtype=np.float64).reshape(-1, 2)
        out.append(replace(b, axes=axes, hinge_sign=np.array([1.0, 1.0, sign]), hinges=hinges, ranges=ranges))
    # Mass each joint moves: its body and everything below (children come after their parents).
    subtree = [0.0] * len(out)
    for k in reversed(range(len(out))):
        subtree[k] += out[k].mass
        if out[k].parent >= 0:
            subtree[out[k].parent] += subtree[k]
    return [replace(b, subtree_mass=m) for b, m in zip(out, subtree, strict=True)]


_Scalar = TypeVar("_Scalar", bound=np.generic)


def read_only(array: npt.NDArray[_Scalar]) -> npt.NDArray[_Scalar]:
    array = np.array(array)
    array.flags.writeable = False
    return array
