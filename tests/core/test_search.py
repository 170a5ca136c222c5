"""The jump search (core/search/search.py, paper 2.4, Eq. 1, Table 2): exact, alignment-invariant, fast.

- Fast equals the one-candidate-at-a-time reference (tools/devkit/search_reference.py) in match and
  cost on random queries (synthetic library), real ones (shared mocap) and the pipeline's own (BC
  windows of pushes on the sample library), ties included, by either strategy (scan and walk) and
  narrowed to classes.
- Each library searches a scope the way measured faster when its index was built.
- Turning and moving the query on the ground changes neither the match nor the cost.
- Retrieval on the real mocap library: 200 perturbed windows found in their own clip.
The bounds themselves are checked in test_search_bounds.py.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from reactive_anim.core.model import bvh, quat
from reactive_anim.core.model.errors import LibraryError
from reactive_anim.core.model.impact import Impact
from reactive_anim.core.model.skeleton import Motion
from reactive_anim.core.react import character_ragdoll, impact_query
from reactive_anim.core.search import search_index
from reactive_anim.core.search.library import Library, load_library
from reactive_anim.core.search.search import search, search_with_fallback
from reactive_anim.core.search.window import (
    SEARCH_ROLES,
    TABLE2_POSITION_WEIGHTS,
    TABLE2_ROTATION_WEIGHTS,
    Query,
    joint_weights,
    query_from_motion,
    window_costs,
)
from tests.support.mocap import MOCAP, REPO, mocap_files
from tools.devkit.library_clips import make_clip, mocap_class, perturbed, write_toml
from tools.devkit.poses import ground_axes
from tools.devkit.search_reference import reference_cost, reference_search

STRATEGIES = search_index.STRATEGIES


@pytest.fixture(scope="module")
def synthetic(tmp_path_factory) -> object:
    """Eight wobbled sample walks in four classes, at 30, 60 and 120 fps (about 900 frames)."""
    folder = tmp_path_factory.mktemp("synthetic")
    classes = ["step_forward", "step_back", "sway_balance", "fall_side_knees"]
    clips = []
    for k in range(8):
        fps = (30.0, 60.0, 120.0)[k % 3]
        make_clip(folder / f"clip{k}.bvh", 100 + k, frames=int(3.5 * fps) if fps < 120 else 260, fps=fps)
        clips.append({"file": f"clip{k}.bvh", "class": classes[k % 4]})
    write_toml(folder, clips)
    return load_library(folder, cache_dir=folder / "cache")


def random_query(library, rng: np.random.Generator, noise_m: float, noise_rad: float) -> Query:
    """A window of the library, perturbed, turned and moved (features level)."""
    clip = int(rng.integers(len(library.clips)))
    start = library.clip_start(clip) + int(rng.integers(library.clips[clip].num_frames - library.window + 1))
    return perturbed(library.features(start, start + library.window), rng, noise_m, noise_rad)


def find_best(
    library: Library,
    query: Query,
    classes: list[str] | None = None,
    position_weights: dict[str, float] = TABLE2_POSITION_WEIGHTS,
    rotation_weights: dict[str, float] = TABLE2_ROTATION_WEIGHTS,
    strategy: str | None = None,
) -> tuple[int, float, int]:
    """The index's exact best (start, cost, evaluated) over the given classes (default all)."""
    index = library.search_index()
    slugs = list(index.class_windows) if classes is None else classes
    wp, wq = joint_weights(position_weights), joint_weights(rotation_weights)
    best = search_index.find_best(index, query, slugs, wp, wq, strategy=strategy)
    return best.start, best.cost, best.evaluated


def assert_same(library, query: Query, classes=None) -> None:
    """Both strategies find the reference's window, at its cost."""
    ref_start, ref_cost = reference_search(library, query, classes)
    for strategy in STRATEGIES:
        start, cost, _ = find_best(library, query, classes, strategy=strategy)
        assert start == ref_start, f"{strategy}: {start} (cost {cost}) vs reference {ref_start} (cost {ref_cost})"
        assert cost == pytest.approx(ref_cost, rel=1e-5, abs=1e-9)


