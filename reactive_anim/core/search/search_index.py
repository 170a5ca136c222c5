"""The search index: a library's windows arranged for pruning, and the exact search over them.

window.py defines Eq. 1 and search_bounds.py the bounds that rule windows out; this module finds
Eq. 1's smallest value over a library's windows, exactly (the paper scanned every window; we return
the same window, far faster), in one of two ways:
- scan, a plain vectorised pass: every window's summary bound; then, cheapest first, the exact cost
  of the first two (a first best), the near-exact interval of the windows whose summary bound is
  within the best, and the exact float64 cost (window.window_costs) of the windows whose interval's
  lower end is within the best upper end.
- walk, a tree: windows in blocks of BLOCK_SIZE consecutive starts, blocks in groups of LEVEL_FANOUT
  (LEVELS levels; no group crosses a class), each node holding the box of its windows' summaries.
  Nodes are visited cheapest bound first, the first alone and then in growing batches; a node whose
  bound is above the best upper end so far is skipped, and the windows of the others go through the
  scan's stages.
A scan costs the same per window whatever the query; a walk costs more per window it reaches but
skips most of a large library. Which is faster depends on the library, so `choose_strategies` times
both on probe queries when the index is built and keeps the faster for the whole library and for
each class (the narrowed search). Both return the same window: every bound is a true bound (see
search_bounds.py), the best is always the upper end of some window's cost, and the exact cost
decides. Ties go to the lowest (class, clip, frame), the order of the library's arrays.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from ..model import quat
from ..model.arrays import AnyFloatArray, BoolArray, Float32Array, FloatArray, IndexArray, Int32Array, IntArray
from .search_bounds import (
    SUMMARY_ROWS,
    QueryArrays,
    near_exact_interval,
    summary_bounds,
    summary_box_bounds,
    window_summaries,
)
from .window import (
    NUM_JOINTS,
    TABLE2_POSITION_WEIGHTS,
    TABLE2_ROTATION_WEIGHTS,
    FrameFeatures,
    Query,
    aligned_window,
    joint_weights,
    window_costs,
)

# The tree: windows per block, nodes per node of the next level, levels.
BLOCK_SIZE = 8
LEVEL_FANOUT = 8
LEVELS = 2
# Windows per pass of the near-exact interval (temporaries of a few hundred KB stay in L2).
CANDIDATE_CHUNK = 512
# A walk visits a level's nodes cheapest first: the first alone, then batches this many times larger.
BATCH_GROWTH = 8
# The first windows offered whose exact cost is computed at once (a first best for the bounds).
EXACT_SEED = 2
# m/s: a clip whose search joints all move slower than this from some frame to its end has a still
# tail there, where no window may reach (window_limits).
SETTLED_SPEED = 0.15
# Probe queries per scope when choosing between scan and walk, and the timing runs of each.
PROBES = 3
PROBE_RUNS = 2
STRATEGIES = ("scan", "walk")


class IndexedFrames(Protocol):
    """What the index reads of a library (core.library.Library): its per-frame features grouped by
    class (`class_ranges[slug]` = flat frame range), each frame's clip and frame number in the clip,
    each clip's length, the window length and the frame rate."""

    @property
    def window(self) -> int: ...

    @property
    def fps(self) -> float: ...

    @property
    def frames(self) -> FrameFeatures: ...

    class_ranges: dict[str, tuple[int, int]]
    clip_index: Int32Array
    frame_index: Int32Array
    clip_frames: IntArray


