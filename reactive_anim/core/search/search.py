"""The jump search (paper section 2.4, steps 3-4): the best clip and jump frame for a query window.

The paper searches the reaction class the network predicts for the library window closest to the
simulated one by Eq. 1 (window.py) and accepts it under a threshold. `search` does that for any set
of classes; `search_with_fallback` tries the given classes in order when the best cost is over the
threshold, keeps the first class's best when none is within it (the whole library only when the
library has none of them), and says which scope produced the match. The search is exact:
search_index.py rules windows out only by true bounds of Eq. 1 (search_bounds.py) and decides by
the exact cost, so the window returned is the one a scan of every window would return (ties to the
lowest class, clip, frame).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..model.arrays import BoolArray, FloatArray
from ..model.classes import CLASS_SLUGS
from ..model.errors import LibraryError
from .library import Library
from .search_index import Best, find_best
from .window import TABLE2_POSITION_WEIGHTS, TABLE2_ROTATION_WEIGHTS, Query, joint_weights, yaw_rotate


@dataclass(frozen=True)
class Match:
    """The best window: where it is, its Eq. 1 cost and how to place the clip on the query.

    jump_frame: the window's first frame in the clip, at the library's rate (the paper's E, where
      the transition jumps into Sequence-2).
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
    jump_frame: int
    source_frame: float
    cost: float
    accepted: bool
    yaw: float
    offset: tuple[float, float]
    scope: str
    candidates_evaluated: int


def search(
    library: Library,
    query: Query,
    classes: list[str] | None = None,
    threshold: float | None = None,
    *,
    position_weights: dict[str, float] = TABLE2_POSITION_WEIGHTS,
    rotation_weights: dict[str, float] = TABLE2_ROTATION_WEIGHTS,
    allowed: BoolArray | None = None,
) -> Match:
    """The best (clip, frame) for the query window by Eq. 1, over all classes or the given ones.

    The match is returned with its cost even when above `threshold` (then `accepted` is False), so
    the caller can decide to widen the search; see `search_with_fallback`. allowed: per window of
    the library's search index, whether it may be chosen (reach.reachable_windows; None: all).
    """
    if query.window != library.window:
        raise LibraryError(
            f"the query window has {query.window} frames but the library was compiled for {library.window}"
        )
    index = library.search_index()
    if classes is None:
        slugs, scope = list(index.class_tops), "all"
    else:
        slugs, scope = list(classes), "+".join(classes)
        for slug in slugs:
            library.require_class(slug)
    tops = index.tops(slugs)
    if len(tops) == 0:
        raise LibraryError(f"no clip in {scope!r} is long enough for a {library.window}-frame window")
    wp, wq = joint_weights(position_weights), joint_weights(rotation_weights)
    best = find_best(index, query, slugs, wp, wq, allowed=allowed)
    if best.start < 0:
        raise LibraryError(f"no window of {scope!r} is among the allowed ones")
    return _match(library, query, best, threshold is None or best.cost <= threshold, scope)


def search_with_fallback(
    library: Library,
    query: Query,
    class_order: list[str],
    threshold: float,
    *,
    position_weights: dict[str, float] = TABLE2_POSITION_WEIGHTS,
    rotation_weights: dict[str, float] = TABLE2_ROTATION_WEIGHTS,
    allowed: BoolArray | None = None,
) -> Match:
    """Try the predicted class, then the next ones in `class_order`: the first match within
    `threshold`; if none is, the first class's best (not accepted), since the class comes from what
    the push does and a poor window of it beats a good one of a reaction the push did not call for
    (on real mocap cast from other skeletons, where costs run higher, a whole-library fallback
    replaced the predicted class in 159 of 332 random pushes: backward falls by forward rolls,
    single steps by falls). Only when the library has none of the classes is the whole library
    searched. `Match.scope` says which search produced it, for the pipeline to report. An unknown
    class slug is an error. allowed: as for `search` (then every class given must have an allowed window).
    """

    def best_of(classes: list[str] | None) -> Match:
        return search(library, query, classes, threshold, position_weights=position_weights,
                      rotation_weights=rotation_weights, allowed=allowed)  # fmt: skip

    first = None
    for slug in class_order:
        if slug not in CLASS_SLUGS:
            library.require_class(slug)  # raises, naming the slug and the known classes
        if slug not in with_allowed(library, [slug], allowed):
            continue
        match = best_of([slug])
        if match.accepted:
            return match
        first = first or match
    return first or best_of(None)


def with_allowed(library: Library, classes: list[str], allowed: BoolArray | None) -> list[str]:
    """The classes, in order, that the library has and that have a window `allowed` allows (every
    one the library has where it is None)."""
    index = library.search_index()
    return [slug for slug in classes if slug in library.class_ranges
            and (allowed is None or bool(allowed[index.windows_of([slug])].any()))]  # fmt: skip


def _match(library: Library, query: Query, best: Best, accepted: bool, scope: str) -> Match:
    start = best.start
    clip_index = int(library.clip_index[start])
    clip = library.clips[clip_index]
    frame = int(library.frame_index[start])
    # Placement: turn the clip's anchor heading onto the query's, then move its ground point there.
    yaw = float(query.features.heading[0]) - float(library.heading[start])
    turned = yaw_rotate(yaw, np.append(library.ground[start].astype(np.float64), 0.0))
    offset: FloatArray = query.features.ground[0].astype(np.float64) - turned[:2]
    turn: complex = np.exp(1j * yaw)  # its angle: yaw wrapped to (-pi, pi]
    return Match(
        clip=clip.name,
        clip_index=clip_index,
        reaction_class=clip.reaction_class,
        jump_frame=frame,
        source_frame=clip.source_frame(frame),
        cost=best.cost,
        accepted=accepted,
        yaw=float(np.angle(turn)),
        offset=(float(offset[0]), float(offset[1])),
        scope=scope,
        candidates_evaluated=best.evaluated,
    )
