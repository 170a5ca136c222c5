"""Vectorised quaternion math, (w, x, y, z) order as in Blender's mathutils and MuJoCo.

Every function takes arrays of any leading shape: `(..., 4)` quaternions, `(..., 3)` vectors.
Euler angles follow the BVH convention: the channel order "ZXY" means R = Rz @ Rx @ Ry, i.e.
intrinsic rotations applied left to right, and vectors are column vectors.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike

from .arrays import FloatArray

AXES = "XYZ"
_EPS = 1e-12


def identity(shape: tuple[int, ...] = ()) -> FloatArray:
    """Identity rotations of the given leading shape: `shape + (4,)`."""
    q = np.zeros(tuple(shape) + (4,))
    q[..., 0] = 1.0
    return q


def normalize(q: ArrayLike) -> FloatArray:
    """Unit quaternions; a zero quaternion stays zero rather than becoming NaN."""
    q = np.asarray(q, dtype=np.float64)
    n = np.linalg.norm(q, axis=-1, keepdims=True)
    return q / np.maximum(n, _EPS)


def mul(a: ArrayLike, b: ArrayLike) -> FloatArray:
    """Hamilton product a*b (apply b first, then a), broadcast over leading axes.

    Each component is written into one output array: np.stack would copy all four again."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    aw, ax, ay, az = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    bw, bx, by, bz = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
    out = np.empty(_shape(a, b))
    out[..., 0] = aw * bw - ax * bx - ay * by - az * bz
    out[..., 1] = aw * bx + ax * bw + ay * bz - az * by
    out[..., 2] = aw * by - ax * bz + ay * bw + az * bx
    out[..., 3] = aw * bz + ax * by - ay * bx + az * bw
    return out


def _shape(a: FloatArray, b: FloatArray) -> tuple[int, ...]:
    """The broadcast shape of two arrays; np.broadcast_shapes costs more than a small product."""
    return a.shape if a.shape == b.shape else np.broadcast_shapes(a.shape, b.shape)


def conj(q: ArrayLike) -> FloatArray:
    """Conjugate, the inverse of a unit quaternion."""
    q = np.asarray(q, dtype=np.float64)
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def rotate(q: ArrayLike, v: ArrayLike) -> FloatArray:
    """Rotate vectors `(..., 3)` by unit quaternions `(..., 4)`."""
    q = np.asarray(q, dtype=np.float64)
    v = np.asarray(v, dtype=np.float64)
    w = q[..., :1]
    u = q[..., 1:]
    t = 2.0 * _cross(u, v)
    return v + w * t + _cross(u, t)


def _cross(a: FloatArray, b: FloatArray) -> FloatArray:
    """np.cross of 3-vectors, the same products in the same order (so bit for bit the same), without
    its axis juggling, which costs more than the arithmetic on the small arrays of FK."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    out = np.empty(_shape(a, b))
    out[..., 0] = a1 * b2 - a2 * b1
    out[..., 1] = a2 * b0 - a0 * b2
    out[..., 2] = a0 * b1 - a1 * b0
    return out


def from_axis_angle(axis: ArrayLike, angle: ArrayLike) -> FloatArray:
    """Rotation by `angle` radians `(...)` about unit `axis` `(..., 3)`."""
    axis = np.asarray(axis, dtype=np.float64)
    half = 0.5 * np.asarray(angle, dtype=np.float64)[..., None]
    out = np.empty(np.broadcast_shapes(half.shape[:-1] + (4,), axis.shape[:-1] + (4,)))
    out[..., :1] = np.cos(half)
    out[..., 1:] = np.sin(half) * axis
    return out


def _axis_index(order: str) -> list[int]:
    idx = [AXES.index(c) for c in order.upper()]
    if sorted(idx) != [0, 1, 2]:
        raise ValueError(f"rotation order must be a permutation of XYZ, got {order!r}")
    return idx


def from_euler(angles: ArrayLike, order: str) -> FloatArray:
    """Quaternions from Euler angles in radians `(..., len(order))`, composed left to right.

    `order` may name one to three distinct axes (a BVH joint may animate fewer than three). The
    first axis' turn is the start (the identity turned by it); each further step is
    mul(q, from_axis_angle(axis, angle)) written as `turn_after`, at a third of the cost.
    """
    angles = np.asarray(angles, dtype=np.float64)
    axes = [AXES.index(a) for a in order.upper()]
    if not axes:
        return identity(angles.shape[:-1])
    half = 0.5 * angles
    q = np.zeros(angles.shape[:-1] + (4,))
    q[..., 0], q[..., 1 + axes[0]] = np.cos(half[..., 0]), np.sin(half[..., 0])
    for k in range(1, len(axes)):
        q = turn_after(q, axes[k], np.cos(half[..., k]), np.sin(half[..., k]))
    return q


def turn_after(q: FloatArray, axis: int, c: FloatArray | float, s: FloatArray | float) -> FloatArray:
    """mul(q, (c, s * e_axis)): q followed by a turn about a coordinate axis (c, s: the cosine and
    sine of half its angle). The products by the turn's zero components are left out: they add
    exact zeros, so the value is mul's, bit for bit (but for the sign of a zero)."""
    w, v = q[..., 0], [q[..., 1], q[..., 2], q[..., 3]]
    i, j = (axis + 1) % 3, (axis + 2) % 3  # e_axis x e_i = e_j
    out = np.empty(q.shape)
    out[..., 0] = w * c - v[axis] * s
    out[..., 1 + axis] = w * s + v[axis] * c
    out[..., 1 + i] = v[i] * c + v[j] * s
    out[..., 1 + j] = v[j] * c - v[i] * s
    return out


