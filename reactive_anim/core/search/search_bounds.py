"""Bounds of Eq. 1 (window.py) that let the jump search rule windows out, each proven here.

window.py defines Eq. 1; search_index.py walks a library with these bounds and computes the exact
float64 cost (window.window_costs) only for the windows they cannot rule out, so the search returns
what a scan of every window returns. A lower bound never exceeds the true cost, an upper bound never
falls below it; both are computed in float32 and then moved outward by margins far above float32
rounding (each function says which), so rounding never moves a bound past the true cost.

1. Window summaries (225 numbers a window instead of Eq. 1's 840, and no trigonometry at query
   time): per joint, the aligned position averaged over each half of the window, and the rotation
   matrix averaged over the whole window.
   Positions: sum_i |a_i - b_i| >= |sum_i (a_i - b_i)| (triangle inequality), so a half of k frames
   contributes at least k |mean_i a_i - mean_i b_i|.
   Rotations: for two rotations theta apart, |R_a - R_b|_F = 2 sqrt(2) sin(theta / 2), so
   theta = 2 asin(|R_a - R_b|_F / (2 sqrt 2)). asin is increasing and convex on [0, 1] and the norm
   of a mean is at most the mean of the norms, so over a window of W frames
   sum_i theta_i >= 2 W asin(|mean_i R_a - mean_i R_b|_F / (2 sqrt 2)). Rotation matrices, unlike
   quaternions, can be averaged: q and -q give the same matrix.
   A box of summaries (per index node) bounds every window in it: a point's distance to a box is
   at most its distance to any point inside.
2. Near-exact interval, per window: Eq. 1's terms in float32, the angle as 8 asin(z) with
   z = sin(theta / 8) <= sin(pi / 8): sin^2(theta / 4) = (1 - |<q_a, q_b>|) / 2 from the
   quaternions, then a half-angle step; asin's series cut after three terms (all its terms are
   positive, so the cut series is below asin; the rest is at most ASIN_SERIES_REST z^7). The upper end lets the search
   prune with a best cost it never computed exactly; the exact float64 cost is computed at the end
   for the windows whose lower end is within the best upper end.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..model.arrays import AnyFloatArray, Float32Array, FloatArray, IndexArray
from .window import NUM_JOINTS, Query

# Lower bounds are shrunk, upper bounds widened, by a relative and an absolute margin against
# float32 rounding (each about 100 times the worst rounding of the quantities involved).
BOUND_RELATIVE_MARGIN = 1e-4
BOUND_ABSOLUTE_MARGIN = 1e-4
# The margin on the squared chord 2 - 2 |<q_a, q_b>| of two float32 unit quaternions (their norms are
# 1 within about 1e-7, so the dot product is within a few 1e-7 of the true cosine).
CHORD_MARGIN = 2e-6
# asin(z) - (z + z^3 / 6 + 3 z^5 / 40) <= 0.0497 z^7 for 0 <= z <= sin(pi / 8), the range of
# z = sin(angle / 8) for rotation angles up to pi (the rest over z^7, a series with positive
# terms, grows with z; at sin(pi / 8) it is 0.04963).
ASIN_SERIES_REST = 0.0497
# Rows of a window summary (each row one number per joint): the first half's mean position
# (x, y, z), the second half's, and the nine entries of the mean rotation matrix.
ROTATION_ENTRIES = 9
SUMMARY_ROWS = 6 + ROTATION_ENTRIES
FIRST_HALF, SECOND_HALF, ROTATION = slice(0, 3), slice(3, 6), slice(6, SUMMARY_ROWS)
# The rotation difference's norm is lowered by this (relative and absolute) before its angle is taken:
# above the float32 rounding of rows below 1 (2.4e-7 each, three of them at most in a norm's error).
NORM_MARGIN = 1e-6
# Windows (or nodes) per pass of a summary bound (temporaries of a few hundred KB stay in L2).
SUMMARY_CHUNK = 512


def shrink(bound: Float32Array) -> Float32Array:
    """A float32 lower bound moved down by the margins."""
    return bound * np.float32(1.0 - BOUND_RELATIVE_MARGIN) - np.float32(BOUND_ABSOLUTE_MARGIN)


def widen(bound: Float32Array) -> Float32Array:
    """A float32 upper bound moved up by the margins."""
    return bound * np.float32(1.0 + BOUND_RELATIVE_MARGIN) + np.float32(BOUND_ABSOLUTE_MARGIN)


# ---------------------------------------------------------------------------------------------
# 1. Window summaries


def half_sizes(window: int) -> tuple[int, int]:
    """Frames in the first and second half of a window (the first one longer; (1, 0) for one frame)."""
    first = (window + 1) // 2
    return first, window - first


def window_summaries(aligned: AnyFloatArray, rot: AnyFloatArray) -> FloatArray:
    """Summaries (SUMMARY_ROWS, n, 15) float64 of n windows from their aligned positions
    (n, W, 15, 3) and joint-local rotations (n, W, 15, 4). Rows first, so each row is a contiguous
    plane. A one-frame window's second half is its first (and weighs nothing, SummaryWeights)."""
    n, window, joints = aligned.shape[:3]
    k1, k2 = half_sizes(window)
    aligned = np.asarray(aligned, np.float64)
    first = aligned[:, :k1].sum(axis=1) * (1.0 / k1)
    second = aligned[:, k1:].sum(axis=1) * (1.0 / k2) if k2 else first
    # A rotation matrix is linear in the quaternion's outer product q q^T, so the mean matrix is
    # that map of the mean outer product.
    q = np.asarray(rot, np.float64)
    q = q / np.sqrt(np.sum(q * q, axis=-1, keepdims=True))
    outer = q.transpose(0, 2, 3, 1) @ q.transpose(0, 2, 1, 3)  # (n, 15, 4, 4), summed over the frames
    matrices = outer.reshape(n, joints, 16) @ (_OUTER_TO_MATRIX / window)  # (n, 15, 9)
    return np.concatenate([first.transpose(2, 0, 1), second.transpose(2, 0, 1), matrices.transpose(2, 0, 1)])