def assert_same_as_every_cost(library, query: Query, classes=None) -> None:
    """Both strategies find the window the exact cost of every window (window.window_costs, the
    vectorised form of the reference) puts first, ties to the lowest start, at that cost; the
    reference's cost of that window agrees."""
    index = library.search_index()
    windows = index.windows_of(list(index.class_windows) if classes is None else classes)
    wp, wq = joint_weights(TABLE2_POSITION_WEIGHTS), joint_weights(TABLE2_ROTATION_WEIGHTS)
    costs = window_costs(library.frames, index.starts[windows], query, wp, wq)
    first = index.starts[windows][np.flatnonzero(costs == costs.min())].min()
    for strategy in STRATEGIES:
        start, cost, _ = find_best(library, query, classes, strategy=strategy)
        assert (start, cost) == (first, costs.min()), strategy
    assert reference_cost(library, int(first), query) == pytest.approx(costs.min(), rel=1e-9)


def test_weights_are_table2() -> None:
    wp, wq = joint_weights(TABLE2_POSITION_WEIGHTS), joint_weights(TABLE2_ROTATION_WEIGHTS)
    by_role = dict(zip(SEARCH_ROLES, zip(wp, wq, strict=True), strict=True))
    assert by_role["neck"] == (0.4, 0.3) and by_role["back"] == (0.4, 0.4) and by_role["waist"] == (0.6, 0.6)
    for side in "lr":
        assert by_role[f"hip_{side}"] == (0.8, 1.0) and by_role[f"knee_{side}"] == (0.6, 0.8)
        assert by_role[f"shoulder_{side}"] == (0.6, 0.4) and by_role[f"elbow_{side}"] == (0.6, 0.4)
        assert by_role[f"wrist_{side}"] == (0.2, 0.2) and by_role[f"ankle_{side}"] == (0.1, 0.1)


def test_reference_cost_is_zero_for_the_window_itself(synthetic) -> None:
    start = synthetic.clip_start(3) + 5
    query = Query(synthetic.features(start, start + synthetic.window))
    assert reference_cost(synthetic, start, query) == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize("noise", [(0.01, 0.02), (0.05, 0.1), (0.3, 0.5)])
def test_fast_equals_reference_on_random_queries(synthetic, noise) -> None:
    rng = np.random.default_rng(int(noise[0] * 1000))
    for _ in range(3):
        assert_same(synthetic, random_query(synthetic, rng, *noise))
    assert_same(synthetic, random_query(synthetic, rng, *noise), ["sway_balance", "step_back"])


def test_other_weights_stay_exact(synthetic) -> None:
    """Weights other than Table 2's: both strategies still find the best window."""
    pw = {**TABLE2_POSITION_WEIGHTS, "wrist": 1.5, "hip": 0.1}
    rw = {**TABLE2_ROTATION_WEIGHTS, "knee": 0.0, "neck": 2.0}
    index = synthetic.search_index()
    rng = np.random.default_rng(11)
    for _ in range(3):
        query = random_query(synthetic, rng, 0.05, 0.1)
        costs = window_costs(synthetic.frames, index.starts, query, joint_weights(pw), joint_weights(rw))
        for strategy in STRATEGIES:
            start, cost, _ = find_best(synthetic, query, position_weights=pw, rotation_weights=rw, strategy=strategy)
            assert start == index.starts[np.argmin(costs)]
            assert cost == pytest.approx(reference_cost(synthetic, start, query, pw, rw), rel=1e-5)


