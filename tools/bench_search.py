#!/usr/bin/env python3
"""Benchmark of the jump search (paper 2.4, Eq. 1): reference vs full vs class-narrowed, one core.

    .venv/bpy-5.0/bin/python tools/bench_search.py

`bench_search(report)` is what tools/bench.py calls; `report(group, name, value, unit, **context)`
prints one figure. bench_common limits BLAS to one core before numpy loads.

The library is built from every clip in ../shared/mocap (test and benchmark data only; classes
by file name, as in tests/core/test_search.py). It has fewer than 100,000 frames, so a scaled
library of at least 100,000 frames is made from the same real clips, each copy turned by a random
yaw and moved on the ground, copies dealt round-robin over the 10 classes so that one class is a
tenth of it. The reference (one candidate at a time, tests/core/search_reference.py) is timed on a
slice of the scaled library and scaled to the whole (it takes about a minute per full query).
Queries: library windows turned, moved and perturbed by 1 cm / 1 degree ("near") and by 5 cm /
5 degrees ("far", closer to what a simulated pose looks like).
"""

from __future__ import annotations

import resource
import tempfile
import time
import tracemalloc
from pathlib import Path

from bench_common import MOCAP, print_table, report

import numpy as np  # noqa: E402  (after bench_common limits BLAS to one core)

from reactive_anim.core import search  # noqa: E402
from reactive_anim.core.library import CLASS_SLUGS, ClipInfo, Library, load_library  # noqa: E402
from tests.core.search_reference import reference_cost  # noqa: E402
from tests.core.test_library import write_toml  # noqa: E402
from tests.core.test_search import mocap_class, perturbed  # noqa: E402

GROUP = "search"
SCALED_FRAMES = 100_000
CACHE = Path(tempfile.gettempdir()) / "reactive_anim_bench_search"


def real_library() -> Library | None:
    files = sorted(MOCAP.glob("**/*.bvh")) if MOCAP.is_dir() else []
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
            cs, sn = np.cos(yaw), np.sin(yaw)
            ground = f.ground @ np.array([[cs, sn], [-sn, cs]]) + rng.uniform(-20, 20, 2)
            moved = search.FrameFeatures(f.pos_local, f.heading + yaw, ground, f.rot)
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
) -> list[search.Query]:
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


def time_queries(lib: Library, queries: list[search.Query], classes=None, runs: int = 3) -> tuple[float, float]:
    """Median over queries of the best-of-`runs` time (ms), and the mean windows evaluated exactly."""
    times, evaluated = [], []
    for q in queries:
        best = np.inf
        for _ in range(runs):
            t = time.perf_counter()
            _, _, n = search.find_best(lib, q, classes)
            best = min(best, time.perf_counter() - t)
        times.append(best * 1000)
        evaluated.append(n)
    return float(np.median(times)), float(np.mean(evaluated))


def numpy_scan_ms(lib: Library, query: search.Query, chunk: int = 8192) -> float:
    """A plain vectorised scan without pruning (every window's exact cost), for scale."""
    index = lib.search_index()
    wp = search.joint_weights(search.TABLE2_POSITION_WEIGHTS)
    wq = search.joint_weights(search.TABLE2_ROTATION_WEIGHTS)
    t = time.perf_counter()
    for a in range(0, len(index.starts), chunk):
        search.window_costs(lib, index.starts[a : a + chunk], query, wp, wq)
    return (time.perf_counter() - t) * 1000


def bound_scan_ms(lib: Library, query: search.Query) -> float:
    """The float32 per-window bound over every window (one vectorised pass, no pruning): the
    speed of a plain numpy scan of the whole library."""
    index = lib.search_index()
    wp = search.joint_weights(search.TABLE2_POSITION_WEIGHTS)
    wq = search.joint_weights(search.TABLE2_ROTATION_WEIGHTS)
    q = search._QueryArrays(query, wp, wq)
    cands = np.arange(len(index.starts))
    t = time.perf_counter()
    for k in range(0, len(cands), search.CANDIDATE_CHUNK):
        search._chunk_terms(index, cands[k : k + search.CANDIDATE_CHUNK], q, 0, index.window)
    return (time.perf_counter() - t) * 1000


def pivot_pruned(lib: Library, queries: list[search.Query]) -> float:
    """Mean fraction of all windows whose pivot (triangle-inequality) bound alone exceeds the best
    cost, i.e. what the pivots prune once the best is known."""
    index = lib.search_index()
    wp = search.joint_weights(search.TABLE2_POSITION_WEIGHTS)
    wq = search.joint_weights(search.TABLE2_ROTATION_WEIGHTS)
    cands = np.arange(len(index.starts))
    fractions = []
    for q in queries:
        _, cost, _ = search.find_best(lib, q)
        dq = search.window_costs(lib, index.pivots, q, wp, wq).astype(np.float32)
        fractions.append(1.0 - len(search._pivot_candidate_filter(index, cands, dq, cost)) / len(cands))
    return float(np.mean(fractions))


def reference_ms(lib: Library, query: search.Query, candidates: int = 2000) -> float:
    """Reference time for the whole library, from `candidates` windows timed one at a time."""
    starts = lib.search_index().starts
    t = time.perf_counter()
    for s in starts[:candidates]:
        reference_cost(lib, int(s), query)
    per_window = (time.perf_counter() - t) / candidates
    return per_window * len(starts) * 1000


def bench_search(report) -> None:
    """Search figures on the real library and the scaled one (see the module docstring)."""
    t = time.perf_counter()
    real = real_library()
    if real is None:
        print(f"# search: skipped, no mocap at {MOCAP}")
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
        search.find_best(lib, make_queries(lib, 1, 0.05, 5.0, seed=3)[0])
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        report(GROUP, "peak memory during one full search", peak / 1e6, "MB", **ctx)
    report(GROUP, "process peak RSS", resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e3, "MB")


if __name__ == "__main__":
    bench_search(report)
    print_table()
