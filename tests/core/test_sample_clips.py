"""The committed sample clips: rebuilt byte for byte by tools/make_sample_clips.py, and a walk that
is physically sane (named joints, planted feet, above the floor, smooth, looping, moving forward).

The tool lives in tools/, which is not a package, so it is imported from its file path.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

from reactive_anim.core import bvh, quat
from reactive_anim.core.skeleton import Motion

REPO = Path(__file__).resolve().parents[2]
TOOL = REPO / "tools" / "make_sample_clips.py"
CLIPS = REPO / "sample_clips"
UP = np.array([0.0, 0.0, 1.0])

# Other code relies on these exact names and this hierarchy (joint -> parent).
PARENTS = {
    "pelvis": None,
    "spine": "pelvis",
    "spine.001": "spine",
    "chest": "spine.001",
    "neck": "chest",
    "head": "neck",
    "shoulder.L": "chest",
    "upper_arm.L": "shoulder.L",
    "forearm.L": "upper_arm.L",
    "hand.L": "forearm.L",
    "shoulder.R": "chest",
    "upper_arm.R": "shoulder.R",
    "forearm.R": "upper_arm.R",
    "hand.R": "forearm.R",
    "thigh.L": "pelvis",
    "shin.L": "thigh.L",
    "foot.L": "shin.L",
    "toe.L": "foot.L",
    "thigh.R": "pelvis",
    "shin.R": "thigh.R",
    "foot.R": "shin.R",
    "toe.R": "foot.R",
}
END_SITES = {"head", "hand.L", "hand.R", "toe.L", "toe.R"}
FEET = ["foot.L", "foot.R", "toe.L", "toe.R"]


@pytest.fixture(scope="module")
def tool() -> ModuleType:
    spec = importlib.util.spec_from_file_location("make_sample_clips", TOOL)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up here while executing
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def walk() -> Motion:
    return bvh.read_bvh(CLIPS / "walk.bvh")


@pytest.fixture(scope="module")
def walk_points(walk: Motion) -> dict[str, np.ndarray]:
    """World positions (T, 3) of every joint, and of every End Site as '<joint>.tip'."""
    pos, rot = walk.global_transforms()
    points = {name: pos[:, j] for j, name in enumerate(walk.skeleton.names)}
    for j, offset in walk.skeleton.end_sites.items():
        points[walk.skeleton.names[j] + ".tip"] = pos[:, j] + quat.rotate(rot[:, j], offset)
    return points


def planted_slides(points: np.ndarray, fps: float) -> list[float]:
    """Horizontal drift of a point over each stretch of frames where it is planted.

    Planted: within 1 cm of its lowest height in the clip and moving slower than 0.2 m/s. A swing
    foot moves far faster; a skating foot still counts as planted, and its drift accumulates.
    """
    speed = np.linalg.norm(np.diff(points[:, :2], axis=0), axis=1) * fps
    speed = np.concatenate([speed[:1], speed])
    planted = (points[:, 2] <= points[:, 2].min() + 0.01) & (speed < 0.2)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], planted.astype(int), [0]])))
    return [
        float(np.linalg.norm(points[a:b, :2] - points[a, :2], axis=1).max()) for a, b in zip(edges[::2], edges[1::2])
    ]


def period(motion: Motion) -> int:
    """The shortest lag (frames, at least 0.4 s) after which every joint rotation repeats."""
    for lag in range(int(0.4 * motion.fps), motion.num_frames // 2 + 1):
        if quat.angle_between(motion.local_rot[lag:], motion.local_rot[:-lag]).max() < 1e-5:
            return lag
    pytest.fail("the walk has no repeating cycle")


# ---------------------------------------------------------------------------------------------
# Reproducible


def test_regenerating_gives_byte_identical_files(tool: ModuleType, tmp_path: Path) -> None:
    written = tool.write_clips(tmp_path)
    assert sorted(p.name for p in written) == sorted(p.name for p in CLIPS.glob("*.bvh"))
    for path in written:
        assert path.read_bytes() == (CLIPS / path.name).read_bytes(), f"{path.name} differs from sample_clips/"


def test_sample_skeleton_is_the_one_in_the_file(tool: ModuleType, walk: Motion) -> None:
    skeleton = tool.sample_skeleton()
    assert skeleton.names == walk.skeleton.names
    np.testing.assert_array_equal(skeleton.parents, walk.skeleton.parents)
    np.testing.assert_allclose(skeleton.offsets, walk.skeleton.offsets, atol=1e-6)
    assert skeleton.end_sites.keys() == walk.skeleton.end_sites.keys()
    for j, tip in skeleton.end_sites.items():
        np.testing.assert_allclose(tip, walk.skeleton.end_sites[j], atol=1e-6)


# ---------------------------------------------------------------------------------------------
# The file


def test_walk_has_the_named_22_joint_skeleton(walk: Motion) -> None:
    sk = walk.skeleton
    assert sk.names == list(PARENTS)
    assert [None if p < 0 else sk.names[p] for p in sk.parents] == list(PARENTS.values())
    assert {sk.names[j] for j in sk.end_sites} == END_SITES


def test_walk_timing(walk: Motion) -> None:
    assert walk.fps == pytest.approx(60.0)
    assert walk.num_frames / walk.fps >= 4.0


def test_units_are_detected_as_centimetres_and_the_character_is_175_cm(walk: Motion) -> None:
    assert bvh.unit_scale(bvh.parse_bvh(CLIPS / "walk.bvh")) == bvh.UNITS["cm"]
    sk = walk.skeleton
    head = sk.index("head")
    crown = sk.rest_positions()[head] + sk.end_sites[head]
    assert crown[2] == pytest.approx(1.75, abs=0.005)
    assert sk.rest_extent() == pytest.approx(1.75, abs=0.03)


def test_rest_pose_has_left_on_plus_x_and_faces_minus_y(walk: Motion) -> None:
    sk = walk.skeleton
    rest = sk.rest_positions()
    for joint in ("upper_arm", "hand", "thigh", "foot"):
        assert rest[sk.index(f"{joint}.L")][0] > 0 > rest[sk.index(f"{joint}.R")][0]
    toe = rest[sk.index("toe.L")] - rest[sk.index("foot.L")]
    assert toe[1] < 0  # the toes point along -Y


# ---------------------------------------------------------------------------------------------
# The motion


def test_stance_feet_do_not_slide(walk: Motion, walk_points: dict[str, np.ndarray]) -> None:
    for name in FEET + ["toe.L.tip", "toe.R.tip"]:
        slides = planted_slides(walk_points[name], walk.fps)
        assert len(slides) >= 4, f"{name} is planted only {len(slides)} times in a 4 s walk"
        assert max(slides) < 0.02, f"{name} slides {max(slides) * 100:.1f} cm while planted"


def test_the_slide_measure_notices_a_skating_foot(walk: Motion) -> None:
    """Guards the test above: the walk with the whole body drifting sideways at 0.1 m/s fails it."""
    drift = np.arange(walk.num_frames)[:, None] / walk.fps * np.array([0.1, 0.0, 0.0])
    skating = Motion(walk.skeleton, walk.fps, walk.root_pos + drift, walk.local_rot)
    foot = skating.global_positions()[:, walk.skeleton.index("foot.L")]
    assert max(planted_slides(foot, walk.fps)) > 0.02


def test_nothing_goes_below_the_floor(walk_points: dict[str, np.ndarray]) -> None:
    lowest = min(walk_points, key=lambda name: walk_points[name][:, 2].min())
    assert walk_points[lowest][:, 2].min() > -0.01, f"{lowest} goes below the floor"


def test_no_joint_turns_faster_than_30_rad_per_s(walk: Motion) -> None:
    speed = quat.angle_between(walk.local_rot[1:], walk.local_rot[:-1]) * walk.fps
    frame, joint = np.unravel_index(np.argmax(speed), speed.shape)
    assert speed.max() < 30.0, f"{walk.skeleton.names[joint]} turns at {speed.max():.1f} rad/s at frame {frame}"


def test_walk_loops_seamlessly(walk: Motion) -> None:
    lag = period(walk)
    assert walk.num_frames % lag == 0, f"{walk.num_frames} frames is not a whole number of {lag}-frame cycles"
    stride = walk.root_pos[lag:] - walk.root_pos[:-lag]
    np.testing.assert_allclose(stride, np.broadcast_to(stride[0], stride.shape), atol=1e-5)
    assert abs(stride[0, 2]) < 1e-5
    # The frame after the last is the first one carried forward by whole strides: the step into it
    # is no bigger than any step inside the clip.
    next_root = walk.root_pos[0] + stride[0] * (walk.num_frames // lag)
    turns = quat.angle_between(walk.local_rot[1:], walk.local_rot[:-1]).max(axis=0)
    seam_turn = quat.angle_between(walk.local_rot[-1], walk.local_rot[0])
    assert np.all(seam_turn <= turns + 1e-6)
    moves = np.linalg.norm(np.diff(walk.root_pos, axis=0), axis=1)
    assert np.linalg.norm(next_root - walk.root_pos[-1]) <= moves.max() + 1e-6


def test_walking_speed_is_brisk_but_a_walk(walk: Motion) -> None:
    lag = period(walk)
    stride = walk.root_pos[lag] - walk.root_pos[0]
    speed = np.linalg.norm(stride[:2]) * walk.fps / lag
    assert 1.0 <= speed <= 1.6


def test_the_character_walks_the_way_it_faces(walk: Motion, walk_points: dict[str, np.ndarray]) -> None:
    travel = walk.root_pos[-1, :2] - walk.root_pos[0, :2]
    travel /= np.linalg.norm(travel)
    # Facing from the hips: forward = (left hip - right hip) x up, so swapped sides would face back.
    facing = np.cross(walk_points["thigh.L"] - walk_points["thigh.R"], UP)[:, :2]
    facing /= np.linalg.norm(facing, axis=1, keepdims=True)
    assert np.min(facing @ travel) > 0.97
    # And the feet point forward too, independently of the names.
    for side in "LR":
        toes = (walk_points[f"toe.{side}"] - walk_points[f"foot.{side}"])[:, :2]
        toes /= np.linalg.norm(toes, axis=1, keepdims=True)
        assert np.mean(toes @ travel) > 0.9
    assert travel @ np.array([0.0, -1.0]) > 0.99  # along -Y, the documented facing
