"""A character on another skeleton than the library's clips.

The search compares joint rotations and positions, which mean the same only on one skeleton; so
the character's query window is retargeted onto the library's skeleton (the first clip's) before
the search, and each clip the search picks (and each get-up chained after it) is retargeted onto
the character before the transition tracks it. The ragdoll stays the character's own, so the
physics matches the body that is hit. When the skeletons are the same nothing is converted.
Skeletons are lined up at their rest poses, or at the first frame of a motion on them (the
character's, or the clip's) where the rest pose is no standing body, as in some files (retarget_map).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from ..model.rig import Rig
from ..model.roles import SIDES
from ..model.skeleton import Motion, Skeleton
from ..search.library import Library, take_start
from ..search.window import Query, query_from_motion
from .retarget import Pose, RetargetMap, lowest_foot_point, reference_pose, retarget, retarget_map

# A skeleton as a dictionary key (_key): its joint names and its rest offsets' bytes.
SkeletonKey = tuple[tuple[str, ...], bytes]


@dataclass
class Casting:
    """How one character's motion meets one library: retarget maps both ways, clips kept once
    retargeted (a bake uses a clip for several impacts). Nothing is computed for a character on
    the library's own skeleton, and everything else only when first needed."""

    character: Motion
    rig: Rig  # the character's
    library: Library
    reference: Motion  # the library's first clip: its skeleton is the one the search compares on
    # skeleton (_key) -> its rig (_rig)
    _rigs: dict[SkeletonKey, Rig] = field(default_factory=dict[SkeletonKey, Rig])
    # skeleton (_key) -> the pose it is lined up at
    _poses: dict[SkeletonKey, Pose] = field(default_factory=dict[SkeletonKey, Pose])
    _maps: dict[tuple[SkeletonKey, SkeletonKey], RetargetMap] = field(
        default_factory=dict[tuple[SkeletonKey, SkeletonKey], RetargetMap]
    )
    _clips: dict[tuple[str, float], Motion] = field(default_factory=dict[tuple[str, float], Motion])

    @classmethod
    def between(cls, character: Motion, rig: Rig, library: Library) -> Casting:
        return cls(character, rig, library, library.clip_motion(library.clips[0].name, library.fps))

    @cached_property
    def same_skeleton(self) -> bool:
        return same_skeleton(self.reference.skeleton, self.character.skeleton)

    @cached_property
    def sole(self) -> float:
        """How high the character's lowest foot point is on the floor, in its own motion."""
        return _sole(self.character, self.rig)

    def query(self, before: Motion, start: float) -> Query:
        """The library-rate window from `start` (before's frames), on the library's skeleton."""
        library = self.library
        if self.same_skeleton:
            return query_from_motion(before, start, library.window, library.fps, self.rig)
        first = int(np.floor(start))
        last = min(before.num_frames, int(np.ceil(start + (library.window - 1) * before.fps / library.fps)) + 2)
        moved = retarget(before.slice(first, last), self._map(self.character, self.reference), fix_feet=False)
        return query_from_motion(moved, start - first, library.window, library.fps, self._rig(self.reference.skeleton))

    def clip(self, name: str, fps: float) -> Motion:
        """A library clip at `fps`, played by the character (its feet held where the clip's are planted)."""
        key = (name, float(fps))
        if key not in self._clips:
            motion = self.library.clip_motion(name, fps)
            if not same_skeleton(motion.skeleton, self.character.skeleton):
                motion = retarget(motion, self._map(motion, self.character), sole=self.sole)
            self._clips[key] = motion
        return self._clips[key]

    def _map(self, source: Motion, target: Motion) -> RetargetMap:
        """The map between two motions' skeletons, each lined up at its reference pose (the first
        motion seen on a skeleton decides its pose)."""
        key = (_key(source.skeleton), _key(target.skeleton))
        if key not in self._maps:
            poses = [self._pose(m) for m in (source, target)]
            self._maps[key] = retarget_map(self._rig(source.skeleton), self._rig(target.skeleton), *poses)
        return self._maps[key]

    def _pose(self, motion: Motion) -> Pose:
        key = _key(motion.skeleton)
        if key not in self._poses:
            self._poses[key] = reference_pose(motion, self._rig(motion.skeleton))
        return self._poses[key]

    def _rig(self, skeleton: Skeleton) -> Rig:
        """The skeleton's rig, made once per skeleton: the character's roles on the character's
        skeleton (or one the same); another skeleton's own roles, or found by name."""
        key = _key(skeleton)
        if key not in self._rigs:
            same = same_skeleton(skeleton, self.character.skeleton)
            self._rigs[key] = Rig(skeleton, self.rig.roles) if same else Rig.of(skeleton)
        return self._rigs[key]


def _sole(motion: Motion, rig: Rig) -> float:
    """The lowest any foot of the motion gets (toes, end sites): where its floor is for its feet.
    A toe joint may sit centimetres over the real sole, and a file's floor anywhere. A first frame
    the take leaves faster than library.CALIBRATION_JUMP is a calibration pose, not the take, and is
    left out (library.take_start, the library's rule for its clips): CMU 139_16 and 140_01 open on
    one with the feet 0.8 m under their floor, and every cast clip was held that far down."""
    pos, rot = motion.global_transforms()
    sk = motion.skeleton
    lowest = np.minimum(*(lowest_foot_point(sk, rig.joint(f"ankle_{s}"), pos, rot) for s in SIDES))
    return float(lowest[take_start(pos, motion.fps) :].min())


def same_skeleton(a: Skeleton, b: Skeleton) -> bool:
    """One skeleton: the same joints, parents and rest offsets (a character with the library's joint
    names but its own proportions, another CMU subject say, is retargeted)."""
    return a.names == b.names and np.array_equal(a.parents, b.parents) and np.allclose(a.offsets, b.offsets, atol=1e-4)


def _key(skeleton: Skeleton) -> SkeletonKey:
    """A skeleton as a dictionary key: its joints and rest offsets (to 0.1 mm)."""
    return tuple(skeleton.names), np.round(skeleton.offsets, 4).tobytes()
