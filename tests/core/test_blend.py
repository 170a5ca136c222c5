"""Blends (core/blend.py): the fade weights, the CF blend's ends, and the placement of a clip."""

from __future__ import annotations

import numpy as np
import pytest

from reactive_anim.core import bvh, quat
from reactive_anim.core.blend import blend, fade_weights, place
from reactive_anim.core.errors import SkeletonError
from tests.support.mocap import REPO


@pytest.fixture(scope="module")
def walk():
    return bvh.read_bvh(REPO / "sample_clips" / "walk.bvh")


def test_fade_weights_run_from_zero_to_one_with_flat_ends() -> None:
    w = fade_weights(21)
    assert w[0] == 0.0 and w[-1] == 1.0
    assert np.all(np.diff(w) > 0)
    slope = np.diff(w) * 20
    assert slope[0] < 0.05 and slope[-1] < 0.05  # a linear fade has slope 1 at both ends, this one 1.9 mid-way
    assert w[10] == pytest.approx(0.5)


def test_blend_equals_each_motion_at_its_end_and_lies_between(walk) -> None:
    a, b = walk.slice(0, 30), walk.slice(100, 130)
    out = blend(a, b, fade_weights(30))
    assert np.array_equal(out.local_rot[0], a.local_rot[0]) and np.array_equal(out.root_pos[0], a.root_pos[0])
    assert np.array_equal(out.local_rot[-1], b.local_rot[-1]) and np.array_equal(out.root_pos[-1], b.root_pos[-1])
    mid = out.local_rot[15]
    to_a, to_b = quat.angle_between(mid, a.local_rot[15]), quat.angle_between(mid, b.local_rot[15])
    total = quat.angle_between(a.local_rot[15], b.local_rot[15])
    assert np.allclose(to_a + to_b, total, atol=1e-9)  # on the shortest arc between the two


def test_blend_refuses_other_skeletons_or_lengths(walk) -> None:
    with pytest.raises(SkeletonError, match="equal lengths"):
        blend(walk.slice(0, 10), walk.slice(0, 11), fade_weights(10))


def test_place_turns_and_moves_the_whole_motion_rigidly(walk) -> None:
    clip = walk.slice(0, 40)
    placed = place(clip, np.pi / 2, (3.0, -1.0))
    p, q = clip.global_positions(), placed.global_positions()
    turned = np.stack([-p[..., 1] + 3.0, p[..., 0] - 1.0, p[..., 2]], axis=-1)
    assert np.allclose(q, turned, atol=1e-9)
    assert np.array_equal(placed.local_rot[:, 1:], clip.local_rot[:, 1:])