def test_only_allowed_windows_are_returned_and_the_best_of_them(synthetic) -> None:
    """With some windows ruled out (reach.reachable_windows on a body on the floor), both strategies
    return the window the exact costs put first among the rest: the query's own window is ruled out,
    so the answer must differ from the unrestricted one; with none allowed in scope, an error."""
    index = synthetic.search_index()
    wp, wq = joint_weights(TABLE2_POSITION_WEIGHTS), joint_weights(TABLE2_ROTATION_WEIGHTS)
    rng = np.random.default_rng(5)
    for _ in range(3):
        query = random_query(synthetic, rng, 0.01, 0.02)
        costs = window_costs(synthetic.frames, index.starts, query, wp, wq)
        allowed = rng.random(len(index.starts)) < 0.5
        allowed[np.argmin(costs)] = False
        expected = index.starts[allowed][np.argmin(costs[allowed])]
        for strategy in STRATEGIES:
            best = search_index.find_best(index, query, list(index.class_windows), wp, wq, strategy=strategy,
                                          allowed=allowed)  # fmt: skip
            assert best.start == expected, strategy
        match = search(synthetic, query, allowed=allowed)
        assert synthetic.clip_start(match.clip_index) + match.jump_frame == expected
        with pytest.raises(LibraryError, match="allowed"):
            search(synthetic, query, ["step_back"], allowed=np.zeros(len(index.starts), dtype=bool))


def test_each_scope_searches_the_way_measured_faster(synthetic) -> None:
    """Building the index times scan and walk for the whole library and each class and keeps the
    faster; a scope of several classes goes by its size; an unknown strategy is refused."""
    index = synthetic.search_index()
    assert set(index.strategies) == {"all", *index.class_windows}
    assert set(index.strategies.values()) <= set(STRATEGIES)
    scanned = [len(index.windows_of([s])) for s in index.class_windows if index.strategies[s] == "scan"]
    assert index.scan_limit >= max(scanned, default=0)
    two = list(index.class_windows)[:2]
    expected = "scan" if len(index.windows_of(two)) <= index.scan_limit else "walk"
    assert index.strategy(two) == expected
    assert index.strategy(list(reversed(index.class_windows))) == index.strategies["all"]
    query = Query(synthetic.features(10, 10 + synthetic.window))
    with pytest.raises(ValueError, match="unknown search strategy 'bisect'"):
        search_index.find_best(index, query, two, joint_weights(TABLE2_POSITION_WEIGHTS),
                               joint_weights(TABLE2_ROTATION_WEIGHTS), strategy="bisect")  # fmt: skip


def test_fast_equals_reference_on_the_pipelines_queries(tmp_path: Path) -> None:
    """Pushes on the sample walk and run (six bones, from all around, 30-300 N.s), each query made
    as the pipeline makes it (react.impact_query), against the sample library: whole library and
    each class, both strategies; one class also against the one-window-at-a-time reference."""
    library = load_library(REPO / "sample_clips", cache_dir=tmp_path / "cache")
    queries = []
    for clip in ("walk", "run"):
        motion = bvh.read_bvh(REPO / "sample_clips" / f"{clip}.bvh")
        ragdoll = character_ragdoll(motion)
        for k, role in enumerate(("chest", "pelvis", "head", "shoulder_l", "hip_r", "knee_l")):
            frame = 20 + 9 * k
            forward, left = ground_axes(motion, frame)
            angle = 2.0 * np.pi * k / 6 + 0.4
            direction = np.cos(angle) * forward + np.sin(angle) * left
            impact = Impact(frame, ragdoll.roles[role], tuple(direction), 30.0 + 54.0 * k)
            queries.append(impact_query(motion, impact, library, ragdoll)[0])
    for k, query in enumerate(queries):
        assert_same_as_every_cost(library, query)
        assert_same_as_every_cost(library, query, [list(library.class_ranges)[k % 10]])
    assert_same(library, queries[0], ["fall_backward_sit"])


def test_no_window_reaches_into_a_clips_still_tail(tmp_path: Path) -> None:
    """The sample step clips recover to a stand and the falls end lying: each has a still tail
    (every search joint slower than SETTLED_SPEED to its end), no window of the index reaches into
    it, and the frame before it moves. A pushed walker matched to a stand blended into a held pose."""
    library = load_library(REPO / "sample_clips", cache_dir=tmp_path / "cache")
    limits = search_index.window_limits(library)
    index = library.search_index()
    ends = library.frame_index[index.starts] + library.window
    assert np.all(ends <= limits[library.clip_index[index.starts]])
    world = library.frames.world_positions()
    for clip, info in enumerate(library.clips):
        rows = np.flatnonzero(library.clip_index == clip)
        speed = np.linalg.norm(np.diff(world[rows], axis=0), axis=-1).max(axis=1) * library.fps
        limit = int(limits[clip])
        assert limit < info.num_frames, info.name  # every sample reaction ends at rest
        settled = search_index.SETTLED_SPEED
        assert speed[limit - 2] >= settled and np.all(speed[limit - 1 :] < settled), info.name


