"""The paper's 10 reaction classes (section 2.3), as stable slugs.

The order is the paper's (one step forward ... fall sideways to the knees); the library groups its
clips in this order and the classifier's outputs follow it.
"""

from __future__ import annotations

CLASS_SLUGS: tuple[str, ...] = (
    "step_forward", "steps_forward", "step_back", "steps_back", "sway_balance",
    "fall_forward_roll", "fall_forward_hands", "fall_backward_sit", "fall_backward_hands", "fall_side_knees",
)  # fmt: skip