@dataclass
class SearchIndex:
    """What the fast search reads, built once per library (a few seconds at 100,000 frames).

    starts: (C,) flat start frame of every valid window, in (class, clip, frame) order;
      `class_windows[slug]` = (first, stop) range of them.
    summaries (S, C, 15) float32: each window's summary (search_bounds.window_summaries), rows first.
    planes (7, N, 15): the library's features as contiguous component planes (x, y, z of pos_local,
      then w, x, y, z of rot) for the near-exact interval; placement (N, 3): each frame's heading
      and ground point (x, y).
    The tree: the nodes of level 0 are blocks of BLOCK_SIZE consecutive windows, each higher level
      groups LEVEL_FANOUT nodes of the level below; `firsts[k]` (n_k + 1,) cuts level k-1's nodes (windows
      for k = 0) into level k's nodes; `class_tops[slug]` = (first, stop) range of top nodes.
      summary_boxes[k]: per node of level k, the low and high corners (S, n_k, 15) of its windows'
      summaries.
    strategies: "scan" or "walk" per scope ("all" and each class slug), and scan_limit, the most
      windows of a scope whose scan was the faster (for scopes of several classes).
    """

    window: int
    frames: FrameFeatures
    starts: IndexArray
    class_windows: dict[str, tuple[int, int]]
    summaries: Float32Array
    planes: AnyFloatArray
    placement: Float32Array
    firsts: list[IntArray]
    class_tops: dict[str, tuple[int, int]]
    summary_boxes: list[tuple[Float32Array, Float32Array]]
    strategies: dict[str, str] = field(default_factory=dict[str, str])
    scan_limit: int = 0
    limits: IntArray = field(default_factory=lambda: np.zeros(0, np.int64))  # window_limits, per clip

    def tops(self, classes: list[str]) -> IndexArray:
        """Top-level nodes of the given classes (a class without a window long enough has none)."""
        ranges = [np.arange(*self.class_tops[slug]) for slug in classes if slug in self.class_tops]
        return np.concatenate(ranges) if ranges else np.zeros(0, np.int64)

    def windows_of(self, classes: list[str]) -> IndexArray:
        """Indices into `starts` of the given classes' windows, in order."""
        ranges = [np.arange(*self.class_windows[slug]) for slug in classes if slug in self.class_windows]
        return np.sort(np.concatenate(ranges)) if ranges else np.zeros(0, np.int64)

    def strategy(self, classes: list[str]) -> str:
        """The faster way to search these classes, as measured (`choose_strategies`); "walk" when
        nothing was measured."""
        scope = "all" if set(classes) >= set(self.class_windows) else "+".join(classes)
        if scope in self.strategies:
            return self.strategies[scope]
        if not self.strategies:
            return "walk"
        return "scan" if len(self.windows_of(classes)) <= self.scan_limit else "walk"

    @property
    def nbytes(self) -> int:
        arrays = [self.starts, self.summaries, self.planes, self.placement, *self.firsts]
        arrays += [a for level in self.summary_boxes for a in level]
        return sum(a.nbytes for a in arrays)


# ---------------------------------------------------------------------------------------------
# Build


def window_limits(library: IndexedFrames) -> IntArray:
    """Per clip, how many of its first frames its windows may span: all of them less a still tail.

    A clip that ends at rest (a step that recovers to a stand, a fall that ends lying) would
    otherwise offer its resting frames as jump points, and a pushed walker's first 0.25 s, which
    Eq. 1 compares by pose alone, often matches a stand best: on 30 random pushes on the sample
    walk, 9 jumped to a step clip's last frame and the reaction was a slide into a held pose. A
    window must end by the clip's last moving frame (some search joint at SETTLED_SPEED or faster);
    a clip still throughout keeps all its windows."""
    clip, frame = library.clip_index, library.frame_index
    world = library.frames.world_positions()
    moving = np.zeros(len(clip), dtype=bool)  # per frame: some joint moved at least that fast into it
    same_clip = clip[1:] == clip[:-1]
    moving[1:] = same_clip & (
        np.linalg.norm(world[1:] - world[:-1], axis=-1).max(axis=1) * library.fps >= SETTLED_SPEED
    )
    last_moving = np.full(len(library.clip_frames), -1, dtype=np.int64)
    np.maximum.at(last_moving, clip[moving], frame[moving])
    limits = np.array(library.clip_frames, dtype=np.int64)
    cut = last_moving + 1 >= library.window
    limits[cut] = np.minimum(limits[cut], last_moving[cut] + 1)
    return limits


