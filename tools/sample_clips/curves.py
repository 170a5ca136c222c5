"""Interpolators the clips are drawn with: periodic waves, cubic Hermite pieces, minimum-jerk
easing between key poses, and the lift of a hand or foot carried from one place to another.

All take numpy arrays of any shape (or plain floats) and are written out exactly once, so every
clip eases and lifts the same way.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import overload

import numpy as np


def wave(phase: np.ndarray, peak_at: float) -> np.ndarray:
    """cos(2 pi (phase - peak_at)): one oscillation per cycle, +1 at `peak_at` (a cycle fraction)."""
    return np.cos(2.0 * np.pi * (phase - peak_at))


def hermite(p0: np.ndarray, m0: np.ndarray, p1: np.ndarray, m1: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Cubic Hermite from p0 (slope m0) to p1 (slope m1) for s in [0, 1]; slopes are per unit s.

    Used for the swing so that position and velocity join the stance phases without a jolt.
    """
    s = s.reshape(s.shape + (1,) * (np.ndim(p0) - 1))
    s2, s3 = s * s, s * s * s
    return (2 * s3 - 3 * s2 + 1) * p0 + (s3 - 2 * s2 + s) * m0 + (-2 * s3 + 3 * s2) * p1 + (s3 - s2) * m1


def hermite_via(
    start: np.ndarray,
    start_slope: np.ndarray,
    middle: float,
    end: np.ndarray,
    end_slope: np.ndarray,
    s: np.ndarray,
    at: float,
) -> np.ndarray:
    """Two cubic Hermite pieces, start -> middle (reached at s = `at` with zero slope) -> end.

    Pins a curve's extreme in the middle of an interval while keeping its ends' values and slopes
    (per unit s), e.g. a swing foot that levels out at mid-swing.
    """
    flat = np.zeros_like(start)
    first = hermite(start, start_slope * at, flat + middle, flat, s / at)
    second = hermite(flat + middle, flat, end, end_slope * (1.0 - at), (s - at) / (1.0 - at))
    return np.where(s < at, first, second)


def minimum_jerk(s: np.ndarray) -> np.ndarray:
    """Minimum-jerk progress 0 -> 1 (zero speed and acceleration at both ends) for s in [0, 1]."""
    s = np.clip(s, 0.0, 1.0)
    return s * s * s * (10.0 - 15.0 * s + 6.0 * s * s)


@overload
def lift_bump(s: float) -> float: ...
@overload
def lift_bump(s: np.ndarray) -> np.ndarray: ...
def lift_bump(s: float | np.ndarray) -> float | np.ndarray:
    """16 s^2 (1 - s)^2: 0 at both ends of a move (s in [0, 1]), 1 half way, leaving and landing
    with zero speed: how high a carried hand or a stepping foot is lifted along the way."""
    return 16.0 * s * s * (1.0 - s) * (1.0 - s)


@dataclass(frozen=True)
class KeyTimeline:
    """Where each frame time falls between key times.

    segment (T,): the key at or before the time (the last interval holds past the last key);
    progress (T,): how far through that interval, 0..1; eased (T,): that progress by minimum jerk.
    """

    segment: np.ndarray
    progress: np.ndarray
    eased: np.ndarray

    def between(self, values: np.ndarray) -> np.ndarray:
        """Per-key values (K, ...) eased from key to key: (T, ...)."""
        weight = self.eased.reshape(-1, *([1] * (values.ndim - 1)))
        return values[self.segment] + (values[self.segment + 1] - values[self.segment]) * weight


def key_timeline(key_times: np.ndarray, times: np.ndarray) -> KeyTimeline:
    """The timeline of frame `times` (T,) over increasing `key_times` (K,), K >= 2, in seconds."""
    segment = np.clip(np.searchsorted(key_times, times, side="right") - 1, 0, len(key_times) - 2)
    through = (times - key_times[segment]) / (key_times[segment + 1] - key_times[segment])
    return KeyTimeline(segment, np.clip(through, 0.0, 1.0), minimum_jerk(through))
