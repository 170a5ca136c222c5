"""Which fall windows a body on the floor can be faded into (search/reach.py), on the sample library."""

from __future__ import annotations

import numpy as np
import pytest

from reactive_anim.core.search.library import Library, load_library
from reactive_anim.core.search.reach import TURN_MOST, hips_up, reachable_windows, up_in_body
from reactive_anim.core.search.window import Query, yaw_rotate
from tests.support.mocap import REPO


@pytest.fixture(scope="module")
def library() -> Library:
    return load_library(REPO / "sample_clips" / "library.toml")


def clip_window(library: Library, name: str, last: bool) -> int:
    """The search index's position of a clip's first or last window."""
    index = library.search_index()
    clip = next(k for k, c in enumerate(library.clips) if c.name == name)
    starts = np.flatnonzero(library.clip_index[index.starts] == clip)
    return int(starts[-1] if last else starts[0])


def query_of(library: Library, window: int) -> Query:
    start = int(library.search_index().starts[window])
    return Query(library.features(start, start + library.window))


def test_a_body_lying_face_down_reaches_its_own_window_but_not_standing_or_face_up(library) -> None:
    lying = clip_window(library, "fall_forward_hands_1.bvh", last=True)
    allowed = reachable_windows(library, query_of(library, lying))
    assert allowed[lying]
    # every clip's first window stands (the falls' too): the hips would rise from the floor
    for clip in library.clips:
        assert not allowed[clip_window(library, clip.name, last=False)], clip.name
    # lying face up at the end of a backward fall: the fade would turn the body over through the floor
    assert not allowed[clip_window(library, "fall_backward_hands_1.bvh", last=True)]
    # face down, as the side fall onto the knees ends: within reach
    assert allowed[clip_window(library, "fall_side_knees_1.bvh", last=True)]


def test_a_standing_body_reaches_standing_windows(library) -> None:
    standing = clip_window(library, "sway_balance_1.bvh", last=False)
    allowed = reachable_windows(library, query_of(library, standing))
    for clip in library.clips:
        assert allowed[clip_window(library, clip.name, last=False)], clip.name


def test_which_way_up_the_body_is_does_not_depend_on_its_heading(library) -> None:
    pos = np.asarray(library.frames.pos_local, dtype=np.float64)[::25]
    turned = yaw_rotate(np.linspace(-3.0, 3.0, len(pos))[:, None], pos)
    assert np.allclose(up_in_body(turned), up_in_body(pos), atol=1e-6)
    assert np.allclose(np.linalg.norm(up_in_body(pos), axis=-1), 1.0)
    assert np.allclose(hips_up(turned), hips_up(pos))


def test_face_down_and_face_up_are_further_apart_than_the_turn_allowed(library) -> None:
    ends = library.search_index().starts + library.window - 1
    down = up_in_body(
        np.asarray(library.frames.pos_local[ends[clip_window(library, "fall_forward_hands_1.bvh", True)]])
    )
    up = up_in_body(np.asarray(library.frames.pos_local[ends[clip_window(library, "fall_backward_hands_1.bvh", True)]]))
    assert np.degrees(np.arccos(np.clip(down @ up, -1.0, 1.0))) > 2 * TURN_MOST


def test_the_fade_s_frames_count_and_stop_at_the_clip_s_end(library) -> None:
    """Over the frames a fade passes through after E: a roll's window early in the roll turns the body
    over within half a second, so a body posed as at its E cannot be faded into it (faded so, a body
    not rolling was turned through a headstand); a clip's last window holds its last pose past its
    end rather than reading the next clip's standing first frames."""
    fade = round(0.5 * library.fps)
    index = library.search_index()
    roll = next(k for k, c in enumerate(library.clips) if c.name == "fall_forward_roll_1.bvh")
    windows = np.flatnonzero(library.clip_index[index.starts] == roll)
    turned_over = [w for w in windows if not reachable_windows(library, query_of(library, int(w)), fade)[w]]
    assert turned_over and all(reachable_windows(library, query_of(library, int(w)))[w] for w in turned_over)
    for clip in library.clips:
        last = clip_window(library, clip.name, last=True)
        assert reachable_windows(library, query_of(library, last), fade)[last], clip.name
