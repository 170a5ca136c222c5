"""Retargeting: a motion recorded on one skeleton, played by another whose bones map to the same roles.

Why: a reaction library is recorded on one skeleton, the animator's character is on another (a
CMU-style BVH, a Bandai Namco one, a Mixamo or Rigify rig, in T-pose or A-pose). Joint-local
rotations mean nothing across skeletons: each is relative to its own rest pose, and rest poses
differ (arms out or down, other proportions, extra spine joints).

What is transferred, per role joint (roles.py): the rotation the joint makes away from a common
reference, not away from its own rest pose. In the core's convention the rest pose has identity
rotations, so a joint's global rotation G is its rotation away from rest, in world axes. For each
role the alignment Q turns the target's bone onto the source's where both skeletons stand in a
reference pose (their rest poses, or a frame of a motion for a skeleton whose rest is no standing
body): its primary axis is the bone (from the role joint to the next role joint down the chain),
its secondary axis a body axis square to it (the left-right line for spine, legs and feet, the
front for the arms). So G_target = G_source Q: a T-pose arm maps onto an arms-down arm, and from
there every turn carries over. Each role bone is then swung onto the
source bone's actual direction (which also follows any extra joints the source bends along the
way), so bone directions match the source's exactly; twist comes from the source's joint. The
pelvis, the root body, takes the source's turn as it is.

Joints without a role (fingers, face, helper bones, extra spine joints) keep their rest pose, or
the target's own animation when a `base` motion is given. Root motion is scaled by the ratio of
leg lengths. Where a foot of the source is planted, the target's foot is held on the floor and in
place by a two-bone leg IK (hip and knee), eased in and out, so proportions that differ do not make
the foot float, sink or slide.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from ..model import quat
from ..model.arrays import BoolArray, FloatArray, IndexArray, unit
from ..model.errors import SkeletonError
from ..model.rig import Rig
from ..model.roles import SIDES
from ..model.skeleton import Motion, Skeleton, forward_kinematics
from .ik import arc, joint_path, two_bone_ik

# Each role's bone: from the role joint toward the next role down the chain (None: no role below,
# the bone points to the joint's own child or end site).
NEXT_ROLE = {
    "pelvis": "waist",
    "waist": "back",
    "back": "chest",
    "chest": "neck",
    "neck": "head",
    "head": None,
    **{f"hip_{s}": f"knee_{s}" for s in SIDES},
    **{f"knee_{s}": f"ankle_{s}" for s in SIDES},
    **{f"ankle_{s}": f"toe_{s}" for s in SIDES},
    **{f"toe_{s}": None for s in SIDES},
    **{f"clavicle_{s}": f"shoulder_{s}" for s in SIDES},
    **{f"shoulder_{s}": f"elbow_{s}" for s in SIDES},
    **{f"elbow_{s}": f"wrist_{s}" for s in SIDES},
    **{f"wrist_{s}": None for s in SIDES},
}
ARM_PARTS = ("clavicle", "shoulder", "elbow", "wrist")
LOWER_BODY = {"pelvis", *(f"{part}_{s}" for part in ("hip", "knee", "ankle", "toe") for s in SIDES)}

# A source foot is planted where its ankle is within this of its lowest height in the clip and it
# moves slower than this; the IK eases in and out over EASE_FRAMES frames.
PLANT_HEIGHT = 0.03  # metres, scaled by the source's leg length / 0.9 m
PLANT_SPEED = 0.2  # metres per second, likewise scaled (a planted foot of the sample walk barely slides)
EASE_FRAMES = 4
MIN_BONE = 1e-3  # metres: a shorter bone has no usable direction


@dataclass(frozen=True)
class RetargetMap:
    """How one skeleton's motion plays on another: joint pairs per role and the rest alignment."""

    source: Skeleton
    target: Skeleton
    roles: list[str]  # the roles both skeletons have, in the target's joint order
    source_joints: IndexArray  # (R,)
    target_joints: IndexArray  # (R,)
    source_child: IndexArray  # (R,) joint the source bone points to (-1: none)
    target_child: IndexArray  # (R,) likewise in the target
    align: FloatArray  # (R, 4) Q: target rest frame -> source rest frame
    scale: float  # target leg length / source leg length
    between: list[list[tuple[int, float]]]  # per role: target joints on its bone without a role, with shares