def turn_before(q: FloatArray, axis: int, c: FloatArray | float, s: FloatArray | float) -> FloatArray:
    """mul((c, s * e_axis), q): a turn about a coordinate axis after q, as `turn_after` does it."""
    w, v = q[..., 0], [q[..., 1], q[..., 2], q[..., 3]]
    i, j = (axis + 1) % 3, (axis + 2) % 3
    out = np.empty(q.shape)
    out[..., 0] = c * w - s * v[axis]
    out[..., 1 + axis] = c * v[axis] + s * w
    out[..., 1 + i] = c * v[i] - s * v[j]
    out[..., 1 + j] = c * v[j] + s * v[i]
    return out


def to_euler(q: ArrayLike, order: str) -> FloatArray:
    """Euler angles in radians `(..., 3)` for a permutation of XYZ, inverse of `from_euler`.

    The last angle is taken from what the first two leave over, so the three angles always
    rebuild the rotation exactly, gimbal lock included (where the first absorbs the shared freedom).
    """
    i, j, k = _axis_index(order)
    q = np.asarray(q, dtype=np.float64)
    m = _matrix_entries(normalize(q), [(i, k), (i, i), (i, j), (j, k), (k, k)])
    s = 1.0 if (j - i) % 3 == 1 else -1.0  # even (cyclic) or odd permutation
    middle = np.arctan2(s * m[i, k], np.hypot(m[i, i], m[i, j]))
    locked = np.hypot(m[j, k], m[k, k]) < 1e-12
    first = np.where(locked, 0.0, np.arctan2(-s * m[j, k], m[k, k]))
    axes = np.eye(3)
    done = mul(from_axis_angle(axes[i], first), from_axis_angle(axes[j], middle))
    row, column = (k + 2) % 3, (k + 1) % 3
    rest = _matrix_entries(normalize(mul(conj(done), q)), [(row, column), (column, column)])
    last = np.arctan2(rest[row, column], rest[column, column])
    out = np.empty(first.shape + (3,))
    out[..., 0], out[..., 1], out[..., 2] = first, middle, last
    return out


def to_matrix(q: ArrayLike) -> FloatArray:
    """Rotation matrices `(..., 3, 3)` of unit quaternions."""
    q = normalize(q)
    m = np.empty(q.shape[:-1] + (3, 3))
    for (r, c), entry in _matrix_entries(q, list(_MATRIX_ENTRIES)).items():
        m[..., r, c] = entry
    return m


# Each entry of a unit quaternion's rotation matrix, from (w, x, y, z).
_MATRIX_ENTRIES: dict[tuple[int, int], Callable[[FloatArray, FloatArray, FloatArray, FloatArray], FloatArray]] = {
    (0, 0): lambda w, x, y, z: 1 - 2 * (y * y + z * z),
    (0, 1): lambda w, x, y, z: 2 * (x * y - w * z),
    (0, 2): lambda w, x, y, z: 2 * (x * z + w * y),
    (1, 0): lambda w, x, y, z: 2 * (x * y + w * z),
    (1, 1): lambda w, x, y, z: 1 - 2 * (x * x + z * z),
    (1, 2): lambda w, x, y, z: 2 * (y * z - w * x),
    (2, 0): lambda w, x, y, z: 2 * (x * z - w * y),
    (2, 1): lambda w, x, y, z: 2 * (y * z + w * x),
    (2, 2): lambda w, x, y, z: 1 - 2 * (x * x + y * y),
}


def _matrix_entries(q: FloatArray, entries: list[tuple[int, int]]) -> dict[tuple[int, int], FloatArray]:
    """Only the wanted entries of the rotation matrices of unit quaternions `q` (already
    normalised): Euler angles need five of the nine, and on the small arrays of a simulation's
    pose tables numpy's per-call cost is most of the work."""
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return {entry: _MATRIX_ENTRIES[entry](w, x, y, z) for entry in dict.fromkeys(entries)}


