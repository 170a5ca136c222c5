"""The committed sample clips: rebuilt by the generator (`python -m tools.sample_clips`), and
physically sane: a walk and a run that loop with planted feet, an idle stand, stepping reactions
whose steps and centre of mass do what their class says, sways, physics falls, get-ups from the
floor to standing, all above the floor, within anatomical joint ranges, smooth, and (the reactions)
ending at rest; and a reaction library list that parses and points at files that exist.

Rebuilt: made twice in one test session, every file comes out byte for byte the same. Against the
committed files: library.toml byte for byte; every clip made without physics numerically, as the
same hierarchy, channels, frame count and frame time with every number equal within the files'
rounding (4 decimals): positions and offsets within 2 units of the last digit, and each joint's
rotation, built from its Euler channels, within 5e-4 degrees of the committed one. Not the bytes:
an angle of exactly 180 degrees is written 180.0000 on one CPU and -180.0000 on another (measured
on an AMD EPYC against the committed files), and near gimbal lock another CPU may split a rotation
into a different Euler triple; both are the same rotation. The falls come from
MuJoCo, which gives the same bits for the same input in one process and on one machine (tested),
but not necessarily on another CPU or build (other SIMD paths round differently), and a fall is
chaotic once the body hits the floor. So a regenerated fall is compared with its committed file
in two parts:
- Up to the first contact of a hand, a knee, the head or the pelvis with the floor (the feet are
  on it from the start): tightly, every joint rotation within 0.01 degrees and the root within
  0.1 mm (the files round to 1e-4 degrees and 1 um).
- From that contact to the end: loosely, the root within 5 cm, every joint within 10 cm and every
  rotation within 15 degrees, the lengths within 1 s (the shorter clip held at its last frame:
  both end at rest, and where a fall comes to rest moves its cut).
Measured by regenerating the falls with every push changed by a tiny fraction of itself: a change
of 1e-8 turns no joint by more than 2e-5 degrees before contact; up to 1e-5, far more than
rounding differences could start, every fall passes (after contact the falls then move by up to
9.4 degrees, 3.7 cm at the root and 8.1 cm at a joint, and one clip's length by 39 frames); from
3e-5 some fail and at 1e-3 (0.1 %) all fail before contact, so a change of the tool is caught.
"""

from __future__ import annotations

import tomllib
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from reactive_anim.core.model import bvh, quat
from reactive_anim.core.model.classes import CLASS_SLUGS, is_fall, reaction_class
from reactive_anim.core.model.classes import CLASSES as ALL_CLASSES
from reactive_anim.core.model.skeleton import Motion
from tools.devkit import believability
from tools.sample_clips import catalogue, falls
from tools.sample_clips.skeleton import sample_skeleton

REPO = Path(__file__).resolve().parents[2]
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
def walk() -> Motion:
    return bvh.read_bvh(CLIPS / "walk.bvh")


@pytest.fixture(scope="module")
def walk_points(walk: Motion) -> dict[str, np.ndarray]:
    return world_points(walk)


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
        float(np.linalg.norm(points[a:b, :2] - points[a, :2], axis=1).max())
        for a, b in zip(edges[::2], edges[1::2], strict=True)
    ]