def _outer_to_matrix() -> FloatArray:
    """The (16, 9) map from q q^T (w, x, y, z; flattened) to the rotation matrix (row-major) of a
    unit quaternion: R00 = ww + xx - yy - zz, R01 = 2 (xy - wz), ..."""
    w, x, y, z = range(4)
    entries = [
        {(w, w): 1, (x, x): 1, (y, y): -1, (z, z): -1}, {(x, y): 2, (w, z): -2}, {(x, z): 2, (w, y): 2},
        {(x, y): 2, (w, z): 2}, {(w, w): 1, (x, x): -1, (y, y): 1, (z, z): -1}, {(y, z): 2, (w, x): -2},
        {(x, z): 2, (w, y): -2}, {(y, z): 2, (w, x): 2}, {(w, w): 1, (x, x): -1, (y, y): -1, (z, z): 1},
    ]  # fmt: skip
    out = np.zeros((16, 9))
    for column, terms in enumerate(entries):
        for (i, k), factor in terms.items():
            out[4 * i + k, column] = factor
    return out


_OUTER_TO_MATRIX = _outer_to_matrix()


@dataclass(frozen=True)
class SummaryWeights:
    """How summary differences become a bound (see section 1): per joint k w_p for each half of k
    frames; 4 W w_theta for the rotation (times asin of the quarter angle's sine), or 2 W w_theta
    times the half angle's sine (looser, from asin(x) >= x); and the absolute rounding margin."""

    halves: Float32Array
    rotation: Float32Array
    rotation_linear: Float32Array
    margin: float

    @classmethod
    def of(cls, window: int, wp: FloatArray, wq: FloatArray) -> SummaryWeights:
        wp, wq = np.asarray(wp, np.float64), np.asarray(wq, np.float64)
        # Every summary number is a float32 rounding (relative 6e-8) of a value below 4 (metres or
        # matrix entries), so a half's mean-position norm is within 1e-6 of its float64 value:
        # 2e-5 per unit of weight and frame is 20 times that (the rotation norms' rounding is
        # NORM_MARGIN's; float32 arithmetic is in the relative margin).
        margin = 2e-5 * window * (float(np.sum(wp)) + float(np.sum(wq)))
        return cls(
            halves=np.stack([k * wp for k in half_sizes(window)]).astype(np.float32),
            rotation=(4.0 * window * wq).astype(np.float32),
            rotation_linear=(2.0 * window * wq).astype(np.float32),
            margin=margin,
        )


