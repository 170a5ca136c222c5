"""Blends (core/transition/blend.py): the fade weights, the CF blend's ends, and the placement of a clip."""

from __future__ import annotations

import numpy as np
import pytest

from reactive_anim.core.model import bvh, quat
from reactive_anim.core.model.errors import SkeletonError
from reactive_anim.core.model.skeleton import Motion, Skeleton
from reactive_anim.core.transition.blend import blend, blend_travel, carry, fade_weights, place
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


@pytest.mark.parametrize(("lag", "delay"), [(1.5, 0.0), (2.5, 0.0), (0.75, 0.0), (1.0, 0.35)])
def test_a_fade_shaped_otherwise_still_runs_from_zero_to_one_with_flat_ends(lag: float, delay: float) -> None:
    w = fade_weights(301, lag, delay)
    assert w[0] == 0.0 and w[-1] == 1.0 and np.all(np.diff(w) >= 0.0)
    slope = np.diff(w) * 300
    assert slope[0] < 0.01 and slope[-1] < 0.01
    assert np.all(w[: int(delay * 300)] == 0.0)  # held back: the first source's alone
    assert (w[150] < 0.5) == (lag > 1.0 or delay > 0.0)


@pytest.mark.parametrize(("lag", "delay"), [(0.0, 0.0), (-1.0, 0.0), (1.0, 1.0), (1.0, -0.1)])
def test_a_fade_shape_out_of_range_is_refused(lag: float, delay: float) -> None:
    with pytest.raises(ValueError, match="delay"):
        fade_weights(10, lag, delay)


def test_blend_equals_each_motion_at_its_end_and_lies_between(walk) -> None:
    a, b = walk.slice(0, 30), walk.slice(100, 130)
    out = blend(a, b, fade_weights(30))
    assert np.array_equal(out.local_rot[0], a.local_rot[0]) and np.array_equal(out.root_pos[0], a.root_pos[0])
    assert np.array_equal(out.local_rot[-1], b.local_rot[-1]) and np.array_equal(out.root_pos[-1], b.root_pos[-1])
    mid = out.local_rot[15]
    to_a, to_b = quat.angle_between(mid, a.local_rot[15]), quat.angle_between(mid, b.local_rot[15])
    total = quat.angle_between(a.local_rot[15], b.local_rot[15])
    assert np.allclose(to_a + to_b, total, atol=1e-9)  # on the shortest arc between the two


def test_carry_starts_from_the_pose_and_lets_go_of_it_smoothly(walk) -> None:
    """theta_blend's start (blend.carry): the first frame takes the pose's rotations, the turn
    between them shrinks without a step, and from `frames` on the motion is its own; the root's
    path is never touched."""
    motion, pose = walk.slice(40, 71), walk.slice(100, 101)
    out = carry(motion, pose, 12)
    assert np.allclose(quat.angle_between(out.local_rot[0], pose.local_rot[0]), 0.0, atol=1e-7)
    assert np.array_equal(out.root_pos, motion.root_pos)
    assert np.allclose(quat.angle_between(out.local_rot[12:], motion.local_rot[12:]), 0.0, atol=1e-7)
    gap = quat.angle_between(out.local_rot, motion.local_rot).max(axis=1)  # the turn still carried
    assert gap[0] > 0.3 and np.all(np.diff(gap[:13]) <= 1e-9)
    assert np.abs(np.diff(gap[:13])).max() < 0.25 * gap[0]  # let go over frames, never at once


def test_blend_refuses_other_skeletons_or_lengths(walk) -> None:
    with pytest.raises(SkeletonError, match="equal lengths"):
        blend(walk.slice(0, 10), walk.slice(0, 11), fade_weights(10))


def test_a_travel_fade_changes_pace_by_the_speed_gap_and_the_next_source_carries_on(walk) -> None:
    """The walk faded into itself standing still 0.5 m behind: a position fade drags the pelvis back
    onto the still one's spot, a travel fade lets it slow down where it is. The pelvis' largest
    acceleration over the floor is the fade's slope times the speed gap (smootherstep: 1.875 / T),
    and the offset returned puts the still source's last frame where the fade ended."""
    fps, frames = walk.fps, 9
    pelvis = walk.skeleton.index("pelvis")
    moving = walk.slice(40, 40 + frames)
    still = Motion(walk.skeleton, fps, np.repeat(moving.root_pos[:1] - [[0.5, 0.0, 0.0]], frames, axis=0),
                   np.repeat(moving.local_rot[:1], frames, axis=0))  # fmt: skip
    w = fade_weights(frames)
    speed = np.linalg.norm(np.diff(moving.global_positions()[:, pelvis, :2], axis=0), axis=1).mean() * fps

    def floor_accel(m: Motion) -> float:
        p = m.global_positions()[:, pelvis, :2]
        return float(np.linalg.norm(np.diff(p, 2, axis=0), axis=1).max() * fps * fps)

    travelled, carried = blend_travel(moving, still, w, pelvis)
    assert floor_accel(travelled) <= 1.3 * 1.875 * speed / ((frames - 1) / fps)
    assert floor_accel(blend(moving, still, w)) > 2.0 * floor_accel(travelled)
    end = travelled.global_positions()[-1, pelvis, :2]
    assert np.allclose(end, still.global_positions()[-1, pelvis, :2] + carried, atol=1e-9)
    assert np.linalg.norm(carried) > 0.5  # it went on forward rather than back to the still spot
    assert np.allclose(travelled.global_positions()[-1, :, 2], still.global_positions()[-1, :, 2])  # heights faded
    # The resume's way: the pace taken up over the first 4 steps, the pose over all 8: from then on
    # the pelvis steps as the still source does (not at all), while the pose is still fading.
    pace = np.concatenate([fade_weights(5), np.ones(frames - 5)])
    quick, _ = blend_travel(moving, still, w, pelvis, pace)
    steps = np.linalg.norm(np.diff(quick.global_positions()[:, pelvis, :2], axis=0), axis=1)
    assert steps[0] > 0.0 and np.allclose(steps[4:], 0.0, atol=1e-9)
    assert not np.allclose(quick.local_rot[5], still.local_rot[5])


