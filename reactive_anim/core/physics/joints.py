"""The joint model, mocap <-> engine: skeleton rotations to the ragdoll's hinge angles and back.

JOINT LIMITS. MuJoCo's ball joint takes one `range`: a cone on the total rotation angle, with no
separate twist, and position actuators cannot drive a ball joint at all. So every servoed ball joint
is three hinges in the body frame, applied in the order flexion (axis e1), twist (e2 = the bone),
abduction (e3); intrinsically, local = R(e1, a) R(e2, b) R(e3, c). A swing cone of S degrees maps to
flexion and abduction ranges of +-S (a square around the cone, slightly more permissive on the
diagonals), a twist range maps to the twist hinge's range as is. Mocap rotations are split into
the three angles by this Euler decomposition, which is singular at a twist of +-90 degrees (only the
shoulder's and forearm's anatomical ranges come near it; there the flexion and abduction angles
swap freedom but the rotation is still rebuilt exactly).

Back from the engine, the output is a core Motion on the full input skeleton. Role joints come from
the simulation; a spine body's bend is shared by the skeleton joints it spans (waist and back over
the spine joints, neck over the neck joints and the head); joints with no body below them (toes,
fingers, twist and face bones) follow the mocap the servos track; joints between bodies (clavicles,
helper bones) keep the start frame's rotation, as the model does.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..model import quat
from ..model.arrays import FloatArray, IndexArray, einsum
from ..model.errors import SimulationError, SkeletonError
from ..model.skeleton import Motion
from .ragdoll import Ragdoll


@dataclass
class HeldPose:
    """The mocap frame whose merged joints (and joints above the pelvis) stay as they are.

    local_rot (J, 4), offsets (J, 3), root_pos (3,): that frame of the input motion; qpos (nq,):
    the ragdoll's joint positions for it (mocap_qpos).
    """

    local_rot: FloatArray
    offsets: FloatArray
    root_pos: FloatArray
    global_pos: FloatArray
    global_rot: FloatArray
    qpos: FloatArray


def _check_finite(motion: Motion, frames: IndexArray) -> None:
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
    ragdoll: Ragdoll, root_pos: FloatArray, local_rot: FloatArray, offsets: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Forward kinematics (N, J, 3) and (N, J, 4) of only the joints the ragdoll needs (body joints
    and their ancestors; fingers and face bones are left at zero), vectorised over frames.
    Rotation matrices inside: a 3x3 product per joint is far cheaper than quaternion helpers on
    small arrays, and this runs once per impact on the critical path."""
    n, count = local_rot.shape[:2]
    joints = ragdoll.index.kinematic_joints
    local_m = np.zeros((n, count, 3, 3))
    local_m[:, joints] = quat.to_matrix(local_rot[:, joints])
    pos = np.zeros((n, count, 3))
    rot_m = np.zeros((n, count, 3, 3))
    root = joints[0]
    pos[:, root] = root_pos
    rot_m[:, root] = local_m[:, root]
    # A level of the hierarchy at a time: each joint's arithmetic is the same as joint by joint.
    for level, parents in ragdoll.index.kinematic_levels:
        pos[:, level] = pos[:, parents] + einsum("njab,njb->nja", rot_m[:, parents], offsets[:, level])
        rot_m[:, level] = rot_m[:, parents] @ local_m[:, level]
    rot = np.zeros((n, count, 4))
    rot[:, joints] = quat.from_matrix(rot_m[:, joints])
    return pos, rot


@dataclass
class _MocapPoses:
    """mocap_qpos of some frames together with the forward kinematics it was computed from, so a
    held pose of one of those frames needs no second FK pass (row k of the batched FK is bitwise the
    FK of that frame alone)."""

    qpos: FloatArray  # (N, nq)
    local_rot: FloatArray  # (N, J, 4) normalised
    offsets: FloatArray  # (N, J, 3)
    root_pos: FloatArray  # (N, 3)
    global_pos: FloatArray  # (N, J, 3), kinematic joints only
    global_rot: FloatArray  # (N, J, 4), kinematic joints only

    def held(self, k: int) -> HeldPose:
        """Row k as a HeldPose, with arrays of its own."""
        return HeldPose(
            local_rot=self.local_rot[k].copy(),
            offsets=np.array(self.offsets[k], dtype=np.float64),
            root_pos=self.root_pos[k].copy(),
            global_pos=self.global_pos[k].copy(),
            global_rot=self.global_rot[k].copy(),
            qpos=self.qpos[k].copy(),
        )


def mocap_qpos(ragdoll: Ragdoll, motion: Motion, frames: IndexArray) -> FloatArray:
    """Ragdoll joint positions (N, nq) of the given frames of a motion of the ragdoll's skeleton.

    Root: pelvis position and the pelvis body's rotation away from the neutral pose. Each hinge
    triple: the body's rotation relative to its parent body, split into flexion, twist and
    abduction angles (the module docstring, JOINT LIMITS). Angles are unwrapped along the frames.
    """
    return _mocap_poses(ragdoll, motion, frames).qpos