class QuerySummary:
    """The query's summary (SUMMARY_ROWS, 15) float32, and the same repeated for a pass over many
    windows (tiled), so that every step of a bound runs over contiguous memory."""

    def __init__(self, query: Query) -> None:
        self.rows = window_summaries(query.aligned[None], query.features.rot[None])[:, 0].astype(np.float32)
        self._tile = self.rows

    def tiled(self, count: int) -> Float32Array:
        """The rows repeated for `count` windows: (SUMMARY_ROWS, count * 15), kept and grown as needed."""
        have = self._tile.shape[1] // NUM_JOINTS
        if have < count:
            self._tile = np.tile(self.rows, (1, max(count, min(2 * have, SUMMARY_CHUNK))))
        return self._tile[:, : count * NUM_JOINTS]


def summary_bounds(summaries: Float32Array, cands: IndexArray | slice, query: QuerySummary, weights: SummaryWeights,
                   best: float = np.inf) -> Float32Array:  # fmt: skip
    """Lower bounds of Eq. 1 (section 1) for the windows `cands` (indices, or a slice) of
    `summaries` (SUMMARY_ROWS, C, 15): each half's mean position and the mean rotation. Bounds that
    a cheaper form already puts above `best` are left at that form (still lower bounds)."""

    def bounds(part: IndexArray | slice, count: int) -> Float32Array:
        diff = _gather(summaries, part).reshape(SUMMARY_ROWS, -1) - query.tiled(count)
        return _bound(diff, count, weights, best)

    return _in_chunks(bounds, cands)


def summary_box_bounds(lo: Float32Array, hi: Float32Array, nodes: IndexArray, query: QuerySummary,
                       weights: SummaryWeights, best: float = np.inf) -> Float32Array:  # fmt: skip
    """Lower bounds of Eq. 1 for every window of the nodes whose summaries lie in the boxes lo..hi
    (SUMMARY_ROWS, n_nodes, 15): the distance from the query's summary to each box (`best` as in
    summary_bounds)."""

    def bounds(part: IndexArray | slice, count: int) -> Float32Array:
        target = query.tiled(count)
        below = _gather(lo, part).reshape(SUMMARY_ROWS, -1) - target
        above = target - _gather(hi, part).reshape(SUMMARY_ROWS, -1)
        np.maximum(below, above, out=below)
        np.maximum(below, 0.0, out=below)
        return _bound(below, count, weights, best)

    return _in_chunks(bounds, nodes)


def _in_chunks(bounds: Callable[[IndexArray | slice, int], Float32Array], items: IndexArray | slice) -> Float32Array:
    """bounds(part, count) over SUMMARY_CHUNK items at a time."""
    if isinstance(items, slice):
        first, stop = items.start, items.stop
        parts = [(slice(a, min(a + SUMMARY_CHUNK, stop)), min(SUMMARY_CHUNK, stop - a))
                 for a in range(first, stop, SUMMARY_CHUNK)]  # fmt: skip
    else:
        parts = [(items[a : a + SUMMARY_CHUNK], len(items[a : a + SUMMARY_CHUNK]))
                 for a in range(0, len(items), SUMMARY_CHUNK)]  # fmt: skip
    if len(parts) == 1:
        return bounds(*parts[0])
    return np.concatenate([bounds(part, count) for part, count in parts] or [np.zeros(0, np.float32)])


