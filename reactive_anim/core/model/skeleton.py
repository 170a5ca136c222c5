"""Skeleton (joint hierarchy and rest offsets), Motion (per-frame joint rotations) and forward kinematics.

Conventions: metres, Z up, quaternions (w, x, y, z). The rest pose has every joint
rotation equal to identity, so rest offsets are expressed in world axes, as in BVH. A joint's local
rotation is relative to its parent's frame; the global rotation of joint j is the product of the
local rotations from the root down to j.

One addition to the design's Motion: `local_pos`, per-frame translations of every joint relative to
its parent. Most mocap animates only the root's position, but some files (the Bandai Namco set)
animate every joint's; without it those files would not match what Blender shows.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from . import quat
from .arrays import BoolArray, FloatArray, IndexArray, IntArray
from .errors import SkeletonError


@dataclass
class Skeleton:
    """Joint names, parent indices (root first, parents before children) and rest offsets (J, 3).

    `end_sites` maps a joint index to the offset of its BVH End Site (the tip of a leaf bone).
    `roles` maps a paper joint role ("hip_l", "knee_r", ...) to a joint name; see roles.py.
    """

    names: list[str]
    parents: IntArray
    offsets: FloatArray
    end_sites: dict[int, FloatArray] = field(default_factory=dict[int, FloatArray])
    roles: dict[str, str] = field(default_factory=dict[str, str])
    # Joints by depth below the root (the root's level first): forward kinematics goes a level at a
    # time, a handful of array operations for all of a level's joints instead of one per joint.
    levels: list[IndexArray] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        self.names = list(self.names)
        self.parents = np.asarray(self.parents, dtype=np.int64)
        self.offsets = np.asarray(self.offsets, dtype=np.float64).reshape(-1, 3)
        count = len(self.names)
        if count == 0:
            raise SkeletonError("a skeleton needs at least one joint")
        if self.parents.shape != (count,) or self.offsets.shape != (count, 3):
            raise SkeletonError(
                f"skeleton arrays disagree: {count} names, parents {self.parents.shape}, offsets {self.offsets.shape}"
            )
        if len(set(self.names)) != count:
            dupes = sorted({n for n in self.names if self.names.count(n) > 1})
            raise SkeletonError(f"duplicate joint names: {', '.join(dupes)}")
        if self.parents[0] != -1 or np.any(self.parents[1:] < 0) or np.any(self.parents[1:] >= np.arange(1, count)):
            raise SkeletonError("joints must be ordered root first, each parent before its children")
        depth = np.zeros(count, dtype=np.int64)
        for j in range(1, count):
            depth[j] = depth[self.parents[j]] + 1
        self.levels = [np.flatnonzero(depth == d) for d in range(int(depth.max()) + 1)]

    @property
    def num_joints(self) -> int:
        return len(self.names)

    def index(self, name: str) -> int:
        """Index of the joint called `name`; the error lists the joints that do exist."""
        try:
            return self.names.index(name)
        except ValueError:
            raise SkeletonError(
                f"the skeleton has no joint '{name}'; its joints are: {', '.join(self.names)}"
            ) from None

    def children(self, joint: int) -> list[int]:
        return [int(c) for c in np.flatnonzero(self.parents == joint)]

    def rest_positions(self) -> FloatArray:
        """World positions of every joint in the rest pose, (J, 3)."""
        pos = np.zeros((self.num_joints, 3))
        pos[0] = self.offsets[0]
        for j in range(1, self.num_joints):
            pos[j] = pos[self.parents[j]] + self.offsets[j]
        return pos

    def rest_extent(self) -> float:
        """Largest side of the rest pose's bounding box, end sites included (about body height)."""
        pos = self.rest_positions()
        tips = [pos[j] + off for j, off in self.end_sites.items()]
        pts = np.vstack([pos] + tips) if tips else pos
        return float(np.max(pts.max(axis=0) - pts.min(axis=0)))


