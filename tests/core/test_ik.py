"""Two-bone IK (core/transition/ik.py): a nearly straight knee keeps its own plane.

A knee bent 3 degrees, its plane turned most of the way to the side (as in a walker turning), asked
to bend further: it bends on in its own plane. Rebuilt about the body's left-right line from 5
degrees of straightness, such a knee flicked 13 cm sideways and back in a kept walk's frame. A knee
bent to the side keeps its plane whichever side of square it is; one bent backward is rebuilt.
"""

from __future__ import annotations

from itertools import pairwise

import numpy as np
import pytest

from reactive_anim.core.model import bvh, quat
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


def _bent_leg(bend: float, heading: float) -> tuple[np.ndarray, np.ndarray, tuple[int, int, int]]:
    """The idle's first frame with the right leg hanging straight down but for a knee bent `bend`
    degrees toward `heading` degrees off forward, to the right (the body faces +x, left is +y)."""
    pos, glob = IDLE.slice(0, 1).global_transforms()
    hip, knee, ankle = (RIG.joints[name] for name in ("hip_r", "knee_r", "ankle_r"))
    thigh = float(np.linalg.norm(pos[0, knee] - pos[0, hip]))
    shin = float(np.linalg.norm(pos[0, ankle] - pos[0, knee]))
    side = np.array([np.cos(np.radians(heading)), -np.sin(np.radians(heading)), 0.0])
    down = np.array([0.0, 0.0, -1.0])
    half = np.radians(bend / 2.0)  # each bone half the bend off the line
    pos[0, knee] = pos[0, hip] + thigh * (np.cos(half) * down + np.sin(half) * side)
    pos[0, ankle] = pos[0, knee] + shin * (np.cos(half) * down - np.sin(half) * side)
    return pos, glob, (hip, knee, ankle)


def _lifted(bend: float, heading: float) -> tuple[np.ndarray, np.ndarray]:
    """The knee's offset from the hip-ankle line before and after its ankle is lifted 5 cm."""
    pos, glob, (hip, knee, ankle) = _bent_leg(bend, heading)
    left, forward = np.array([[0.0, 1.0, 0.0]]), np.array([[1.0, 0.0, 0.0]])
    before = _off_line(pos[0, hip], pos[0, knee], pos[0, ankle])
    goal = pos[:, ankle] + np.array([0.0, 0.0, 0.05])
    two_bone_ik(IDLE.skeleton, pos, glob, (hip, knee, ankle), goal, np.ones(1), left, forward)
    assert np.linalg.norm(pos[0, ankle] - goal[0]) < 1e-6
    return before, _off_line(pos[0, hip], pos[0, knee], pos[0, ankle])


def _turn(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.dot(a, b) / np.linalg.norm(a) / np.linalg.norm(b))))


def test_a_knee_bent_three_degrees_bends_on_in_its_own_plane():
    before, after = _lifted(3.0, 80.0)  # its plane turned most of the way to the side
    assert np.linalg.norm(after) > 2 * np.linalg.norm(before)  # bent further
    assert _turn(after, before) < 5.0


def test_a_knee_bent_to_the_side_keeps_its_plane_on_either_side_of_square():
    """A limb swung out to the side bends about an axis near right angles to the body's left-right
    line; a little past it (95 degrees off forward) it is no more backward than at 85. The arm of a
    lying body, lifted out of the floor, crossed it from frame to frame and its elbow flicked
    between its own plane and one rebuilt about the left-right line (478 m/s^2)."""
    for heading in (85.0, 95.0):
        before, after = _lifted(20.0, heading)
        assert _turn(after, before) < 5.0, heading


def test_a_knee_bent_backward_is_rebuilt_bending_forward():
    before, after = _lifted(10.0, 170.0)
    assert _turn(after, before) > 150.0
    assert after[0] > 0.0  # the knee now ahead of the hip-ankle line: bent forward, shin back


def test_a_knee_s_plane_turns_gradually_as_its_bend_turns_backward() -> None:
    """Bent 20 degrees at headings from the side round to straight back, 2 degrees apart: where it
    stops counting as bent its own way, the lifted knee's plane turns over a band of headings, never
    more than 15 degrees between neighbours (a single threshold flicked it 120 degrees)."""
    offsets = [_lifted(20.0, heading)[1] for heading in np.arange(90.0, 182.0, 2.0)]
    turns = [_turn(a, b) for a, b in pairwise(offsets)]
    assert max(turns) < 15.0, np.round(turns, 1)


def _bent_straight_back(abduct: float, lean: float) -> tuple[np.ndarray, np.ndarray]:
    """The right thigh swung out `abduct` degrees to the side, the knee bent 30 degrees straight
    back but for `lean` (of a radian) toward the front; its offset from the hip-ankle line before
    and after the ankle is lifted 5 cm."""
    pos, glob = IDLE.slice(0, 1).global_transforms()
    hip, knee, ankle = (RIG.joints[name] for name in ("hip_r", "knee_r", "ankle_r"))
    thigh = float(np.linalg.norm(pos[0, knee] - pos[0, hip]))
    shin = float(np.linalg.norm(pos[0, ankle] - pos[0, knee]))
    along = np.array([0.0, -np.sin(np.radians(abduct)), -np.cos(np.radians(abduct))])
    left, forward = np.array([0.0, 1.0, 0.0]), np.array([1.0, 0.0, 0.0])
    square = left - along * np.dot(left, along)
    axis = square / np.linalg.norm(square) + lean * forward
    axis /= np.linalg.norm(axis)
    shin_dir = quat.rotate(quat.from_axis_angle(-axis, np.radians(30.0)), along)
    pos[0, knee] = pos[0, hip] + thigh * along
    pos[0, ankle] = pos[0, knee] + shin * shin_dir
    before = _off_line(pos[0, hip], pos[0, knee], pos[0, ankle])
    goal = pos[:, ankle] + np.array([0.0, 0.0, 0.05])
    two_bone_ik(IDLE.skeleton, pos, glob, (hip, knee, ankle), goal, np.ones(1), left[None], forward[None])
    assert np.linalg.norm(pos[0, ankle] - goal[0]) < 1e-6
    return before, _off_line(pos[0, hip], pos[0, knee], pos[0, ankle])


@pytest.mark.parametrize("abduct", [0.0, 45.0, 60.0])
def test_a_knee_bent_straight_back_is_rebuilt_however_far_the_thigh_is_swung_out(abduct: float) -> None:
    """Judged against the whole left-right line, a knee bent straight back under a thigh swung out
    45 degrees or more read as only partly backward, and its two candidate planes lay half a turn
    apart: a thousandth of a radian either way turned it 70-139 degrees."""
    _, ahead = _bent_straight_back(abduct, 1e-3)
    _, behind = _bent_straight_back(abduct, -1e-3)
    assert _turn(ahead, behind) < 1.0