def build_index(
    library: IndexedFrames,
    *,
    block_size: int = BLOCK_SIZE,
    fanout: int = LEVEL_FANOUT,
    levels: int = LEVELS,
    choose: bool = True,
) -> SearchIndex:
    """Valid window starts with their summaries, grouped into a tree per class with each node's
    box of summaries, and the faster strategy per scope.

    choose: time scan and walk on probe queries (choose_strategies); else every scope walks.
    """
    window, frames = library.window, library.frames
    limits = window_limits(library)
    starts_by_class: list[IndexArray] = []
    class_windows: dict[str, tuple[int, int]] = {}
    count = 0
    for slug, (a, b) in library.class_ranges.items():
        frame = library.frame_index[a:b]
        length = limits[library.clip_index[a:b]]
        valid = np.flatnonzero(frame + window <= length) + a
        if len(valid):
            starts_by_class.append(valid)
            class_windows[slug] = (count, count + len(valid))
            count += len(valid)
    starts = np.concatenate(starts_by_class) if starts_by_class else np.zeros(0, np.int64)
    # Summaries from windows built a chunk at a time (bounded memory).
    summaries = np.zeros((SUMMARY_ROWS, len(starts), NUM_JOINTS), np.float32)
    chunk = 4096
    for first in range(0, len(starts), chunk):
        rows = starts[first : first + chunk, None] + np.arange(window)
        aligned = aligned_window(
            *(a[rows].astype(np.float64) for a in (frames.pos_local, frames.heading, frames.ground))
        )
        summaries[:, first : first + chunk] = window_summaries(aligned, frames.rot[rows])
    # The tree: blocks per class, then groups of nodes; per node the box of its windows' summaries.
    firsts: list[IntArray] = []
    class_nodes = class_windows
    for size in [block_size] + [fanout] * (levels - 1):
        first, class_nodes = _group(class_nodes, size)
        firsts.append(first)
    index = SearchIndex(
        window=window,
        frames=frames,
        starts=starts,
        class_windows=class_windows,
        summaries=summaries,
        planes=np.ascontiguousarray(np.concatenate([frames.pos_local, frames.rot], axis=2).transpose(2, 0, 1)),
        placement=np.concatenate([frames.heading[:, None], frames.ground], axis=1).astype(np.float32),
        firsts=firsts,
        class_tops=class_nodes,
        summary_boxes=_node_boxes(summaries, firsts),
        limits=limits,
    )
    if choose:
        choose_strategies(index)
    return index


def _group(class_ranges: dict[str, tuple[int, int]], size: int) -> tuple[IntArray, dict[str, tuple[int, int]]]:
    """Cut each class's range of items into groups of `size`: the cuts and each class's groups."""
    first = [0]
    ranges: dict[str, tuple[int, int]] = {}
    for slug, (a, b) in class_ranges.items():
        g0 = len(first) - 1
        first.extend(list(range(a + size, b, size)) + [b])
        ranges[slug] = (g0, len(first) - 1)
    return np.asarray(first, np.int64), ranges


def _node_boxes(rows: Float32Array, firsts: list[IntArray]) -> list[tuple[Float32Array, Float32Array]]:
    """Per level, the low and high corners (r, n_k, 15) of each node's `rows` (r, C, 15)."""
    if rows.shape[1] == 0:
        empty = [np.zeros((rows.shape[0], len(f) - 1, rows.shape[2]), rows.dtype) for f in firsts]
        return [(e, e) for e in empty]
    lo = np.minimum.reduceat(rows, firsts[0][:-1], axis=1)
    hi = np.maximum.reduceat(rows, firsts[0][:-1], axis=1)
    boxes = [(lo, hi)]
    for first in firsts[1:]:
        if len(first) > 1:
            lo, hi = np.minimum.reduceat(lo, first[:-1], axis=1), np.maximum.reduceat(hi, first[:-1], axis=1)
        boxes.append((lo, hi))
    return boxes


# ---------------------------------------------------------------------------------------------
# Search


@dataclass(frozen=True)
class Best:
    """The exact best window: its flat start frame, its Eq. 1 cost, and how many float64 costs were
    computed on the way (the other windows were ruled out by bounds)."""

    start: int
    cost: float
    evaluated: int


def find_best(
    index: SearchIndex,
    query: Query,
    classes: list[str],
    wp: FloatArray,
    wq: FloatArray,
    *,
    strategy: str | None = None,
    allowed: BoolArray | None = None,
) -> Best:
    """Exact best window of the given classes for the query. wp, wq: per-joint weights
    (window.joint_weights). strategy: "scan" or "walk"; default the faster one for these classes.
    allowed: per window (`starts` order), whether it may be returned (None: all); the bounds of a
    node hold for any part of its windows, so the search stays exact."""
    strategy = strategy or index.strategy(classes)
    if strategy not in STRATEGIES:
        raise ValueError(f"unknown search strategy {strategy!r}; strategies are: {', '.join(STRATEGIES)}")
    candidates = _Candidates(index, query, wp, wq, allowed)
    if strategy == "scan":
        _scan(candidates, index.windows_of(classes))
    else:
        _Walk(candidates).visit(len(index.firsts) - 1, index.tops(classes))
    return candidates.finish()