def test_place_turns_and_moves_the_whole_motion_rigidly(walk) -> None:
    clip = walk.slice(0, 40)
    placed = place(clip, np.pi / 2, (3.0, -1.0))
    p, q = clip.global_positions(), placed.global_positions()
    turned = np.stack([-p[..., 1] + 3.0, p[..., 0] - 1.0, p[..., 2]], axis=-1)
    assert np.allclose(q, turned, atol=1e-9)
    assert np.array_equal(placed.local_rot[:, 1:], clip.local_rot[:, 1:])


def _on_ground_root(motion: Motion, animated: bool) -> Motion:
    """The motion under a ground root bone that stays at the origin, as in the Bandai Namco files:
    the walk carried by the hips' own position channels (animated), or the hips hung 4.5 m from the
    root by their rest offset with the root carrying the walk (as a cast clip of such a file)."""
    sk = motion.skeleton
    long = np.array([0.0, 4.5, 0.9])
    root_offsets = motion.root_pos if animated else np.broadcast_to(long, motion.root_pos.shape)
    skeleton = Skeleton(["ground", *sk.names], np.concatenate([[-1], np.where(sk.parents < 0, 0, sk.parents + 1)]),
                        np.concatenate([np.zeros((1, 3)), long[None], sk.offsets[1:]]))  # fmt: skip
    offsets = np.concatenate([np.zeros((motion.num_frames, 1, 3)), motion.joint_offsets()], axis=1)
    offsets[:, 1] = root_offsets
    rot = np.concatenate([quat.identity((motion.num_frames, 1)), motion.local_rot], axis=1)
    root = np.zeros((motion.num_frames, 3)) if animated else motion.root_pos - long
    return Motion(skeleton, motion.fps, root, rot, offsets if animated else None)


@pytest.mark.parametrize("animated", [True, False])
def test_hips_under_a_ground_root_fade_along_the_line_between_the_sources(walk, animated) -> None:
    """Two sources whose ground roots are half a turn apart (a placed clip and the character):
    blended through the root's turn, the hips would swing on an arc as wide as their offset from
    the root; in world space they go straight from one source's hips to the other's. With the
    hips' offset animated the root goes straight too and the offset takes up the difference; with
    both on the rest bone, the bone keeps its length and the root moves to hang the hips."""
    a = _on_ground_root(walk.slice(0, 30), animated)
    b = place(_on_ground_root(walk.slice(100, 130), animated), 0.9 * np.pi, (4.0, -2.0))
    w = fade_weights(30)
    out = blend(a, b, w)
    hips = [m.global_transforms() for m in (a, b, out)]
    line = hips[0][0][:, 1] + (hips[1][0][:, 1] - hips[0][0][:, 1]) * w[:, None]
    assert np.abs(hips[2][0][:, 1] - line).max() < 1e-9
    turned = quat.slerp(hips[0][1][:, 1], hips[1][1][:, 1], w)
    assert quat.angle_between(hips[2][1][:, 1], turned).max() < 1e-9
    if animated:
        assert np.array_equal(out.root_pos, a.root_pos + (b.root_pos - a.root_pos) * w[:, None])
        assert out.local_pos is not None and a.local_pos is not None and b.local_pos is not None
        assert np.array_equal(out.local_pos[0], a.local_pos[0]) and np.array_equal(out.local_pos[-1], b.local_pos[-1])
    else:
        assert out.local_pos is None  # the bone keeps its rest length on every frame
        assert np.array_equal(out.root_pos[[0, -1]], np.stack([a.root_pos[0], b.root_pos[-1]]))


def test_a_single_frame_or_none_blends() -> None:
    """The get-up chain can fade over one frame (blend of length 1); an empty blend is empty."""
    walk = bvh.read_bvh(REPO / "sample_clips" / "walk.bvh")
    one = blend(walk.slice(0, 1), walk.slice(50, 51), fade_weights(1))
    assert np.array_equal(one.local_rot, walk.local_rot[50:51])
    assert blend(walk.slice(0, 0), walk.slice(0, 0), fade_weights(0)).num_frames == 0


def test_a_joint_passing_half_a_turn_from_the_other_source_keeps_its_arc(walk) -> None:
    """One source turns a joint steadily past half a turn from the other's (a leg the simulation
    kicked high against a planted clip leg): the shorter arc on each frame would switch sides there
    and the joint jump by about half a turn; the fade keeps one arc, at most 11 degrees a frame."""
    a, b = walk.slice(0, 30), walk.slice(0, 30)
    angles = np.radians(150.0 + 2.0 * np.arange(30))  # 180 degrees apart at frame 15
    a.local_rot[:, 1] = quat.from_axis_angle(np.array([0.0, 0.0, 1.0]), angles)
    b.local_rot[:, 1] = quat.identity((30,))
    out = blend(a, b, fade_weights(30))
    steps = np.degrees(quat.angle_between(out.local_rot[1:, 1], out.local_rot[:-1, 1]))
    assert steps.max() < 15.0, steps.max()
    shortest = quat.slerp(a.local_rot[:, 1], b.local_rot[:, 1], fade_weights(30))
    assert np.degrees(quat.angle_between(shortest[1:], shortest[:-1])).max() > 90.0  # what it did before
