"""Benchmark of the jump search (paper 2.4, Eq. 1) on the queries the pipeline really makes.

Libraries: the sample library (sample_clips/library.toml, the bake's default) and a scaled library
of at least 100,000 frames made from every clip in ../shared/mocap (test and benchmark data only;
classes by file name, tools/devkit/library_clips.py's mocap_class): copies of the clips, each
turned by a random yaw and moved on the ground, dealt round-robin over the classes so that each
has an equal share. Without ../shared the scaled library and the shared walks are skipped, with
the reason printed.

Real queries, made by the pipeline's own code (core.react.impact_query: the push simulated over BC,
the library-rate window ending at C, retargeted onto the library's skeleton when the character's
differs): PUSHES pushes on each of the sample walk and run and two shared walks (Bandai Namco
walk_normal_001, CMU via iClone 002_01), on six bones, from directions all around the character,
30 to 300 N·s, at frames spread over the clip (no randomness). The narrowed search is the class
the shipped classifier ranks first among the library's, the pipeline's first search. For the
scaled library also the earlier synthetic queries: library windows turned, moved and perturbed by
1 cm / 1 degree ("near") and 5 cm / 5 degrees ("far").

Brute force, timed in the same run: every window's exact Eq. 1 cost in float32, vectorised with
numpy a chunk of windows at a time (brute_force_costs). Each search time is the best of RUNS, the
figure the median over a query set (and its maximum). The search is exact (the tests check it
against a one-window-at-a-time reference); here its result is also compared with the brute force.
"""

from __future__ import annotations

import resource
import tempfile
import time
import tracemalloc
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from reactive_anim.core.classify.classifier import load_classifier
from reactive_anim.core.model import bvh
from reactive_anim.core.model.classes import CLASS_SLUGS
from reactive_anim.core.model.impact import Impact
from reactive_anim.core.physics.workspace import Workspace
from reactive_anim.core.react import character_ragdoll, impact_query
from reactive_anim.core.search.library import ClipInfo, Library, load_library
from reactive_anim.core.search.search_index import Best, find_best
from reactive_anim.core.search.window import (
    TABLE2_POSITION_WEIGHTS,
    TABLE2_ROTATION_WEIGHTS,
    FrameFeatures,
    Query,
    joint_weights,
    window_costs,
    yaw_rotate,
)
from reactive_anim.core.transition.casting import Casting
from tools.devkit.library_clips import mocap_class, perturbed, write_toml
from tools.devkit.mocap import MOCAP, REPO, mocap_files
from tools.devkit.poses import ground_axes
from tools.devkit.search_reference import reference_cost

from .common import report, skipped

GROUP = "search"
SCALED_FRAMES = 100_000
CACHE = Path(tempfile.gettempdir()) / "reactive_anim_bench_search"
WP = joint_weights(TABLE2_POSITION_WEIGHTS)
WQ = joint_weights(TABLE2_ROTATION_WEIGHTS)
RUNS = 3
# The clips pushed for the real queries, by query set; shared ones relative to ../shared/mocap.
SAMPLE_CLIPS = {"sample walk": REPO / "sample_clips" / "walk.bvh", "sample run": REPO / "sample_clips" / "run.bvh"}
SHARED_CLIPS = {
    "Bandai Namco walk": MOCAP / "bandai_namco" / "dataset-1" / "dataset-1_walk_normal_001.bvh",
    "CMU (iClone) walk": MOCAP / "cmu_iclone" / "002_01.bvh",
}
PUSHES = 12
PUSHED_ROLES = ("chest", "pelvis", "head", "shoulder_l", "hip_r", "knee_l")
STRENGTHS = (30.0, 300.0)  # N·s, the weakest and the strongest push
BRUTE_FORCE_CHUNK = 1024


@dataclass(frozen=True)
class RealQuery:
    """A query the pipeline makes: the push it comes from and the class the pipeline searches first."""

    clip: str
    impact: Impact
    query: Query
    narrowed: str


def sample_library() -> Library:
    return load_library(REPO / "sample_clips", cache_dir=CACHE / "sample")


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