@dataclass
class Motion:
    """Per-frame pose of a skeleton.

    root_pos: (T, 3) world position of the root joint, metres.
    local_rot: (T, J, 4) unit quaternions, each joint relative to its parent, rest pose = identity.
    local_pos: (T, J, 3) joint translations relative to the parent, or None to use the rest
      offsets (row 0, the root, is ignored: root_pos holds it).
    """

    skeleton: Skeleton
    fps: float
    root_pos: FloatArray
    local_rot: FloatArray
    local_pos: FloatArray | None = None

    def __post_init__(self) -> None:
        self.root_pos = np.asarray(self.root_pos, dtype=np.float64)
        self.local_rot = np.asarray(self.local_rot, dtype=np.float64)
        frames = self.root_pos.shape[0]
        count = self.skeleton.num_joints
        if self.root_pos.shape != (frames, 3) or self.local_rot.shape != (frames, count, 4):
            raise SkeletonError(
                f"motion arrays do not fit a {count}-joint skeleton: root_pos {self.root_pos.shape}, "
                f"local_rot {self.local_rot.shape}"
            )
        if self.local_pos is not None:
            self.local_pos = np.asarray(self.local_pos, dtype=np.float64)
            if self.local_pos.shape != (frames, count, 3):
                raise SkeletonError(f"local_pos has shape {self.local_pos.shape}, expected {(frames, count, 3)}")
        if not self.fps > 0:
            raise SkeletonError(f"frames per second must be positive, got {self.fps}")

    @property
    def num_frames(self) -> int:
        return self.root_pos.shape[0]

    @property
    def frame_time(self) -> float:
        return 1.0 / self.fps

    def joint_offsets(self) -> FloatArray:
        """Per-frame parent-relative translations (T, J, 3): local_pos or the rest offsets."""
        if self.local_pos is not None:
            return self.local_pos
        return np.broadcast_to(self.skeleton.offsets, (self.num_frames,) + self.skeleton.offsets.shape)

    def global_transforms(self) -> tuple[FloatArray, FloatArray]:
        """World joint positions (T, J, 3) and rotations (T, J, 4) by forward kinematics."""
        offsets = self.skeleton.offsets if self.local_pos is None else self.local_pos
        return forward_kinematics(self.skeleton, self.root_pos, self.local_rot, offsets)

    def global_positions(self) -> FloatArray:
        return self.global_transforms()[0]

    def global_rotations(self) -> FloatArray:
        return self.global_transforms()[1]

    def slice(self, start: int, stop: int) -> Motion:
        """Frames [start, stop) as a new Motion sharing the skeleton."""
        local_pos = None if self.local_pos is None else self.local_pos[start:stop].copy()
        return replace(
            self,
            root_pos=self.root_pos[start:stop].copy(),
            local_rot=self.local_rot[start:stop].copy(),
            local_pos=local_pos,
        )

    def frames(self, first: int, count: int) -> Motion:
        """`count` frames from `first`, the first frame held before the motion's start and the last
        past its end."""
        index = np.clip(np.arange(first, first + count), 0, self.num_frames - 1)
        local_pos = None if self.local_pos is None else self.local_pos[index]
        return replace(self, root_pos=self.root_pos[index], local_rot=self.local_rot[index], local_pos=local_pos)

    def concat(self, other: Motion) -> Motion:
        """This motion followed by `other` (same skeleton and frame rate)."""
        if other.skeleton.names != self.skeleton.names or not np.isclose(other.fps, self.fps):
            raise SkeletonError("can only join motions of the same skeleton and frame rate")
        local_pos = None
        if self.local_pos is not None or other.local_pos is not None:
            local_pos = np.concatenate([self.joint_offsets(), other.joint_offsets()])
        return replace(
            self,
            root_pos=np.concatenate([self.root_pos, other.root_pos]),
            local_rot=np.concatenate([self.local_rot, other.local_rot]),
            local_pos=local_pos,
        )


