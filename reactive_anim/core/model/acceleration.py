"""Joint accelerations as the project reads them on capture: second differences of positions over a
fixed stride of time, whatever the frame rate. Per frame at 120 fps, a capture's jitter reads as
acceleration several times what the same motion shows at 30 fps; over 1/30 s a limit in m/s^2 means
the same on every rig (the real references in docs/measurements.md are read this way)."""

from __future__ import annotations

import numpy as np

from .arrays import FloatArray

STRIDE = 1.0 / 30.0  # s


def stride_frames(fps: float) -> int:
    """STRIDE in frames at `fps`, at least one."""
    return max(1, round(STRIDE * fps))


def accelerations(positions: FloatArray, fps: float) -> FloatArray:
    """(T, ...) the acceleration's size (m/s^2) of points `positions` (T, ..., 3) centred on each
    frame, over stride_frames(fps); NaN within a stride of either end."""
    stride = stride_frames(fps)
    out = np.full(positions.shape[:-1], np.nan)
    if len(positions) > 2 * stride:
        second = positions[2 * stride :] - 2.0 * positions[stride:-stride] + positions[: -2 * stride]
        out[stride:-stride] = np.linalg.norm(second, axis=-1) * (fps / stride) ** 2
    return out