def pushes(clip: str, path: Path, library: Library, classifier) -> list[RealQuery]:
    """PUSHES pushes on the clip at frames spread over it, bones in turn, directions around the
    character, strengths from STRENGTHS[0] to STRENGTHS[1]; each one's query and narrowed class."""
    motion = bvh.read_bvh(path)
    ragdoll = character_ragdoll(motion)
    workspace = Workspace(ragdoll)
    casting = Casting.between(motion, ragdoll.rig, library)
    first, last = 0.1 * motion.num_frames, motion.num_frames - 1 - 0.3 * motion.fps
    out = []
    for k, frame in enumerate(np.linspace(first, last, PUSHES).round()):
        forward, left = ground_axes(motion, frame, ragdoll.roles)
        angle = 2.0 * np.pi * k / PUSHES + 0.3
        direction = np.cos(angle) * forward + np.sin(angle) * left
        strength = STRENGTHS[0] + (STRENGTHS[1] - STRENGTHS[0]) * ((5 * k) % PUSHES) / (PUSHES - 1)
        impact = Impact(float(frame), ragdoll.roles[PUSHED_ROLES[k % len(PUSHED_ROLES)]], tuple(direction), strength)
        query, bc = impact_query(motion, impact, library, ragdoll, workspace=workspace, casting=casting)
        probabilities = classifier.classify(motion, bc, ragdoll)
        order = [CLASS_SLUGS[i] for i in np.argsort(-probabilities, kind="stable")]
        out.append(RealQuery(clip, impact, query, next(s for s in order if s in library.class_ranges)))
    return out


def real_queries(library: Library) -> dict[str, list[RealQuery]]:
    """The real query sets for a library: the sample walk and run, and the shared walks (when
    ../shared is there)."""
    classifier = load_classifier()
    sets = {
        "sample walk, run": [q for name, path in SAMPLE_CLIPS.items() for q in pushes(name, path, library, classifier)]
    }
    if all(path.is_file() for path in SHARED_CLIPS.values()):
        sets["shared walks"] = [
            q for name, path in SHARED_CLIPS.items() for q in pushes(name, path, library, classifier)
        ]
    else:
        skipped(GROUP, "real queries on the shared walks:")
    return sets


def brute_force_costs(lib: Library, query: Query, cands: np.ndarray, chunk: int = BRUTE_FORCE_CHUNK) -> np.ndarray:
    """Every window's exact Eq. 1 cost in float32 (cands: indices into the index's window starts),
    vectorised a chunk of windows at a time over the features as contiguous component planes: each
    window turned and moved into its first frame's heading frame, joint distances and rotation
    angles (2 acos |<q_a, q_b>|) weighted and summed."""
    index = lib.search_index()
    starts = index.starts[cands]
    q_pos = query.aligned.astype(np.float32).transpose(2, 0, 1)
    q_rot = query.features.rot.astype(np.float32).transpose(2, 0, 1)
    window = query.window
    wp, wq = np.tile(WP, window).astype(np.float32), np.tile(WQ, window).astype(np.float32)
    out = np.empty(len(starts), np.float32)
    for a in range(0, len(starts), chunk):
        rows = starts[a : a + chunk, None] + np.arange(window)
        where = np.take(index.placement, rows, axis=0)  # heading, ground x, y
        first = where[:, :1, 0]
        turn = where[..., 0] - first
        off = where[..., 1:] - where[:, :1, 1:]
        c0, s0 = np.cos(first), np.sin(first)
        shift_x = (c0 * off[..., 0] + s0 * off[..., 1])[..., None]
        shift_y = (c0 * off[..., 1] - s0 * off[..., 0])[..., None]
        comps = np.take(index.planes, rows, axis=1)  # (7, n, W, 15)
        cr, sr = np.cos(turn)[..., None], np.sin(turn)[..., None]
        x = cr * comps[0] - sr * comps[1] + shift_x - q_pos[0]
        y = sr * comps[0] + cr * comps[1] + shift_y - q_pos[1]
        z = comps[2] - q_pos[2]
        dist = np.sqrt(x * x + y * y + z * z)
        dot = np.abs((comps[3:] * q_rot[:, None]).sum(axis=0))
        angle = 2.0 * np.arccos(np.minimum(dot, 1.0))
        n = len(rows)
        out[a : a + n] = dist.reshape(n, -1) @ wp + angle.reshape(n, -1) @ wq
    return out