def test_a_clip_still_throughout_keeps_its_windows(tmp_path: Path) -> None:
    """A clip with no motion at all is its own reaction (a stand): all its windows stay."""
    motion = bvh.read_bvh(REPO / "sample_clips" / "idle.bvh")
    still = Motion(motion.skeleton, motion.fps, np.repeat(motion.root_pos[:1], 40, axis=0),
                   np.repeat(motion.local_rot[:1], 40, axis=0))  # fmt: skip
    (tmp_path / "still.bvh").write_text(bvh.format_bvh(still))
    write_toml(tmp_path, [{"file": "still.bvh", "class": "sway_balance"}])
    library = load_library(tmp_path, cache_dir=tmp_path / "cache")
    assert search_index.window_limits(library)[0] == library.clips[0].num_frames


def test_fast_equals_reference_on_unrelated_queries(synthetic, tmp_path: Path) -> None:
    """Queries from clips that are not in the library, at other frame rates."""
    rng = np.random.default_rng(7)
    for k, fps in enumerate((24.0, 60.0, 100.0)):
        motion = bvh.read_bvh(make_clip(tmp_path / f"other{k}.bvh", 500 + k, 150, fps))
        start = float(rng.uniform(0, motion.num_frames - 0.4 * fps))
        query = query_from_motion(motion, start, synthetic.window, synthetic.fps)
        assert_same(synthetic, query)


def test_ties_go_to_the_lowest_class_clip_frame(tmp_path: Path) -> None:
    """Identical clips give identical costs; the first in (class, clip, frame) order wins."""
    make_clip(tmp_path / "a.bvh", 3, 90, 30.0)
    (tmp_path / "b.bvh").write_bytes((tmp_path / "a.bvh").read_bytes())
    (tmp_path / "c.bvh").write_bytes((tmp_path / "a.bvh").read_bytes())
    write_toml(tmp_path, [
        {"file": "a.bvh", "class": "sway_balance"},
        {"file": "b.bvh", "class": "step_back"},  # an earlier class than a.bvh's
        {"file": "c.bvh", "class": "step_back"},
    ])  # fmt: skip
    lib = load_library(tmp_path, cache_dir=tmp_path / "cache")
    assert [c.name for c in lib.clips] == ["b.bvh", "c.bvh", "a.bvh"]
    rng = np.random.default_rng(3)
    for _ in range(3):
        start = lib.clip_start(2) + int(rng.integers(0, 80))
        query = perturbed(lib.features(start, start + lib.window), rng, 0.02, 0.03)
        match = search(lib, query)
        assert match.clip == "b.bvh"
        ref_start, ref_cost = reference_search(lib, query)
        assert lib.clip_index[ref_start] == 0 and match.cost == pytest.approx(ref_cost, rel=1e-5)
        assert search(lib, query, ["sway_balance"]).clip == "a.bvh"
        for strategy in STRATEGIES:
            assert find_best(lib, query, strategy=strategy)[:2] == (ref_start, match.cost)
            # Narrowed to the later class alone: its own copy wins there.
            start = find_best(lib, query, ["sway_balance"], strategy=strategy)[0]
            assert lib.clip_index[start] == 2 and lib.frame_index[start] == lib.frame_index[ref_start]


def rotated_motion(motion: Motion, yaw: float, shift: np.ndarray) -> Motion:
    """The motion turned by `yaw` about the vertical through the origin and moved on the ground."""
    turn = quat.from_axis_angle(np.array([0.0, 0.0, 1.0]), np.array(yaw))
    local_rot = motion.local_rot.copy()
    local_rot[:, 0] = quat.mul(turn, local_rot[:, 0])
    root = quat.rotate(turn, motion.root_pos) + np.array([shift[0], shift[1], 0.0])
    return Motion(motion.skeleton, motion.fps, root, local_rot, motion.local_pos)