def _gather(values: Float32Array, part: IndexArray | slice) -> Float32Array:
    """The items `part` (indices, or a slice) of values (R, C, 15) along the second axis."""
    return values[:, part] if isinstance(part, slice) else np.take(values, part, axis=1)


def _bound(diff: Float32Array, count: int, weights: SummaryWeights, best: float) -> Float32Array:
    """Section 1's bound (count,) from the summary differences (SUMMARY_ROWS, count * 15) (squared
    in place), shrunk by the margins. Each joint's rotation angle 2 asin(x) is first bounded by 2 x
    (asin's first term); only the windows this leaves within `best` get the tight form."""
    diff *= diff
    positions = _norms(diff[FIRST_HALF], count) @ weights.halves[0]
    positions += _norms(diff[SECOND_HALF], count) @ weights.halves[1]
    x = _rotation_sines(_norms(diff[ROTATION], count))
    total = _shrink_summary(positions + x @ weights.rotation_linear, weights)
    close = np.flatnonzero(total <= best) if np.isfinite(best) else slice(None)
    x = x[close]
    x *= x
    total[close] = _shrink_summary(positions[close] + _asin_below(_half_angle(x)) @ weights.rotation, weights)
    return total


def _norms(squared: Float32Array, count: int) -> Float32Array:
    """Euclidean norms (count, 15) from squared differences (r, count * 15), one row a component."""
    norm = squared.sum(axis=0)
    np.sqrt(norm, out=norm)
    return norm.reshape(count, NUM_JOINTS)


def _rotation_sines(norm: Float32Array) -> Float32Array:
    """x = |mean R_a - mean R_b| / (2 sqrt 2) (in place), the sine of half the angle of a rotation
    difference that long: theta = 2 asin(x). x is first lowered by NORM_MARGIN against float32
    rounding (theta is steep in x near pi). The tight form takes the angle as 4 asin(y) with the
    quarter angle's sine y = x / sqrt(2 + 2 sqrt(1 - x^2)) <= sin(pi / 4), where asin's cut series
    is within 1% (it is poor near 1); 4 asin(y) >= 4 y >= 2 x, so it is never below the loose form."""
    norm *= np.float32((1.0 - NORM_MARGIN) / (2.0 * np.sqrt(2.0)))
    norm -= np.float32(NORM_MARGIN)
    return np.clip(norm, 0.0, 1.0, out=norm)


def _shrink_summary(total: Float32Array, weights: SummaryWeights) -> Float32Array:
    return total * np.float32(1.0 - BOUND_RELATIVE_MARGIN) - np.float32(weights.margin)


def _asin_below(y: Float32Array) -> Float32Array:
    """y + y^3 / 6 + 3 y^5 / 40 <= asin(y) on [0, 1] (float32, y's dtype)."""
    y2 = y * y
    series = y2 * np.float32(3.0 / 40.0)
    series += np.float32(1.0 / 6.0)
    series *= y2
    series += np.float32(1.0)
    series *= y
    return series


# ---------------------------------------------------------------------------------------------
# 2. Near-exact interval


class QueryArrays:
    """The query in the bounds' float32 layout: aligned positions (3, W, 15), rotations (4, W, 15),
    weights tiled over the window (W * 15,), its summary and the summary weights."""

    def __init__(self, query: Query, wp: FloatArray, wq: FloatArray) -> None:
        window = query.window
        self.window = window
        self.pos = np.ascontiguousarray(query.aligned.transpose(2, 0, 1), dtype=np.float32)
        self.rot = np.ascontiguousarray(query.features.rot.transpose(2, 0, 1), dtype=np.float32)
        self.wp, self.wq, self.summary_weights = _query_weights(window, tuple(wp), tuple(wq))
        self.summary = QuerySummary(query)