def best_window(lib: Library, query: Query, classes: list[str] | None = None) -> Best:
    """The exact best window over the given classes (default: all), as the search finds it."""
    index = lib.search_index()
    return find_best(index, query, list(index.class_windows) if classes is None else classes, WP, WQ)


def timed_ms(fn, runs: int = RUNS) -> tuple[float, object]:
    """Best of `runs` wall times (ms) and the last result."""
    best, result = np.inf, None
    for _ in range(runs):
        start = time.perf_counter()
        result = fn()
        best = min(best, time.perf_counter() - start)
    return best * 1000, result


@dataclass
class QuerySetFigures:
    full_ms: list[float]
    narrowed_ms: list[float]
    brute_ms: list[float]
    brute_narrowed_ms: list[float]
    agree: int
    evaluated: list[int]


def measure(lib: Library, queries: list[tuple[Query, str]], brute_queries: int) -> QuerySetFigures:
    """Search times (full, narrowed) of each query, the brute force's (full on the first
    `brute_queries`, its time does not depend on the query; narrowed on each), and how many full
    searches found the brute force's window (or one within its float32 rounding)."""
    index = lib.search_index()
    everything = np.arange(len(index.starts))
    figures = QuerySetFigures([], [], [], [], 0, [])
    for k, (query, narrowed) in enumerate(queries):
        full_ms, found = timed_ms(lambda q=query: best_window(lib, q))
        narrowed_ms, _ = timed_ms(lambda q=query, s=narrowed: best_window(lib, q, [s]))
        assert isinstance(found, Best)
        figures.full_ms.append(full_ms)
        figures.narrowed_ms.append(narrowed_ms)
        figures.evaluated.append(found.evaluated)
        if k < brute_queries:
            ms, costs = timed_ms(lambda q=query: brute_force_costs(lib, q, everything), runs=1)
            figures.brute_ms.append(ms)
            figures.agree += _agrees(lib, query, found, np.asarray(costs))
        ms, _ = timed_ms(lambda q=query, s=narrowed: brute_force_costs(lib, q, index.windows_of([s])), runs=2)
        figures.brute_narrowed_ms.append(ms)
    return figures


def _agrees(lib: Library, query: Query, found: Best, brute: np.ndarray) -> bool:
    """The search's window is the brute force's, or costs no more than it (exactly, in float64)."""
    starts = lib.search_index().starts
    brute_start = int(starts[np.argmin(brute)])
    exact = float(window_costs(lib.frames, np.array([brute_start]), query, WP, WQ)[0])
    return found.start == brute_start or found.cost <= exact


# The goals (ms, median over a query set): library -> (full, narrowed); None where none is set.
GOALS_MS = {"sample": (3.0, 1.0), "scaled": (10.0, None)}


def report_query_set(label: str, name: str, figures: QuerySetFigures, **ctx: object) -> None:
    """Median (and maximum) search times against the goals, the brute force's, the speed-up,
    agreement."""
    full, narrowed = np.median(figures.full_ms), np.median(figures.narrowed_ms)
    brute, brute_narrowed = np.median(figures.brute_ms), np.median(figures.brute_narrowed_ms)
    goal_full, goal_narrowed = GOALS_MS.get(label, (None, None))
    ctx = {**ctx, "queries": len(figures.full_ms), "query_set": name}
    report(GROUP, f"full search, {name} (median)", float(full), "ms/query", max_ms=round(max(figures.full_ms), 3),
           windows_evaluated=float(np.mean(figures.evaluated)), goal_ms=goal_full,
           goal_met=None if goal_full is None else bool(full <= goal_full), **ctx)  # fmt: skip
    report(GROUP, f"narrowed search, {name} (median)", float(narrowed), "ms/query",
           max_ms=round(max(figures.narrowed_ms), 3), goal_ms=goal_narrowed,
           goal_met=None if goal_narrowed is None else bool(narrowed <= goal_narrowed), **ctx)  # fmt: skip
    report(GROUP, f"float32 brute force, all windows, {name}", float(brute), "ms/query", **ctx)
    report(GROUP, f"float32 brute force, narrowed class, {name}", float(brute_narrowed), "ms/query", **ctx)
    report(GROUP, f"speed-up over brute force, full, {name}", float(brute / full), "x", **ctx)
    report(GROUP, f"speed-up over brute force, narrowed, {name}", float(brute_narrowed / narrowed), "x", **ctx)
    report(GROUP, f"full searches agreeing with the brute force, {name}", figures.agree, "queries",
           checked=len(figures.brute_ms), **ctx)  # fmt: skip