class _Candidates:
    """One query's windows that bounds have not ruled out, and the best upper end of a window's cost
    so far. `offer` passes windows through the per-window bounds (the first offer's most promising
    windows straight to their exact cost, which gives a first best); `finish` computes the exact
    cost of those still in and returns the best."""

    def __init__(
        self, index: SearchIndex, query: Query, wp: FloatArray, wq: FloatArray, allowed: BoolArray | None = None
    ) -> None:
        self.index, self.query, self.allowed = index, query, allowed
        self.wp, self.wq = wp, wq
        self.arrays = QueryArrays(query, wp, wq)
        self.best = np.float32(np.inf)  # the lowest upper end of a window's cost so far
        self.kept: list[IndexArray] = []  # windows still in, and the lower ends of their costs
        self.kept_low: list[Float32Array] = []
        self.exact: list[tuple[IndexArray, FloatArray]] = []  # (starts, exact costs) computed so far

    def offer(self, cands: IndexArray) -> None:
        """Rule out what the summary bound can, then refine the rest cheapest first."""
        cands = self.kept_in(cands)
        if len(cands) == 0:
            return
        arrays = self.arrays
        bound = summary_bounds(self.index.summaries, cands, arrays.summary, arrays.summary_weights, float(self.best))
        keep = bound <= self.best
        order = np.argsort(bound[keep], kind="stable")
        self.refine(cands[keep][order], bound[keep][order])

    def kept_in(self, cands: IndexArray) -> IndexArray:
        """The windows among `cands` the search may return."""
        return cands if self.allowed is None else cands[self.allowed[cands]]

    def refine(self, cands: IndexArray, full: Float32Array) -> None:
        """Windows sorted by their full summary bounds `full`: the first ones' exact costs if none is
        known yet, then the near-exact interval of those whose bound is within the best."""
        if not self.exact:
            self.evaluate(cands[:EXACT_SEED])
            cands, full = cands[EXACT_SEED:], full[EXACT_SEED:]
        index, arrays = self.index, self.arrays
        for k in range(0, len(cands), CANDIDATE_CHUNK):
            chunk = cands[k : k + CANDIDATE_CHUNK]
            chunk = chunk[full[k : k + CANDIDATE_CHUNK] <= self.best]  # the best may have dropped
            if len(chunk) == 0:
                continue
            low, high = near_exact_interval(index.planes, index.placement, index.starts[chunk], arrays)
            self.best = min(self.best, high.min())
            keep = low <= self.best
            self.kept.append(chunk[keep])
            self.kept_low.append(low[keep])

    def evaluate(self, cands: IndexArray) -> None:
        """The exact float64 costs of the windows `cands`; the best drops to the lowest of them."""
        if len(cands) == 0:
            return
        starts = self.index.starts[cands]
        costs = window_costs(self.index.frames, starts, self.query, self.wp, self.wq)
        self.exact.append((starts, costs))
        self.best = min(self.best, _float32_at_least(float(costs.min())))

    def finish(self) -> Best:
        """The exact float64 cost of every window whose lower end is within the best upper end; the
        lowest of all exact costs wins, ties to the lowest start (the library's order)."""
        if self.kept:
            cands, low = np.concatenate(self.kept), np.concatenate(self.kept_low)
            self.evaluate(cands[low <= self.best])
        if not self.exact:
            return Best(-1, float("inf"), 0)
        starts = np.concatenate([s for s, _ in self.exact])
        costs = np.concatenate([c for _, c in self.exact])
        order = np.lexsort((starts, costs))
        return Best(int(starts[order[0]]), float(costs[order[0]]), len(starts))


def _float32_at_least(value: float) -> np.float32:
    """The float32 nearest `value` from above (bounds compared with it stay on the safe side)."""
    rounded = np.float32(value)
    return rounded if rounded >= value else np.nextafter(rounded, np.float32(np.inf))


def _scan(candidates: _Candidates, cands: IndexArray) -> None:
    """The plain pass: every window's summary bound at once, then the exact and near-exact stages
    cheapest first."""
    cands = candidates.kept_in(cands)
    if len(cands) == 0:
        return
    contiguous = cands[-1] - cands[0] + 1 == len(cands)
    part = slice(int(cands[0]), int(cands[-1]) + 1) if contiguous else cands
    arrays = candidates.arrays
    bound = summary_bounds(candidates.index.summaries, part, arrays.summary, arrays.summary_weights)
    order = np.argsort(bound, kind="stable")
    candidates.refine(cands[order], bound[order])