Pose = tuple[FloatArray, FloatArray]  # one frame's global positions (J, 3) and rotations (J, 4)


def rest_pose(skeleton: Skeleton) -> Pose:
    return skeleton.rest_positions(), quat.identity((skeleton.num_joints,))


def motion_pose(motion: Motion, frame: int = 0) -> Pose:
    """A frame of a motion as a reference pose (see retarget_map)."""
    pos, rot = motion.global_transforms()
    return pos[frame], rot[frame]


def uprightness(rig: Rig, positions: FloatArray) -> FloatArray:
    """How much each pose (positions (..., J, 3)) is a standing body: the least of how straight up
    the neck is over the pelvis and how straight down each leg hangs (1: exactly; arms anywhere)."""

    def down(top: str, bottom: str) -> FloatArray:
        v = positions[..., rig.joint(bottom), :] - positions[..., rig.joint(top), :]
        return -v[..., 2] / np.maximum(np.linalg.norm(v, axis=-1), 1e-12)

    legs = [down(f"hip_{s}", f"ankle_{s}") for s in SIDES]
    return np.minimum(-down("pelvis", "neck"), np.minimum(*legs))


def standing_rest(rig: Rig) -> bool:
    """The rest pose is a standing body, so it can line up bones with another skeleton's."""
    return bool(uprightness(rig, rig.skeleton.rest_positions()) > 0.9)


def reference_pose(motion: Motion, rig: Rig) -> Pose:
    """Where a motion's skeleton (the rig's) is lined up with another: its rest pose if that is a
    standing body (exact between skeletons of one body), else its most upright frame (a clip may
    start lying)."""
    if standing_rest(rig):
        return rest_pose(motion.skeleton)
    pos, rot = motion.global_transforms()
    best = int(np.argmax(uprightness(rig, pos)))
    return pos[best], rot[best]


def retarget_map(
    source_rig: Rig, target_rig: Rig, source_pose: Pose | None = None, target_pose: Pose | None = None
) -> RetargetMap:
    """The map from the source rig's skeleton to the target rig's.

    The poses (default: the rest poses) are where the two skeletons are lined up bone by bone: each
    must be a natural standing posture, since a bone's twist is read from it against the body's
    left-right line. A rest pose can be anything (a file may rest with its legs up and turn them
    down in every frame), so for a skeleton whose rest is not a standing body, pass a frame of its
    motion (motion_pose)."""
    src, tgt = _distinct(source_rig), _distinct(target_rig)
    source, target = src.skeleton, tgt.skeleton
    shared = [r for r in NEXT_ROLE if r in src.roles and r in tgt.roles]
    shared.sort(key=lambda r: tgt.joint(r))
    src_pose, tgt_pose = source_pose or rest_pose(source), target_pose or rest_pose(target)
    src_j = np.array([src.joint(r) for r in shared])
    tgt_j = np.array([tgt.joint(r) for r in shared])
    ends = [_next_role(r, shared, (src, tgt)) for r in shared]
    src_child = np.array([_bone_end(src, r, nxt) for r, nxt in zip(shared, ends, strict=True)])
    tgt_child = np.array([_bone_end(tgt, r, nxt) for r, nxt in zip(shared, ends, strict=True)])
    align = np.empty((len(shared), 4))
    for k, role in enumerate(shared):
        src_frame = _bone_frame(src, src_pose, role, src_j[k], src_child[k])
        tgt_frame = _bone_frame(tgt, tgt_pose, role, tgt_j[k], tgt_child[k])
        turn = quat.from_matrix(src_frame @ tgt_frame.T)  # target's bone frame onto the source's
        align[k] = quat.mul(quat.mul(quat.conj(src_pose[1][src_j[k]]), turn), tgt_pose[1][tgt_j[k]])
    scale = tgt.leg_length / src.leg_length
    between = [_between(target, int(j), int(c), set(tgt_j.tolist())) for j, c in zip(tgt_j, tgt_child, strict=True)]
    return RetargetMap(source, target, shared, src_j, tgt_j, src_child, tgt_child, align, scale, between)