def period(motion: Motion) -> int:
    """The shortest lag (frames, at least 0.4 s) after which every joint rotation repeats."""
    for lag in range(int(0.4 * motion.fps), motion.num_frames // 2 + 1):
        if quat.angle_between(motion.local_rot[lag:], motion.local_rot[:-lag]).max() < 1e-5:
            return lag
    pytest.fail("the walk has no repeating cycle")


# ---------------------------------------------------------------------------------------------
# Reproducible


# The clips are written to 4 decimals (catalogue.write_clip): a unit in the last printed digit.
LAST_DIGIT = 1e-4
# Each file's number is within half a unit of the value it was computed from, and two CPUs
# compute the same value to within far less, so two files differ by at most one unit: positions
# and offsets (cm) by one, a rotation (degrees) by one per angle, three in all; the tolerances
# leave some margin and still catch a change of a thousandth of a degree or a hundredth of a mm.
POSITION_TOLERANCE = 2 * LAST_DIGIT
ROTATION_TOLERANCE = 5 * LAST_DIGIT
MADE_WITHOUT_PHYSICS = [name for name in catalogue.CLIPS if name not in catalogue.PHYSICS]


def clip_differences(fresh: bvh.BVHData, committed: bvh.BVHData) -> list[str]:
    """How a clip differs from another beyond the rounding of its printed numbers ([] if it does
    not): the hierarchy, channels, frame count and frame time must be the same; offsets, End Sites
    and position channels equal within POSITION_TOLERANCE (file units); each joint's rotation in
    each frame, built from its Euler channels, within ROTATION_TOLERANCE degrees of the other's,
    so -180 and 180 or a gimbal-equivalent triple are the same."""
    if fresh.names != committed.names or fresh.parents != committed.parents:
        return ["the joints or their parents differ"]
    if fresh.channels != committed.channels:
        return ["the channels differ"]
    if fresh.end_sites.keys() != committed.end_sites.keys():
        return ["the End Sites are on other joints"]
    if fresh.num_frames != committed.num_frames or fresh.frame_time != committed.frame_time:
        return [
            f"{fresh.num_frames} frames of {fresh.frame_time} s, the other {committed.num_frames} of "
            f"{committed.frame_time} s"
        ]
    problems = []
    offsets = np.abs(fresh.offsets - committed.offsets).max()
    tips = max((np.abs(fresh.end_sites[j] - committed.end_sites[j]).max() for j in fresh.end_sites), default=0.0)
    if max(offsets, tips) > POSITION_TOLERANCE:
        problems.append(f"offsets differ by up to {max(offsets, tips):.4g}")
    columns = [c for ch in fresh.channels for c in ch.position_columns]
    if columns:
        moved = np.abs(fresh.values[:, columns] - committed.values[:, columns])
        if moved.max() > POSITION_TOLERANCE:
            frame, k = np.unravel_index(np.argmax(moved), moved.shape)
            problems.append(f"position value {columns[k] + 1} differs by {moved.max():.4g} at frame {frame}")
    for j, ch in enumerate(fresh.channels):
        if not ch.rotation:
            continue
        turns = [quat.from_euler(np.radians(d.values[:, ch.rotation_columns]), ch.rotation) for d in (fresh, committed)]
        turn = np.degrees(quat.angle_between(*turns))
        if turn.max() > ROTATION_TOLERANCE:
            problems.append(f"{fresh.names[j]} turns {turn.max():.4g} degrees away at frame {np.argmax(turn)}")
    return problems


@pytest.fixture(scope="module")
def regenerated(tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    """Every clip and library.toml written afresh by the generator."""
    return catalogue.write_clips(tmp_path_factory.mktemp("sample_clips"))


@pytest.fixture(scope="module")
def regenerated_again(regenerated: list[Path], tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    """The same written a second time in this session, into another folder (after the first, so
    with the generator's caches warm)."""
    return catalogue.write_clips(tmp_path_factory.mktemp("sample_clips_again"))


def test_regeneration_writes_the_committed_files(regenerated: list[Path]) -> None:
    committed = [*CLIPS.glob("*.bvh"), CLIPS / "library.toml"]
    assert sorted(p.name for p in regenerated) == sorted(p.name for p in committed)


def test_regenerating_twice_on_one_machine_gives_byte_identical_files(
    regenerated: list[Path], regenerated_again: list[Path]
) -> None:
    """Every file, the physics falls too."""
    assert [p.name for p in regenerated_again] == [p.name for p in regenerated]
    for first, again in zip(regenerated, regenerated_again, strict=True):
        assert first.read_bytes() == again.read_bytes(), f"{first.name} differs between two runs"


def test_regenerated_library_is_byte_identical_to_the_committed_one(regenerated: list[Path]) -> None:
    fresh = next(p for p in regenerated if p.name == "library.toml")
    assert fresh.read_bytes() == (CLIPS / "library.toml").read_bytes(), "library.toml differs from sample_clips/"


@pytest.mark.parametrize("name", MADE_WITHOUT_PHYSICS)
def test_regenerated_clip_matches_the_committed_one_but_for_rounding(regenerated: list[Path], name: str) -> None:
    """Every clip but the physics falls (compared within looser tolerances below)."""
    fresh = bvh.parse_bvh(next(p for p in regenerated if p.name == f"{name}.bvh"))
    problems = clip_differences(fresh, bvh.parse_bvh(CLIPS / f"{name}.bvh"))
    assert not problems, f"{name} differs from sample_clips/: " + "; ".join(problems)


def edited(name: str, change: Callable[[int, list[str]], None]) -> bvh.BVHData:
    """A committed clip with `change(frame, values)` applied to the number strings of each motion
    line, parsed."""
    lines = (CLIPS / f"{name}.bvh").read_text(encoding="utf-8").split("\n")
    assert lines[-1] == ""
    first = next(i for i, line in enumerate(lines) if line.startswith("Frame Time:")) + 1
    for frame, i in enumerate(range(first, len(lines) - 1)):
        values = lines[i].split(" ")
        change(frame, values)
        lines[i] = " ".join(values)
    return bvh.parse_bvh("\n".join(lines).encode(), name=f"{name} (edited)")


def equivalent_triple(z: float, x: float, y: float) -> list[float]:
    """The other ZXY Euler triple of the same rotation: (z + 180, 180 - x, y + 180), in [-180, 180)."""
    return [(a + 180.0) % 360.0 - 180.0 for a in (z + 180.0, 180.0 - x, y + 180.0)]


def test_clip_comparison_takes_the_same_rotations_written_otherwise() -> None:
    """Guards the comparison: it accepts -180.0000 and 180.0000 swapped, a rotation written as its
    other Euler triple, and every number one unit off in the last digit."""
    name = "getup_face_down"
    committed = bvh.parse_bvh(CLIPS / f"{name}.bvh")
    thigh = committed.channels[committed.names.index("thigh.L")]
    assert thigh.rotation == "ZXY"

    def swap(frame: int, values: list[str]) -> None:
        values[:] = [{"-180.0000": "180.0000", "180.0000": "-180.0000"}.get(v, v) for v in values]

    swapped = edited(name, swap)
    assert np.sum(swapped.values != committed.values) > 20, "the clip has few angles of 180 to swap"
    assert clip_differences(swapped, committed) == []

    def other_triple(frame: int, values: list[str]) -> None:
        triple = equivalent_triple(*(float(values[c]) for c in thigh.rotation_columns))
        for c, angle in zip(thigh.rotation_columns, triple, strict=True):
            values[c] = f"{angle:.4f}"

    other = edited(name, other_triple)
    moved = np.abs(other.values - committed.values)[:, thigh.rotation_columns]
    assert np.all(np.minimum(moved, 360.0 - moved).max(axis=1) > 1.0), "the triples should differ"
    assert clip_differences(other, committed) == []

    def one_unit(frame: int, values: list[str]) -> None:
        values[:] = [f"{float(v) + (-1) ** (frame + k) * LAST_DIGIT:.4f}" for k, v in enumerate(values)]

    off = edited(name, one_unit)
    assert np.abs(off.values - committed.values).min() > 0.9 * LAST_DIGIT
    assert clip_differences(off, committed) == []


@pytest.mark.parametrize(
    ("joint", "axis", "change"),
    [
        ("forearm.L", 0, 0.01),  # degrees, about Z
        ("thigh.R", 1, 0.001),  # degrees, about X: ten units in the last digit
        ("head", 2, -0.001),  # degrees, about Y
        ("pelvis", None, 0.001),  # cm, the root's height: ten units
    ],
)
def test_clip_comparison_rejects_a_real_change(joint: str, axis: int | None, change: float) -> None:
    """Guards the comparison: one value changed in one frame beyond the files' rounding fails it."""
    name = "steps_forward_1"
    committed = bvh.parse_bvh(CLIPS / f"{name}.bvh")
    ch = committed.channels[committed.names.index(joint)]
    column = ch.position_columns[1] if axis is None else ch.rotation_columns[axis]
    middle = committed.num_frames // 2

    def nudge(frame: int, values: list[str]) -> None:
        if frame == middle:
            values[column] = f"{float(values[column]) + change:.4f}"

    assert clip_differences(edited(name, nudge), committed) != []


def test_a_fall_is_bit_identical_when_made_twice_in_one_process() -> None:
    """Same input, same bits: the walk-start fall made, another fall made in between (sharing the
    cached ragdoll), then the first made again."""
    fall = falls.FALLS["fall_forward_hands_3"]
    first = falls.fall_clip(fall)
    falls.fall_clip(falls.FALLS["fall_backward_sit_1"])
    again = falls.fall_clip(fall)
    assert np.array_equal(first.root_pos, again.root_pos)
    assert np.array_equal(first.local_rot, again.local_rot)


def test_sample_skeleton_is_the_one_in_the_file(walk: Motion) -> None:
    skeleton = sample_skeleton()
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
    assert np.min(facing(walk_points) @ travel) > 0.97
    # And the feet point forward too, independently of the names.
    for side in "LR":
        toes = (walk_points[f"toe.{side}"] - walk_points[f"foot.{side}"])[:, :2]
        toes /= np.linalg.norm(toes, axis=1, keepdims=True)
        assert np.mean(toes @ travel) > 0.9
    assert travel @ np.array([0.0, -1.0]) > 0.99  # along -Y, the documented facing


# ---------------------------------------------------------------------------------------------
# Every clip


ALL = sorted(p.stem for p in CLIPS.glob("*.bvh"))
LOCOMOTION = ["walk", "run", "idle"]
REACTIONS = [n for n in ALL if n.startswith("step")]
GETUPS = [n for n in ALL if n.startswith("getup_")]
FALLS = [n for n in ALL if n.startswith("fall_")]
SWAYS = [n for n in ALL if n.startswith("sway_")]
CLASSES = CLASS_SLUGS  # the sample library has clips of every class
FLOOR_TOLERANCE = 0.01
MAX_TURN = 30.0  # rad/s between frames
HEEL = np.array([0.0, 0.056, -0.068])  # heel below and behind the ankle at rest (tools/sample_clips: HEEL_BACK)
# Anatomical ranges, degrees. Hinges are measured as signed flexion about their axis (the knee
# bends about +X, the elbow about -X, and nothing else may turn them); other joints as the total
# angle of their rotation from the rest pose (standing, arms down), kept within a generous adult
# range of motion: hip flexion up to 140 in a deep squat; shoulder elevation up to 180; a hand
# flat on the floor under a near-vertical forearm is extended about 90, plus the forearm's
# pronation this skeleton has no bone for; ankle plantarflexion of a lying foot about 65; toes
# bent back up to 70 when kneeling on them; spine and neck joints share a bend over several
# joints, so each turns only a little.
HINGES = {"shin": (np.array([1.0, 0.0, 0.0]), 0.0, 150.0), "forearm": (np.array([-1.0, 0.0, 0.0]), 0.0, 150.0)}
MAX_ROTATION = {
    "spine": 30.0,
    "spine.001": 30.0,
    "chest": 30.0,
    "neck": 45.0,
    "head": 45.0,
    "shoulder": 30.0,
    "upper_arm": 180.0,
    "hand": 150.0,
    "thigh": 150.0,
    "foot": 70.0,
    "toe": 70.0,
}
# Segment masses as fractions of body mass (Winter, Table 4.1), each placed at a joint of the
# segment, for a centre of mass good enough to tell forward from backward.
MASSES = {
    "pelvis": 0.142,
    "spine": 0.1,
    "spine.001": 0.1,
    "chest": 0.155,
    "head": 0.081,
    "upper_arm": 0.028,
    "forearm": 0.016,
    "hand": 0.006,
    "thigh": 0.1,
    "shin": 0.0465,
    "foot": 0.0145,
}


@pytest.fixture(scope="module")
def clips() -> dict[str, Motion]:
    return {name: bvh.read_bvh(CLIPS / f"{name}.bvh") for name in ALL}


def world_points(motion: Motion) -> dict[str, np.ndarray]:
    """World positions (T, 3) of every joint, every End Site ('<joint>.tip') and the heels."""
    pos, rot = motion.global_transforms()
    sk = motion.skeleton
    points = {name: pos[:, j] for j, name in enumerate(sk.names)}
    for j, offset in sk.end_sites.items():
        points[sk.names[j] + ".tip"] = pos[:, j] + quat.rotate(rot[:, j], offset)
    for side in "LR":
        j = sk.index(f"foot.{side}")
        points[f"heel.{side}"] = pos[:, j] + quat.rotate(rot[:, j], HEEL)
    return points


def sole_height(points: dict[str, np.ndarray], side: str) -> np.ndarray:
    """How far (T,) a foot's lowest contact point (heel, ball, toe tip) is above where it is when
    the foot stands flat."""
    rest = {"heel": 0.0, "toe": 0.0245, "toe.tip": 0.0105}
    return np.min(
        [points[f"{part}.{side}" if part != "toe.tip" else f"toe.{side}.tip"][:, 2] - z for part, z in rest.items()],
        axis=0,
    )


def touchdowns(points: dict[str, np.ndarray]) -> list[tuple[str, int]]:
    """(side, frame) of each time a foot comes down: its sole was over 2 cm up and is back within 5 mm."""
    found = []
    for side in "LR":
        up = False
        for frame, h in enumerate(sole_height(points, side)):
            if h > 0.02:
                up = True
            elif up and h < 0.005:
                found.append((side, frame))
                up = False
    return sorted(found, key=lambda item: item[1])


def centre_of_mass(motion: Motion) -> np.ndarray:
    pos = motion.global_positions()
    weights = np.array(
        [MASSES.get(name.split(".")[0] if name != "spine.001" else name, 0.0) for name in motion.skeleton.names]
    )
    return np.einsum("tjk,j->tk", pos, weights) / weights.sum()


def facing(points: dict[str, np.ndarray]) -> np.ndarray:
    """Unit ground directions (T, 2) the hips face: (left hip - right hip) x up."""
    f = np.cross(points["thigh.L"] - points["thigh.R"], UP)[:, :2]
    return f / np.linalg.norm(f, axis=1, keepdims=True)


def test_there_are_locomotion_steps_and_getups() -> None:
    assert set(LOCOMOTION) <= set(ALL)
    for cls in ("step_forward", "steps_forward", "step_back", "steps_back", "step_left", "step_right"):
        assert len([n for n in REACTIONS if n.rsplit("_", 1)[0] == cls]) >= 3, cls
    assert set(GETUPS) == {"getup_face_down", "getup_face_up", "getup_sitting"}


def test_the_folder_stays_small() -> None:
    assert sum(p.stat().st_size for p in CLIPS.iterdir()) < 5_000_000


@pytest.mark.parametrize("name", ALL)
def test_clip_is_on_the_sample_skeleton_at_60_fps(clips: dict[str, Motion], name: str) -> None:
    motion = clips[name]
    assert motion.skeleton.names == list(PARENTS)
    assert motion.fps == pytest.approx(60.0)


@pytest.mark.parametrize("name", ALL)
def test_no_foot_or_hand_below_the_floor(clips: dict[str, Motion], name: str) -> None:
    points = world_points(clips[name])
    ends = {k: v for k, v in points.items() if k.split(".")[0] in ("foot", "toe", "heel", "hand")}
    lowest = min(ends, key=lambda k: ends[k][:, 2].min())
    z = ends[lowest][:, 2]
    assert z.min() > -FLOOR_TOLERANCE, f"{name}: {lowest} is {-z.min() * 100:.1f} cm under the floor @ {z.argmin()}"


@pytest.mark.parametrize("name", ALL)
def test_joints_stay_within_anatomical_ranges(clips: dict[str, Motion], name: str) -> None:
    motion = clips[name]
    sk = motion.skeleton
    for j, joint in enumerate(sk.names):
        kind = joint.rsplit(".", 1)[0] if joint.endswith((".L", ".R")) else joint
        q = motion.local_rot[:, j]
        if kind in HINGES:
            axis, low, high = HINGES[kind]
            q = np.where(q[:, :1] < 0, -q, q)
            flexion = np.degrees(2 * np.arctan2(q[:, 1:] @ axis, q[:, 0]))
            off_axis = np.degrees(2 * np.arcsin(np.clip(np.linalg.norm(np.cross(q[:, 1:], axis), axis=1), 0, 1)))
            assert off_axis.max() < 1.0, f"{name}: {joint} turns {off_axis.max():.1f} deg off its hinge"
            assert flexion.min() >= low - 0.5 and flexion.max() <= high, (
                f"{name}: {joint} flexes {flexion.min():.0f}..{flexion.max():.0f} deg, outside {low:.0f}..{high:.0f}"
            )
        elif kind in MAX_ROTATION:
            angle = np.degrees(quat.angle_between(quat.identity(), q))
            assert angle.max() <= MAX_ROTATION[kind], (
                f"{name}: {joint} turns {angle.max():.0f} deg (limit {MAX_ROTATION[kind]:.0f}), frame {angle.argmax()}"
            )


@pytest.mark.parametrize("name", ALL)
def test_no_joint_turns_faster_than_30_rad_per_s_in_any_clip(clips: dict[str, Motion], name: str) -> None:
    motion = clips[name]
    speed = quat.angle_between(motion.local_rot[1:], motion.local_rot[:-1]) * motion.fps
    frame, joint = np.unravel_index(np.argmax(speed), speed.shape)
    joint_name = motion.skeleton.names[joint]
    assert speed.max() < MAX_TURN, f"{name}: {joint_name} turns at {speed.max():.1f} rad/s at frame {frame}"


@pytest.mark.parametrize("name", REACTIONS + FALLS + SWAYS + GETUPS)
def test_clip_ends_at_rest(clips: dict[str, Motion], name: str) -> None:
    """The last 0.2 s: no joint moves more than 5 mm, no joint turns more than 1 degree."""
    motion = clips[name]
    tail = int(0.2 * motion.fps)
    pos = motion.global_positions()[-tail:]
    assert np.linalg.norm(pos - pos[-1], axis=-1).max() < 0.005
    assert np.degrees(quat.angle_between(motion.local_rot[-tail:], motion.local_rot[-1])).max() < 1.0


# ---------------------------------------------------------------------------------------------
# Locomotion


@pytest.mark.parametrize("name", LOCOMOTION)
def test_locomotion_stance_feet_do_not_slide(clips: dict[str, Motion], name: str) -> None:
    points = world_points(clips[name])
    for part in FEET + ["toe.L.tip", "toe.R.tip"]:
        slides = planted_slides(points[part], clips[name].fps)
        assert slides and max(slides) < 0.02, f"{name}: {part} slides {max(slides) * 100:.1f} cm while planted"


def test_run_is_a_loop_at_3_m_per_s_with_flight(clips: dict[str, Motion]) -> None:
    run = clips["run"]
    assert run.num_frames / run.fps >= 2.0
    lag = period(run)
    assert run.num_frames % lag == 0
    stride = run.root_pos[lag] - run.root_pos[0]
    assert 2.7 <= np.linalg.norm(stride[:2]) * run.fps / lag <= 3.3
    assert stride @ np.array([0.0, -1.0, 0.0]) > 0
    points = world_points(run)
    airborne = (sole_height(points, "L") > 0.01) & (sole_height(points, "R") > 0.01)
    # Two flights per cycle, each at least 3 frames (50 ms).
    edges = np.flatnonzero(np.diff(airborne.astype(int)) == 1)
    assert len(edges) >= 2 * (run.num_frames // lag) - 1
    assert airborne.sum() >= 3 * 2 * (run.num_frames // lag)


def test_idle_stands_still_and_loops(clips: dict[str, Motion]) -> None:
    idle = clips["idle"]
    assert idle.num_frames / idle.fps >= 4.0
    points = world_points(idle)
    assert np.ptp(idle.root_pos[:, :2], axis=0).max() < 0.05  # a weight shift, not a walk
    assert points["pelvis"][:, 2].min() > 0.9 and points["head"][:, 2].min() > 1.5
    # The frame after the last is the first: the seam is no bigger a step than any in the clip.
    turns = quat.angle_between(idle.local_rot[1:], idle.local_rot[:-1]).max(axis=0)
    assert np.all(quat.angle_between(idle.local_rot[-1], idle.local_rot[0]) <= turns + 1e-4)
    moves = np.linalg.norm(np.diff(idle.root_pos, axis=0), axis=1)
    assert np.linalg.norm(idle.root_pos[0] - idle.root_pos[-1]) <= moves.max() + 1e-5
    # Something breathes: the chest moves, by a little.
    assert 0.001 < np.ptp(idle.global_rotations()[:, idle.skeleton.index("chest"), 1]) < 0.1


# ---------------------------------------------------------------------------------------------
# Stepping reactions


@pytest.mark.parametrize("name", REACTIONS)
def test_step_clip_starts_from_the_standing_pose(clips: dict[str, Motion], name: str) -> None:
    """Frame 0 is a pose the idle stand passes through: every joint within 5 degrees of idle's
    first frame, the pelvis at the same height."""
    first, idle = clips[name], clips["idle"]
    diff = np.degrees(quat.angle_between(first.local_rot[0], idle.local_rot[0]))
    assert diff.max() < 5.0, f"{name}: {first.skeleton.names[int(diff.argmax())]} is {diff.max():.1f} deg off standing"
    assert first.root_pos[0, 2] == pytest.approx(idle.root_pos[0, 2], abs=0.01)


@pytest.mark.parametrize("name", REACTIONS)
def test_step_clip_moves_the_centre_of_mass_the_way_its_class_says(clips: dict[str, Motion], name: str) -> None:
    motion = clips[name]
    points = world_points(motion)
    com = centre_of_mass(motion)
    ahead = facing(points)[0]
    axis = {"forward": ahead, "backward": -ahead, "left": np.array([-ahead[1], ahead[0]])}
    axis["right"] = -axis["left"]
    travel = (com[-1] - com[0])[:2] @ axis[reaction_class(name.rsplit("_", 1)[0]).way]
    assert travel > 0.1, f"{name}: the centre of mass moves {travel:+.2f} m the way its class goes"


@pytest.mark.parametrize("name", REACTIONS)
def test_step_clip_has_the_number_of_steps_its_class_says(clips: dict[str, Motion], name: str) -> None:
    steps = touchdowns(world_points(clips[name]))
    if name.startswith("steps_"):
        assert len(steps) >= 2, f"{name}: touch-downs {steps}"
    else:
        assert len(steps) == 1, f"{name}: touch-downs {steps}"


@pytest.mark.parametrize("name", REACTIONS)
def test_step_clip_ends_standing(clips: dict[str, Motion], name: str) -> None:
    points = world_points(clips[name])
    assert points["pelvis"][-1, 2] > 0.8 and points["head"][-1, 2] > 1.4
    for side in "LR":
        assert abs(sole_height(points, side)[-1]) < 0.005, f"{name}: the {side} foot ends off the floor"


def test_the_touchdown_count_notices_a_missing_step(clips: dict[str, Motion]) -> None:
    """Guards the count: the standing idle has none, a walk has one per step."""
    assert touchdowns(world_points(clips["idle"])) == []
    assert len(touchdowns(world_points(clips["walk"]))) >= 7


# ---------------------------------------------------------------------------------------------
# Get-ups


@pytest.mark.parametrize("name", GETUPS)
def test_getup_goes_from_the_floor_to_standing(clips: dict[str, Motion], name: str) -> None:
    points = world_points(clips[name])
    assert points["pelvis"][0, 2] < 0.4, f"{name} starts with the pelvis at {points['pelvis'][0, 2]:.2f} m"
    assert points["pelvis"][-1, 2] > 0.8 and points["head"][-1, 2] > 1.5
    for side in "LR":
        assert abs(sole_height(points, side)[-1]) < 0.005


def test_getups_start_as_their_names_say(clips: dict[str, Motion]) -> None:
    """Face down: the chest's front points at the floor; face up: at the sky; sitting: the trunk
    is more up than lying and the feet are on the floor."""

    def chest_front(name: str) -> np.ndarray:
        motion = clips[name]
        return quat.rotate(motion.global_rotations()[0, motion.skeleton.index("chest")], np.array([0.0, -1.0, 0.0]))

    assert chest_front("getup_face_down")[2] < -0.8
    assert chest_front("getup_face_up")[2] > 0.8
    sitting = world_points(clips["getup_sitting"])
    assert sitting["head"][0, 2] > 0.6 and sitting["pelvis"][0, 2] < 0.4


# ---------------------------------------------------------------------------------------------
# The reaction library's list


@pytest.fixture(scope="module")
def library() -> dict:
    with open(CLIPS / "library.toml", "rb") as f:
        return tomllib.load(f)


def test_library_lists_every_reaction_with_a_known_class(library: dict) -> None:
    assert set(library) <= {"clip", "chain"}
    for clip in library["clip"]:
        assert set(clip) <= {"file", "class", "frames", "next"}, clip
        assert clip["class"] in CLASSES
        assert (CLIPS / clip["file"]).is_file(), clip["file"]
        if "next" in clip:
            assert (CLIPS / clip["next"]).is_file(), clip["next"]
        if "frames" in clip:
            start, end = clip["frames"]
            assert 0 <= start < end
    listed = {clip["file"] for clip in library["clip"]}
    assert listed == {f"{n}.bvh" for n in REACTIONS + FALLS + SWAYS}
    per_class = {c: sum(clip["class"] == c for clip in library["clip"]) for c in CLASSES}
    assert all(n >= 3 for n in per_class.values()), per_class


def test_library_chains_the_getups(library: dict) -> None:
    for chain in library["chain"]:
        assert set(chain) == {"file"}
        assert (CLIPS / chain["file"]).is_file()
    assert {c["file"] for c in library["chain"]} == {f"{n}.bvh" for n in GETUPS}
    assert not {f"{n}.bvh" for n in LOCOMOTION} & {c["file"] for c in library["clip"] + library["chain"]}


@pytest.mark.parametrize("name", FALLS)
def test_a_fall_lying_down_chains_the_get_up_for_how_it_lies(
    clips: dict[str, Motion], library: dict, name: str
) -> None:
    """Measured on the clip's last frame: the chest's front up (lying on the back) chains the
    face-up get-up, down the face-down one; a fall that ends sitting (head high) the sitting one."""
    motion = clips[name]
    chest = motion.global_rotations()[-1, motion.skeleton.index("chest")]
    front_up = float(quat.rotate(chest, np.array([0.0, -1.0, 0.0]))[2])
    head = world_points(motion)["head"][-1, 2]
    fits = "getup_sitting.bvh" if head > 0.5 else "getup_face_up.bvh" if front_up > 0 else "getup_face_down.bvh"
    entry = next(c for c in library["clip"] if c["file"] == f"{name}.bvh")
    assert entry["next"] == fits, (name, front_up, head)


def test_falls_chain_to_the_getup_that_fits_how_they_end(library: dict) -> None:
    expected = {
        "fall_forward_hands": "getup_face_down.bvh",
        "fall_forward_roll": "getup_face_up.bvh",
        "fall_backward_hands": "getup_sitting.bvh",
        "fall_backward_sit": "getup_sitting.bvh",
    }
    for clip in library["clip"]:
        if is_fall(clip["class"]):
            assert clip.get("next", "").startswith("getup_"), clip
            if clip["class"] in expected:
                assert clip["next"] == expected[clip["class"]], clip


# ---------------------------------------------------------------------------------------------
# Falls (physics: the ragdoll pushed, PD servos toward protective key poses) and sways


# A regenerated fall against its committed file (see the module docstring): before the first floor
# contact of anything but the feet, and after it.
BEFORE_CONTACT_DEGREES, BEFORE_CONTACT_ROOT = 0.01, 0.0001
AFTER_CONTACT_DEGREES, AFTER_CONTACT_ROOT, AFTER_CONTACT_JOINT = 15.0, 0.05, 0.10
LENGTH_SLACK = 1.0  # s


def first_contact(name: str) -> int:
    """The frame of the first floor contact of any body but the feet, as the simulation reports it
    (the clip's length if none)."""
    run = falls.simulate_fall(falls.FALLS[name])
    times = [t for body, t in run.first_contact.items() if not body.startswith("ankle")]
    return round(min(times) * run.motion.fps) if times else run.motion.num_frames


def held_to(motion: Motion, frames: int) -> Motion:
    """The motion lengthened to `frames` by holding its last frame."""
    extra = frames - motion.num_frames
    root = np.concatenate([motion.root_pos, np.repeat(motion.root_pos[-1:], extra, axis=0)])
    local = np.concatenate([motion.local_rot, np.repeat(motion.local_rot[-1:], extra, axis=0)])
    return Motion(motion.skeleton, motion.fps, root, local)


@pytest.mark.parametrize("name", FALLS)
def test_regenerated_fall_matches_the_committed_one_within_tolerance(
    clips: dict[str, Motion], regenerated: list[Path], name: str
) -> None:
    assert name in catalogue.PHYSICS
    committed = clips[name]
    fresh = bvh.read_bvh(next(p for p in regenerated if p.name == f"{name}.bvh"))
    slack = abs(fresh.num_frames - committed.num_frames) / committed.fps
    assert slack <= LENGTH_SLACK, f"{name}: {fresh.num_frames} frames, committed {committed.num_frames}"
    frames = max(fresh.num_frames, committed.num_frames)
    fresh, committed_held = held_to(fresh, frames), held_to(committed, frames)
    turn = np.degrees(quat.angle_between(fresh.local_rot, committed_held.local_rot)).max(axis=1)
    root = np.linalg.norm(fresh.root_pos - committed_held.root_pos, axis=1)
    joint = np.linalg.norm(fresh.global_positions() - committed_held.global_positions(), axis=-1).max(axis=1)
    contact = first_contact(name)
    assert turn[:contact].max() < BEFORE_CONTACT_DEGREES and root[:contact].max() < BEFORE_CONTACT_ROOT, (
        f"{name} before contact (frame {contact}): joints {turn[:contact].max():.4f} deg, root "
        f"{root[:contact].max() * 1000:.3f} mm from sample_clips/"
    )
    after = slice(contact, None)
    assert (
        turn[after].max() < AFTER_CONTACT_DEGREES
        and root[after].max() < AFTER_CONTACT_ROOT
        and joint[after].max() < AFTER_CONTACT_JOINT
    ), (
        f"{name} after contact (frame {contact}): joints {turn[after].max():.1f} deg and "
        f"{joint[after].max() * 100:.1f} cm, root {root[after].max() * 100:.1f} cm from sample_clips/"
    )


def test_there_are_falls_and_sways() -> None:
    for cls in [c.slug for c in ALL_CLASSES if c.family in ("sway", "fall")]:
        assert len([n for n in FALLS + SWAYS if n.rsplit("_", 1)[0] == cls]) >= 3, cls


@pytest.mark.parametrize("name", FALLS)
def test_fall_ends_on_the_floor(clips: dict[str, Motion], name: str) -> None:
    points = world_points(clips[name])
    assert points["pelvis"][-1, 2] < 0.4, f"{name} ends with the pelvis at {points['pelvis'][-1, 2]:.2f} m"
    assert points["pelvis"][0, 2] > 0.9, f"{name} does not start upright"


@pytest.mark.parametrize("name", FALLS + SWAYS)
def test_fall_or_sway_moves_the_centre_of_mass_the_way_its_class_says(clips: dict[str, Motion], name: str) -> None:
    motion = clips[name]
    points = world_points(motion)
    com = centre_of_mass(motion)
    ahead = facing(points)[0]
    travel = (com[-1] - com[0])[:2] @ ahead
    if name.startswith("fall_forward"):
        assert travel > 0.15, f"{name}: the centre of mass moves {travel:+.2f} m along the facing"
    elif name.startswith("fall_backward"):
        assert travel < -0.15, f"{name}: the centre of mass moves {travel:+.2f} m along the facing"
    elif name.startswith("fall_side"):
        sideways = abs((com[-1] - com[0])[:2] @ np.array([-ahead[1], ahead[0]]))
        assert sideways > abs(travel) and sideways > 0.2, f"{name}: sideways {sideways:.2f} m, along {travel:+.2f} m"
    else:  # a sway: the centre of mass goes out with the push and comes back over the feet
        out = np.linalg.norm(com[:, :2] - com[0, :2], axis=1).max()
        assert out > 0.02 and np.linalg.norm(com[-1, :2] - com[0, :2]) < 0.01, (name, out)


@pytest.mark.parametrize("name", [n for n in FALLS if "_hands_" in n])
def test_hands_fall_touches_the_floor_with_a_hand_before_the_pelvis(name: str) -> None:
    """By the simulation's own floor contacts."""
    contact = falls.simulate_fall(falls.FALLS[name]).first_contact
    hands = [contact[side] for side in ("wrist_l", "wrist_r") if side in contact]
    assert hands, f"{name}: no hand reaches the floor"
    pelvis = contact.get("pelvis", np.inf)
    assert min(hands) < pelvis, f"{name}: hand down at {min(hands):.2f} s, pelvis at {pelvis:.2f} s"


@pytest.mark.parametrize("name", [n for n in FALLS if n.startswith("fall_backward_sit")])
def test_backward_sit_ends_sitting_without_rolling_onto_the_back(clips: dict[str, Motion], name: str) -> None:
    """From the moment the pelvis is down the head stays above 0.5 m: it sits, it does not rock
    over onto its back (the physics did that with harder pushes)."""
    points = world_points(clips[name])
    contact = falls.simulate_fall(falls.FALLS[name]).first_contact
    assert "pelvis" in contact, f"{name}: the pelvis never reaches the floor"
    landed = round(contact["pelvis"] * clips[name].fps)
    head = points["head"][landed:, 2]
    assert head.min() > 0.5, f"{name}: the head drops to {head.min():.2f} m at frame {landed + head.argmin()}"


@pytest.mark.parametrize("name", [n for n in FALLS if n.startswith("fall_forward_roll")])
def test_forward_roll_goes_over_and_ends_face_up(clips: dict[str, Motion], name: str) -> None:
    """The trunk turns over forwards: the chest's front faces the floor, then the pelvis comes over
    the head (hips above the head while the head is low), and the body ends on its back."""
    motion = clips[name]
    points = world_points(motion)
    over = (points["pelvis"][:, 2] > points["head"][:, 2] + 0.1) & (points["head"][:, 2] < 0.4)
    assert over.any(), f"{name}: the hips never come over the head"
    chest = quat.rotate(motion.global_rotations()[-1, motion.skeleton.index("chest")], np.array([0.0, -1.0, 0.0]))
    assert chest[2] > 0.8, f"{name}: ends with the chest's front at {chest[2]:+.2f} (face up is +1)"


@pytest.mark.parametrize("name", [n for n in FALLS if n.startswith("fall_side_knees")])
def test_side_fall_lands_on_a_knee_first(name: str) -> None:
    """By the simulation's own floor contacts: a leg (thigh or shin body, the knee is where they
    meet) before the pelvis and trunk."""
    contact = falls.simulate_fall(falls.FALLS[name]).first_contact
    knees = [contact[body] for body in ("hip_l", "hip_r", "knee_l", "knee_r") if body in contact]
    assert knees, f"{name}: no knee reaches the floor ({contact})"
    others = [t for body, t in contact.items() if body in ("pelvis", "waist", "back")]
    assert min(knees) < min(others, default=np.inf), (name, contact)


@pytest.mark.parametrize("name", FALLS)
def test_fall_starts_from_a_pose_of_the_idle_or_the_walk(clips: dict[str, Motion], name: str) -> None:
    """Frame 0 is a frame of the idle stand or the walk: every joint within 5 degrees of one of
    their frames (the toes, which the ragdoll does not have, aside)."""
    motion = clips[name]
    toes = [motion.skeleton.index(n) for n in ("toe.L", "toe.R")]
    keep = [j for j in range(motion.skeleton.num_joints) if j not in toes]
    best = min(
        np.degrees(quat.angle_between(clips[src].local_rot[:, keep], motion.local_rot[0, keep])).max(axis=1).min()
        for src in ("idle", "walk")
    )
    assert best < 5.0, f"{name}: frame 0 is {best:.1f} deg from every idle and walk frame"


@pytest.mark.parametrize("name", SWAYS)
def test_sway_keeps_the_feet_in_place_and_ends_standing(clips: dict[str, Motion], name: str) -> None:
    points = world_points(clips[name])
    for part in ("foot.L", "foot.R", "toe.L.tip", "toe.R.tip", "heel.L", "heel.R"):
        moved = np.linalg.norm(points[part] - points[part][0], axis=1).max()
        assert moved < 0.05, f"{name}: {part} moves {moved * 100:.1f} cm"
    assert touchdowns(points) == []
    assert points["pelvis"][-1, 2] > 0.9 and points["head"][-1, 2] > 1.5


def test_the_falls_accelerate_no_joint_past_the_softening(clips: dict[str, Motion]) -> None:
    """The falls are made by physics, whose contacts stop a limb within a 2 ms step (the rolls'
    heads struck the floor at 135-153 m/s^2, the hands at C at up to 350), and cast onto a taller
    character a clip accelerates in proportion. So the generator softens them where a joint passes
    falls.FALL_SPIKE; no joint of the body, the push's own frame left out, accelerates past its
    top (real falls reach 166, tools/bench.py quality)."""
    roles = falls.sample_ragdoll().roles
    for name in (n for n in ALL if n.startswith("fall_")):
        motion = clips[name]
        pos, _ = motion.global_transforms()
        accel = believability.acceleration(pos[:, believability.body_joints(roles, motion)], motion.fps)
        assert np.nanmax(accel[1:]) < falls.FALL_SPIKE[1], (name, float(np.nanmax(accel[1:])))