@functools.lru_cache(maxsize=8)
def _query_weights(
    window: int, wp: tuple[float, ...], wq: tuple[float, ...]
) -> tuple[Float32Array, Float32Array, SummaryWeights]:
    """Weights tiled over the window (W * 15,) float32, and the summary weights (kept per weights)."""
    tiled_wp, tiled_wq = (np.tile(np.asarray(w, np.float32), window) for w in (wp, wq))
    return tiled_wp, tiled_wq, SummaryWeights.of(window, np.asarray(wp), np.asarray(wq))


def near_exact_interval(
    planes: AnyFloatArray, placement: Float32Array, starts: IndexArray, q: QueryArrays
) -> tuple[Float32Array, Float32Array]:
    """Lower and upper bounds (n,) of Eq. 1 for the windows starting at the flat frames `starts`.

    planes (7, N, 15): the library's pos_local (x, y, z) and rot (w, x, y, z) as contiguous
    component planes; placement (N, 3): each frame's heading and ground point (x, y). Positions are
    aligned and compared in float32; angles as in section 2.
    """
    n = len(starts)
    frames = starts[:, None] + np.arange(q.window)
    # Each frame in the heading frame of the window's first one: turned by the heading difference,
    # moved by the ground offset turned back by the first frame's heading.
    where = np.take(placement, frames, axis=0)  # (n, W, 3)
    where -= where[:, :1]
    first = np.take(placement[:, 0], starts)[:, None]
    cos0, sin0 = np.cos(first), np.sin(first)
    off_x, off_y = where[..., 1], where[..., 2]
    shift_x = (cos0 * off_x + sin0 * off_y)[..., None]
    shift_y = (cos0 * off_y - sin0 * off_x)[..., None]
    cr, sr = np.cos(where[..., 0])[..., None], np.sin(where[..., 0])[..., None]
    comps = np.take(planes, frames, axis=1)  # (7, n, W, 15)
    px, py = comps[0], comps[1]
    dx = cr * px
    dx -= sr * py
    dx += shift_x - q.pos[0]
    dy = sr * px
    dy += cr * py
    dy += shift_y - q.pos[1]
    dz = comps[2]
    dz -= q.pos[2]
    dx *= dx
    dy *= dy
    dz *= dz
    dx += dy
    dx += dz
    np.sqrt(dx, out=dx)
    positions = dx.reshape(n, -1) @ q.wp
    # Rotations: |<q_a, q_b>| gives sin^2(angle / 4) = (1 - |<q_a, q_b>|) / 2 for unit quaternions,
    # moved by the chord margin down (lower end) and up (upper end); then z = sin(angle / 8).
    dot = comps[3:] * q.rot[:, None]
    dot = np.abs(dot.sum(axis=0))
    quarter2 = np.float32(0.5) - np.float32(0.5) * dot
    ends = np.stack([quarter2 - np.float32(CHORD_MARGIN / 4), quarter2 + np.float32(CHORD_MARGIN / 4)])
    np.clip(ends, 0.0, 0.5, out=ends)
    eighth = _half_angle(ends)
    angles = _asin_below(eighth)
    high = eighth[1]
    rest = high * high
    rest *= rest
    rest *= high
    rest *= high * high  # z^7
    rest *= np.float32(ASIN_SERIES_REST)
    angles[1] += rest
    rotations = angles.reshape(2, n, -1) @ q.wq
    rotations *= np.float32(8.0)
    return shrink(positions + rotations[0]), widen(positions + rotations[1])


def _half_angle(sine2: Float32Array) -> Float32Array:
    """sin(a / 2) from sin^2(a) for a <= pi / 2 (float32, in place): s^2 / (2 + 2 sqrt(1 - s^2))."""
    root = np.subtract(np.float32(1.0), sine2)
    np.sqrt(root, out=root)
    root += np.float32(1.0)
    root *= np.float32(2.0)
    sine2 /= root
    return np.sqrt(sine2, out=sine2)