def reference_ms(lib: Library, query: Query, candidates: int = 300) -> float:
    """Reference time for the whole library, from `candidates` windows timed one at a time."""
    starts = lib.search_index().starts
    t = time.perf_counter()
    for s in starts[:candidates]:
        reference_cost(lib, int(s), query)
    per_window = (time.perf_counter() - t) / candidates
    return per_window * len(starts) * 1000


def synthetic_queries(
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


def bench_library(label: str, lib: Library, query_sets: dict[str, list[RealQuery]], brute_queries: int) -> None:
    """Every figure of one library: index, real query sets, synthetic ones (scaled library)."""
    t = time.perf_counter()
    index = lib.search_index()
    ctx = {"library": label, "frames": lib.num_frames, "windows": len(index.starts), "window": lib.window}
    report(GROUP, "index build (with the strategy choice)", time.perf_counter() - t, "s", **ctx)
    report(GROUP, "index size", index.nbytes / 1e6, "MB", features_mb=round(lib.nbytes / 1e6, 3), **ctx)
    scans = sorted(scope for scope, s in index.strategies.items() if s == "scan")
    report(GROUP, "scopes searched by a plain scan (the rest walk the tree)", len(scans), "scopes",
           of=len(index.strategies), full=index.strategies.get("all"), **ctx)  # fmt: skip
    for name, queries in query_sets.items():
        figures = measure(lib, [(q.query, q.narrowed) for q in queries], brute_queries)
        report_query_set(label, name, figures, **ctx)
    if label == "scaled":
        sizes = {s: b - a for s, (a, b) in lib.class_ranges.items()}
        narrow = min(sizes, key=lambda s: abs(sizes[s] - lib.num_frames / 10))
        for kind, noise in (("near", (0.01, 1.0)), ("far", (0.05, 5.0))):
            full = synthetic_queries(lib, 12, *noise, seed=1)
            narrowed = synthetic_queries(lib, 12, *noise, seed=2, slug=narrow)
            full_ms = [timed_ms(lambda q=q: best_window(lib, q))[0] for q in full]
            narrow_ms = [timed_ms(lambda q=q: best_window(lib, q, [narrow]))[0] for q in narrowed]
            goal = 5.0 if kind == "near" else None
            report(GROUP, f"full search, {kind} synthetic queries (median)", float(np.median(full_ms)), "ms/query",
                   max_ms=round(max(full_ms), 3), goal_ms=goal,
                   goal_met=None if goal is None else bool(np.median(full_ms) <= goal), **ctx)  # fmt: skip
            report(GROUP, f"narrowed search, {kind} synthetic queries (median)", float(np.median(narrow_ms)),
                   "ms/query", max_ms=round(max(narrow_ms), 3), narrowed_to=narrow, **ctx)  # fmt: skip
    first = next(iter(query_sets.values()))[0].query
    report(GROUP, "reference (one window at a time, extrapolated)", reference_ms(lib, first), "ms/query", **ctx)
    # Peak memory of one full search (numpy allocations, tracemalloc).
    tracemalloc.start()
    best_window(lib, first)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    report(GROUP, "peak memory during one full search", peak / 1e6, "MB", **ctx)


def bench_search() -> None:
    """Search figures on the sample library and the scaled one (see the module docstring)."""
    sample = sample_library()
    bench_library("sample", sample, real_queries(sample), brute_queries=PUSHES * 4)
    real = real_library()
    if real is None:
        skipped(GROUP, "the 100,000-frame library:")
    else:
        scaled = scaled_library(real, SCALED_FRAMES) if real.num_frames < SCALED_FRAMES else real
        bench_library("scaled", scaled, real_queries(scaled), brute_queries=4)
    report(GROUP, "process peak RSS", resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e3, "MB")