def _between(target: Skeleton, joint: int, child: int, role_joints: set[int]) -> list[tuple[int, float]]:
    """Target joints without a role on a role's bone (extra spine or neck joints), each with its
    share of the bone's rest length from the top: they take that share of the source's turn from
    this role to the next, so the chain curves as the source's does instead of kinking at one joint."""
    if child < 0 or child not in role_joints:
        return []
    chain = joint_path(target, joint, child)[::-1]  # joint, ..., child
    if chain[0] != joint or len(chain) < 3:
        return []
    rest = target.rest_positions()
    lengths = np.linalg.norm(np.diff(rest[chain], axis=0), axis=1)
    share = np.cumsum(lengths) / max(float(lengths.sum()), 1e-9)
    return [(j, float(w)) for j, w in zip(chain[1:-1], share[:-1], strict=True) if j not in role_joints]


def _distinct(rig: Rig) -> Rig:
    """The rig without a `back` that shares the waist's or chest's joint (roles.py allows it): one
    joint cannot take two roles' rotations, and its bone would have no length."""
    roles = rig.roles
    shared = roles.get("back") in (roles.get("waist"), roles.get("chest"))
    return Rig(rig.skeleton, {r: name for r, name in roles.items() if not (r == "back" and shared)})


def _next_role(role: str, shared: list[str], rigs: tuple[Rig, ...]) -> str | None:
    """The role a role's bone points to, the same on both skeletons (so the bone means the same):
    the next one down the chain that both have, away from this joint on both (a zero-length bone
    has no direction)."""
    nxt = NEXT_ROLE[role]
    while nxt is not None:
        if nxt in shared and all(_distance(rig, role, nxt) > MIN_BONE for rig in rigs):
            return nxt
        nxt = NEXT_ROLE[nxt]
    return None


def _distance(rig: Rig, a: str, b: str) -> float:
    rest = rig.skeleton.rest_positions()
    return float(np.linalg.norm(rest[rig.joint(a)] - rest[rig.joint(b)]))


def _bone_end(rig: Rig, role: str, nxt: str | None) -> int:
    """The joint a role's bone points to: the next role's, else the joint's first child away from it
    (-1: none)."""
    if nxt is not None:
        return rig.joint(nxt)
    skeleton = rig.skeleton
    rest = skeleton.rest_positions()
    joint = rig.joint(role)
    children = [c for c in skeleton.children(joint) if np.linalg.norm(rest[c] - rest[joint]) > MIN_BONE]
    return children[0] if children else -1


def _bone_frame(rig: Rig, pose: Pose, role: str, joint: int, child: int) -> FloatArray:
    """A role bone's frame in a pose (columns): along the bone, then toward a body axis square to
    it in every natural pose: the body's left-right line for the spine, legs and feet (hips for the
    lower body, shoulders above), its front for the arms, which hang down or stretch sideways."""
    skeleton = rig.skeleton
    pos, rot = pose
    if child >= 0:
        along = pos[child] - pos[joint]
    else:  # a bone without a child points along its end site, else up
        along = quat.rotate(rot[joint], skeleton.end_sites.get(int(joint), np.array([0.0, 0.0, 1.0])))
    if np.linalg.norm(along) < MIN_BONE and skeleton.parents[joint] >= 0:  # an End Site at 0 0 0: as its parent
        along = pos[joint] - pos[skeleton.parents[joint]]
    left, right = (pos[rig.joint(r)] for r in _lateral_pair(role))
    up = pos[rig.joint("neck")] - pos[rig.joint("pelvis")]
    side = left - right
    toward = np.cross(side, up) if role.split("_")[0] in ARM_PARTS else side
    return _frame(along, toward, up)


