"""The jump search: paper section 2.4, Eq. 1 with Table 2's weights, exact and fast.

Eq. 1 compares a query window of `ws` frames with every library window of the same length:

    D(f_s, f_m) = sum_{i<ws} sum_j  w_p[j] * |p_j(f_s+i) - p_j(f_m+i)|  +  w_q[j] * |theta_j(f_s+i) - theta_j(f_m+i)|

over the 15 joints of Table 2 (neck, back, waist and both hips, knees, shoulders, elbows, wrists,
ankles; left and right weighted alike). The best (clip, frame) is the window with the lowest D;
the caller accepts it under a threshold.

Definitions (the paper leaves them open; these are ours):
- Units: positions in metres, angles in radians, so one radian weighs like one metre.
- |theta_a - theta_b| is the rotation angle of q_a^-1 q_b for the joint's *local* rotation (relative
  to its skeleton parent), in [0, pi], q and -q equal. Local rotations do not change when the whole
  character turns or moves, so they need no alignment. The pelvis is not in Table 2 and carries no
  rotation term; its orientation enters through the aligned positions of the joints that hang from it.
- Alignment: before positions are compared, the candidate window is turned about the vertical (Z)
  axis and moved on the ground so that its *first* frame (the jump frame f_m itself) has the
  query's first-frame pelvis ground point and heading. The first frame anchors it because that
  is the frame the search returns and where the pipeline places Sequence-2: the transform that
  makes the two windows agree there is exactly the placement of the clip, returned with the match
  (`Match.yaw`, `Match.offset`). Heights are not changed (the ground is Z = 0 in both).
- Heading: the twist about world Z of the pelvis' global rotation (yaw = 2 atan2(q_z, q_w) of the
  twist-swing split q = twist * swing) plus the facing of the skeleton's rest pose (perpendicular to
  the rest hip line). Turning the whole character by a yaw adds exactly that yaw to the twist, so
  the alignment cancels it; unlike a projected "forward" axis it stays defined when the pelvis tips
  far over (falls), failing only at a pelvis turned exactly upside down.

How the search is fast and still exact (what we do beyond the paper, which scanned every window):
- Per-frame features are stored in the frame's own heading frame (pelvis ground point at the
  origin, heading along +X). A candidate window expressed in its first frame's heading frame needs
  only each frame's relative heading and ground offset, so a window is rebuilt from per-frame data.
- Lower-bound pruning, four filters, each a valid lower bound of Eq. 1 (never above the true cost):
  1. Pivots (triangle inequality): Eq. 1 between windows, each expressed in its own first frame's
     heading frame, is a metric (a weighted sum of Euclidean distances and of rotation angles,
     which are metrics; the alignment is a rigid move of each window into its own frame). So for
     any window P, D(q, c) >= |D(q, P) - D(P, c)|. The index keeps D(P_k, c) in float32 for PIVOTS
     pivot windows chosen far apart (farthest-point traversal on a subsample) and every candidate
     c, and per node the range of them; a query computes its K exact D(q, P_k) in float64
     and bounds a node by max_k max(lo_k - D(q, P_k), D(q, P_k) - hi_k), a candidate by
     max_k |D(q, P_k) - D(P_k, c)|, both less the float32 error of the stored distances
     (_pivot_error, a wide margin). This costs K numbers per node or candidate instead of the
     7 * W * 15 of the boxes or the near-exact bound, and prunes most of the library: on the
     100k-frame bench library 99.96% of candidates for near queries, 96% for far ones (at the
     final best cost, K = 32; K = 16 prunes 93% of far ones). It holds for Table 2's weights
     only; other weights skip it. Before the traversal, the SEED_BLOCKS blocks with the lowest
     pivot bound are evaluated, so the best cost is good from the start.
  2. Boxes: candidate windows are grouped into blocks of BLOCK_SIZE consecutive starts and blocks
     into groups of LEVEL_FANOUT (LEVELS levels; no group crosses a class). Each group keeps, per
     window frame and joint, the bounding box of the aligned positions and of the local-rotation
     quaternions. Point-to-box distance bounds the position terms; for rotations the box's largest
     |<q_query, q>| bounds the angle through 2 acos(x) >= 2 sqrt(2 - 2x). Groups are visited
     cheapest bound (the larger of box and pivot bound) first; one whose bound is above the best
     cost found so far is skipped. Box bounds are computed only for nodes the pivots leave.
  3. Near-exact float32 bound per candidate (for those the pivots leave): the position terms in
     float32 and the angle 4 asin(c/2) (c the quaternion chord) through the first three terms of
     asin's series, whose terms are all positive, so a truncated series is below the angle (by
     1e-4 at 90 degrees, 0.8% at 180). (Early abandoning after the first two window frames was
     dropped with the pivots: the candidates the pivots leave are close enough that two frames
     almost never exceed the best, and one pass is cheaper than two.)
  4. Exact cost in float64 (window_costs), only for candidates whose bound can still beat the best.
  Float32 bounds are shrunk by a relative and an absolute margin (and the chord's by its own), far
  above float32 rounding, so rounding can never push a bound over the true cost; the result is the
  reference's to float64 rounding.
- Index cost of the pivots: K float32 per candidate (12.8 MB at 100k windows, K = 32) and K passes
  over the library's windows at build (about 7 of the 9 s at 100k windows; build time grows with
  K, far queries slow down with fewer: K = 16 builds in 5 s, far full searches take 1.5x as long).
- The exact float64 costs compute the rotation angle from the quaternion components directly
  (_angles), the same formula as quat.angle_between without its per-call overhead.
- Layout: the index keeps the features as contiguous component planes (x, y, z, w, ...) and
  gathers rows with np.take, so every step is a plain elementwise pass over contiguous float32.
- Ties go to the lowest (class, clip, frame), the order of the library's arrays.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import quat
from .errors import LibraryError
from .skeleton import Motion

# Table 2, per joint row: (position weight w_p, rotation weight w_theta); left and right alike.
TABLE2_POSITION_WEIGHTS: dict[str, float] = {
    "neck": 0.4, "back": 0.4, "waist": 0.6, "hip": 0.8, "knee": 0.6,
    "shoulder": 0.6, "elbow": 0.6, "wrist": 0.2, "ankle": 0.1,
}  # fmt: skip
TABLE2_ROTATION_WEIGHTS: dict[str, float] = {
    "neck": 0.3, "back": 0.4, "waist": 0.6, "hip": 1.0, "knee": 0.8,
    "shoulder": 0.4, "elbow": 0.4, "wrist": 0.2, "ankle": 0.1,
}  # fmt: skip
# The joints Eq. 1 sums over, in feature order (roles.py names).
SEARCH_ROLES: tuple[str, ...] = (
    "neck", "back", "waist", "hip_l", "hip_r", "knee_l", "knee_r", "shoulder_l", "shoulder_r",
    "elbow_l", "elbow_r", "wrist_l", "wrist_r", "ankle_l", "ankle_r",
)  # fmt: skip
NUM_JOINTS = len(SEARCH_ROLES)

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


def table2_row(role: str) -> str:
    """Table 2's row for a role: "hip_l" -> "hip"."""
    return role.rsplit("_", 1)[0] if role.endswith(("_l", "_r")) else role


