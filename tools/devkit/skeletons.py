"""Skeletons made from the sample one for tests and benchmarks: another rest pose (arms out in a
T-pose instead of down), other proportions, a joint without a role. Needs no Blender."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from reactive_anim.core.model import bvh, quat
from reactive_anim.core.model.skeleton import Skeleton
from tools.devkit.mocap import REPO

WALK = bvh.read_bvh(REPO / "sample_clips" / "walk.bvh")


def turned_chain(skeleton: Skeleton, top: str, rotation: np.ndarray) -> Skeleton:
    """The skeleton with every offset below joint `top` (and their end sites) turned by `rotation`."""
    offsets, ends = skeleton.offsets.copy(), dict(skeleton.end_sites)
    start = skeleton.index(top)
    below = [j for j in range(skeleton.num_joints) if j != start and start in ancestors(skeleton, j)]
    for j in below:
        offsets[j] = quat.rotate(rotation, offsets[j])
    for j in [start, *below]:
        if j in ends:
            ends[j] = quat.rotate(rotation, ends[j])
    return replace(skeleton, offsets=offsets, end_sites=ends, roles={})


def ancestors(skeleton: Skeleton, joint: int) -> list[int]:
    found = []
    while skeleton.parents[joint] >= 0:
        joint = int(skeleton.parents[joint])
        found.append(joint)
    return found


def t_pose_variant() -> Skeleton:
    """The sample skeleton with its arms out sideways (T-pose) instead of down, legs 12% longer, and
    a finger (a joint without a role) on the left hand."""
    skeleton = with_finger(WALK.skeleton)
    for side, sign in (("L", 1.0), ("R", -1.0)):
        # down (0, 0, -1) -> out (sign, 0, 0): a quarter turn about the forward axis
        skeleton = turned_chain(skeleton, f"upper_arm.{side}", quat.from_axis_angle([0, 1.0, 0], -sign * np.pi / 2))
    offsets = skeleton.offsets.copy()
    for name in ("shin.L", "shin.R", "foot.L", "foot.R"):
        offsets[skeleton.index(name)] *= 1.12
    return replace(skeleton, offsets=offsets)


def with_finger(skeleton: Skeleton) -> Skeleton:
    hand = skeleton.index("hand.L")
    ends = {j: v for j, v in skeleton.end_sites.items() if j != hand}
    count = skeleton.num_joints
    ends[count] = np.array([0.0, 0.0, -0.08])
    return Skeleton(
        names=[*skeleton.names, "finger.L"],
        parents=np.append(skeleton.parents, hand),
        offsets=np.vstack([skeleton.offsets, [0.0, 0.0, -0.1]]),
        end_sites=ends,
    )


def role_bone_angles(mapping, source: np.ndarray, target: np.ndarray) -> dict[str, float]:
    """Mean angle (degrees) per role between the source's and the target's bone directions, from
    global positions (T, J, 3) of each (retarget.RetargetMap `mapping` names the bones)."""
    angles = {}
    for k, role in enumerate(mapping.roles):
        if mapping.source_child[k] < 0 or mapping.target_child[k] < 0:
            continue
        a = source[:, mapping.source_child[k]] - source[:, mapping.source_joints[k]]
        b = target[:, mapping.target_child[k]] - target[:, mapping.target_joints[k]]
        cos = np.sum(a * b, -1) / np.linalg.norm(a, axis=-1) / np.linalg.norm(b, axis=-1)
        angles[role] = float(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))).mean())
    return angles
