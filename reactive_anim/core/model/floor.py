"""A foot on the floor: the one definition every stage uses (the classifier's support, the feet held
across seams, the believability measures).

A foot point stands on the floor when it is within FOOT_ON_FLOOR of it: toe clearance in a walk's
swing is about 1.5 cm, so a swinging foot stays above. Within FOOT_SURELY_ON it surely does (MuJoCo's
soft contacts let a standing capsule sink a few millimetres): what the capture point's base of
support counts. A soft judgement ramps from surely on to as far above FOOT_ON_FLOOR, so a millimetre
more or less changes a result by little."""

from __future__ import annotations

import numpy as np

from .arrays import BoolArray, FloatArray

FOOT_ON_FLOOR = 0.02  # m over the floor
FOOT_SURELY_ON = 0.01  # m over the floor
# The ramp's top and width, written so that they are exact in floating point (0.03 and 0.02).
_RAMP_TOP = FOOT_ON_FLOOR + (FOOT_ON_FLOOR - FOOT_SURELY_ON)
_RAMP_WIDTH = 2.0 * (FOOT_ON_FLOOR - FOOT_SURELY_ON)


def surely_on_floor(height: FloatArray, floor: float) -> BoolArray:
    """Which points (heights in metres, world) surely stand on the floor."""
    return height - floor <= FOOT_SURELY_ON


def on_floor(height: FloatArray, floor: float) -> FloatArray:
    """How much points at these heights stand on the floor, 0..1: 1 up to FOOT_SURELY_ON over it,
    0.5 at FOOT_ON_FLOOR, 0 from as far above."""
    return np.clip((floor + _RAMP_TOP - height) / _RAMP_WIDTH, 0.0, 1.0)