def joint_weights(weights: dict[str, float]) -> np.ndarray:
    """Per-joint weights (15,) in SEARCH_ROLES order from a Table 2 row -> weight mapping."""
    missing = [r for r in {table2_row(role) for role in SEARCH_ROLES} if r not in weights]
    if missing:
        raise LibraryError(f"search weights lack the Table 2 rows: {', '.join(sorted(missing))}")
    return np.array([float(weights[table2_row(role)]) for role in SEARCH_ROLES])


# ---------------------------------------------------------------------------------------------
# Per-frame features


@dataclass
class FrameFeatures:
    """What Eq. 1 reads of each frame, for T frames and the 15 joints of SEARCH_ROLES.

    pos_local: (T, 15, 3) joint positions in the frame's own heading frame (pelvis ground point at
      the origin, heading along +X, Z up, metres).
    heading: (T,) pelvis heading about Z, radians.  ground: (T, 2) pelvis ground point (x, y).
    rot: (T, 15, 4) joint-local rotations (w, x, y, z), w >= 0.
    """

    pos_local: np.ndarray
    heading: np.ndarray
    ground: np.ndarray
    rot: np.ndarray

    @property
    def num_frames(self) -> int:
        return self.heading.shape[0]

    def world_positions(self) -> np.ndarray:
        """Joint positions in world space (T, 15, 3), rebuilt from the heading frames."""
        return _yaw_rotate(self.heading[:, None], self.pos_local) + _ground3(self.ground)[:, None]