def test_turning_and_moving_the_query_changes_nothing(synthetic, tmp_path: Path) -> None:
    motion = bvh.read_bvh(make_clip(tmp_path / "q.bvh", 77, 150, 60.0))
    rng = np.random.default_rng(11)
    for start in (3.0, 40.5, 90.0):
        base = search(synthetic, query_from_motion(motion, start, synthetic.window, synthetic.fps))
        for yaw, shift in ((0.7, (0.0, 0.0)), (-2.9, (3.0, -1.0)), (np.pi, (-120.0, 85.0))) + (
            (rng.uniform(-np.pi, np.pi), rng.uniform(-500, 500, 2)),
        ):
            turned = rotated_motion(motion, yaw, np.asarray(shift))
            moved = query_from_motion(turned, start, synthetic.window, synthetic.fps)
            match = search(synthetic, moved)
            assert (match.clip, match.jump_frame) == (base.clip, base.jump_frame)
            assert match.cost == pytest.approx(base.cost, rel=1e-5, abs=1e-5)
            # The returned placement moves with the query.
            assert np.angle(np.exp(1j * (match.yaw - base.yaw - yaw))) == pytest.approx(0.0, abs=1e-5)


def test_match_places_the_clip_on_the_query(synthetic) -> None:
    """Applying (yaw, offset) to the clip's first frame puts its pelvis on the query's."""
    rng = np.random.default_rng(5)
    query = random_query(synthetic, rng, 0.0, 0.0)
    match = search(synthetic, query)
    assert match.cost == pytest.approx(0.0, abs=1e-4)
    start = synthetic.clip_start(match.clip_index) + match.jump_frame
    g = synthetic.ground[start].astype(float)
    c, s = np.cos(match.yaw), np.sin(match.yaw)
    placed = np.array([c * g[0] - s * g[1], s * g[0] + c * g[1]]) + match.offset
    assert placed == pytest.approx(query.features.ground[0], abs=1e-4)


def test_threshold_and_fallback(synthetic) -> None:
    rng = np.random.default_rng(9)
    clip = next(k for k, c in enumerate(synthetic.clips) if c.reaction_class == "step_back")
    start = synthetic.clip_start(clip) + 10
    query = perturbed(synthetic.features(start, start + synthetic.window), rng, 0.01, 0.01)
    own = synthetic.clips[clip].reaction_class
    best = search(synthetic, query)
    assert best.reaction_class == own and best.scope == "all" and best.accepted
    other = search(synthetic, query, ["step_forward"], threshold=best.cost * 1.01)
    assert other.reaction_class == "step_forward" and not other.accepted and other.cost > best.cost
    fell = search_with_fallback(synthetic, query, ["step_forward", own], threshold=best.cost * 1.01)
    assert fell.scope == own and fell.accepted and fell.clip == best.clip
    # None of the likely classes within the threshold: the most probable one's best, not another
    # class's better window (the class comes from what the push does).
    kept = search_with_fallback(synthetic, query, ["step_forward", "fall_side_knees"], threshold=best.cost * 1.01)
    assert kept.scope == "step_forward" and kept.clip == other.clip and not kept.accepted
    nothing = search_with_fallback(synthetic, query, ["step_forward"], threshold=best.cost * 0.5)
    assert nothing.scope == "step_forward" and not nothing.accepted
    # Only a library with none of the classes is searched whole.
    wide = search_with_fallback(synthetic, query, ["fall_forward_roll"], threshold=best.cost * 1.01)
    assert wide.scope == "all" and wide.clip == best.clip
    # A class the library lacks is passed over; an unknown slug is an error.
    skipped = search_with_fallback(synthetic, query, ["fall_forward_roll", own], threshold=best.cost * 1.01)
    assert skipped.scope == own and skipped.accepted
    with pytest.raises(LibraryError, match="unknown reaction class 'tumble'"):
        search_with_fallback(synthetic, query, ["tumble"], threshold=1.0)


