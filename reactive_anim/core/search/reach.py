"""Which library windows a body already on the floor can be faded into.

Eq. 1 compares whole windows, so the nearest window of a class can end in a pose the body at C
cannot reach in a fade of a third of a second. On a body already down the fade then does what no
body would: a sitting body pushed again was matched to a fall's standing first window (Eq. 1 cost
85, over the threshold, but the nearest fall of the push's way); through the fade the hips rose
from 8 to 51 cm and the body fell again. With a few millimetres of hand moved, the same push was
matched to a sitting window (cost 73) while the body lay back: the fade turned the hips 129 degrees
(16 a frame) and swept a toe 69 cm through the floor (docs/measurements.md, session 9).

A window is out of reach when, in its last frame (E, where the fade into the clip starts) or the
frames the fade then passes through, the clip has the hips more than HIPS_RISE higher over the
lowest searched joint than the body at C (a lying body stood up), or the body turned more than
TURN_MOST away from the body's at C with respect to the vertical (lying back against sitting up,
face down against face up). The fade's frames count, not E's alone: the fade takes the body to
the clip's pose at F whether the clip gets there by its own motion or not. A kneeling body bent
forward, pushed again from the front, was 57 degrees from a backward sit's E but 72 from its
frames 9 later, where the clip sits up; faded in, the hips rose from 0.26 to 0.72 m and the body
fell again. A roll's window early in the roll turns a body not rolling over within the fade. The
turn is read from the body's own axes (hips to neck, hip to hip), so it does not depend on how
the heading is read from a body lying down. Heights are over the lowest joint, not z = 0: neither a clip's floor nor a
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


def reachable_windows(library: Library, query: Query, fade: int = 0) -> BoolArray:
    """Per window of the library's search index (SearchIndex.starts order), whether a body posed as
    the query's last frame can be faded into the clip from the window's last frame on: over that
    frame and the `fade` frames after it (the library's rate, within the clip), which the fade
    passes through on its way into the clip."""
    index = library.search_index()
    ends = index.starts + library.window - 1
    last = np.searchsorted(library.clip_index, library.clip_index[ends], side="right") - 1
    frames = np.minimum(ends[:, None] + np.arange(fade + 1), last[:, None])  # (windows, fade + 1)
    poses = library.frames.pos_local[frames].astype(np.float64)
    body = np.asarray(query.features.pos_local[-1], dtype=np.float64)
    rise = (hips_up(poses) - hips_up(body)).max(axis=1)
    turn = np.degrees(np.arccos(np.clip(up_in_body(poses) @ up_in_body(body), -1.0, 1.0))).max(axis=1)
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