def _lateral_pair(role: str) -> tuple[str, str]:
    return ("hip_l", "hip_r") if role in LOWER_BODY else ("shoulder_l", "shoulder_r")


def _frame(primary: FloatArray, secondary: FloatArray, fallback: FloatArray) -> FloatArray:
    """Orthonormal frame (columns) with its first axis along `primary`, its second toward
    `secondary`, or toward `fallback` where `secondary` runs along `primary`."""
    a = primary / max(float(np.linalg.norm(primary)), 1e-12)
    for toward in (secondary, fallback, np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0])):
        b: FloatArray = toward - a * np.dot(a, toward)
        if np.linalg.norm(b) > 0.2 * max(float(np.linalg.norm(toward)), 1e-12):
            b = b / np.linalg.norm(b)
            return np.stack([a, b, np.cross(a, b)], axis=1)
    raise SkeletonError("a bone's frame has no direction")  # unreachable: the last two are orthogonal


def retarget(
    motion: Motion,
    mapping: RetargetMap,
    base: Motion | None = None,
    fix_feet: bool = True,
    sole: float | None = None,
) -> Motion:
    """`motion` (on mapping.source) played by mapping.target.

    base: the target's own motion (same frame count) whose joints without a role are kept (fingers,
    face); None keeps their rest pose. fix_feet: hold the target's feet where the source's are
    planted (see the module docstring). sole: how high the target's lowest foot point stands when
    its foot is on the floor (files differ: a toe joint 4 cm up, an end site at the sole); default
    the source's, scaled.
    """
    if motion.skeleton.names != mapping.source.names:
        raise SkeletonError("the motion's skeleton is not the retarget map's source skeleton")
    if base is not None and (base.skeleton.names != mapping.target.names or base.num_frames != motion.num_frames):
        raise SkeletonError("the base motion must be on the target skeleton, with as many frames as the motion")
    src_pos, src_rot = motion.global_transforms()
    target = mapping.target
    n, count = motion.num_frames, target.num_joints
    keep = quat.normalize(base.local_rot) if base is not None else quat.identity((n, count))
    glob = _chain_globals(target, _wanted_globals(mapping, src_pos, src_rot), keep)
    root_pos = _root_positions(mapping, motion, glob, src_pos)
    out = Motion(skeleton=target, fps=motion.fps, root_pos=root_pos, local_rot=local_rotations(target, glob))
    if fix_feet:
        out = _plant_feet(mapping, motion, (src_pos, src_rot), out, sole)
    return out


def _wanted_globals(mapping: RetargetMap, src_pos: FloatArray, src_rot: FloatArray) -> dict[int, FloatArray]:
    """Target joint -> (T, 4) global rotation, for every role joint and the joints on its bone: the
    source's turn through the rest alignment (joints on the bone: their share of the turn to the next
    role), then all swung so the bone lies along the source bone's actual direction."""
    rest = mapping.target.rest_positions()
    n = len(src_pos)
    wanted: dict[int, FloatArray] = {}
    for k in range(len(mapping.roles)):
        top_s, end_s = mapping.source_joints[k], mapping.source_child[k]
        top_t, end_t = int(mapping.target_joints[k]), mapping.target_child[k]
        rots = {top_t: quat.mul(src_rot[:, top_s], mapping.align[k])}
        for joint, share in mapping.between[k]:
            turn = quat.slerp(src_rot[:, top_s], src_rot[:, end_s], np.full(n, share))
            rots[joint] = quat.mul(turn, mapping.align[k])
        if end_s >= 0 and end_t >= 0 and mapping.roles[k] != "pelvis":  # the root body turns as the source's
            chain = [*rots, int(end_t)]
            now = sum(quat.rotate(rots[a], rest[b] - rest[a]) for a, b in itertools.pairwise(chain))
            swing = arc(unit(np.asarray(now)), unit(src_pos[:, end_s] - src_pos[:, top_s]))
            rots = {j: quat.mul(swing, r) for j, r in rots.items()}
        wanted.update(rots)
    return wanted


