"""Which library windows a body already on the floor can be faded into.

Eq. 1 compares whole windows, so the nearest window of a class can end in a pose the body at C
cannot reach in a fade of a third of a second. On a body already down the fade then does what no
body would: a sitting body pushed again was matched to a fall's standing first window (Eq. 1 cost
85, over the threshold, but the nearest fall of the push's way); through the fade the hips rose
from 8 to 51 cm and the body fell again. With a few millimetres of hand moved, the same push was
matched to a sitting window (cost 73) while the body lay back: the fade turned the hips 129 degrees
(16 a frame) and swept a toe 69 cm through the floor (docs/measurements.md, session 9).

A window is out of reach when its last frame (E, where the fade lands) has the hips more than
HIPS_RISE higher over the lowest searched joint than the body at C (a lying body stood up), or
the body turned more than TURN_MOST away from the body's at C with respect to the vertical
(lying back against sitting up, face down against face up). The turn is read from the body's own
axes (hips to neck, hip to hip), so it does not depend on how the heading is read from a body
lying down. Heights are over the lowest joint, not z = 0: neither a clip's floor nor a
character's need be there.
"""

from __future__ import annotations

import numpy as np

from ..model.arrays import AnyFloatArray, BoolArray, FloatArray
from .library import Library
from .window import SEARCH_ROLES, Query

HIPS_RISE = 0.3  # m on the library's skeleton: a window whose hips end this much higher stands a lying body up
# deg: lying back and sitting up are 80 apart (the case above), face down and face up 180; an upright
# body pushed over turns by less within a fade
TURN_MOST = 60.0

_HIPS = [SEARCH_ROLES.index("hip_l"), SEARCH_ROLES.index("hip_r")]
_NECK = SEARCH_ROLES.index("neck")


def reachable_windows(library: Library, query: Query) -> BoolArray:
    """Per window of the library's search index (SearchIndex.starts order), whether a body posed as
    the query's last frame can be faded into the window's last frame."""
    index = library.search_index()
    ends = library.frames.pos_local[index.starts + library.window - 1].astype(np.float64)
    body = np.asarray(query.features.pos_local[-1], dtype=np.float64)
    rise = hips_up(ends) - hips_up(body)
    turn = np.degrees(np.arccos(np.clip(up_in_body(ends) @ up_in_body(body), -1.0, 1.0)))
    return (rise <= HIPS_RISE) & (turn <= TURN_MOST)


def hips_up(pos_local: AnyFloatArray) -> FloatArray:
    """The hips' height over the lowest searched joint, per frame (..., 15, 3) -> (...)."""
    return pos_local[..., _HIPS, 2].mean(axis=-1) - pos_local[..., 2].min(axis=-1)


def up_in_body(pos_local: AnyFloatArray) -> FloatArray:
    """The world's up in the body's own axes (hips to neck, right hip to left, and the normal of the
    two), unit vectors (..., 3): the same for one pose whatever its heading."""
    hips = pos_local[..., _HIPS, :].mean(axis=-2)
    trunk = _unit(pos_local[..., _NECK, :] - hips)
    side = pos_local[..., _HIPS[0], :] - pos_local[..., _HIPS[1], :]
    side = _unit(side - np.sum(side * trunk, axis=-1, keepdims=True) * trunk)
    front = np.cross(side, trunk)
    return np.stack([trunk[..., 2], side[..., 2], front[..., 2]], axis=-1)


def _unit(v: FloatArray) -> FloatArray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-9)
