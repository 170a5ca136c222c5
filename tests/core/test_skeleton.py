"""Forward kinematics: a level of the hierarchy at a time gives the same bits as joint by joint."""

from __future__ import annotations

import numpy as np

from reactive_anim.core.model import bvh, quat
from reactive_anim.core.model.skeleton import forward_kinematics
from tests.support.mocap import REPO


def _joint_by_joint(skeleton, root_pos, local_rot, offsets):
    pos, rot = np.empty(local_rot.shape[:2] + (3,)), np.empty(local_rot.shape)
    pos[:, 0], rot[:, 0] = root_pos, local_rot[:, 0]
    for j in range(1, skeleton.num_joints):
        p = skeleton.parents[j]
        pos[:, j] = pos[:, p] + quat.rotate(rot[:, p], offsets[:, j])
        rot[:, j] = quat.mul(rot[:, p], local_rot[:, j])
    return pos, rot


def test_levels_cover_every_joint_once_parents_first() -> None:
    skeleton = bvh.read_bvh(REPO / "sample_clips" / "walk.bvh").skeleton
    order = np.concatenate(skeleton.levels)
    assert sorted(order.tolist()) == list(range(skeleton.num_joints))
    depth = {int(j): d for d, level in enumerate(skeleton.levels) for j in level}
    assert all(depth[j] == depth[int(skeleton.parents[j])] + 1 for j in range(1, skeleton.num_joints))


def test_forward_kinematics_by_levels_is_bit_identical_to_joint_by_joint() -> None:
    motion = bvh.read_bvh(REPO / "sample_clips" / "walk.bvh")
    rng = np.random.default_rng(4)
    local_rot = quat.normalize(motion.local_rot + rng.normal(scale=0.05, size=motion.local_rot.shape))
    offsets = np.broadcast_to(motion.skeleton.offsets, local_rot.shape[:2] + (3,))
    fast = forward_kinematics(motion.skeleton, motion.root_pos, local_rot, offsets)
    slow = _joint_by_joint(motion.skeleton, motion.root_pos, local_rot, offsets)
    np.testing.assert_array_equal(fast[0], slow[0])
    np.testing.assert_array_equal(fast[1], slow[1])
