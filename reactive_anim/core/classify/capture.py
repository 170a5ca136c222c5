"""The capture point and the base of support: what balance needs at one instant.

Hof, Gazendam and Sinke 2005 ("The condition for dynamic stability", J Biomech 38:1) model the body
as an inverted pendulum of height z0: with w0 = sqrt(g / z0), the extrapolated centre of mass
XCoM = x + v / w0 (horizontal) must lie over the base of support for the body to come to rest
without stepping; Pratt et al. 2006 and Koolen et al. 2012 call the same point the instantaneous
capture point. Used by the outcome rule (outcome.py) and, as inputs, by the classifier
(features.py).

The base of support is the convex hull of the soles touching the floor: of each foot that touches
(the simulation's contacts; for a motion capture, its sole surely on the floor, model/floor.py), the
ends of its sole capsule surely on the floor (a heel strike touches with the heel
only), each a disc of the sole's radius. The support is then the convex hull of those points
grown by that radius (a Minkowski sum, handled exactly: its boundary is the hull's edges moved out
and arcs round its corners; an octagon per disc, tried first, made the features depend on the
character's heading by up to a centimetre). Any other body on the floor means the character is
down.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..model.arrays import BoolArray, FloatArray, einsum
from ..model.floor import surely_on_floor
from ..physics.probe import PoseProbe
from ..physics.ragdoll import Ragdoll

GRAVITY = 9.81  # m/s², the simulation's


def eigenfrequency(height: float) -> float:
    """w0 = sqrt(g / z0) of an inverted pendulum of height z0 (m), 1/s."""
    return math.sqrt(GRAVITY / max(height, 0.05))


def xcom(com: FloatArray, velocity: FloatArray, omega: float) -> FloatArray:
    """The extrapolated centre of mass over the floor, (2,)."""
    return np.asarray(com)[:2] + np.asarray(velocity)[:2] / omega


@dataclass(frozen=True)
class Support:
    """Floor contact at one instant: `points` (K, 2) where the soles touch, each the centre of a
    disc of `radius` (the sole's half-width); `down`: a body other than the feet touches the floor."""

    points: FloatArray
    radius: float
    down: bool = False

    def reach(self, target: FloatArray, direction: FloatArray) -> float:
        """How far a centre of pressure can move along `direction` inside the support, starting from
        the support's point nearest to `target` (`target` itself if inside); 0 without contact."""
        length = float(np.linalg.norm(direction))
        if len(self.points) == 0 or length == 0.0:
            return 0.0
        hull = convex_hull(self.points)
        start = self._nearest(hull, np.asarray(target, dtype=np.float64))
        ends = np.roll(hull, -1, axis=0) if len(hull) > 2 else hull[::-1]
        unit = np.asarray(direction, dtype=np.float64) / length
        return max(0.0, max(_capsule_exit(start, unit, a, b, self.radius) for a, b in zip(hull, ends, strict=True)))

    def _nearest(self, hull: FloatArray, target: FloatArray) -> FloatArray:
        """The support's point nearest to `target`: the hull's nearest point moved toward the target
        by the radius, or the target itself within the radius of the hull."""
        on_hull = nearest_in_polygon(hull, target)
        gap = float(np.linalg.norm(target - on_hull))
        return target if gap <= self.radius else on_hull + (target - on_hull) * (self.radius / gap)


def convex_hull(points: FloatArray) -> FloatArray:
    """Andrew's monotone chain, counter-clockwise, (V, 2)."""
    pts = sorted({(float(x), float(y)) for x, y in np.round(points, 12)})
    if len(pts) < 3:
        return np.array(pts).reshape(-1, 2)

    def half(seq: list[tuple[float, float]]) -> list[tuple[float, float]]:
        out: list[tuple[float, float]] = []
        for p in seq:
            while len(out) >= 2 and _turn(out[-2], out[-1], p) <= 0:
                out.pop()
            out.append(p)
        return out

    lower, upper = half(pts), half(pts[::-1])
    return np.array(lower[:-1] + upper[:-1])


def _turn(a: tuple[float, float], b: tuple[float, float], c: tuple[float, float]) -> float:
    return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])