def _yaw_rotate(angle: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate vectors (..., 3) about Z by `angle` (broadcast against (...))."""
    c, s = np.cos(angle), np.sin(angle)
    out = np.empty(np.broadcast_shapes(np.shape(angle) + (3,), v.shape))
    out[..., 0] = c * v[..., 0] - s * v[..., 1]
    out[..., 1] = s * v[..., 0] + c * v[..., 1]
    out[..., 2] = v[..., 2]
    return out


def _ground3(ground: np.ndarray) -> np.ndarray:
    return np.concatenate([ground, np.zeros(ground.shape[:-1] + (1,))], axis=-1)


def rest_heading(motion: Motion, roles: dict[str, str]) -> float:
    """Facing of the rest pose: perpendicular to the hip line, on the ground (radians about Z).

    Skeletons differ in which way their rest pose faces (CMU +Z in Y-up files, others -Y or +Y), so
    the pelvis twist alone would not compare across skeletons; adding this makes 0 mean "facing +X".
    """
    rest = motion.skeleton.rest_positions()
    sk = motion.skeleton
    left = rest[sk.index(roles["hip_l"])] - rest[sk.index(roles["hip_r"])]
    forward = np.cross(left, [0.0, 0.0, 1.0])
    if np.hypot(forward[0], forward[1]) < 1e-9:
        return 0.0
    return float(np.arctan2(forward[1], forward[0]))


def frame_features(motion: Motion, roles: dict[str, str]) -> FrameFeatures:
    """Eq. 1's per-frame features of a whole motion (see FrameFeatures), by forward kinematics."""
    sk = motion.skeleton
    joints = [sk.index(roles[role]) for role in SEARCH_ROLES]
    pelvis = sk.index(roles["pelvis"])
    pos, rot = motion.global_transforms()
    q = rot[:, pelvis]
    heading = 2.0 * np.arctan2(q[:, 3], q[:, 0]) + rest_heading(motion, roles)
    heading = np.angle(np.exp(1j * heading))  # wrap to (-pi, pi]
    ground = pos[:, pelvis, :2].copy()
    world = pos[:, joints]
    pos_local = _yaw_rotate(-heading[:, None], world - _ground3(ground)[:, None])
    local = motion.local_rot[:, joints]
    local = np.where(local[..., :1] < 0, -local, local)
    return FrameFeatures(pos_local, heading, ground, local)


def resample(motion: Motion, times: np.ndarray) -> Motion:
    """The motion at the given times in seconds (linear root and joint offsets, slerped rotations).

    Library clips and queries come at 30, 60, 120 fps; Eq. 1 sums per frame, so both are brought to
    the library's rate first and a window covers the same time in every clip.
    """
    times = np.asarray(times, dtype=float)
    last = motion.num_frames - 1
    x = np.clip(times * motion.fps, 0.0, last)
    lo = np.minimum(np.floor(x).astype(np.int64), max(last - 1, 0))
    hi = np.minimum(lo + 1, last)
    t = x - lo
    root = motion.root_pos[lo] * (1 - t)[:, None] + motion.root_pos[hi] * t[:, None]
    weight = np.broadcast_to(t[:, None], motion.local_rot[lo].shape[:2])
    rot = quat.slerp(motion.local_rot[lo], motion.local_rot[hi], weight)
    local_pos = None
    if motion.local_pos is not None:
        local_pos = motion.local_pos[lo] * (1 - t)[:, None, None] + motion.local_pos[hi] * t[:, None, None]
    fps = 1.0 / (times[1] - times[0]) if len(times) > 1 else motion.fps
    return Motion(motion.skeleton, fps, root, rot, local_pos)


# ---------------------------------------------------------------------------------------------
# Windows and the query


def aligned_window(pos_local: np.ndarray, heading: np.ndarray, ground: np.ndarray) -> np.ndarray:
    """Window positions in the heading frame of its first frame: (..., W, 15, 3) from
    pos_local (..., W, 15, 3), heading (..., W), ground (..., W, 2)."""
    rel = heading - heading[..., :1]
    offset = ground - ground[..., :1, :]
    back = -heading[..., :1]
    c, s = np.cos(back), np.sin(back)
    shift = np.stack([c * offset[..., 0] - s * offset[..., 1], s * offset[..., 0] + c * offset[..., 1]], axis=-1)
    out = _yaw_rotate(rel[..., None], pos_local)
    out[..., :2] += shift[..., None, :]
    return out


@dataclass
class Query:
    """A query window of W frames at the library's rate: FrameFeatures plus its aligned positions."""

    features: FrameFeatures
    aligned: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        f = self.features
        self.aligned = aligned_window(f.pos_local.astype(float), f.heading.astype(float), f.ground.astype(float))

    @property
    def window(self) -> int:
        return self.features.num_frames


def query_from_motion(
    motion: Motion, start_frame: float, window: int, fps: float, roles: dict[str, str] | None = None
) -> Query:
    """The query window starting at `start_frame` (the motion's frames): `window` frames at `fps`.

    roles: the skeleton's role map; default `motion.skeleton.roles`, else found by roles.py.
    """
    from .roles import assign_roles

    roles = roles or motion.skeleton.roles or assign_roles(motion.skeleton)
    times = start_frame / motion.fps + np.arange(window) / fps
    end = (motion.num_frames - 1) / motion.fps
    if start_frame < 0 or times[-1] > end + 1e-9:
        raise LibraryError(
            f"the query window ({window} frames at {fps:g} fps from frame {start_frame:g}) runs past the "
            f"motion's {motion.num_frames} frames at {motion.fps:g} fps"
        )
    return Query(frame_features(resample(motion, times), roles))


# ---------------------------------------------------------------------------------------------
# Exact costs of given candidates (vectorised) and the lower-bound index


def window_costs(library, starts: np.ndarray, query: Query, wp: np.ndarray, wq: np.ndarray) -> np.ndarray:
    """Eq. 1 for the candidate windows starting at flat frames `starts` (n,), float64 (n,)."""
    frames = np.asarray(starts)[:, None] + np.arange(query.window)
    cand = aligned_window(
        *(a[frames].astype(float) for a in (library.pos_local, library.heading, library.ground))
    )
    dist = np.sqrt(np.sum((cand - query.aligned) ** 2, axis=-1))  # (n, W, 15)
    rot = library.rot[frames].astype(float)
    angle = _angles(query.features.rot.astype(float).transpose(2, 0, 1), rot.transpose(3, 0, 1, 2))  # (n, W, 15)
    # Row-wise sums (not BLAS), so identical windows get bit-identical costs and ties stay ties.
    return ((dist * wp).sum(axis=-1) + (angle * wq).sum(axis=-1)).sum(axis=1)


def _angles(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Rotation angle of a^-1 b for quaternions given as component planes (w, x, y, z, ...),
    2 atan2(|vector part|, |scalar part|) as quat.angle_between, without its stacking (several
    times faster on the few windows the search evaluates exactly)."""
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    w = aw * bw + ax * bx + ay * by + az * bz
    vx = aw * bx - bw * ax - (ay * bz - az * by)
    vy = aw * by - bw * ay - (az * bx - ax * bz)
    vz = aw * bz - bw * az - (ax * by - ay * bx)
    return 2.0 * np.arctan2(np.sqrt(vx * vx + vy * vy + vz * vz), np.abs(w))


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
    starts: np.ndarray
    firsts: list[np.ndarray]
    boxes: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]
    class_tops: dict[str, tuple[int, int]]
    planes: np.ndarray
    heading: np.ndarray
    ground: np.ndarray
    pivots: np.ndarray
    pivot_dist: np.ndarray
    pivot_ranges: list[tuple[np.ndarray, np.ndarray]]
    pivot_margin: float
    pivot_windows: tuple[np.ndarray, np.ndarray]

    @property
    def nbytes(self) -> int:
        arrays = [a for level in self.boxes for a in level] + self.firsts + [self.starts, self.planes]
        arrays += [self.pivot_dist, *self.pivot_windows] + [a for level in self.pivot_ranges for a in level]
        return sum(a.nbytes for a in arrays)


def _reduce_boxes(boxes, first: np.ndarray):
    """Boxes of groups: min of lows, max of highs over the ranges cut by `first`."""
    plo, phi, rlo, rhi = boxes
    cut = first[:-1]
    return (
        np.minimum.reduceat(plo, cut, axis=0), np.maximum.reduceat(phi, cut, axis=0),
        np.minimum.reduceat(rlo, cut, axis=0), np.maximum.reduceat(rhi, cut, axis=0),
    )  # fmt: skip


def _group(class_ranges: dict[str, tuple[int, int]], size: int) -> tuple[np.ndarray, dict[str, tuple[int, int]]]:
    """Cut each class's range of items into groups of `size`: the cuts and each class's groups."""
    first, ranges = [0], {}
    for slug, (a, b) in class_ranges.items():
        g0 = len(first) - 1
        first.extend(list(range(a + size, b, size)) + [b])
        ranges[slug] = (g0, len(first) - 1)
    return np.asarray(first, np.int64), ranges


def _canonical_windows(library, starts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Aligned positions (n, 3, W, 15) float64 and rotations (n, 4, W, 15) of the windows `starts`."""
    frames = starts[:, None] + np.arange(library.window)
    pos = aligned_window(*(a[frames].astype(float) for a in (library.pos_local, library.heading, library.ground)))
    return pos.transpose(0, 3, 1, 2), library.rot[frames].transpose(0, 3, 1, 2)


def _pivot_distances(pos: np.ndarray, rot: np.ndarray, ppos: np.ndarray, prot: np.ndarray, wp, wq) -> np.ndarray:
    """_pivot_distances_chunk a cache-sized chunk of windows at a time."""
    step = 512
    return np.concatenate([_pivot_distances_chunk(pos[a : a + step], rot[a : a + step], ppos, prot, wp, wq)
                           for a in range(0, max(len(pos), 1), step)])  # fmt: skip


def _pivot_distances_chunk(pos: np.ndarray, rot: np.ndarray, ppos: np.ndarray, prot: np.ndarray, wp, wq) -> np.ndarray:
    """Eq. 1 between windows (pos (n, 3, W, 15), rot (n, 4, W, 15)) and pivots (K, 3 or 4, W, 15),
    (n, K) float32, within _pivot_error of the exact cost (see there). The angle is 4 asin(c / 2) of
    the chord c = |q_a -+ q_b| taken from the component differences: unlike acos of the dot product
    it keeps float32's precision at small angles."""
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


def _pivot_error(distance: float, window: int, wp, wq) -> float:
    """How far a float32 pivot distance can be from the exact cost, with a wide margin.

    Every one of Eq. 1's 2 * W * 15 terms is within about 2e-6 of exact (aligned coordinates of a
    quarter-second window are metres, rounded to float32 at 6e-8 relative; the chord's angle has a
    slope of at most 2.9); we allow 1e-4 per unit of weight and term, plus 1e-4 of the distance
    for the float32 sum of the terms (at most 240 * 6e-8 = 1.5e-5 relative at W = 8)."""
    return 1e-4 * distance + 1e-4 * window * (float(np.sum(wp)) + float(np.sum(wq)))


def _choose_pivots(library, starts: np.ndarray, count: int, wp, wq) -> np.ndarray:
    """Pivot windows (indices into `starts`) far apart: farthest-point traversal over a subsample.

    Far-apart pivots see the library from different sides, so for most candidates some pivot's
    distance differs from the query's by more than the best cost (the triangle bound prunes it)."""
    sample = np.arange(0, len(starts), PIVOT_SAMPLE_STEP)
    count = min(count, len(sample))
    if count == 0:
        return np.zeros(0, np.int64)
    pos, rot = _canonical_windows(library, starts[sample])

    def distances(i: int) -> np.ndarray:
        return _pivot_distances(pos, rot, pos[i : i + 1], rot[i : i + 1], wp, wq)[:, 0]

    current = int(np.argmax(distances(0)))  # the window farthest from an arbitrary one
    chosen, nearest = [], np.full(len(sample), np.inf, np.float32)
    for _ in range(count):
        chosen.append(current)
        np.minimum(nearest, distances(current), out=nearest)
        current = int(np.argmax(nearest))
    return sample[np.asarray(chosen[:count], np.int64)]


def build_index(library, block_size: int = BLOCK_SIZE, fanout: int = LEVEL_FANOUT, levels: int = LEVELS,
                pivots: int = PIVOTS, cached_pivots: tuple[np.ndarray, np.ndarray] | None = None) -> SearchIndex:
    """Valid window starts, grouped into a hierarchy of blocks per class, with their boxes and the
    pivot distances (for Table 2's weights).

    cached_pivots: (pivot start frames, pivot distances) of an earlier build of the same library
    (SearchIndex.pivots, .pivot_dist); the pivot distances are most of the build time, so a library
    loaded from its cache reuses them. Ignored when they do not fit this library's windows.
    """
    window = library.window
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
    ppos, prot = _canonical_windows(library, starts[pivot_idx])
    pivot_dist = reuse[1] if reuse else np.empty((len(starts), len(pivot_idx)), np.float32)
    # Boxes per block, from candidate windows built a chunk at a time (bounded memory).
    nb = len(block_first) - 1
    plo, phi = np.empty((nb, 3, window, NUM_JOINTS), np.float32), np.empty((nb, 3, window, NUM_JOINTS), np.float32)
    rlo, rhi = np.empty((nb, 4, window, NUM_JOINTS), np.float32), np.empty((nb, 4, window, NUM_JOINTS), np.float32)
    chunk = max(1, 4096 // block_size)
    for b0 in range(0, nb, chunk):
        b1 = min(nb, b0 + chunk)
        s0, s1 = block_first[b0], block_first[b1]
        pos, rot = _canonical_windows(library, starts[s0:s1])
        if not reuse:
            pivot_dist[s0:s1] = _pivot_distances(pos, rot, ppos, prot, wp, wq)
        cut = block_first[b0:b1] - s0
        plo[b0:b1] = np.minimum.reduceat(pos, cut, axis=0)
        phi[b0:b1] = np.maximum.reduceat(pos, cut, axis=0)
        rlo[b0:b1] = np.minimum.reduceat(rot, cut, axis=0)
        rhi[b0:b1] = np.maximum.reduceat(rot, cut, axis=0)
    firsts, boxes = [block_first], [(plo, phi, rlo, rhi)]
    for _ in range(1, levels):
        first, class_nodes = _group(class_nodes, fanout)
        firsts.append(first)
        boxes.append(_reduce_boxes(boxes[-1], first) if len(first) > 1 else boxes[-1])
    # Rotation boxes as centre and half-widths (see _box_bounds).
    boxes = [(lo, hi, 0.5 * (rlo + rhi), 0.5 * (rhi - rlo)) for lo, hi, rlo, rhi in boxes]
    return SearchIndex(
        window, starts, firsts, boxes, class_nodes,
        np.ascontiguousarray(np.concatenate([library.pos_local, library.rot], axis=2).transpose(2, 0, 1)),
        library.heading, library.ground,
        starts[pivot_idx], pivot_dist, *_pivot_node_ranges(pivot_dist, firsts, window, wp, wq),
        (ppos.reshape(len(ppos), 3, -1).transpose(1, 0, 2).copy(),
         prot.reshape(len(prot), 4, -1).transpose(1, 0, 2).astype(float)),
    )  # fmt: skip


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


def _pivot_node_ranges(pivot_dist: np.ndarray, firsts: list[np.ndarray], window: int, wp, wq):
    """Per level, the range (lo, hi) of each node's pivot distances, widened by the float32 error
    (one margin for all: the error at the largest distance); and that margin."""
    if pivot_dist.size == 0:
        return [(np.zeros((len(f) - 1, 0), np.float32),) * 2 for f in firsts], 0.0
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

    def __init__(self, query: Query, wp: np.ndarray, wq: np.ndarray):
        self.pos = np.ascontiguousarray(query.aligned.transpose(2, 0, 1), dtype=np.float32)
        self.rot = np.ascontiguousarray(query.features.rot.transpose(2, 0, 1), dtype=np.float32)
        self.rot_abs = np.abs(self.rot)
        self.wp = np.ascontiguousarray(np.broadcast_to(wp, (query.window, NUM_JOINTS)), dtype=np.float32)
        self.wq = np.ascontiguousarray(np.broadcast_to(wq, (query.window, NUM_JOINTS)), dtype=np.float32)


def _safe(bound: np.ndarray) -> np.ndarray:
    return bound * (1.0 - _BOUND_RELATIVE_MARGIN) - _BOUND_ABSOLUTE_MARGIN


def _box_bounds(boxes, idx: np.ndarray, q: _QueryArrays) -> np.ndarray:
    """Lower bounds of Eq. 1 for the boxes `idx` (n,), shrunk against float32 rounding."""
    n = len(idx)
    if n and idx[-1] - idx[0] + 1 == n and np.all(np.diff(idx) == 1):
        plo, phi, rc, rh = (b[idx[0] : idx[0] + n] for b in boxes)  # a run of nodes: views, no copy
    else:
        plo, phi, rc, rh = (np.take(b, idx, axis=0) for b in boxes)
    # Positions: distance from each query joint to the box of candidate positions.
    d = np.maximum(plo - q.pos, q.pos - phi)
    np.maximum(d, 0.0, out=d)
    d *= d
    dist = d[:, 0] + d[:, 1] + d[:, 2]
    np.sqrt(dist, out=dist)
    # Rotations: over a box with centre c and half-widths h, the largest |<q_query, q>| is
    # |<q_query, c>| + <|q_query|, h>; it bounds the angle through 2 acos(x) >= 2 sqrt(2 - 2x).
    centre = rc[:, 0] * q.rot[0]
    spread = rh[:, 0] * q.rot_abs[0]
    for k in (1, 2, 3):
        centre += rc[:, k] * q.rot[k]
        spread += rh[:, k] * q.rot_abs[k]
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
    angle = _angles(query.features.rot.reshape(-1, 4).T.astype(float)[:, None], rot)
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
    c0, s0 = np.cos(heading0), np.sin(heading0)
    shift_x = (c0 * off_x + s0 * off_y)[..., None]
    shift_y = (c0 * off_y - s0 * off_x)[..., None]
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


# ---------------------------------------------------------------------------------------------
# Public search


@dataclass
class Match:
    """The best window: where it is, its Eq. 1 cost and how to place the clip on the query.

    frame: first frame of the window in the clip, at the library's rate (the jump frame).
    source_frame: that frame in the clip's BVH file (after its frame range start).
    yaw, offset: the turn about Z (radians) and ground move (x, y) that put the clip's frame on
    the query's first frame (apply yaw about the origin first, then add offset).
    accepted: cost within the threshold (True when no threshold was given).
    scope: what was searched ("all", a class slug, or a list of them joined by "+").
    candidates_evaluated: windows whose exact float64 cost was computed (the rest were pruned).
    """

    clip: str
    clip_index: int
    reaction_class: str
    frame: int
    source_frame: float
    cost: float
    accepted: bool
    yaw: float
    offset: tuple[float, float]
    scope: str
    candidates_evaluated: int


def _check_query(library, query: Query) -> None:
    if query.window != library.window:
        raise LibraryError(
            f"the query window has {query.window} frames but the library was compiled for {library.window}"
        )


def _selected_tops(library, index: SearchIndex, classes: list[str] | None) -> tuple[np.ndarray, str]:
    if classes is None:
        slugs = list(index.class_tops)
        scope = "all"
    else:
        slugs = list(classes)
        for slug in slugs:
            library.require_class(slug)
        scope = "+".join(slugs)
    ranges = [np.arange(*index.class_tops[s]) for s in slugs if s in index.class_tops]
    tops = np.concatenate(ranges) if ranges else np.zeros(0, np.int64)
    if len(tops) == 0:
        raise LibraryError(f"no clip in {scope!r} is long enough for a {library.window}-frame window")
    return tops, scope


def _ranges(first: np.ndarray, stop: np.ndarray) -> np.ndarray:
    """Concatenated aranges [first[k], stop[k]) without a Python loop."""
    lengths = stop - first
    total = int(lengths.sum())
    if total == 0:
        return np.zeros(0, np.int64)
    offsets = np.repeat(first - np.concatenate([[0], np.cumsum(lengths)[:-1]]), lengths)
    return np.arange(total) + offsets


def find_best(
    library,
    query: Query,
    classes: list[str] | None = None,
    position_weights: dict[str, float] = TABLE2_POSITION_WEIGHTS,
    rotation_weights: dict[str, float] = TABLE2_ROTATION_WEIGHTS,
) -> tuple[int, float, int]:
    """Exact best window start (flat frame), its cost and how many float64 costs were computed."""
    _check_query(library, query)
    index = library.search_index()
    tops, _ = _selected_tops(library, index, classes)
    wp, wq = joint_weights(position_weights), joint_weights(rotation_weights)
    q = _QueryArrays(query, wp, wq)
    # The pivot distances hold for Table 2's weights only; other weights go without them.
    use_pivots = len(index.pivots) > 0 and np.array_equal(wp, joint_weights(TABLE2_POSITION_WEIGHTS)) \
        and np.array_equal(wq, joint_weights(TABLE2_ROTATION_WEIGHTS))
    # D(q, P) exactly (its float32 rounding, 6e-8 relative, is far inside the pivot margin).
    dq = _pivot_query_distances(index, query, wp, wq).astype(np.float32) if use_pivots else None

    best_cost, best_start, evaluated = np.inf, -1, 0

    def evaluate(cands: np.ndarray) -> None:
        """Exact float64 costs of the candidates whose near-exact bound can still beat the best."""
        nonlocal best_cost, best_start, evaluated
        if use_pivots:
            cands = _pivot_candidate_filter(index, cands, dq, best_cost)
        cands, bound = _candidate_bounds(index, cands, q, best_cost)
        order = np.argsort(bound, kind="stable")
        cands, bound = cands[order], bound[order]
        i = 0
        while i < len(cands) and bound[i] <= best_cost:
            group = cands[i : i + 8][bound[i : i + 8] <= best_cost]
            i += 8
            costs = window_costs(library, index.starts[group], query, wp, wq)
            evaluated += len(group)
            for cost, cand in zip(costs, group):
                start = int(index.starts[cand])
                if cost < best_cost or (cost == best_cost and start < best_start):
                    best_cost, best_start = float(cost), start

    def visit(level: int, nodes: np.ndarray) -> None:
        """Nodes of one level, cheapest bound first, in growing batches; skip what cannot win."""
        if use_pivots:  # the cheap triangle bound first; the boxes only for what it leaves
            pivot = _pivot_node_bounds(index, level, nodes, dq)
            keep = pivot <= best_cost
            nodes, pivot = nodes[keep], pivot[keep]
            if len(nodes) == 0:
                return
        bound = _box_bounds(index.boxes[level], nodes, q)
        if use_pivots:
            np.maximum(bound, pivot, out=bound)
        keep = bound <= best_cost
        nodes, bound = nodes[keep], bound[keep]
        order = np.argsort(bound, kind="stable")
        nodes, bound = nodes[order], bound[order]
        first = index.firsts[level]
        # The most promising node alone first (to get a good best early), then growing batches.
        step, i = 1, 0
        while i < len(nodes) and bound[i] <= best_cost:
            group = nodes[i : i + step][bound[i : i + step] <= best_cost]
            i += step
            step = min(step * 4, 256)
            children = _ranges(first[group], first[group + 1])
            if level == 0:
                evaluate(children)
            else:
                visit(level - 1, children)

    if use_pivots:
        evaluate(_seed_candidates(index, tops, dq))
    visit(len(index.boxes) - 1, tops)
    return best_start, best_cost, evaluated


def search(
    library,
    query: Query,
    classes: list[str] | None = None,
    threshold: float | None = None,
    position_weights: dict[str, float] = TABLE2_POSITION_WEIGHTS,
    rotation_weights: dict[str, float] = TABLE2_ROTATION_WEIGHTS,
) -> Match:
    """The best (clip, frame) for the query window by Eq. 1, over all classes or the given ones.

    The match is returned with its cost even when above `threshold` (then `accepted` is False), so
    the caller can decide to widen the search; see `search_with_fallback`.
    """
    start, cost, evaluated = find_best(library, query, classes, position_weights, rotation_weights)
    scope = "all" if classes is None else "+".join(classes)
    return _match(library, query, start, cost, threshold, scope, evaluated)


def search_with_fallback(
    library,
    query: Query,
    class_order: list[str],
    threshold: float,
    position_weights: dict[str, float] = TABLE2_POSITION_WEIGHTS,
    rotation_weights: dict[str, float] = TABLE2_ROTATION_WEIGHTS,
) -> Match:
    """Try the predicted class, then the next ones in `class_order`, then the whole library.

    Returns the first match within `threshold`; if none is, the whole library's best (not
    accepted). `Match.scope` says which search produced it, for the pipeline to report. A class the
    library has no clips of is passed over (the next one is the fallback anyway); an unknown class
    slug is an error.
    """
    from .library import CLASS_SLUGS  # library imports this module

    for slug in class_order:
        if slug not in CLASS_SLUGS:
            library.require_class(slug)  # raises, naming the slug and the known classes
        if slug not in library.class_ranges:
            continue
        match = search(library, query, [slug], threshold, position_weights, rotation_weights)
        if match.accepted:
            return match
    return search(library, query, None, threshold, position_weights, rotation_weights)


def _match(library, query: Query, start: int, cost: float, threshold, scope: str, evaluated: int) -> Match:
    clip_index = int(library.clip_index[start])
    clip = library.clips[clip_index]
    frame = int(library.frame_index[start])
    # Placement: turn the clip's anchor heading onto the query's, then move its ground point there.
    yaw = float(query.features.heading[0]) - float(library.heading[start])
    g = library.ground[start].astype(float)
    c, s = np.cos(yaw), np.sin(yaw)
    turned = np.array([c * g[0] - s * g[1], s * g[0] + c * g[1]])
    offset = query.features.ground[0].astype(float) - turned
    return Match(
        clip=clip.name,
        clip_index=clip_index,
        reaction_class=clip.reaction_class,
        frame=frame,
        source_frame=clip.source_frame(frame),
        cost=cost,
        accepted=threshold is None or cost <= threshold,
        yaw=float(np.angle(np.exp(1j * yaw))),
        offset=(float(offset[0]), float(offset[1])),
        scope=scope,
        candidates_evaluated=evaluated,
    )
