"""Benchmark of the jump search (paper 2.4, Eq. 1): reference vs full vs class-narrowed, one core.

The library is built from every clip in ../shared/mocap (test and benchmark data only; classes by
file name: tests/support/library_clips.py's mocap_class, as the search tests use). It has fewer
than 100,000 frames, so a scaled library of at least 100,000 frames is made from the same real
clips, each copy turned by a random yaw and moved on the ground, copies dealt round-robin over the
10 classes so that one class is a tenth of it. The reference (one candidate at a time,
tests/support/search_reference.py) is timed on a slice of the scaled library and scaled to the
whole (it takes about a minute per full query).
Queries: library windows turned, moved and perturbed by 1 cm / 1 degree ("near") and by 5 cm /
5 degrees ("far", closer to what a simulated pose looks like).

Two figures look inside the index (the float32 bound of every window, the share the pivot bound
prunes): they call search_index's private passes, as only a benchmark of the index should.
"""

from __future__ import annotations

import resource
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np

from reactive_anim.core import search_index
from reactive_anim.core.classes import CLASS_SLUGS
from reactive_anim.core.library import ClipInfo, Library, load_library
from reactive_anim.core.search_index import find_best
from reactive_anim.core.window import (
    TABLE2_POSITION_WEIGHTS,
    TABLE2_ROTATION_WEIGHTS,
    FrameFeatures,
    Query,
    joint_weights,
    window_costs,
    yaw_rotate,
)
from tests.support.library_clips import mocap_class, perturbed, write_toml
from tests.support.mocap import mocap_files
from tests.support.search_reference import reference_cost

from .common import report, skipped

GROUP = "search"
SCALED_FRAMES = 100_000
CACHE = Path(tempfile.gettempdir()) / "reactive_anim_bench_search"
WP = joint_weights(TABLE2_POSITION_WEIGHTS)
WQ = joint_weights(TABLE2_ROTATION_WEIGHTS)


def real_library() -> Library | None:
    files = mocap_files()
    if not files:
        return None
    folder = CACHE / "real"
    folder.mkdir(parents=True, exist_ok=True)
    write_toml(folder, [{"file": str(p), "class": mocap_class(p)} for p in files])
    return load_library(folder / "library.toml", cache_dir=folder / "cache")


def scaled_library(real: Library, frames: int, seed: int = 0) -> Library:
    """Copies of the real clips, each turned by a random yaw and moved on the ground, classes dealt
    round-robin so every class holds about a tenth of the frames."""
    rng = np.random.default_rng(seed)
    parts, total, k = [], 0, 0
    while total < frames:
        for c, clip in enumerate(real.clips):
            a = real.clip_start(c)
            f = real.features(a, a + clip.num_frames)
            yaw = rng.uniform(-np.pi, np.pi)
            ground = yaw_rotate(yaw, np.pad(f.ground, ((0, 0), (0, 1))))[:, :2] + rng.uniform(-20, 20, 2)
            moved = FrameFeatures(f.pos_local, f.heading + yaw, ground, f.rot)
            info = ClipInfo(f"{clip.name}#copy{k}", clip.path, CLASS_SLUGS[len(parts) % len(CLASS_SLUGS)],
                            clip.source_fps, clip.source_start, clip.num_frames, None)  # fmt: skip
            parts.append((info, moved))
            total += clip.num_frames
            k += 1
            if total >= frames:
                break
    return Library.concatenate(parts, real.settings)


def make_queries(
    lib: Library, count: int, noise_m: float, noise_deg: float, seed: int, slug: str | None = None
) -> list[Query]:
    """Library windows turned, moved and perturbed; from one class's clips when `slug` is given
    (what a correct classifier would narrow to)."""
    rng = np.random.default_rng(seed)
    clips = [k for k, c in enumerate(lib.clips) if slug is None or c.reaction_class == slug]
    queries = []
    for _ in range(count):
        clip = clips[int(rng.integers(len(clips)))]
        start = lib.clip_start(clip) + int(rng.integers(lib.clips[clip].num_frames - lib.window + 1))
        queries.append(perturbed(lib.features(start, start + lib.window), rng, noise_m, np.radians(noise_deg)))
    return queries


def best_window(lib: Library, query: Query, classes: list[str] | None = None) -> search_index.Best:
    """The exact best window over the given classes (default: all), as the search finds it."""
    index = lib.search_index()
    return find_best(index, query, list(index.class_tops) if classes is None else classes, WP, WQ)


def time_queries(
    lib: Library, queries: list[Query], classes: list[str] | None = None, runs: int = 3
) -> tuple[float, float]:
    """Median over queries of the best-of-`runs` time (ms), and the mean windows evaluated exactly."""
    times, evaluated = [], []
    for q in queries:
        best = np.inf
        for _ in range(runs):
            t = time.perf_counter()
            found = best_window(lib, q, classes)
            best = min(best, time.perf_counter() - t)
        times.append(best * 1000)
        evaluated.append(found.evaluated)
    return float(np.median(times)), float(np.mean(evaluated))


