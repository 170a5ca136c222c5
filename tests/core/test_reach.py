"""Which fall windows a body down can be faded into (search/reach.py), on the sample library."""

from __future__ import annotations

import numpy as np
import pytest

from reactive_anim.core.model import quat
from reactive_anim.core.model.classes import is_fall
from reactive_anim.core.search.library import Library, load_library
from reactive_anim.core.search.reach import hips_up, reachable_windows, up_in_body, within_turn
from reactive_anim.core.search.window import SEARCH_ROLES, Query, yaw_rotate
from tests.support.mocap import REPO

HIPS = [SEARCH_ROLES.index("hip_l"), SEARCH_ROLES.index("hip_r")]
NECK = SEARCH_ROLES.index("neck")


@pytest.fixture(scope="module")
def library() -> Library:
    return load_library(REPO / "sample_clips" / "library.toml")


def everything(library: Library) -> list[str]:
    return list(library.class_ranges)


def clip_window(library: Library, name: str, last: bool) -> int:
    """The search index's position of a clip's first or last window."""
    index = library.search_index()
    clip = next(k for k, c in enumerate(library.clips) if c.name == name)
    starts = np.flatnonzero(library.clip_index[index.starts] == clip)
    return int(starts[-1] if last else starts[0])


def query_of(library: Library, window: int) -> Query:
    start = int(library.search_index().starts[window])
    return Query(library.features(start, start + library.window))


def last_pose(library: Library, name: str) -> np.ndarray:
    """The pose (15, 3) at the end of a clip's last window."""
    window = clip_window(library, name, last=True)
    return np.asarray(library.frames.pos_local[library.search_index().starts[window] + library.window - 1], float)


def test_a_body_lying_face_down_reaches_its_own_window_but_not_standing_or_face_up(library) -> None:
    lying = clip_window(library, "fall_forward_hands_1.bvh", last=True)
    allowed = reachable_windows(library, query_of(library, lying), everything(library), 0)
    assert allowed[lying]
    # every clip's first window stands (the falls' too): the hips would rise from the floor
    for clip in library.clips:
        assert not allowed[clip_window(library, clip.name, last=False)], clip.name
    # reclined face up on the hands at the end of a backward fall: turned over through the floor
    assert not allowed[clip_window(library, "fall_backward_hands_1.bvh", last=True)]
    # face down, as the side fall onto the knees ends: within reach
    assert allowed[clip_window(library, "fall_side_knees_1.bvh", last=True)]


def test_only_the_classes_asked_for_are_allowed(library) -> None:
    lying = clip_window(library, "fall_forward_hands_1.bvh", last=True)
    allowed = reachable_windows(library, query_of(library, lying), ["fall_side_knees"], 0)
    assert allowed[clip_window(library, "fall_side_knees_1.bvh", last=True)] and not allowed[lying]
    classes = library.clip_index[library.search_index().starts[allowed]]
    assert {library.clips[k].reaction_class for k in classes} == {"fall_side_knees"}


def test_a_standing_body_reaches_standing_windows(library) -> None:
    standing = clip_window(library, "sway_balance_1.bvh", last=False)
    allowed = reachable_windows(library, query_of(library, standing), everything(library), 0)
    for clip in library.clips:
        assert allowed[clip_window(library, clip.name, last=False)], clip.name


def test_which_way_up_the_body_is_does_not_depend_on_its_heading(library) -> None:
    pos = np.asarray(library.frames.pos_local, dtype=np.float64)[::25]
    turned = yaw_rotate(np.linspace(-3.0, 3.0, len(pos))[:, None], pos)
    assert np.allclose(up_in_body(turned), up_in_body(pos), atol=1e-6)
    assert np.allclose(np.linalg.norm(up_in_body(pos), axis=-1), 1.0)
    assert np.allclose(hips_up(turned), hips_up(pos))


def _turned(pose: np.ndarray, axis: np.ndarray, degrees: float) -> np.ndarray:
    """The pose turned about `axis` through the hips' midpoint."""
    centre = pose[HIPS].mean(axis=0)
    return centre + quat.rotate(quat.from_axis_angle(axis / np.linalg.norm(axis), np.radians(degrees)), pose - centre)


def test_a_lying_body_may_not_turn_over_nor_sit_up_but_may_turn_about_the_vertical(library) -> None:
    """Turned about its own trunk, a body face down reaches a slight roll (40 degrees) but not its back
    (180); pitched up 80 degrees (lying to sitting) it is out of reach; turned about the vertical it
    is the same body."""
    face_down = last_pose(library, "fall_forward_hands_1.bvh")
    trunk = face_down[NECK] - face_down[HIPS].mean(axis=0)
    side = face_down[HIPS[0]] - face_down[HIPS[1]]
    to = up_in_body(face_down)
    for degrees, reachable in ((40.0, True), (180.0, False)):
        assert bool(within_turn(up_in_body(_turned(face_down, trunk, degrees)), to)) == reachable, degrees
    for degrees in (80.0, -80.0):
        assert not within_turn(up_in_body(_turned(face_down, side, degrees)), to), degrees
    assert within_turn(up_in_body(_turned(face_down, np.array([0.0, 0.0, 1.0]), 170.0)), to)


def test_the_fade_s_frames_count_and_stop_at_the_clip_s_end(library) -> None:
    """Over the frames a fade passes through after E: a roll's window early in the roll turns the
    body head over heels within the fade, so a body posed as at its E cannot be faded into it; a
    clip's last window holds its last pose past its end rather than reading the next clip's
    standing first frames."""
    fade = round(0.5 * library.fps)
    index = library.search_index()
    falls = [slug for slug in library.class_ranges if is_fall(slug)]
    roll = next(k for k, c in enumerate(library.clips) if c.name == "fall_forward_roll_1.bvh")
    windows = np.flatnonzero(library.clip_index[index.starts] == roll)
    assert any(not reachable_windows(library, query_of(library, int(w)), falls, fade)[w] for w in windows)
    for clip in library.clips:
        if is_fall(clip.reaction_class):
            last = clip_window(library, clip.name, last=True)
            assert reachable_windows(library, query_of(library, last), falls, fade)[last], clip.name