def test_search_errors(synthetic) -> None:
    start = synthetic.clip_start(0)
    query = Query(synthetic.features(start, start + synthetic.window))
    with pytest.raises(LibraryError, match="no clips of class 'fall_forward_roll'"):
        search(synthetic, query, ["fall_forward_roll"])
    with pytest.raises(LibraryError, match="unknown reaction class 'jump'"):
        search(synthetic, query, ["jump"])
    short = Query(synthetic.features(start, start + 5))
    with pytest.raises(LibraryError, match="query window has 5 frames but the library was compiled for 8"):
        search(synthetic, short)
    motion = bvh.read_bvh(Path(synthetic.clips[0].path))
    with pytest.raises(LibraryError, match="runs past the motion"):
        query_from_motion(motion, motion.num_frames - 2, synthetic.window, synthetic.fps)


# ---------------------------------------------------------------------------------------------
# Real mocap


def mocap_library(folder: Path, files: list[Path]):
    clips = [{"file": str(p), "class": mocap_class(p)} for p in files]
    write_toml(folder, clips)
    return load_library(folder / "library.toml", cache_dir=folder / "cache")


@pytest.fixture(scope="module")
def real_library(tmp_path_factory):
    files = mocap_files()
    if not files:
        pytest.skip(f"real mocap not available: no BVH files under {MOCAP} (../shared/mocap is test-only data)")
    return mocap_library(tmp_path_factory.mktemp("real"), files)


def test_fast_equals_reference_on_real_mocap(tmp_path: Path) -> None:
    """A small real library (reference scans are slow) against windows of clips not in it."""
    names = [
        "bandai_namco/dataset-1/dataset-1_walk_normal_001.bvh",
        "bandai_namco/dataset-1/dataset-1_run_normal_001.bvh",
        "bandai_namco/dataset-1/dataset-1_walk-back_normal_001.bvh",
        "cmu/91_59.bvh",
        "cmu_iclone/007_12.bvh",
    ]
    files = [MOCAP / n for n in names]
    if not all(p.is_file() for p in files):
        pytest.skip(f"real mocap not available under {MOCAP} (../shared/mocap is test-only data)")
    lib = mocap_library(tmp_path, files)
    rng = np.random.default_rng(21)
    for name in ("bandai_namco/dataset-2/dataset-2_walk_normal_001.bvh", "cmu_iclone/002_01.bvh", "cmu/90_18.bvh"):
        motion = bvh.read_bvh(MOCAP / name)
        start = float(rng.uniform(0, motion.num_frames - 0.4 * motion.fps))
        assert_same(lib, query_from_motion(motion, start, lib.window, lib.fps))
    for _ in range(2):
        assert_same(lib, random_query(lib, rng, 0.02, 0.02))
    assert_same(lib, random_query(lib, rng, 0.1, 0.2), ["steps_forward", "step_back"])


def test_retrieval_on_real_mocap(real_library) -> None:
    """A window cut from a library clip, turned, moved and perturbed (1 cm, 1 degree) is found
    in the same clip within 2 frames in at least 95% of 200 trials."""
    lib = real_library
    rng = np.random.default_rng(2026)
    hits = 0
    misses = []
    for _ in range(200):
        clip = int(rng.integers(len(lib.clips)))
        frame = int(rng.integers(lib.clips[clip].num_frames - lib.window + 1))
        start = lib.clip_start(clip) + frame
        query = perturbed(lib.features(start, start + lib.window), rng, 0.01, np.radians(1.0))
        match = search(lib, query)
        if match.clip_index == clip and abs(match.jump_frame - frame) <= 2:
            hits += 1
        else:
            misses.append((lib.clips[clip].name, frame, match.clip, match.jump_frame))
    rate = hits / 200
    print(f"\nretrieval on the real mocap library ({lib.num_frames} frames, {len(lib.clips)} clips): "
          f"{hits}/200 = {rate:.1%} within 2 frames of the right clip")  # fmt: skip
    for miss in misses[:10]:
        print("  miss:", miss)
    assert rate >= 0.95
