"""A foot on the floor (core/model/floor.py): the hard rules and the soft ramp agree."""

from __future__ import annotations

import numpy as np

from reactive_anim.core.model.floor import FOOT_ON_FLOOR, FOOT_SURELY_ON, on_floor, surely_on_floor


def test_the_ramp_is_full_where_a_foot_surely_stands_half_at_the_definition_and_empty_as_far_above() -> None:
    floor = 0.37  # a mocap floor off z = 0
    heights = floor + np.array([-0.01, 0.0, FOOT_SURELY_ON / 2, FOOT_ON_FLOOR, 0.025, 0.035, 0.2])
    weight = on_floor(heights, floor)
    assert np.allclose(weight, [1.0, 1.0, 1.0, 0.5, 0.25, 0.0, 0.0])
    assert np.all(np.diff(weight) <= 0.0)  # higher never stands more
    assert surely_on_floor(heights, floor).tolist() == [True, True, True, False, False, False, False]
