"""The one easing curve the stages share: wherever something fades or ramps in (the CF fade's
weights, CD's servo gains rising from BC's), its rate and its acceleration start and end at zero,
so the fade adds no velocity step and no jolt where it begins or ends."""

from __future__ import annotations

from typing import TypeVar

from .arrays import FloatArray

Ease = TypeVar("Ease", float, FloatArray)


def smootherstep(s: Ease) -> Ease:
    """The quintic 6s^5 - 15s^4 + 10s^3 for s in [0, 1]: 0 to 1, first and second derivatives zero
    at both ends."""
    return s * s * s * (s * (6.0 * s - 15.0) + 10.0)