def forward_kinematics(
    skeleton: Skeleton, root_pos: FloatArray, local_rot: FloatArray, offsets: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Global positions (T, J, 3) and rotations (T, J, 4), vectorised over frames: views of fresh
    joint-major arrays (writable, not C-contiguous).

    offsets: (T, J, 3) or (J, 3) parent-relative translations; the root's row is ignored.
    """
    frames, count = local_rot.shape[:2]
    # joint-major inside (a level's joints gathered as whole rows, not strided across frames): a
    # third less time on a 101-joint rig; returned frame-major, as views
    # rest offsets (J, 3) broadcast over the frames as they are, per-frame ones copied joint-major
    offsets = offsets[:, None] if offsets.ndim == 2 else np.ascontiguousarray(np.moveaxis(offsets, 1, 0))
    local = np.ascontiguousarray(np.moveaxis(local_rot, 1, 0))
    pos = np.empty((count, frames, 3))
    rot = np.empty((count, frames, 4))
    pos[0] = root_pos
    rot[0] = local[0]
    for joints in skeleton.levels[1:]:  # elementwise, so the same bits as joint by joint
        p = skeleton.parents[joints]
        parent_rot = rot[p]
        pos[joints] = pos[p] + quat.rotate(parent_rot, offsets[joints])
        rot[joints] = quat.mul(parent_rot, local[joints])
    return np.moveaxis(pos, 0, 1), np.moveaxis(rot, 0, 1)


def frame_times(motion: Motion, fps: float) -> FloatArray:
    """Times in seconds of the frames at `fps` that fit within the motion (from its first frame)."""
    duration = (motion.num_frames - 1) / motion.fps
    return np.arange(int(np.floor(duration * fps + 1e-9)) + 1) / fps


def resample(motion: Motion, times: FloatArray) -> Motion:
    """The motion at the given times in seconds (linear root and joint offsets, slerped rotations).

    Library clips and queries come at 30, 60, 120 fps; Eq. 1 sums per frame, so both are brought to
    the library's rate first and a window covers the same time in every clip.
    """
    times = np.asarray(times, dtype=np.float64)
    last = motion.num_frames - 1
    x = np.clip(times * motion.fps, 0.0, last)
    lo = np.minimum(np.floor(x).astype(np.int64), max(last - 1, 0))
    hi = np.minimum(lo + 1, last)
    t = x - lo
    root = motion.root_pos[lo] * (1 - t)[:, None] + motion.root_pos[hi] * t[:, None]
    weight = np.broadcast_to(t[:, None], motion.local_rot[lo].shape[:2])
    rot = quat.slerp(motion.local_rot[lo], motion.local_rot[hi], weight)
    local_pos = None
    if motion.local_pos is not None:
        local_pos = motion.local_pos[lo] * (1 - t)[:, None, None] + motion.local_pos[hi] * t[:, None, None]
    fps = 1.0 / (times[1] - times[0]) if len(times) > 1 else motion.fps
    return Motion(motion.skeleton, fps, root, rot, local_pos)


def root_child(skeleton: Skeleton) -> int | None:
    """The root's child when it has exactly one (a ground bone above the hips: Bandai Namco's
    joint_Root, iClone's BoneRoot), else None."""
    kids = np.flatnonzero(skeleton.parents == 0)
    return int(kids[0]) if len(kids) == 1 else None


def child_in_world(motion: Motion, frames: IndexArray, child: int) -> tuple[FloatArray, FloatArray]:
    """World position (n, 3) and rotation (n, 4) of a child of the root on the given frames."""
    turn = motion.local_rot[frames, 0]
    world = motion.root_pos[frames] + quat.rotate(turn, motion.joint_offsets()[frames, child])
    return world, quat.mul(turn, motion.local_rot[frames, child])


def _root_at(motion: Motion, pos: FloatArray, rot: FloatArray) -> BoolArray:
    """Per frame, whether the root stands at (pos, rot), to a micrometre and q or -q alike."""
    near = np.abs(motion.root_pos - pos).max(axis=1) <= 1e-6
    return near & (np.abs(motion.local_rot[:, 0] @ rot) >= 1.0 - 1e-12)


def static_root(motion: Motion) -> tuple[FloatArray, FloatArray] | None:
    """The root's one transform (position, rotation) when it never moves and has a single child:
    a ground bone that stays put while the hips' own channels carry the walk (Bandai Namco's
    joint_Root, in 68 of the 72 shared files); None otherwise."""
    if root_child(motion.skeleton) is None:
        return None
    pos, rot = motion.root_pos[0].copy(), motion.local_rot[0, 0].copy()
    return (pos, rot) if np.all(_root_at(motion, pos, rot)) else None


def hold_root(motion: Motion, pos: FloatArray, rot: FloatArray) -> Motion:
    """The same world motion with the root held at (pos, rot) on every frame, its single child's
    offset and rotation taking up the rest, as in a file with a static ground root (static_root).
    A reaction's sources put such a root wherever their own conventions do (the simulation moves it
    with the pelvis, a placed clip turns it about the origin), and fading between them sent the
    root bone metres across the floor. Frames whose root is already there stay bit for bit."""
    kid = root_child(motion.skeleton)
    if kid is None:
        raise SkeletonError("hold_root needs a root with a single child")
    moved = np.flatnonzero(~_root_at(motion, pos, rot))
    if len(moved) == 0:
        return motion
    world, turned = child_in_world(motion, moved, kid)
    back = quat.conj(np.broadcast_to(rot, turned.shape))
    root_pos, local_rot, local_pos = motion.root_pos.copy(), motion.local_rot.copy(), motion.joint_offsets().copy()
    root_pos[moved], local_rot[moved, 0] = pos, rot
    local_pos[moved, kid] = quat.rotate(back, world - pos)
    local_rot[moved, kid] = quat.mul(back, turned)
    return replace(motion, root_pos=root_pos, local_rot=local_rot, local_pos=local_pos)
