"""The bounds the jump search rules windows out with (core/search/search_bounds.py) are true bounds of
Eq. 1: every window summary bound and node box bound at or below the exact cost (window.py), the
near-exact interval around it; on queries near and far from the library, from clips outside it, at
zero cost, and the pipeline's own (BC windows of pushes, core.react.impact_query)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from reactive_anim.core.model import bvh, quat
from reactive_anim.core.model.impact import Impact
from reactive_anim.core.react import character_ragdoll, impact_query
from reactive_anim.core.search import search_bounds
from reactive_anim.core.search.library import Library, load_library
from reactive_anim.core.search.search_index import build_index
from reactive_anim.core.search.window import (
    TABLE2_POSITION_WEIGHTS,
    TABLE2_ROTATION_WEIGHTS,
    Query,
    joint_weights,
    query_from_motion,
    window_costs,
)
from tests.support.mocap import REPO
from tools.devkit.library_clips import make_clip, perturbed, write_toml
from tools.devkit.poses import ground_axes

WP, WQ = joint_weights(TABLE2_POSITION_WEIGHTS), joint_weights(TABLE2_ROTATION_WEIGHTS)


@pytest.fixture(scope="module")
def library(tmp_path_factory) -> Library:
    """Six wobbled sample walks in three classes, at 30 and 60 fps."""
    folder = tmp_path_factory.mktemp("bounds")
    classes = ["step_forward", "sway_balance", "fall_side_knees"]
    for k in range(6):
        make_clip(folder / f"clip{k}.bvh", 300 + k, frames=110, fps=(30.0, 60.0)[k % 2])
    write_toml(folder, [{"file": f"clip{k}.bvh", "class": classes[k % 3]} for k in range(6)])
    return load_library(folder, cache_dir=folder / "cache")


def queries_around(library: Library, tmp_path: Path) -> list[Query]:
    """Library windows as they are (cost 0), perturbed a little and a lot, and windows of a clip
    outside the library."""
    rng = np.random.default_rng(17)
    out = []
    for noise in ((0.0, 0.0), (0.01, 0.02), (0.05, 0.1), (0.3, 0.8)):
        clip = int(rng.integers(len(library.clips)))
        start = library.clip_start(clip) + int(rng.integers(library.clips[clip].num_frames - library.window + 1))
        out.append(perturbed(library.features(start, start + library.window), rng, *noise))
    motion = bvh.read_bvh(make_clip(tmp_path / "other.bvh", 901, 150, 50.0))
    out += [query_from_motion(motion, start, library.window, library.fps) for start in (3.0, 70.5)]
    return out


def assert_bounds_hold(library: Library, queries: list[Query], wp: np.ndarray = WP, wq: np.ndarray = WQ) -> None:
    """Summary bounds (tight and loose forms), box bounds of every node and the near-exact interval
    of every window against its exact float64 cost."""
    index = build_index(library, choose=False)
    windows = np.arange(len(index.starts))
    for query in queries:
        exact = window_costs(library.frames, index.starts, query, wp, wq)
        arrays = search_bounds.QueryArrays(query, wp, wq)
        summary, weights = arrays.summary, arrays.summary_weights
        tight = search_bounds.summary_bounds(index.summaries, windows, summary, weights)
        assert np.all(tight <= exact)
        # With a best of -inf every bound stays in the loose form (asin(x) >= x): below the tight one.
        loose = search_bounds.summary_bounds(index.summaries, slice(0, len(windows)), summary, weights, -np.inf)
        assert np.all(loose <= tight + 1e-4)
        # Node boxes bound every window below them.
        below = windows
        for level, (lo, hi) in enumerate(index.summary_boxes):
            first = index.firsts[level]
            nodes = np.searchsorted(first, below, side="right") - 1
            boxes = search_bounds.summary_box_bounds(lo, hi, np.arange(len(first) - 1), summary, weights)
            assert np.all(boxes[nodes] <= exact)
            below = nodes
        low, high = search_bounds.near_exact_interval(index.planes, index.placement, index.starts, arrays)
        assert np.all(low <= exact) and np.all(exact <= high)
        # The interval is narrow (so a search evaluates few windows exactly), except at angles near
        # zero, where the chord's rounding margin dominates (a query at cost 0 is one of those).
        if exact.min() > 1.0:
            assert np.all(high - low <= 3e-4 * exact + 0.03)


def test_bounds_hold_on_synthetic_queries(library, tmp_path: Path) -> None:
    assert_bounds_hold(library, queries_around(library, tmp_path))


def test_bounds_hold_for_other_weights(library, tmp_path: Path) -> None:
    wp = joint_weights({**TABLE2_POSITION_WEIGHTS, "wrist": 1.5, "hip": 0.1})
    wq = joint_weights({**TABLE2_ROTATION_WEIGHTS, "knee": 0.0, "neck": 2.0})
    assert_bounds_hold(library, queries_around(library, tmp_path)[:3], wp, wq)


def test_bounds_hold_on_the_pipelines_queries(tmp_path: Path) -> None:
    """Pushes on the sample walk, each query made as the pipeline makes it, against the sample
    library (the rotation differences are large there: the summary's angle form matters)."""
    library = load_library(REPO / "sample_clips", cache_dir=tmp_path / "cache")
    walk = bvh.read_bvh(REPO / "sample_clips" / "walk.bvh")
    ragdoll = character_ragdoll(walk)
    queries = []
    for k, (frame, role, strength) in enumerate(((40, "chest", 30.0), (75, "pelvis", 150.0), (110, "head", 300.0))):
        forward, left = ground_axes(walk, frame)
        angle = 2.0 * np.pi * k / 3
        impact = Impact(frame, ragdoll.roles[role], tuple(np.cos(angle) * forward + np.sin(angle) * left), strength)
        queries.append(impact_query(walk, impact, library, ragdoll)[0])
    assert_bounds_hold(library, queries)


def test_half_angle_and_asin_series() -> None:
    """The pieces the angle bounds are made of: the half-angle step, and asin's cut series below
    asin with the stated rest above it, on the whole range the search uses (to the float32 rounding
    of the series' coefficients, 3e-8, far inside the bounds' relative margin)."""
    angle = np.linspace(0.0, np.pi / 2, 2001)
    half = search_bounds._half_angle((np.sin(angle) ** 2).astype(np.float32))
    assert np.allclose(half, np.sin(angle / 2), atol=1e-5)
    z = np.linspace(0.0, np.sin(np.pi / 8), 2001)
    series = search_bounds._asin_below(z)
    assert np.all(series <= np.arcsin(z) * (1 + 1e-7))
    assert np.all(np.arcsin(z) <= (series + search_bounds.ASIN_SERIES_REST * z**7) * (1 + 1e-7))
    y = np.linspace(0.0, 1.0, 2001)
    assert np.all(search_bounds._asin_below(y) <= np.arcsin(y) * (1 + 1e-7))


def test_summaries_of_rotations_average_matrices() -> None:
    """A summary's rotation rows are the mean rotation matrix, q and -q alike."""
    rng = np.random.default_rng(3)
    q = quat.normalize(rng.normal(size=(2, 8, 15, 4)))
    flipped = q * np.where(rng.random((2, 8, 15, 1)) < 0.5, -1.0, 1.0)
    aligned = rng.normal(size=(2, 8, 15, 3))
    summary = search_bounds.window_summaries(aligned, flipped)
    expected = quat.to_matrix(q).reshape(2, 8, 15, 9).mean(axis=1)
    assert np.allclose(summary[search_bounds.ROTATION].transpose(1, 2, 0), expected, atol=1e-12)
    assert np.allclose(summary[search_bounds.FIRST_HALF].transpose(1, 2, 0), aligned[:, :4].mean(axis=1))
    assert np.allclose(summary[search_bounds.SECOND_HALF].transpose(1, 2, 0), aligned[:, 4:].mean(axis=1))
