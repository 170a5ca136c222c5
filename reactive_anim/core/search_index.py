"""The search index: lower bounds of Eq. 1 that prune the jump search, and the exact traversal.

window.py defines Eq. 1; this module finds its smallest value over a library's windows, exactly (the
paper scanned every window; we return the same window, far faster). Each filter below is a valid
lower bound of Eq. 1 (never above the true cost), so a candidate is skipped only when it cannot win:
1. Pivots (triangle inequality): Eq. 1 between windows, each expressed in its own first frame's
   heading frame, is a metric (a weighted sum of Euclidean distances and of rotation angles, which
   are metrics; the alignment is a rigid move of each window into its own frame). So for any window
   P, D(q, c) >= |D(q, P) - D(P, c)|. The index keeps D(P_k, c) in float32 for PIVOTS pivot windows
   chosen far apart (farthest-point traversal on a subsample) and every candidate c, and per node
   the range of them; a query computes its K exact D(q, P_k) in float64 and bounds a node by
   max_k max(lo_k - D(q, P_k), D(q, P_k) - hi_k), a candidate by max_k |D(q, P_k) - D(P_k, c)|,
   both less the float32 error of the stored distances (_pivot_error, a wide margin). That costs K
   numbers per node or candidate instead of the 7 * W * 15 of the boxes. It holds for Table 2's
   weights only; other weights skip it. Before the traversal, the SEED_BLOCKS blocks with the lowest
   pivot bound are evaluated, so the best cost is good from the start.
2. Boxes: candidate windows are grouped into blocks of BLOCK_SIZE consecutive starts and blocks into
   groups of LEVEL_FANOUT (LEVELS levels; no group crosses a class). Each group keeps, per window
   frame and joint, the bounding box of the aligned positions and of the local-rotation quaternions.
   Point-to-box distance bounds the position terms; for rotations the box's largest |<q_query, q>|
   bounds the angle through 2 acos(x) >= 2 sqrt(2 - 2x). Groups are visited cheapest bound first;
   one whose bound is above the best cost so far is skipped.
3. Near-exact float32 bound per candidate the pivots leave: the position terms in float32 and the
   angle 4 asin(c/2) (c the quaternion chord) through the first three terms of asin's series, whose
   terms are all positive, so a truncated series is below the angle.
4. Exact cost in float64 (window.window_costs), only for candidates whose bound can still beat the best.
Float32 bounds are shrunk by a relative and an absolute margin (and the chord's by its own), far
above float32 rounding, so rounding never lifts a bound over the true cost; the result is the
reference's to float64 rounding. Layout: the features as contiguous component planes (x, y, z, w,
...) gathered with np.take, so every step is a plain elementwise pass over contiguous float32.
Ties go to the lowest (class, clip, frame), the order of the library's arrays.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from .window import (
    NUM_JOINTS,
    TABLE2_POSITION_WEIGHTS,
    TABLE2_ROTATION_WEIGHTS,
    FrameFeatures,
    Query,
    aligned_window,
    joint_weights,
    rotation_angles,
    window_costs,
)

# The lower-bound index: candidates per block, nodes per node of the next level, levels.
BLOCK_SIZE = 16
LEVEL_FANOUT = 8
LEVELS = 2
# Pivot windows of the triangle-inequality bound (see _pivot_node_bounds), and the subsample step the
# farthest-point choice of them runs on.
PIVOTS = 32
PIVOT_SAMPLE_STEP = 16
# Blocks (lowest triangle bound first) evaluated before the traversal, for a good first best cost.
SEED_BLOCKS = 4
# Candidates per pass of the near-exact bound.
CANDIDATE_CHUNK = 512
# Bounds are computed in float32; shrink them so rounding never lifts one above a true cost.
_BOUND_RELATIVE_MARGIN = 1e-4
_BOUND_ABSOLUTE_MARGIN = 1e-4
_DOT_MARGIN = 2e-6
_CHORD_MARGIN = 2e-6


class IndexedFrames(Protocol):
    """What the index reads of a library (core.library.Library): its per-frame features grouped by
    class (`class_ranges[slug]` = flat frame range), each frame's clip and frame number in the clip,
    each clip's length, and the window length."""

    @property
    def window(self) -> int: ...

    @property
    def frames(self) -> FrameFeatures: ...

    class_ranges: dict[str, tuple[int, int]]
    clip_index: np.ndarray
    frame_index: np.ndarray
    clip_frames: np.ndarray