def _chain_globals(target: Skeleton, wanted: dict[int, FloatArray], keep: FloatArray) -> FloatArray:
    """Global rotations (T, J, 4) of every target joint: role joints as wanted, the others carried
    by their parent with their kept local rotation."""
    n, count = keep.shape[:2]
    glob = np.empty((n, count, 4))
    for j in range(count):
        if j in wanted:
            glob[:, j] = wanted[j]
        elif target.parents[j] < 0:
            glob[:, j] = keep[:, j]
        else:
            glob[:, j] = quat.mul(glob[:, target.parents[j]], keep[:, j])
    return glob


def local_rotations(target: Skeleton, glob: FloatArray) -> FloatArray:
    """Local rotations (T, J, 4) of global ones, normalised and continuous along the frames."""
    local = glob.copy()
    child = np.arange(1, target.num_joints)
    local[:, child] = quat.mul(quat.conj(glob[:, target.parents[child]]), glob[:, child])
    return quat.make_continuous(quat.normalize(local))


def _root_positions(mapping: RetargetMap, motion: Motion, glob: FloatArray, src_pos: FloatArray) -> FloatArray:
    """Target root positions that put the target's pelvis at the source's, scaled by leg length
    (heights measured from the floor, z = 0, in both)."""
    target = mapping.target
    pelvis_k = mapping.roles.index("pelvis")
    want = src_pos[:, mapping.source_joints[pelvis_k]] * mapping.scale
    zero = np.zeros((motion.num_frames, 3))
    local = local_rotations(target, glob)
    at_origin = forward_kinematics(target, zero, local, target.offsets)[0][:, mapping.target_joints[pelvis_k]]
    return want - at_origin


# ---------------------------------------------------------------------------------------------
# Feet


def planted(motion: Motion, ankle: int, positions: FloatArray, leg: float) -> BoolArray:
    """(T,) frames where the ankle rests on the floor: low (near its lowest height) and slow."""
    height = positions[:, ankle, 2]
    speed = np.zeros(motion.num_frames)
    if motion.num_frames > 1:
        step = np.linalg.norm(np.diff(positions[:, ankle], axis=0), axis=-1) * motion.fps
        speed[1:] = step
        speed[0] = step[0]
    scale = leg / 0.9
    return (height < height.min() + PLANT_HEIGHT * scale) & (speed < PLANT_SPEED * scale)