class _Walk:
    """One query's walk down the tree, its windows offered to the candidate stage."""

    def __init__(self, candidates: _Candidates) -> None:
        self.candidates = candidates
        self.index = candidates.index

    def bounds(self, level: int, nodes: IndexArray) -> tuple[IndexArray, Float32Array]:
        """The nodes whose summary box may hold a window within the best, and their bounds."""
        lo, hi = self.index.summary_boxes[level]
        arrays = self.candidates.arrays
        bound = summary_box_bounds(lo, hi, nodes, arrays.summary, arrays.summary_weights, float(self.candidates.best))
        keep = bound <= self.candidates.best
        return nodes[keep], bound[keep]

    def visit(self, level: int, nodes: IndexArray) -> None:
        """Nodes of one level, cheapest bound first, in growing batches; skip what cannot win."""
        if len(nodes) == 0:
            return
        nodes, bound = self.bounds(level, nodes)
        order = np.argsort(bound, kind="stable")
        nodes, bound = nodes[order], bound[order]
        first = self.index.firsts[level]
        # The most promising node alone first (to get a good best early), then growing batches.
        step, i = 1, 0
        while i < len(nodes) and bound[i] <= self.candidates.best:
            group = nodes[i : i + step][bound[i : i + step] <= self.candidates.best]
            i += step
            step *= BATCH_GROWTH
            children = _ranges(first[group], first[group + 1])
            if level == 0:
                self.candidates.offer(children)
            else:
                self.visit(level - 1, children)


def _ranges(first: IntArray, stop: IntArray) -> IndexArray:
    """Concatenated aranges [first[k], stop[k]) without a Python loop."""
    lengths = stop - first
    total = int(lengths.sum())
    if total == 0:
        return np.zeros(0, np.int64)
    offsets = np.repeat(first - np.concatenate([[0], np.cumsum(lengths)[:-1]]), lengths)
    return np.arange(total) + offsets


# ---------------------------------------------------------------------------------------------
# Choosing scan or walk


def choose_strategies(index: SearchIndex, *, probes: int = PROBES, runs: int = PROBE_RUNS) -> dict[str, str]:
    """Time scan and walk on probe queries for the whole library and for each class; keep the faster
    per scope in index.strategies (and the largest scope the scan won in index.scan_limit).

    The probes are windows of the scope turned 10 degrees at every joint and moved 10 cm (fixed
    seeds), about as far from the library as the pipeline's queries. Timings are the best of `runs`,
    the median over the probes. Both ways are exact, so the choice changes only the time."""
    scopes = {"all": list(index.class_windows)} | {slug: [slug] for slug in index.class_windows}
    index.strategies, index.scan_limit = {}, 0
    for scope, classes in scopes.items():
        queries = _probe_queries(index, index.windows_of(classes), probes)
        if not queries:
            continue
        times: dict[str, float] = {}
        for strategy in STRATEGIES:
            runs_s = [[_timed(index, q, classes, strategy) for _ in range(runs)] for q in queries]
            times[strategy] = float(np.median([min(r) for r in runs_s]))
        index.strategies[scope] = min(times, key=lambda s: times[s])
        if index.strategies[scope] == "scan":
            index.scan_limit = max(index.scan_limit, len(index.windows_of(classes)))
    return index.strategies


def _timed(index: SearchIndex, query: Query, classes: list[str], strategy: str) -> float:
    """Seconds one search of these classes takes with the given strategy (Table 2's weights)."""
    wp, wq = joint_weights(TABLE2_POSITION_WEIGHTS), joint_weights(TABLE2_ROTATION_WEIGHTS)
    start = time.perf_counter()
    find_best(index, query, classes, wp, wq, strategy=strategy)
    return time.perf_counter() - start


def _probe_queries(index: SearchIndex, cands: IndexArray, count: int) -> list[Query]:
    """`count` windows spread over `cands`, each joint turned 10 degrees about a random axis and
    moved 10 cm in a random direction (seeded: the same probes every build)."""
    if len(cands) == 0:
        return []
    rng = np.random.default_rng(2009)
    frames, window = index.frames, index.window
    queries: list[Query] = []
    for k in np.linspace(0, len(cands) - 1, count).astype(int):
        rows: IndexArray = np.arange(index.starts[cands[k]], index.starts[cands[k]] + window)
        move: FloatArray = rng.normal(size=frames.pos_local[rows].shape)
        move *= 0.1 / np.linalg.norm(move, axis=-1, keepdims=True)
        axis = rng.normal(size=move.shape)
        axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
        half = np.radians(10.0) / 2
        turn = np.concatenate([np.full(move.shape[:-1] + (1,), np.cos(half)), np.sin(half) * axis], axis=-1)
        rot = quat.mul(frames.rot[rows].astype(np.float64), turn)
        rot *= np.where(rot[..., :1] < 0, -1.0, 1.0)
        feats = FrameFeatures(frames.pos_local[rows] + move, frames.heading[rows].astype(np.float64),
                              frames.ground[rows].astype(np.float64), rot)  # fmt: skip
        queries.append(Query(feats))
    return queries
