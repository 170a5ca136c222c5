"""A fall's C..F fade shape (core/transition/fade_shape.py).

- A body turning fast faded into a still pose: a shape calmer than the plain smootherstep is taken,
  but not one that would jolt the pelvis at F past the real takes' p99.
- Where the plain fade adds nothing to what the sources do, it stays.
- On real takes pushed at 300 N·s: side falls of a body thrown flat stay under the real falls'
  largest acceleration from C to F (tests/core/test_react.py), and a roll's pelvis at F is as with
  the plain fade.
"""

from __future__ import annotations

import numpy as np
import pytest

from reactive_anim.core.classify.classifier import load_classifier
from reactive_anim.core.model import bvh, quat
from reactive_anim.core.model.impact import Impact
from reactive_anim.core.model.rig import Rig
from reactive_anim.core.model.skeleton import Motion
from reactive_anim.core.react import ReactionSettings, character_ragdoll, react
from reactive_anim.core.search.library import load_library
from reactive_anim.core.transition.blend import blend, fade_weights
from reactive_anim.core.transition.fade_shape import SEAM_PELVIS, calmest_fade, fade_context
from tests.support.mocap import REPO, require_mocap
from tools.devkit import believability as bl
from tools.devkit.poses import ground_axes

WALK = bvh.read_bvh(REPO / "sample_clips" / "walk.bvh")
RIG = Rig.of(WALK.skeleton)
INNER = 30  # the fade's frames


def _tumbling(frames: int, turns_per_second: float, stop: float, gap: float) -> Motion:
    """The walk's first pose held `gap` m along y from where it stands, the whole body turning head
    over heels, slowing to a stop at `stop` of the frames (a body thrown flat, landing)."""
    t = np.arange(frames) / WALK.fps
    speed = 2 * np.pi * turns_per_second * np.clip(1.0 - t / (t[-1] * stop), 0.0, 1.0) ** 2
    angle = np.concatenate([[0.0], np.cumsum(speed[1:] / WALK.fps)])
    local = np.repeat(WALK.local_rot[:1], frames, axis=0)
    local[:, 0] = quat.mul(quat.from_axis_angle(np.array([1.0, 0.0, 0.0]), angle), local[:, 0])
    root = np.repeat(WALK.root_pos[:1], frames, axis=0) + np.array([0.0, gap, 0.0])
    return Motion(WALK.skeleton, WALK.fps, root, local)


def _still(frames: int) -> Motion:
    return Motion(
        WALK.skeleton, WALK.fps, np.repeat(WALK.root_pos[:1], frames, 0), np.repeat(WALK.local_rot[:1], frames, 0)
    )


def _moves(sim: Motion, clip: Motion, inner: np.ndarray) -> tuple[float, float]:
    """The faded output's largest joint acceleration, and the pelvis' largest on F and the frames
    either side."""
    before, after = fade_context(WALK.fps)
    weights = np.concatenate([np.zeros(before), inner, np.ones(after)])
    accel = bl.acceleration(blend(sim.frames(0, clip.num_frames), clip, weights).global_positions(), WALK.fps)
    f = before + len(inner) - 1
    return float(np.nanmax(accel)), float(np.nanmax(accel[f - 1 : f + 2, 0]))


def _fade(sim: Motion, clip: Motion) -> np.ndarray:
    return calmest_fade(sim, clip, RIG)


def test_a_tumbling_body_is_faded_along_a_calmer_shape() -> None:
    before, after = fade_context(WALK.fps)
    sim, clip = _tumbling(before + INNER, 1.5, 0.7, 0.6), _still(before + INNER + after)
    chosen, plain = _fade(sim, clip), fade_weights(INNER)
    assert not np.allclose(chosen, plain)
    assert _moves(sim, clip, chosen)[0] < 0.99 * _moves(sim, clip, plain)[0]
    assert chosen[0] == 0.0 and chosen[-1] == 1.0 and np.all(np.diff(chosen) >= 0.0)


def test_a_shape_that_would_jolt_the_pelvis_at_f_is_passed_over() -> None:
    """A tumble that stops half way, a metre from the clip: the calmest shape by the joints alone
    (smootherstep of t^1.5) fades so steeply at the end that the pelvis jolts past the real takes'
    p99 at F; the shape taken is calmer than the plain one and does not."""
    before, after = fade_context(WALK.fps)
    sim, clip = _tumbling(before + INNER, 1.5, 0.5, 1.0), _still(before + INNER + after)
    chosen, plain = _fade(sim, clip), fade_weights(INNER)
    steep = _moves(sim, clip, fade_weights(INNER, 1.5))
    assert steep[0] < _moves(sim, clip, chosen)[0] and steep[1] > SEAM_PELVIS  # what the check is for
    assert _moves(sim, clip, chosen)[0] < _moves(sim, clip, plain)[0]
    assert _moves(sim, clip, chosen)[1] <= SEAM_PELVIS


def test_the_plain_fade_stays_where_it_adds_nothing() -> None:
    before, after = fade_context(WALK.fps)
    chosen = _fade(WALK.slice(0, before + INNER), WALK.slice(0, before + INNER + after))
    assert np.array_equal(chosen, fade_weights(INNER))


@pytest.fixture(scope="module")
def library():
    return load_library(REPO / "sample_clips" / "library.toml")


def test_a_roll_s_fade_jolts_the_pelvis_at_f_no_harder_than_the_plain_one(library) -> None:
    """A Bandai dash pushed on the chest from behind at 300 N·s rolls forward: the calmest shape by
    the joints alone (held back a third of C..F) would move the pelvis at 45 m/s^2 as the fade
    ends; the output's pelvis there is as with the plain fade."""
    motion = bvh.read_bvh(require_mocap("bandai_namco/dataset-1/dataset-1_dash_angry_001.bvh"))
    ragdoll = character_ragdoll(motion)
    ahead, _ = ground_axes(motion, 47, ragdoll.roles)
    impact = Impact(47.0, ragdoll.roles["chest"], tuple(ahead), 300.0)
    floor = bl.lowest_floor(motion, ragdoll.roles)
    jolts = []
    for calm in (True, False):
        r = react(motion, impact, library, load_classifier(), ReactionSettings(calm_fade=calm), ragdoll=ragdoll)
        assert r.motion is not None and r.reaction_class == "fall_forward_roll"
        pelvis = bl.profile(r.motion, ragdoll.roles, floor, start=0).pelvis_accel
        jolts.append(float(np.nanmax(pelvis[r.frame_f - 1 : r.frame_f + 2])))
    assert jolts[0] <= jolts[1] + 0.5, jolts