def nearest_in_polygon(polygon: FloatArray, point: FloatArray) -> FloatArray:
    """The point itself if inside the convex polygon (counter-clockwise), else the nearest point of
    its boundary; a polygon of one or two vertices is a point or a segment."""
    if len(polygon) == 1:
        return polygon[0].astype(np.float64)
    edges = np.roll(polygon, -1, axis=0) - polygon
    rel = point - polygon
    if len(polygon) > 2 and np.all(edges[:, 0] * rel[:, 1] - edges[:, 1] * rel[:, 0] >= 0.0):
        return np.asarray(point, dtype=np.float64)
    along = einsum("ij,ij->i", rel, edges) / np.maximum(einsum("ij,ij->i", edges, edges), 1e-18)
    candidates = polygon + np.clip(along, 0.0, 1.0)[:, None] * edges
    return candidates[np.argmin(np.linalg.norm(candidates - point, axis=1))]


def _capsule_exit(start: FloatArray, unit: FloatArray, a: FloatArray, b: FloatArray, radius: float) -> float:
    """The largest t with start + t unit within `radius` of the segment a-b (-inf if none): the
    strip beside the segment, then the discs at its ends."""
    best = max(_disc_exit(start, unit, a, radius), _disc_exit(start, unit, b, radius))
    edge = b - a
    length = float(np.linalg.norm(edge))
    if length < 1e-12:
        return best
    along, across = edge / length, np.array([-edge[1], edge[0]]) / length
    low, high = -np.inf, np.inf
    for axis, lo, hi in ((along, 0.0, length), (across, -radius, radius)):
        offset, rate = float((start - a) @ axis), float(unit @ axis)
        if abs(rate) < 1e-12:
            if not lo <= offset <= hi:
                return best
            continue
        first, second = sorted(((lo - offset) / rate, (hi - offset) / rate))
        low, high = max(low, first), min(high, second)
    return max(best, high) if low <= high else best


def _disc_exit(start: FloatArray, unit: FloatArray, centre: FloatArray, radius: float) -> float:
    """The largest t with start + t unit within `radius` of `centre` (-inf if the line misses)."""
    rel = start - centre
    half = float(rel @ unit)
    discriminant = half * half - float(rel @ rel) + radius * radius
    return -half + math.sqrt(discriminant) if discriminant >= 0.0 else -math.inf


def foot_bodies(ragdoll: Ragdoll) -> list[int]:
    """The ragdoll bodies (indices into ragdoll.bodies) that are feet: what may touch the floor
    without the body being down."""
    return [k for k, body in enumerate(ragdoll.bodies) if body.name.startswith("ankle")]


class SoleGeometry:
    """Where a ragdoll's soles are, from its geometry at given joint positions (qpos). Holds its own
    pose probe: one per thread."""

    def __init__(self, ragdoll: Ragdoll):
        self.probe = PoseProbe(ragdoll)
        self.geom_body = self.probe.geom_body
        self.is_foot = np.isin(self.geom_body, foot_bodies(ragdoll))
        self.radius = float(np.mean(self.probe.radii[self.is_foot]))

    def lowest_sole(self, qpos: FloatArray) -> float:
        """Height of the lowest point of the soles at these joint positions (m)."""
        _, lowest = self.probe.capsule_ends(qpos)
        return float(lowest[np.repeat(self.is_foot, 2)].min())

    def support(self, qpos: FloatArray, floor: float, touching: BoolArray | None = None) -> Support:
        """The support at these joint positions. touching: (B,) which ragdoll bodies touch the floor
        (SimResult.contacts of the sample), or None to judge it from the geometry."""
        ends, lowest = self.probe.capsule_ends(qpos)
        near = surely_on_floor(lowest, floor).reshape(-1, 2)
        body_touches = near.any(axis=1) if touching is None else np.asarray(touching, dtype=bool)[self.geom_body]
        sole_ends = near | (body_touches[:, None] & ~near.any(axis=1, keepdims=True) & _lower_end(lowest))
        on_floor = (sole_ends & (body_touches & self.is_foot)[:, None]).reshape(-1)
        down = bool(np.any(body_touches & ~self.is_foot))
        return Support(ends[on_floor, :2], self.radius, down)


def _lower_end(lowest: FloatArray) -> BoolArray:
    """(G, 2) True at each capsule's lower end (a body that touches with neither end within the gap
    touches with its lower one)."""
    pairs = lowest.reshape(-1, 2)
    return np.stack([pairs[:, 0] <= pairs[:, 1], pairs[:, 0] > pairs[:, 1]], axis=1)
