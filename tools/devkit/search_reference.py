"""The straightforward reference for Eq. 1 (paper section 2.4): one candidate at a time, as written.

For every library window (clip, f_m) that fits in its clip, in (class, clip, frame) order: rebuild the
candidate's world joint positions, align them to the query (turn about Z by the difference of the
first frames' headings, then move the first frame's pelvis ground point onto the query's), and sum
w_p |p_query - p_candidate| + w_theta * angle(q_query^-1 q_candidate) over window frames and joints.
Keep a candidate only when strictly cheaper, so ties go to the first (lowest class, clip, frame).
Used by the tests and the search benchmark (tools/benchmarks) to check and time the fast search.
"""

from __future__ import annotations

import numpy as np

from reactive_anim.core.model import quat
from reactive_anim.core.search.search_index import window_limits
from reactive_anim.core.search.window import TABLE2_POSITION_WEIGHTS, TABLE2_ROTATION_WEIGHTS, Query, joint_weights


def _turn(points: np.ndarray, yaw: float) -> np.ndarray:
    c, s = np.cos(yaw), np.sin(yaw)
    rz = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return points @ rz.T


def reference_cost(
    library,
    start: int,
    query: Query,
    position_weights=TABLE2_POSITION_WEIGHTS,
    rotation_weights=TABLE2_ROTATION_WEIGHTS,
) -> float:
    """Eq. 1 between the query and the library window starting at flat frame `start`."""
    wp, wq = joint_weights(position_weights), joint_weights(rotation_weights)
    window = query.window
    cand = library.features(start, start + window)
    q = query.features
    q_world = q.world_positions()
    c_world = cand.world_positions()
    # Align: candidate's first-frame pelvis ground point to the origin, turn, then onto the query's.
    yaw = q.heading[0] - cand.heading[0]
    c_anchor = np.array([cand.ground[0, 0], cand.ground[0, 1], 0.0])
    q_anchor = np.array([q.ground[0, 0], q.ground[0, 1], 0.0])
    c_aligned = _turn(c_world - c_anchor, yaw) + q_anchor
    total = 0.0
    for i in range(window):
        position_term = np.linalg.norm(q_world[i] - c_aligned[i], axis=-1)  # (15,)
        angle_term = quat.angle_between(q.rot[i], cand.rot[i])  # (15,)
        total += float(position_term @ wp + angle_term @ wq)
    return total


def reference_search(library, query: Query, classes: list[str] | None = None) -> tuple[int, float]:
    """Best flat start frame and its cost, scanning every candidate window one at a time."""
    slugs = list(library.class_ranges) if classes is None else classes
    best_start, best_cost = -1, np.inf
    limits = window_limits(library)  # which windows are candidates is the index's definition
    for slug in slugs:
        a, b = library.class_ranges[slug]
        for start in range(a, b):
            clip = library.clip_index[start]
            if library.frame_index[start] + query.window > limits[clip]:
                continue
            cost = reference_cost(library, start, query)
            if cost < best_cost:
                best_start, best_cost = start, cost
    return best_start, best_cost
