"""Which library windows a body down or going down can be faded into.

Eq. 1 compares whole windows, so the nearest window of a class can end in a pose the body at C
cannot reach within a fade (half a second, up to ReactionSettings.fall_transition for a fall). On a
body already down the fade then does what no body would: a sitting body pushed again was faded
into a fall's standing first window, rose, and fell again; a body lying back was faded into a
sitting window, and its legs swept through the floor as the fade turned it upright
(docs/measurements.md).

A window is out of reach when, in its last frame (E, where the fade into the clip starts) or the
frames the fade then passes through, the clip has
- the hips more than HIPS_RISE higher over the lowest searched joint than the body at C (a lying
  body stood up), or
- the body turned more than TURN_MOST from the body's with respect to the vertical (lying back
  against sitting up, face down against face up, a roll's head over heels against a body not
  rolling; a body on its side is as far from lying on its back as from its front).
The fade's frames count, not E's alone: the fade takes the body to the clip's pose at F whether
the clip gets there by its own motion or not. Everything is read from the body's own axes (hips
to neck, hip to hip), so it does not depend on how a heading is read from a body lying down, and
heights are over the lowest joint: neither a clip's floor nor a character's need be at z = 0.
"""

from __future__ import annotations

import numpy as np

from ..model.arrays import AnyFloatArray, BoolArray, FloatArray
from .library import Library
from .window import SEARCH_ROLES, Query

HIPS_RISE = 0.3  # m on the library's skeleton: a window whose hips end this much higher stands a lying body up
TURN_MOST = 60.0  # deg: lying back and sitting up are about 80 apart, face down and face up 180

_HIPS = [SEARCH_ROLES.index("hip_l"), SEARCH_ROLES.index("hip_r")]
_NECK = SEARCH_ROLES.index("neck")


def reachable_windows(library: Library, query: Query, classes: list[str], fade: int) -> BoolArray:
    """Per window of the library's search index (SearchIndex.starts order), whether it is one of the
    classes' and a body posed as the query's last frame can be faded into the clip from the window's
    last frame on: over that frame and the `fade` frames after it (the library's rate, within the
    clip), which the fade passes through on its way into the clip."""
    index = library.search_index()
    allowed = np.zeros(len(index.starts), dtype=bool)
    windows = index.windows_of(classes)
    if not len(windows):
        return allowed
    ends = index.starts[windows] + library.window - 1
    last = np.searchsorted(library.clip_index, library.clip_index[ends], side="right") - 1
    frames = np.minimum(ends[:, None] + np.arange(fade + 1), last[:, None])  # (windows, fade + 1)
    used, where = np.unique(frames, return_inverse=True)  # each library frame's pose read once
    poses = library.frames.pos_local[used].astype(np.float64)
    body = np.asarray(query.features.pos_local[-1], dtype=np.float64)
    rise = hips_up(poses)[where].reshape(frames.shape) - hips_up(body)
    turned = ~within_turn(up_in_body(poses), up_in_body(body))[where].reshape(frames.shape)
    allowed[windows] = ~((rise > HIPS_RISE) | turned).any(axis=1)
    return allowed


def hips_up(pos_local: AnyFloatArray) -> FloatArray:
    """The hips' height over the lowest searched joint, per frame (..., 15, 3) -> (...)."""
    return pos_local[..., _HIPS, 2].mean(axis=-1) - pos_local[..., 2].min(axis=-1)


def up_in_body(pos_local: AnyFloatArray) -> FloatArray:
    """The world's up in the body's own axes (hips to neck, right hip to left, and the belly's way,
    the normal of the two), unit vectors (..., 3): the same for one pose whatever its heading."""
    hips = pos_local[..., _HIPS, :].mean(axis=-2)
    trunk = _unit(pos_local[..., _NECK, :] - hips)
    side = pos_local[..., _HIPS[0], :] - pos_local[..., _HIPS[1], :]
    side = _unit(side - np.sum(side * trunk, axis=-1, keepdims=True) * trunk)
    front = np.cross(side, trunk)
    return np.stack([trunk[..., 2], side[..., 2], front[..., 2]], axis=-1)


def within_turn(up: FloatArray, to: FloatArray) -> BoolArray:
    """Whether bodies whose up_in_body is `up` (..., 3) are turned no more than TURN_MOST from one
    whose is `to` (3,) with respect to the vertical (a turn about the vertical is free)."""
    return np.degrees(np.arccos(np.clip(up @ to, -1.0, 1.0))) <= TURN_MOST


def _unit(v: FloatArray) -> FloatArray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-9)