def _mocap_poses(ragdoll: Ragdoll, motion: Motion, frames: IndexArray) -> _MocapPoses:
    """mocap_qpos, keeping the FK on the way (see _MocapPoses)."""
    if motion.skeleton.names != ragdoll.skeleton.names:
        raise SkeletonError("the motion's skeleton is not the ragdoll's skeleton (joint names differ)")
    frames = np.asarray(frames, dtype=int)
    _check_finite(motion, frames)
    offsets = np.broadcast_to(motion.joint_offsets()[frames], (len(frames),) + motion.skeleton.offsets.shape)
    root_pos = motion.root_pos[frames]
    local_rot = quat.normalize(motion.local_rot[frames])
    pos, grot = _kinematics(ragdoll, root_pos, local_rot, offsets)
    joints, parents = ragdoll.index.body_joints, ragdoll.index.body_parents
    # Body rotation in MuJoCo = global rotation relative to the neutral pose.
    x = quat.make_continuous(quat.mul(grot[:, joints], quat.conj(ragdoll.neutral_global_rot[joints])))
    qpos = np.zeros((len(frames), ragdoll.model.nq))
    qpos[:, 0:3] = pos[:, ragdoll.root.joint]
    qpos[:, 3:7] = x[:, 0]
    # All bodies at once: rotation relative to the parent body, in the joint frame, as Euler angles.
    rel = quat.mul(quat.conj(x[:, parents]), x)
    fq = ragdoll.index.frame_quat
    angles = quat.to_euler(quat.mul(quat.conj(fq), quat.mul(rel, fq)), "XYZ")  # (N, B, 3)
    hinge = angles[:, ragdoll.index.hinge_body, ragdoll.index.hinge_slot] * ragdoll.index.hinge_sign
    qpos[:, ragdoll.index.hinge_qpos] = np.unwrap(hinge, axis=0)
    return _MocapPoses(
        qpos=qpos, local_rot=local_rot, offsets=offsets, root_pos=root_pos, global_pos=pos, global_rot=grot
    )


def _interp_qpos(table: FloatArray, t: float) -> FloatArray:
    """Row-interpolate a per-frame qpos table at fractional index t (root rotation by slerp)."""
    i = int(np.clip(np.floor(t), 0, len(table) - 1))
    j = min(i + 1, len(table) - 1)
    s = float(np.clip(t - i, 0.0, 1.0))
    q = table[i] + (table[j] - table[i]) * s
    q[3:7] = quat.slerp(table[i, 3:7], table[j, 3:7], s)
    return q


@dataclass
class MocapTable:
    """Ragdoll joint positions of the motion's frames first .. first + len(qpos) - 1 (one FK pass)."""

    first: int
    qpos: FloatArray
    poses: _MocapPoses

    def at(self, frame: float) -> FloatArray:
        return _interp_qpos(self.qpos, frame - self.first)

    def held(self, frame: int) -> HeldPose:
        """The held pose of a frame of the table."""
        k = frame - self.first
        if not 0 <= k < len(self.qpos):
            raise SimulationError(
                f"frame {frame} is outside the pose table's frames {self.first}..{self.first + len(self.qpos) - 1}"
            )
        return self.poses.held(k)


def mocap_table(ragdoll: Ragdoll, motion: Motion, lo: float, hi: float) -> MocapTable:
    first = int(max(0, np.floor(lo)))
    last = int(min(motion.num_frames - 1, np.ceil(hi)))
    poses = _mocap_poses(ragdoll, motion, np.arange(first, last + 1))
    return MocapTable(first, poses.qpos, poses)


def same_turns(ragdoll: Ragdoll, targets: FloatArray, start: FloatArray) -> None:
    """Shift each hinge's target angles (K, nq) by whole turns, in place, so that the first lies
    within half a turn of the start's. Angles are unwrapped along one motion's frames, so a start
    from another motion (the end of BC, tracking a clip) can sit a whole turn from its target: a
    shoulder raised overhead in a sword slash was 6.1 rad from the target it then tried to reach
    (a 5,400 J jump in one frame, SimulationError)."""
    hinges = ragdoll.index.hinge_qpos
    gap: FloatArray = (start[hinges] - targets[0, hinges]) / (2.0 * np.pi)
    turns = np.round(gap)
    if np.any(turns):
        targets[:, hinges] += 2.0 * np.pi * turns


def to_motion(
    ragdoll: Ragdoll,
    held: HeldPose,
    follow: FloatArray,
    body_rot: FloatArray,
    pelvis_pos: FloatArray,
    held_body_rot: FloatArray,
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
    joints = ragdoll.index.body_joints
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


def _body_local_rotations(ragdoll: Ragdoll, held: HeldPose, body_rot: FloatArray) -> FloatArray:
    """(N, B, 4) the local rotations of the body joints for body rotations (N, B, 4): each body's
    joint turns from its parent body, carried through the held merged bones between them (a ground
    root bone above the pelvis holds)."""
    skeleton, joints, hrot = ragdoll.skeleton, ragdoll.index.body_joints, held.global_rot
    glob = quat.mul(body_rot, ragdoll.neutral_global_rot[joints])
    body_local = np.empty_like(glob)
    parent = skeleton.parents[ragdoll.root.joint]
    body_local[:, 0] = glob[:, 0] if parent < 0 else quat.mul(quat.conj(hrot[parent]), glob[:, 0])
    body_parent = ragdoll.index.body_parents[1:]
    carry = quat.mul(quat.conj(hrot[joints[body_parent]]), hrot[skeleton.parents[joints[1:]]])
    parent_rot = quat.mul(glob[:, body_parent], carry)
    body_local[:, 1:] = quat.mul(quat.conj(parent_rot), glob[:, 1:])
    return body_local


def _share_bends(ragdoll: Ragdoll, local: FloatArray, held: FloatArray) -> None:
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


def local_rotations(motion: Motion, frames: IndexArray) -> FloatArray:
    """(len(frames), J, 4) normalised local rotations; frames past the end hold the last."""
    return quat.normalize(motion.local_rot[np.clip(frames, 0, motion.num_frames - 1)])