# Aligned positions (n, 3, W, 15) and rotations (n, 4, W, 15) of n windows, components second.
Windows = tuple[np.ndarray, np.ndarray]
# Per node: aligned positions' low and high corners (n, 3, W, 15), rotations' centre and half-widths (n, 4, W, 15).
Boxes = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]


@dataclass
class SearchIndex:
    """What the fast search reads, built once per library (not cached: about 9 s at 100k frames, most
    of it the pivot distances).

    starts: (C,) flat start frame of every valid window, in (class, clip, frame) order.
    levels[0] are blocks of BLOCK_SIZE consecutive starts, each higher level groups LEVEL_FANOUT
    nodes of the level below; `firsts[k]` (n_k + 1,) cuts level k-1's nodes (starts for k = 0) into
    level k's nodes. No node crosses a class; `class_tops[slug]` = (first, stop) range of top nodes.
    `boxes[k]`: boxes of level k's nodes, float32, components first so every step is a plain
    elementwise pass: positions (n, 3, W, 15) of the aligned windows as lo and hi, rotations
    (n, 4, W, 15) as centre and half-width.
    planes (7, N, 15): the library's features as contiguous component planes (x, y, z of pos_local,
    then w, x, y, z of rot), so a gathered component is contiguous and passes over it run at full speed.
    pivots (K,): flat start frames of the pivot windows. pivot_dist (C, K) float32: Eq. 1 from each
    pivot to each candidate, within _pivot_error(d) of the exact cost. pivot_ranges[k]: per node of
    level k, (lo, hi) (n, K) of pivot_dist over the node's candidates, already widened by the error.
    pivot_windows: the pivots' aligned positions (3, K, W * 15) and rotations (4, K, W * 15), float64,
    so a query's distances to them skip the window rebuild of window_costs.
    """

    window: int
    frames: FrameFeatures
    starts: np.ndarray
    firsts: list[np.ndarray]
    boxes: list[Boxes]
    class_tops: dict[str, tuple[int, int]]
    planes: np.ndarray
    heading: np.ndarray
    ground: np.ndarray
    pivots: np.ndarray
    pivot_dist: np.ndarray
    pivot_ranges: list[tuple[np.ndarray, np.ndarray]]
    pivot_margin: float
    pivot_windows: tuple[np.ndarray, np.ndarray]

    def tops(self, classes: list[str]) -> np.ndarray:
        """Top-level nodes of the given classes (a class without a window long enough has none)."""
        ranges = [np.arange(*self.class_tops[slug]) for slug in classes if slug in self.class_tops]
        return np.concatenate(ranges) if ranges else np.zeros(0, np.int64)

    @property
    def nbytes(self) -> int:
        arrays = [a for level in self.boxes for a in level] + self.firsts + [self.starts, self.planes]
        arrays += [self.pivot_dist, *self.pivot_windows] + [a for level in self.pivot_ranges for a in level]
        return sum(a.nbytes for a in arrays)


def _reduce_boxes(boxes: Boxes, first: np.ndarray) -> Boxes:
    """Boxes of groups: min of lows, max of highs over the ranges cut by `first`."""
    pos_lo, pos_hi, rot_lo, rot_hi = boxes
    cut = first[:-1]
    return (
        np.minimum.reduceat(pos_lo, cut, axis=0), np.maximum.reduceat(pos_hi, cut, axis=0),
        np.minimum.reduceat(rot_lo, cut, axis=0), np.maximum.reduceat(rot_hi, cut, axis=0),
    )  # fmt: skip


def _group(class_ranges: dict[str, tuple[int, int]], size: int) -> tuple[np.ndarray, dict[str, tuple[int, int]]]:
    """Cut each class's range of items into groups of `size`: the cuts and each class's groups."""
    first, ranges = [0], {}
    for slug, (a, b) in class_ranges.items():
        g0 = len(first) - 1
        first.extend(list(range(a + size, b, size)) + [b])
        ranges[slug] = (g0, len(first) - 1)
    return np.asarray(first, np.int64), ranges


def _canonical_windows(frames: FrameFeatures, starts: np.ndarray, window: int) -> tuple[np.ndarray, np.ndarray]:
    """Aligned positions (n, 3, W, 15) float64 and rotations (n, 4, W, 15) of the windows `starts`."""
    rows = starts[:, None] + np.arange(window)
    pos = aligned_window(*(a[rows].astype(float) for a in (frames.pos_local, frames.heading, frames.ground)))
    return pos.transpose(0, 3, 1, 2), frames.rot[rows].transpose(0, 3, 1, 2)