def sandwich(r: ArrayLike, q: ArrayLike) -> FloatArray:
    """r q r^-1 for unit `r`: the rotation `q` carried into the frame that `r` turns to (same angle,
    its axis turned by r). A matrix on the vector part: 15 products and sums a quaternion where
    mul(mul(r, q), conj(r)) takes 56, for the long per-bone conversions of action I/O. Equal to
    that to rounding, not bit for bit."""
    r, q = np.asarray(r, dtype=np.float64), np.asarray(q, dtype=np.float64)
    m = to_matrix(r)
    x, y, z = q[..., 1], q[..., 2], q[..., 3]
    out = np.empty(_shape(r, q))
    out[..., 0] = q[..., 0]
    for a in range(3):
        out[..., 1 + a] = m[..., a, 0] * x + m[..., a, 1] * y + m[..., a, 2] * z
    return out


def from_matrix(m: ArrayLike) -> FloatArray:
    """Unit quaternions (w >= 0) of rotation matrices `(..., 3, 3)`, stable for every angle."""
    m = np.asarray(m, dtype=np.float64)
    m00, m01, m02 = m[..., 0, 0], m[..., 0, 1], m[..., 0, 2]
    m10, m11, m12 = m[..., 1, 0], m[..., 1, 1], m[..., 1, 2]
    m20, m21, m22 = m[..., 2, 0], m[..., 2, 1], m[..., 2, 2]
    trace = m00 + m11 + m22
    # Four candidate formulas; use the one with the largest pivot for numerical stability.
    d21, d02, d10 = m21 - m12, m02 - m20, m10 - m01
    s01, s02, s12 = m01 + m10, m02 + m20, m12 + m21
    cands = np.empty(m.shape[:-2] + (4, 4))
    cands[..., 0, :] = _columns(1 + trace, d21, d02, d10)
    cands[..., 1, :] = _columns(d21, 1 + m00 - m11 - m22, s01, s02)
    cands[..., 2, :] = _columns(d02, s01, 1 - m00 + m11 - m22, s12)
    cands[..., 3, :] = _columns(d10, s02, s12, 1 - m00 - m11 + m22)
    pivots = _columns(trace, m00, m11, m22)
    best = np.argmax(pivots, axis=-1)
    q = np.take_along_axis(cands, best[..., None, None], axis=-2)[..., 0, :]
    q = normalize(q)
    return np.where(q[..., :1] < 0, -q, q)


def _columns(*parts: FloatArray) -> FloatArray:
    """np.stack(parts, -1) for same-shaped arrays, into one array without stack's copies."""
    out = np.empty(parts[0].shape + (len(parts),))
    for k, part in enumerate(parts):
        out[..., k] = part
    return out


def angle_between(a: ArrayLike, b: ArrayLike) -> FloatArray:
    """Rotation angle in radians of a^-1 b, in [0, pi]; q and -q count as the same rotation."""
    d = mul(conj(a), b)
    return 2.0 * np.arctan2(np.linalg.norm(d[..., 1:], axis=-1), np.abs(d[..., 0]))


def slerp(a: ArrayLike, b: ArrayLike, t: ArrayLike, *, shortest: bool = True) -> FloatArray:
    """Spherical interpolation; `t` broadcasts against `(...)`. Along the shorter arc, or with
    shortest=False along the arc toward `b` as signed (the longer way round where <a, b> < 0), for
    a caller that keeps the arc continuous over time (blend.blend); a whole turn (b = -a) has no
    axis to take and goes the short way, staying at `a`."""
    a = normalize(a)
    b = normalize(b)
    t = np.asarray(t, dtype=np.float64)[..., None]
    dot = np.sum(a * b, axis=-1, keepdims=True)
    flip = dot < 0 if shortest else dot < -1.0 + 1e-12
    b = np.where(flip, -b, b)
    dot = np.where(flip, -dot, dot)
    theta = np.arccos(np.clip(dot, -1.0, 1.0))
    sin_theta = np.sin(theta)
    near = sin_theta < 1e-6
    safe = np.where(near, 1.0, sin_theta)
    wa = np.where(near, 1.0 - t, np.sin((1.0 - t) * theta) / safe)
    wb = np.where(near, t, np.sin(t * theta) / safe)
    return normalize(wa * a + wb * b)


def make_continuous(q: ArrayLike) -> FloatArray:
    """Flip signs along axis 0 (time) so consecutive quaternions lie in the same hemisphere.

    Keyframe curves interpolate components linearly; without this a q / -q jump would make a bone
    spin the long way round between two frames.
    """
    q = np.array(q, dtype=np.float64, copy=True)
    if len(q) < 2:
        return q
    dots = np.sum(q[1:] * q[:-1], axis=-1)
    flips = np.cumsum(dots < 0, axis=0) % 2 == 1
    q[1:][flips] *= -1.0
    return q
