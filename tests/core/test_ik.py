"""Two-bone IK (core/transition/ik.py): a nearly straight knee keeps its own plane.

A knee bent 3 degrees, its plane turned most of the way to the side (as in a walker turning), asked
to bend further: it bends on in its own plane. Rebuilt about the body's left-right line from 5
degrees of straightness, such a knee flicked 13 cm sideways and back in a kept walk's frame.
"""

from __future__ import annotations

import numpy as np

from reactive_anim.core.model import bvh
from reactive_anim.core.model.rig import Rig
from reactive_anim.core.transition.ik import two_bone_ik
from tests.support.mocap import REPO

IDLE = bvh.read_bvh(REPO / "sample_clips" / "idle.bvh")
RIG = Rig.of(IDLE.skeleton)


def _off_line(hip: np.ndarray, knee: np.ndarray, ankle: np.ndarray) -> np.ndarray:
    """The knee's offset from the hip-ankle line."""
    axis = (ankle - hip) / np.linalg.norm(ankle - hip)
    rel = knee - hip
    return rel - axis * np.dot(rel, axis)


def test_a_knee_bent_three_degrees_bends_on_in_its_own_plane():
    pos, glob = IDLE.slice(0, 1).global_transforms()
    hip, knee, ankle = (RIG.joints[name] for name in ("hip_r", "knee_r", "ankle_r"))
    thigh = float(np.linalg.norm(pos[0, knee] - pos[0, hip]))
    shin = float(np.linalg.norm(pos[0, ankle] - pos[0, knee]))
    left, forward = np.array([[0.0, 1.0, 0.0]]), np.array([[1.0, 0.0, 0.0]])
    side = np.array([np.cos(np.radians(80.0)), -np.sin(np.radians(80.0)), 0.0])  # 80 degrees off forward
    down = np.array([0.0, 0.0, -1.0])
    half = np.radians(1.5)  # each bone 1.5 degrees off the line: the knee 3 degrees from straight
    pos[0, knee] = pos[0, hip] + thigh * (np.cos(half) * down + np.sin(half) * side)
    pos[0, ankle] = pos[0, knee] + shin * (np.cos(half) * down - np.sin(half) * side)
    assert (
        np.sum(np.cross(pos[0, hip] - pos[0, knee], pos[0, ankle] - pos[0, knee]) * left[0]) < 0.0
    )  # bent forward a little
    before = _off_line(pos[0, hip], pos[0, knee], pos[0, ankle])
    goal = pos[:, ankle] + np.array([0.0, 0.0, 0.05])
    two_bone_ik(IDLE.skeleton, pos, glob, (hip, knee, ankle), goal, np.ones(1), left, forward)
    after = _off_line(pos[0, hip], pos[0, knee], pos[0, ankle])
    assert np.linalg.norm(pos[0, ankle] - goal[0]) < 1e-6
    assert np.linalg.norm(after) > 2 * np.linalg.norm(before)  # bent further
    turned = np.degrees(np.arccos(np.dot(after, before) / np.linalg.norm(after) / np.linalg.norm(before)))
    assert turned < 5.0, turned
