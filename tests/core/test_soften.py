"""Softening the simulated stretch where a joint's acceleration spikes (core/transition/soften.py),
on the sample walk made to stop dead, as a contact stops a simulated limb between two frames."""

from __future__ import annotations

import numpy as np
import pytest

from reactive_anim.core.model import bvh
from reactive_anim.core.model.acceleration import STRIDE
from reactive_anim.core.model.skeleton import Motion
from reactive_anim.core.transition.soften import OUTDONE, OUTDONE_PASSES, SIGMA, SPIKE_FULL, soften
from tests.support.mocap import REPO
from tools.devkit import believability as bl

STOP = 120  # the frame from which the stopped walk holds its pose


@pytest.fixture(scope="module")
def walk() -> Motion:
    return bvh.read_bvh(REPO / "sample_clips" / "walk.bvh")


@pytest.fixture(scope="module")
def stopped(walk) -> Motion:
    """The sample walk holding frame STOP's pose from there on: the swing foot, at about 4 m/s,
    stops within a frame."""
    held = np.minimum(np.arange(walk.num_frames), STOP)
    return Motion(walk.skeleton, walk.fps, walk.root_pos[held], walk.local_rot[held])


def largest_acceleration(motion: Motion, first: int, stop: int) -> float:
    return float(np.nanmax(bl.acceleration(motion.global_positions(), motion.fps)[first:stop]))


def test_a_dead_stop_is_rounded_off_and_the_rest_left_as_it_was(walk, stopped) -> None:
    """The stop's acceleration (over the benchmark's 1/30 s stride) more than halves; the
    frames before `first`, and those too far from the stop for its stencil and the Gaussian's reach
    to touch, are the same bit for bit."""
    first = STOP - 30
    out = soften(stopped, first)
    raw = largest_acceleration(stopped, STOP - 10, STOP + 10)
    assert raw > 100.0, raw  # the walk's own largest is 59 m/s^2
    assert largest_acceleration(out, STOP - 10, STOP + 10) < 0.5 * raw  # measured 123 -> 44
    assert np.array_equal(out.local_rot[:first], stopped.local_rot[:first])
    touched = round(STRIDE * walk.fps) * 2 + int(np.ceil(2.0 * SIGMA * walk.fps)) + 1
    assert np.array_equal(out.local_rot[STOP + touched :], stopped.local_rot[STOP + touched :])
    assert np.array_equal(out.root_pos[STOP + touched :], stopped.root_pos[STOP + touched :])
    assert not np.array_equal(out.local_rot[STOP - 2 : STOP + 2], stopped.local_rot[STOP - 2 : STOP + 2])


def test_a_harder_stop_is_softened_again_until_it_no_longer_spikes(walk) -> None:
    """The sample walk played twice as fast, stopped dead: its feet stop from about 8 m/s (257
    m/s^2). One pass of the Gaussian leaves 106, over SPIKE_FULL; softened again while a frame
    spikes (soften.PASSES), the stop ends under it (measured 57)."""
    fast = Motion(walk.skeleton, walk.fps, walk.root_pos[::2], walk.local_rot[::2])
    held = np.minimum(np.arange(fast.num_frames), STOP // 2)
    stopped = Motion(fast.skeleton, fast.fps, fast.root_pos[held], fast.local_rot[held])
    around = (STOP // 2 - 10, STOP // 2 + 10)
    assert largest_acceleration(stopped, *around) > 200.0
    assert largest_acceleration(soften(stopped, STOP // 2 - 30), *around) < SPIKE_FULL


def test_frames_from_last_on_are_read_but_never_written(stopped) -> None:
    """Softened up to `last` only (a reaction's end, where the original take plays on): the frames
    from `last` on stay bit for bit though the stop spikes there too, and those before it near the
    stop are softened."""
    last = STOP + 1
    out = soften(stopped, STOP - 30, last=last)
    assert np.array_equal(out.local_rot[last:], stopped.local_rot[last:])
    assert np.array_equal(out.root_pos[last:], stopped.root_pos[last:])
    assert not np.array_equal(out.local_rot[STOP - 2 : last], stopped.local_rot[STOP - 2 : last])


def test_a_whole_reaction_is_softened_only_where_it_nears_real_falls(walk, stopped) -> None:
    """With OUTDONE: the walk stopped dead (123 m/s^2) is left as it is; played four times as fast
    and stopped (561), one pass leaves it over the real falls' largest (166), and OUTDONE_PASSES
    passes bring it under."""
    out = soften(stopped, STOP - 30, OUTDONE, passes=OUTDONE_PASSES)
    assert np.array_equal(out.local_rot, stopped.local_rot) and np.array_equal(out.root_pos, stopped.root_pos)
    fast = Motion(walk.skeleton, walk.fps, walk.root_pos[::4], walk.local_rot[::4])
    stop = STOP // 4
    held = np.minimum(np.arange(fast.num_frames), stop)
    hard = Motion(fast.skeleton, fast.fps, fast.root_pos[held], fast.local_rot[held])
    around = (stop - 8, stop + 8)
    assert largest_acceleration(hard, *around) > 400.0
    assert largest_acceleration(soften(hard, stop - 20, OUTDONE, passes=1), *around) > 166.0  # measured 173
    assert largest_acceleration(soften(hard, stop - 20, OUTDONE, passes=OUTDONE_PASSES), *around) < 166.0  # 116


def test_a_pass_up_to_last_writes_what_a_pass_over_the_whole_motion_writes_before_it(stopped) -> None:
    """soften reads only the frames a row before `last` can see: before `last`, one pass up to it
    is the same, bit for bit, as one pass over the whole motion, wherever `last` falls near the
    stop."""
    whole = soften(stopped, STOP - 30, passes=1)
    for last in range(STOP - 25, STOP + 5):
        part = soften(stopped, STOP - 30, passes=1, last=last)
        assert np.array_equal(part.local_rot[:last], whole.local_rot[:last]), last
        assert np.array_equal(part.root_pos[:last], whole.root_pos[:last]), last


def test_a_motion_without_spikes_is_returned_as_it_is() -> None:
    """The sample idle: no joint accelerates anywhere near SPIKE_FROM, so nothing changes."""
    idle = bvh.read_bvh(REPO / "sample_clips" / "idle.bvh")
    out = soften(idle, 1)
    assert np.array_equal(out.local_rot, idle.local_rot) and np.array_equal(out.root_pos, idle.root_pos)


def test_the_sign_of_a_quaternion_does_not_change_the_result(stopped) -> None:
    """q and -q are the same turn: with every other frame's rotations negated, the softened pose is
    the same (rotations are averaged made continuous in time), and the frames left alone are the
    ones left alone unflipped."""
    flipped = stopped.local_rot.copy()
    flipped[1::2] *= -1.0
    flipped_motion = Motion(stopped.skeleton, stopped.fps, stopped.root_pos, flipped)
    a, b = soften(stopped, STOP - 30), soften(flipped_motion, STOP - 30)
    assert np.allclose(a.global_positions(), b.global_positions(), atol=1e-9)
    # and a frame it does not soften keeps its own quaternion, sign and all
    changed = [
        np.flatnonzero((m.local_rot != src.local_rot).any(axis=(1, 2)))
        for m, src in ((a, stopped), (b, flipped_motion))
    ]
    assert np.array_equal(changed[0], changed[1]) and len(changed[0]) < stopped.num_frames - (STOP - 30)