def _plant_feet(
    mapping: RetargetMap, motion: Motion, source: tuple[FloatArray, FloatArray], out: Motion, sole: float | None
) -> Motion:
    """Hold each target foot where the source's is planted: in place from the frame the plant began,
    its lowest point (toes, end sites) as high over the target's sole as the source foot's is over
    the source's, scaled. Measured on the feet as they are posed, whatever the rest poses."""
    source_roles = dict(zip(mapping.roles, mapping.source_joints, strict=True))
    target_roles = dict(zip(mapping.roles, mapping.target_joints, strict=True))
    if not all(f"{p}_{s}" in source_roles for p in ("hip", "knee", "ankle") for s in SIDES):
        return out
    src_leg = Rig(mapping.source, {r: mapping.source.names[j] for r, j in source_roles.items()}).leg_length
    feet = [(source_roles[f"ankle_{s}"], target_roles[f"ankle_{s}"], s) for s in SIDES]
    down = {s: planted(motion, ankle_s, source[0], src_leg) for ankle_s, _, s in feet}
    src_low = {s: lowest_foot_point(mapping.source, ankle_s, *source) for ankle_s, _, s in feet}
    planted_low = [src_low[s][down[s]] for s in down if down[s].any()]
    src_sole = float(np.min(np.concatenate(planted_low))) if planted_low else min(v.min() for v in src_low.values())
    target_sole = src_sole * mapping.scale if sole is None else sole
    pos, glob = out.global_transforms()
    # Height of each target foot's lowest point over where it belongs, per frame.
    over = {
        s: lowest_foot_point(mapping.target, ankle_t, pos, glob)
        - (target_sole + (src_low[s] - src_sole) * mapping.scale)
        for _, ankle_t, s in feet
    }
    # Proportions differ (pelvis over hips, ankles over soles): first the whole body down (or up) by
    # the most any planted foot floats, then the legs lift the feet that would sink (a leg can bend
    # but not stretch). Without a planted foot, the lowest foot reaches its height at its lowest.
    if planted_low:
        sink = float(np.max(np.concatenate([over[s][down[s]] for s in down])))
    else:
        sink = float(np.min(np.minimum(*over.values())))
    root_pos = out.root_pos - np.array([0.0, 0.0, sink])
    pos[..., 2] -= sink
    left = pos[:, target_roles["hip_l"]] - pos[:, target_roles["hip_r"]]
    forward = np.cross(left, pos[:, target_roles["neck"]] - pos[:, target_roles["pelvis"]])
    for ankle_s, ankle_t, s in feet:
        goal = pos[:, ankle_t].copy()
        goal[:, 2] -= over[s] - sink
        goal = _planted_track(goal, source[0][:, ankle_s] * mapping.scale, down[s])
        weight = _eased(down[s])
        ankle = pos[:, ankle_t]
        goal = ankle + weight[:, None] * (goal - ankle)
        # Off the plants (and easing out of them), a foot the proportions put through the floor is
        # lifted onto it, by as much as it sinks (no higher than the source's foot, which may itself
        # dip below its sole).
        belongs = (src_low[s] - src_sole) * mapping.scale  # over the target's sole
        below = np.maximum(np.minimum(belongs, 0.0) - (over[s] + belongs - sink), 0.0)
        goal[:, 2] = np.maximum(goal[:, 2], ankle[:, 2] + below)
        moved = ((weight > 0.0) | (below > 0.0)).astype(np.float64)
        joints = (target_roles[f"hip_{s}"], target_roles[f"knee_{s}"], ankle_t)
        two_bone_ik(mapping.target, pos, glob, joints, goal, moved, left, forward)
    return Motion(
        skeleton=out.skeleton, fps=out.fps, root_pos=root_pos, local_rot=local_rotations(mapping.target, glob)
    )


def lowest_foot_point(skeleton: Skeleton, ankle: int, positions: FloatArray, rotations: FloatArray) -> FloatArray:
    """(T,) height of a foot's lowest point: the ankle, the joints below it and their end sites (a
    hand's, from the wrist, likewise)."""
    return foot_points(skeleton, ankle, positions, rotations)[..., 2].min(axis=1)


def foot_points(skeleton: Skeleton, ankle: int, positions: FloatArray, rotations: FloatArray) -> FloatArray:
    """(T, P, 3) a foot's points: the ankle, the joints below it and their end sites."""
    below = [j for j in range(skeleton.num_joints) if ankle in joint_path(skeleton, ankle, j)]
    points = [positions[:, j] for j in below]
    for j in below:
        if j in skeleton.end_sites:
            points.append(positions[:, j] + quat.rotate(rotations[:, j], skeleton.end_sites[j]))
    return np.stack(points, axis=1)


def _planted_track(goal: FloatArray, source: FloatArray, down: BoolArray) -> FloatArray:
    """Within each planted run the goal's ground position moves only as the (scaled) source ankle
    does from where the run began: a planted source foot stays put, and so does the target's, even
    where the proportions would have carried it along."""
    tracked = goal.copy()
    start = None
    for t, on in enumerate(down):
        start = (t if start is None else start) if on else None
        if start is not None:
            tracked[t, :2] = goal[start, :2] + source[t, :2] - source[start, :2]
    return tracked


def _eased(down: BoolArray) -> FloatArray:
    """1 on planted frames, ramping to 0 over EASE_FRAMES frames on either side."""
    weight = down.astype(np.float64)
    for shift in range(1, EASE_FRAMES + 1):
        ramp = 1.0 - shift / (EASE_FRAMES + 1)
        weight[shift:] = np.maximum(weight[shift:], ramp * down[:-shift])
        weight[:-shift] = np.maximum(weight[:-shift], ramp * down[shift:])
    return weight