def numpy_scan_ms(lib: Library, query: Query, chunk: int = 8192) -> float:
    """A plain vectorised scan without pruning (every window's exact cost), for scale."""
    index = lib.search_index()
    t = time.perf_counter()
    for a in range(0, len(index.starts), chunk):
        window_costs(lib.frames, index.starts[a : a + chunk], query, WP, WQ)
    return (time.perf_counter() - t) * 1000


def bound_scan_ms(lib: Library, query: Query) -> float:
    """The float32 per-window bound over every window (one vectorised pass, no pruning): the
    speed of a plain numpy scan of the whole library."""
    index = lib.search_index()
    q = search_index._QueryArrays(query, WP, WQ)
    cands = np.arange(len(index.starts))
    chunk = search_index.CANDIDATE_CHUNK
    t = time.perf_counter()
    for k in range(0, len(cands), chunk):
        search_index._chunk_terms(index, cands[k : k + chunk], q, 0, index.window)
    return (time.perf_counter() - t) * 1000


def pivot_pruned(lib: Library, queries: list[Query]) -> float:
    """Mean fraction of all windows whose pivot (triangle-inequality) bound alone exceeds the best
    cost, i.e. what the pivots prune once the best is known."""
    index = lib.search_index()
    cands = np.arange(len(index.starts))
    fractions = []
    for q in queries:
        cost = best_window(lib, q).cost
        dq = window_costs(lib.frames, index.pivots, q, WP, WQ).astype(np.float32)
        fractions.append(1.0 - len(search_index._pivot_candidate_filter(index, cands, dq, cost)) / len(cands))
    return float(np.mean(fractions))


def reference_ms(lib: Library, query: Query, candidates: int = 2000) -> float:
    """Reference time for the whole library, from `candidates` windows timed one at a time."""
    starts = lib.search_index().starts
    t = time.perf_counter()
    for s in starts[:candidates]:
        reference_cost(lib, int(s), query)
    per_window = (time.perf_counter() - t) / candidates
    return per_window * len(starts) * 1000


def bench_search() -> None:
    """Search figures on the real library and the scaled one (see the module docstring)."""
    t = time.perf_counter()
    real = real_library()
    if real is None:
        skipped(GROUP)
        return
    report(GROUP, "real library load", time.perf_counter() - t, "s", frames=real.num_frames,
           clips=len(real.clips), cached=real.loaded_from_cache)  # fmt: skip
    libs = [("real", real)]
    if real.num_frames < SCALED_FRAMES:
        libs.append(("scaled", scaled_library(real, SCALED_FRAMES)))
    for label, lib in libs:
        t = time.perf_counter()
        index = lib.search_index()
        ctx = {"library": label, "frames": lib.num_frames, "windows": len(index.starts), "window": lib.window,
               "fps": lib.fps}  # fmt: skip
        report(GROUP, "index build", time.perf_counter() - t, "s", **ctx)
        report(GROUP, "features size", lib.nbytes / 1e6, "MB", **ctx)
        report(GROUP, "index size", index.nbytes / 1e6, "MB", **ctx)
        # The class with the size nearest a tenth of the library, for the narrowed search.
        sizes = {s: b - a for s, (a, b) in lib.class_ranges.items()}
        narrow = min(sizes, key=lambda s: abs(sizes[s] - lib.num_frames / 10))
        for kind, noise in (("near", (0.01, 1.0)), ("far", (0.05, 5.0))):
            queries = make_queries(lib, 20, *noise, seed=1)
            full_ms, full_eval = time_queries(lib, queries)
            report(GROUP, f"full search ({kind} queries)", full_ms, "ms/query", windows_evaluated=full_eval, **ctx)
            report(GROUP, f"full search frames/ms ({kind})", lib.num_frames / full_ms, "frames/ms", **ctx)
            report(GROUP, f"windows pruned by the pivot bound alone ({kind})", 100 * pivot_pruned(lib, queries), "%",
                   pivots=len(index.pivots), **ctx)  # fmt: skip
            narrow_queries = make_queries(lib, 20, *noise, seed=2, slug=narrow)
            n_ms, n_eval = time_queries(lib, narrow_queries, [narrow])
            report(GROUP, f"narrowed search ({kind} queries)", n_ms, "ms/query", windows_evaluated=n_eval,
                   narrowed_to=narrow, narrowed_frames=sizes[narrow], **ctx)  # fmt: skip
            scan = min(numpy_scan_ms(lib, queries[0]) for _ in range(2))
            report(GROUP, "exact float64 cost of every window, no pruning", scan, "ms/query", **ctx)
            bound_scan = min(bound_scan_ms(lib, queries[0]) for _ in range(3))
            report(GROUP, "float32 near-exact bound of every window, no pruning", bound_scan, "ms/query", **ctx)
            ref = reference_ms(lib, queries[0])
            report(GROUP, "reference (one window at a time)", ref, "ms/query", extrapolated_from_windows=2000, **ctx)
            report(GROUP, f"speed-up full vs reference ({kind})", ref / full_ms, "x", **ctx)
        # Peak memory of one full search (numpy allocations, tracemalloc) and of the process.
        tracemalloc.start()
        best_window(lib, make_queries(lib, 1, 0.05, 5.0, seed=3)[0])
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        report(GROUP, "peak memory during one full search", peak / 1e6, "MB", **ctx)
    report(GROUP, "process peak RSS", resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e3, "MB")