def _pivot_distances(windows: Windows, pivots: Windows, wp: np.ndarray, wq: np.ndarray) -> np.ndarray:
    """_pivot_distances_chunk a cache-sized chunk of windows at a time."""
    pos, rot = windows
    step = 512
    return np.concatenate([_pivot_distances_chunk((pos[a : a + step], rot[a : a + step]), pivots, wp, wq)
                           for a in range(0, max(len(pos), 1), step)])  # fmt: skip


def _pivot_distances_chunk(windows: Windows, pivots: Windows, wp: np.ndarray, wq: np.ndarray) -> np.ndarray:
    """Eq. 1 between windows (pos (n, 3, W, 15), rot (n, 4, W, 15)) and pivots (K, 3 or 4, W, 15),
    (n, K) float32, within _pivot_error of the exact cost (see there). The angle is 4 asin(c / 2) of
    the chord c = |q_a -+ q_b| taken from the component differences: unlike acos of the dot product
    it keeps float32's precision at small angles."""
    pos, rot = windows
    ppos, prot = pivots
    n, k = len(pos), len(ppos)
    # Component planes (c, n, W * 15), contiguous, so every step is a plain elementwise pass.
    pos = np.ascontiguousarray(pos.reshape(n, 3, -1).transpose(1, 0, 2), dtype=np.float32)
    rot = np.ascontiguousarray(rot.reshape(n, 4, -1).transpose(1, 0, 2), dtype=np.float32)
    ppos, prot = ppos.reshape(k, 3, -1).astype(np.float32), prot.reshape(k, 4, -1).astype(np.float32)
    terms = pos.shape[2]
    wp = np.resize(np.asarray(wp, np.float32), terms)  # (W * 15,): joint weights tiled over frames
    wq = np.resize(np.asarray(wq, np.float32), terms)
    out = np.empty((n, k), np.float32)
    dist, chord, tmp = (np.empty((n, terms), np.float32) for _ in range(3))
    for j in range(k):
        np.subtract(pos[0], ppos[j, 0], out=dist)
        np.square(dist, out=dist)
        for c in (1, 2):
            np.subtract(pos[c], ppos[j, c], out=tmp)
            np.square(tmp, out=tmp)
            dist += tmp
        np.sqrt(dist, out=dist)
        # Chord to the nearer of +-pivot: the sign of the dot product picks it.
        np.multiply(rot[0], prot[j, 0], out=chord)
        for c in (1, 2, 3):
            np.multiply(rot[c], prot[j, c], out=tmp)
            chord += tmp
        sign = np.copysign(np.float32(1), chord)
        np.multiply(sign, prot[j, 0], out=tmp)
        np.subtract(rot[0], tmp, out=tmp)
        np.square(tmp, out=chord)
        for c in (1, 2, 3):
            np.multiply(sign, prot[j, c], out=tmp)
            np.subtract(rot[c], tmp, out=tmp)
            np.square(tmp, out=tmp)
            chord += tmp
        np.sqrt(chord, out=chord)
        chord *= np.float32(0.5)
        np.minimum(chord, 1.0, out=chord)
        np.arcsin(chord, out=chord)
        out[:, j] = dist @ wp + (chord @ wq) * np.float32(4.0)
    return out


def _pivot_error(distance: float, window: int, wp: np.ndarray, wq: np.ndarray) -> float:
    """How far a float32 pivot distance can be from the exact cost, with a wide margin.

    Every one of Eq. 1's 2 * W * 15 terms is within about 2e-6 of exact (aligned coordinates of a
    quarter-second window are metres, rounded to float32 at 6e-8 relative; the chord's angle has a
    slope of at most 2.9); we allow 1e-4 per unit of weight and term, plus 1e-4 of the distance
    for the float32 sum of the terms (at most 240 * 6e-8 = 1.5e-5 relative at W = 8)."""
    return 1e-4 * distance + 1e-4 * window * (float(np.sum(wp)) + float(np.sum(wq)))


def _choose_pivots(
    library: IndexedFrames, starts: np.ndarray, count: int, wp: np.ndarray, wq: np.ndarray
) -> np.ndarray:
    """Pivot windows (indices into `starts`) far apart: farthest-point traversal over a subsample.

    Far-apart pivots see the library from different sides, so for most candidates some pivot's
    distance differs from the query's by more than the best cost (the triangle bound prunes it)."""
    sample = np.arange(0, len(starts), PIVOT_SAMPLE_STEP)
    count = min(count, len(sample))
    if count == 0:
        return np.zeros(0, np.int64)
    pos, rot = _canonical_windows(library.frames, starts[sample], library.window)

    def distances(i: int) -> np.ndarray:
        return _pivot_distances((pos, rot), (pos[i : i + 1], rot[i : i + 1]), wp, wq)[:, 0]

    current = int(np.argmax(distances(0)))  # the window farthest from an arbitrary one
    chosen, nearest = [], np.full(len(sample), np.inf, np.float32)
    for _ in range(count):
        chosen.append(current)
        np.minimum(nearest, distances(current), out=nearest)
        current = int(np.argmax(nearest))
    return sample[np.asarray(chosen[:count], np.int64)]


def build_index(
    library: IndexedFrames,
    *,
    block_size: int = BLOCK_SIZE,
    fanout: int = LEVEL_FANOUT,
    levels: int = LEVELS,
    pivots: int = PIVOTS,
    cached_pivots: tuple[np.ndarray, np.ndarray] | None = None,
) -> SearchIndex:
    """Valid window starts, grouped into a hierarchy of blocks per class, with their boxes and the
    pivot distances (for Table 2's weights).

    cached_pivots: (pivot start frames, pivot distances) of an earlier build of the same library
    (SearchIndex.pivots, .pivot_dist); the pivot distances are most of the build time, so a library
    loaded from its cache reuses them. Ignored when they do not fit this library's windows.
    """
    window, frames = library.window, library.frames
    starts_by_class, class_starts, count = [], {}, 0
    for slug, (a, b) in library.class_ranges.items():
        frame = library.frame_index[a:b]
        length = library.clip_frames[library.clip_index[a:b]]
        valid = np.flatnonzero(frame + window <= length) + a
        if len(valid):
            starts_by_class.append(valid)
            class_starts[slug] = (count, count + len(valid))
            count += len(valid)
    starts = np.concatenate(starts_by_class) if starts_by_class else np.zeros(0, np.int64)
    block_first, class_nodes = _group(class_starts, block_size)
    wp, wq = joint_weights(TABLE2_POSITION_WEIGHTS), joint_weights(TABLE2_ROTATION_WEIGHTS)
    reuse = _fitting_pivots(starts, cached_pivots)
    pivot_idx = reuse[0] if reuse else _choose_pivots(library, starts, pivots, wp, wq)
    pivot_pos, pivot_rot = _canonical_windows(frames, starts[pivot_idx], window)
    pivot_dist = reuse[1] if reuse else np.empty((len(starts), len(pivot_idx)), np.float32)
    # Boxes per block, from candidate windows built a chunk at a time (bounded memory).
    blocks = len(block_first) - 1
    pos_lo, pos_hi = (np.empty((blocks, 3, window, NUM_JOINTS), np.float32) for _ in range(2))
    rot_lo, rot_hi = (np.empty((blocks, 4, window, NUM_JOINTS), np.float32) for _ in range(2))
    chunk = max(1, 4096 // block_size)
    for block in range(0, blocks, chunk):
        block_stop = min(blocks, block + chunk)
        first, stop = block_first[block], block_first[block_stop]
        pos, rot = _canonical_windows(frames, starts[first:stop], window)
        if not reuse:
            pivot_dist[first:stop] = _pivot_distances((pos, rot), (pivot_pos, pivot_rot), wp, wq)
        cut = block_first[block:block_stop] - first
        pos_lo[block:block_stop] = np.minimum.reduceat(pos, cut, axis=0)
        pos_hi[block:block_stop] = np.maximum.reduceat(pos, cut, axis=0)
        rot_lo[block:block_stop] = np.minimum.reduceat(rot, cut, axis=0)
        rot_hi[block:block_stop] = np.maximum.reduceat(rot, cut, axis=0)
    firsts, boxes = [block_first], [(pos_lo, pos_hi, rot_lo, rot_hi)]
    for _ in range(1, levels):
        first, class_nodes = _group(class_nodes, fanout)
        firsts.append(first)
        boxes.append(_reduce_boxes(boxes[-1], first) if len(first) > 1 else boxes[-1])
    # Rotation boxes as centre and half-widths (see _box_bounds).
    boxes = [(lo, hi, 0.5 * (r_lo + r_hi), 0.5 * (r_hi - r_lo)) for lo, hi, r_lo, r_hi in boxes]
    pivot_ranges, pivot_margin = _pivot_node_ranges(pivot_dist, firsts, window, wp, wq)
    return SearchIndex(
        window=window,
        frames=frames,
        starts=starts,
        firsts=firsts,
        boxes=boxes,
        class_tops=class_nodes,
        planes=np.ascontiguousarray(np.concatenate([frames.pos_local, frames.rot], axis=2).transpose(2, 0, 1)),
        heading=frames.heading,
        ground=frames.ground,
        pivots=starts[pivot_idx],
        pivot_dist=pivot_dist,
        pivot_ranges=pivot_ranges,
        pivot_margin=pivot_margin,
        pivot_windows=(
            pivot_pos.reshape(len(pivot_pos), 3, -1).transpose(1, 0, 2).copy(),
            pivot_rot.reshape(len(pivot_rot), 4, -1).transpose(1, 0, 2).astype(float),
        ),
    )


def _fitting_pivots(
    starts: np.ndarray, cached: tuple[np.ndarray, np.ndarray] | None
) -> tuple[np.ndarray, np.ndarray] | None:
    """(indices into starts, distances) of cached pivots, or None when they do not fit `starts`."""
    if cached is None:
        return None
    pivot_starts, dist = cached
    idx = np.searchsorted(starts, pivot_starts)
    fits = (
        dist.shape == (len(starts), len(pivot_starts)) and dist.dtype == np.float32
        and np.all(idx < len(starts)) and np.array_equal(starts[np.minimum(idx, len(starts) - 1)], pivot_starts)
    )  # fmt: skip
    return (idx, dist) if fits else None


def _pivot_node_ranges(
    pivot_dist: np.ndarray, firsts: list[np.ndarray], window: int, wp: np.ndarray, wq: np.ndarray
) -> tuple[list[tuple[np.ndarray, np.ndarray]], float]:
    """Per level, the range (lo, hi) of each node's pivot distances, widened by the float32 error
    (one margin for all: the error at the largest distance); and that margin."""
    if pivot_dist.size == 0:
        empty = [np.zeros((len(f) - 1, 0), np.float32) for f in firsts]
        return [(e, e) for e in empty], 0.0
    margin = np.float32(_pivot_error(float(pivot_dist.max()), window, wp, wq))
    lo = np.minimum.reduceat(pivot_dist, firsts[0][:-1], axis=0) - margin
    hi = np.maximum.reduceat(pivot_dist, firsts[0][:-1], axis=0) + margin
    ranges = [(lo, hi)]
    for first in firsts[1:]:
        if len(first) > 1:
            lo, hi = np.minimum.reduceat(lo, first[:-1], axis=0), np.maximum.reduceat(hi, first[:-1], axis=0)
        ranges.append((lo, hi))
    return ranges, float(margin)


class _QueryArrays:
    """The query in the search's float32 layout: aligned positions (3, W, 15), rotations (4, W, 15),
    weights tiled over the window (W, 15)."""

    def __init__(self, query: Query, wp: np.ndarray, wq: np.ndarray) -> None:
        self.pos = np.ascontiguousarray(query.aligned.transpose(2, 0, 1), dtype=np.float32)
        self.rot = np.ascontiguousarray(query.features.rot.transpose(2, 0, 1), dtype=np.float32)
        self.rot_abs = np.abs(self.rot)
        self.wp = np.ascontiguousarray(np.broadcast_to(wp, (query.window, NUM_JOINTS)), dtype=np.float32)
        self.wq = np.ascontiguousarray(np.broadcast_to(wq, (query.window, NUM_JOINTS)), dtype=np.float32)


def _safe(bound: np.ndarray) -> np.ndarray:
    return bound * (1.0 - _BOUND_RELATIVE_MARGIN) - _BOUND_ABSOLUTE_MARGIN


def _box_bounds(boxes: Boxes, idx: np.ndarray, q: _QueryArrays) -> np.ndarray:
    """Lower bounds of Eq. 1 for the boxes `idx` (n,), shrunk against float32 rounding."""
    n = len(idx)
    if n and idx[-1] - idx[0] + 1 == n and np.all(np.diff(idx) == 1):
        lo, hi, centre_box, half = (b[idx[0] : idx[0] + n] for b in boxes)  # a run of nodes: views, no copy
    else:
        lo, hi, centre_box, half = (np.take(b, idx, axis=0) for b in boxes)
    # Positions: distance from each query joint to the box of candidate positions.
    d = np.maximum(lo - q.pos, q.pos - hi)
    np.maximum(d, 0.0, out=d)
    d *= d
    dist = d[:, 0] + d[:, 1] + d[:, 2]
    np.sqrt(dist, out=dist)
    # Rotations: over a box with centre c and half-widths h, the largest |<q_query, q>| is
    # |<q_query, c>| + <|q_query|, h>; it bounds the angle through 2 acos(x) >= 2 sqrt(2 - 2x).
    centre = centre_box[:, 0] * q.rot[0]
    spread = half[:, 0] * q.rot_abs[0]
    for k in (1, 2, 3):
        centre += centre_box[:, k] * q.rot[k]
        spread += half[:, k] * q.rot_abs[k]
    top = np.abs(centre)
    top += spread
    top += _DOT_MARGIN
    np.minimum(top, 1.0, out=top)
    angle = np.sqrt(2.0 - 2.0 * top)
    angle *= 2.0
    total = dist.reshape(n, -1) @ q.wp.reshape(-1) + angle.reshape(n, -1) @ q.wq.reshape(-1)
    return _safe(total)


def _pivot_query_distances(index: SearchIndex, query: Query, wp: np.ndarray, wq: np.ndarray) -> np.ndarray:
    """D(q, P_k) for the pivots in float64, as window_costs, from the stored pivot windows."""
    pos, rot = index.pivot_windows  # (3, K, W * 15), (4, K, W * 15)
    qpos = query.aligned.reshape(-1, 3).T[:, None]
    dist = np.sqrt(((pos - qpos) ** 2).sum(axis=0))
    angle = rotation_angles(query.features.rot.reshape(-1, 4).T.astype(float)[:, None], rot)
    window = query.window
    return dist @ np.tile(wp, window) + angle @ np.tile(wq, window)


def _pivot_node_bounds(index: SearchIndex, level: int, nodes: np.ndarray, dq: np.ndarray) -> np.ndarray:
    """Triangle-inequality lower bounds of Eq. 1 for nodes of a level: for every candidate c of the
    node and pivot P, D(q, c) >= |D(q, P) - D(P, c)| >= max(lo - D(q, P), D(q, P) - hi) where
    [lo, hi] holds the node's D(P, c) (widened by their float32 error). Eq. 1 on aligned windows
    is a metric: a weighted sum of Euclidean distances of canonical positions and of rotation
    angles, the aligment being a rigid move of each window into its own first frame."""
    lo, hi = index.pivot_ranges[level]
    lo, hi = np.take(lo, nodes, axis=0), np.take(hi, nodes, axis=0)
    lo -= dq
    hi -= dq  # now -(dq - hi)
    np.negative(hi, out=hi)
    np.maximum(lo, hi, out=lo)
    return _safe(lo.max(axis=1, initial=0.0))


def _pivot_candidate_filter(index: SearchIndex, cands: np.ndarray, dq: np.ndarray, best: float) -> np.ndarray:
    """The candidates whose triangle bound max_k |D(q, P_k) - D(P_k, c)| (less the float32 error)
    is within `best`."""
    d = np.take(index.pivot_dist, cands, axis=0)
    d -= dq
    np.abs(d, out=d)
    bound = _safe(d.max(axis=1, initial=0.0) - np.float32(index.pivot_margin))
    return cands[bound <= best]


def _seed_candidates(index: SearchIndex, tops: np.ndarray, dq: np.ndarray) -> np.ndarray:
    """Candidates of the few blocks (under the top nodes `tops`) with the lowest triangle bound.

    Evaluated before the traversal, they give a good best cost from the start, so the traversal
    prunes hard from its first node (its own order, by the top nodes' bounds, can start far off)."""
    first = index.firsts[0]
    nodes = tops
    for level in range(len(index.firsts) - 1, 0, -1):
        nodes = _ranges(index.firsts[level][nodes], index.firsts[level][nodes + 1])
    bound = _pivot_node_bounds(index, 0, nodes, dq)
    blocks = SEED_BLOCKS
    if len(nodes) > blocks:
        nodes = nodes[np.argpartition(bound, blocks)[:blocks]]
    return _ranges(first[nodes], first[nodes + 1])


def _candidate_bounds(
    index: SearchIndex, cands: np.ndarray, q: _QueryArrays, best: float
) -> tuple[np.ndarray, np.ndarray]:
    """The candidates whose near-exact lower bound (`_chunk_terms`) is within `best`, and those bounds.

    Works a cache-sized chunk at a time (temporaries of a few hundred KB stay in L2)."""
    kept, bounds = [], []
    for k in range(0, len(cands), CANDIDATE_CHUNK):
        chunk = cands[k : k + CANDIDATE_CHUNK]
        total = _safe(_chunk_terms(index, chunk, q, 0, index.window))
        alive = total <= best
        kept.append(chunk[alive])
        bounds.append(total[alive])
    if not kept:
        return np.zeros(0, np.int64), np.zeros(0, np.float32)
    return np.concatenate(kept), np.concatenate(bounds)


def _chunk_terms(index: SearchIndex, cands: np.ndarray, q: _QueryArrays, i0: int, i1: int) -> np.ndarray:
    """Near-exact lower bounds of Eq. 1's terms over window frames [i0, i1) for candidate windows
    (positions in float32; the angle 4 asin(c/2) of the chord c = |q_a -+ q_b| bounded by the first
    three terms of asin's series, all of whose terms are positive), without the rounding margin."""
    starts = index.starts[cands]
    anchor = starts[:, None]
    frames = anchor + np.arange(i0, i1)
    # np.take: several times faster than fancy indexing for these row gathers.
    heading0 = np.take(index.heading, anchor)
    heading = np.take(index.heading, frames)
    rel = heading - heading0
    ground0 = np.take(index.ground, anchor, axis=0)
    ground = np.take(index.ground, frames, axis=0)
    off_x = ground[..., 0] - ground0[..., 0]
    off_y = ground[..., 1] - ground0[..., 1]
    cos0, sin0 = np.cos(heading0), np.sin(heading0)
    shift_x = (cos0 * off_x + sin0 * off_y)[..., None]
    shift_y = (cos0 * off_y - sin0 * off_x)[..., None]
    cr, sr = np.cos(rel)[..., None], np.sin(rel)[..., None]
    planes = index.planes
    qpos = q.pos[:, i0:i1]
    qr = q.rot[:, i0:i1]
    px, py = np.take(planes[0], frames, axis=0), np.take(planes[1], frames, axis=0)  # (n, W, 15) each
    dx = cr * px
    dx -= sr * py
    dx += shift_x - qpos[0]
    dy = sr * px
    dy += cr * py
    dy += shift_y - qpos[1]
    dz = np.take(planes[2], frames, axis=0)
    dz -= qpos[2]
    dx *= dx
    dy *= dy
    dz *= dz
    dx += dy
    dx += dz
    np.sqrt(dx, out=dx)
    dot = np.take(planes[3], frames, axis=0)
    dot *= qr[0]
    for k in (1, 2, 3):
        part = np.take(planes[3 + k], frames, axis=0)
        part *= qr[k]
        dot += part
    # Chord c = |q_a -+ q_b| (nearer sign): c^2 = 2 - 2|<q_a, q_b>| for unit quaternions; float32
    # norms are 1 within about 1e-7, so subtracting _CHORD_MARGIN keeps c^2 from above the truth.
    np.abs(dot, out=dot)
    y2 = np.float32(0.5) - np.float32(0.5) * dot - np.float32(_CHORD_MARGIN / 4)  # (c / 2)^2
    np.maximum(y2, 0.0, out=y2)
    y = np.sqrt(y2)
    series = y2 * np.float32(3.0 / 40.0)
    series += np.float32(1.0 / 6.0)
    series *= y2
    series += np.float32(1.0)
    series *= y
    n = len(cands)
    return dx.reshape(n, -1) @ q.wp[i0:i1].reshape(-1) + (series.reshape(n, -1) @ q.wq[i0:i1].reshape(-1)) * 4.0


def _ranges(first: np.ndarray, stop: np.ndarray) -> np.ndarray:
    """Concatenated aranges [first[k], stop[k]) without a Python loop."""
    lengths = stop - first
    total = int(lengths.sum())
    if total == 0:
        return np.zeros(0, np.int64)
    offsets = np.repeat(first - np.concatenate([[0], np.cumsum(lengths)[:-1]]), lengths)
    return np.arange(total) + offsets


def uses_pivots(wp: np.ndarray, wq: np.ndarray) -> bool:
    """The stored pivot distances are Eq. 1 with Table 2's weights; other weights go without them."""
    return np.array_equal(wp, joint_weights(TABLE2_POSITION_WEIGHTS)) and np.array_equal(
        wq, joint_weights(TABLE2_ROTATION_WEIGHTS)
    )


@dataclass(frozen=True)
class Best:
    """The exact best window: its flat start frame, its Eq. 1 cost, and how many float64 costs were
    computed on the way (the other candidates were pruned)."""

    start: int
    cost: float
    evaluated: int


def find_best(index: SearchIndex, query: Query, classes: list[str], wp: np.ndarray, wq: np.ndarray) -> Best:
    """Exact best window of the given classes for the query. wp, wq: per-joint weights (window.joint_weights)."""
    return _Traversal(index, query, wp, wq).run(index.tops(classes))


class _Traversal:
    """One query's walk down the index, keeping the best window found so far."""

    def __init__(self, index: SearchIndex, query: Query, wp: np.ndarray, wq: np.ndarray) -> None:
        self.index = index
        self.query = query
        self.wp, self.wq = wp, wq
        self.arrays = _QueryArrays(query, wp, wq)
        # D(q, P) exactly (its float32 rounding, 6e-8 relative, is far inside the pivot margin).
        self.pivot_query: np.ndarray | None = None
        if len(index.pivots) > 0 and uses_pivots(wp, wq):
            self.pivot_query = _pivot_query_distances(index, query, wp, wq).astype(np.float32)
        self.best_cost, self.best_start, self.evaluated = np.inf, -1, 0

    def run(self, tops: np.ndarray) -> Best:
        if self.pivot_query is not None:
            self.evaluate(_seed_candidates(self.index, tops, self.pivot_query))
        self.visit(len(self.index.boxes) - 1, tops)
        return Best(self.best_start, float(self.best_cost), self.evaluated)

    def evaluate(self, cands: np.ndarray) -> None:
        """Exact float64 costs of the candidates whose near-exact bound can still beat the best."""
        index = self.index
        if self.pivot_query is not None:
            cands = _pivot_candidate_filter(index, cands, self.pivot_query, self.best_cost)
        cands, bound = _candidate_bounds(index, cands, self.arrays, self.best_cost)
        order = np.argsort(bound, kind="stable")
        cands, bound = cands[order], bound[order]
        i = 0
        while i < len(cands) and bound[i] <= self.best_cost:
            group = cands[i : i + 8][bound[i : i + 8] <= self.best_cost]
            i += 8
            costs = window_costs(index.frames, index.starts[group], self.query, self.wp, self.wq)
            self.evaluated += len(group)
            for cost, cand in zip(costs, group, strict=True):
                start = int(index.starts[cand])
                if cost < self.best_cost or (cost == self.best_cost and start < self.best_start):
                    self.best_cost, self.best_start = float(cost), start

    def visit(self, level: int, nodes: np.ndarray) -> None:
        """Nodes of one level, cheapest bound first, in growing batches; skip what cannot win."""
        index = self.index
        pivot = None
        if self.pivot_query is not None:  # the cheap triangle bound first; the boxes only for what it leaves
            pivot = _pivot_node_bounds(index, level, nodes, self.pivot_query)
            keep = pivot <= self.best_cost
            nodes, pivot = nodes[keep], pivot[keep]
            if len(nodes) == 0:
                return
        bound = _box_bounds(index.boxes[level], nodes, self.arrays)
        if pivot is not None:
            np.maximum(bound, pivot, out=bound)
        keep = bound <= self.best_cost
        nodes, bound = nodes[keep], bound[keep]
        order = np.argsort(bound, kind="stable")
        nodes, bound = nodes[order], bound[order]
        first = index.firsts[level]
        # The most promising node alone first (to get a good best early), then growing batches.
        step, i = 1, 0
        while i < len(nodes) and bound[i] <= self.best_cost:
            group = nodes[i : i + step][bound[i : i + step] <= self.best_cost]
            i += step
            step = min(step * 4, 256)
            children = _ranges(first[group], first[group + 1])
            if level == 0:
                self.evaluate(children)
            else:
                self.visit(level - 1, children)
