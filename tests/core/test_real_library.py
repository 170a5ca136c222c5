"""A reaction library of real captures (issue "A real-capture library breaks"): CMU falls chained to
CMU get-ups, read from ../shared/mocap (test-only data: the library.toml is written into tmp_path
and names the shared files where they are, nothing is copied), pushed on a Bandai Namco walk.

- A `[[chain]]` with `frames` plays from that frame.
- A calibration first frame (every CMU file opens on the converter's T-pose, left at 77-172 m/s) is
  never searched or played: the get-up used to start from it, lifting the lying body 0.8 m at the
  chain and floating the whole get-up as high.
- A push that keeps its feet is no fall when the library has only falls: the walk is kept, the hit
  simulated, and the reaction's note (the bake summary's line) says why.

The class policy is also checked without shared mocap, on libraries cut from the sample clips.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

from reactive_anim.core.classify.classifier import load_classifier
from reactive_anim.core.classify.outcome import Outcome
from reactive_anim.core.model import bvh
from reactive_anim.core.model.impact import Impact
from reactive_anim.core.model.skeleton import Motion, frame_times
from reactive_anim.core.react import (
    KEPT_CLIP,
    ReactionSettings,
    _missing_class,
    _off_push,
    _query_ending_at,
    character_ragdoll,
    react,
    resume_fade_frames,
)
from reactive_anim.core.search.library import Library, load_library
from reactive_anim.core.transition.casting import Casting
from tests.support.mocap import REPO, require_mocap
from tools.devkit.poses import ground_axes

WALK = "bandai_namco/dataset-2/dataset-2_walk_normal_001.bvh"
FALL_ON_FACE = "cmu/90_16.bvh"  # stands, leaps, falls forward onto the front, lies still
RUG_PULL = "cmu/90_18.bvh"  # the feet go out, falls backward onto the back, lies still
GETUP_FACE_DOWN = "cmu/140_01.bvh"  # lies face down about 1.5 s, gets up by 4.5 s
GETUP_FROM_GROUND = "cmu/139_16.bvh"  # lies face down until about 1.2 s, stands by 3.4 s
B = 60  # a frame of the walk mid-stride


def _library(folder: Path, clips: list[dict], chains: list[dict]) -> Library:
    """A library.toml in `folder` naming files where they are (absolute paths), compiled."""
    folder.mkdir(parents=True, exist_ok=True)
    tables = [("clip", c) for c in clips] + [("chain", c) for c in chains]
    text = ""
    for kind, table in tables:
        text += f"[[{kind}]]\n" + "".join(f"{k} = {_toml(v)}\n" for k, v in table.items()) + "\n"
    (folder / "library.toml").write_text(text, encoding="utf-8")
    return load_library(folder, cache_dir=folder / "cache")


def _toml(value: object) -> str:
    if isinstance(value, Path | str):
        return f'"{value}"'
    return str(value)


def _pelvis_height(motion: Motion, roles: dict[str, str]) -> np.ndarray:
    return motion.global_positions()[:, motion.skeleton.index(roles["pelvis"]), 2]


def _trunk_rise(motion: Motion, roles: dict[str, str]) -> np.ndarray:
    """How far the neck is above the pelvis: the trunk's pose, wherever the body is placed or lifted."""
    heights = motion.global_positions()[..., 2]
    return heights[:, motion.skeleton.index(roles["neck"])] - heights[:, motion.skeleton.index(roles["pelvis"])]


@pytest.fixture(scope="module")
def walk() -> Motion:
    return bvh.read_bvh(require_mocap(WALK))


@pytest.fixture(scope="module")
def ragdoll(walk):
    return character_ragdoll(walk)


@pytest.fixture(scope="module")
def classifier():
    return load_classifier()


@pytest.fixture(scope="module")
def falls(tmp_path_factory) -> Library:
    """Real falls only: a forward fall chained to a face-down get-up cut to start 1 s in (frames),
    a backward fall with nothing chained."""
    face, rug, getup = (require_mocap(f) for f in (FALL_ON_FACE, RUG_PULL, GETUP_FACE_DOWN))
    return _library(
        tmp_path_factory.mktemp("falls"),
        [{"file": face, "class": "fall_forward_hands", "next": getup}, {"file": rug, "class": "fall_backward_sit"}],
        [{"file": getup, "frames": [120, 831]}],
    )


@pytest.fixture(scope="module")
def uncut(tmp_path_factory) -> Library:
    """The forward fall chained to a get-up given without frames: both open on a calibration pose."""
    face, getup = require_mocap(FALL_ON_FACE), require_mocap(GETUP_FROM_GROUND)
    return _library(
        tmp_path_factory.mktemp("uncut"), [{"file": face, "class": "fall_forward_hands", "next": getup}],
        [{"file": getup}],
    )  # fmt: skip


def _fall_and_get_up(walk: Motion, ragdoll, library: Library):
    """A hard push from behind forced into the forward fall, which chains its get-up; the reaction,
    the get-up as the character plays it (cast onto the walk's skeleton) and the chain's seam (the
    fall's last frame, where the get-up starts fading in)."""
    casting = Casting.between(walk, ragdoll.rig, library)
    push = Impact(B, ragdoll.roles["chest"], tuple(ground_axes(walk, B)[0]), 150.0, reaction="fall_forward_hands")
    reaction = react(walk, push, library, ragdoll=ragdoll, casting=casting)
    assert reaction.chained is not None
    getup = casting.clip(reaction.chained, walk.fps)
    window = round(library.window * walk.fps / library.fps)  # the walk resumes from there to its fade's end
    getup_end = reaction.end_frame + 1 - resume_fade_frames(window, walk.fps) + window
    return reaction, getup, getup_end - getup.num_frames


@pytest.mark.mocap
def test_a_chain_with_frames_plays_from_that_frame(walk, ragdoll, falls) -> None:
    """`frames = [120, 831]` on the face-down get-up: the bake plays it from BVH frame 120 (lying,
    1 s before it pushes up), not from its first frame."""
    path = require_mocap(GETUP_FACE_DOWN)
    name = str(path)
    assert falls.chain_frames[name] == (120, 831)
    file = bvh.read_bvh(path)
    assert np.array_equal(falls.clip_motion(name, file.fps).root_pos, file.root_pos[120:831])
    reaction, getup, seam = _fall_and_get_up(walk, ragdoll, falls)
    assert reaction.chained == name
    assert getup.num_frames == len(frame_times(file.slice(120, 831), walk.fps))  # frames 120.. at the walk's rate
    # After the chain's fade and before the walk resumes, the output is the get-up (placed on the
    # floor plan; where the cast get-up lies a few cm under the walk's floor, the whole body is
    # lifted onto it, and hands and feet by their IK: the trunk's pose is the cast clip's).
    overlap = round(ReactionSettings().chain_blend * walk.fps)
    # the walk fades in from the re-entry window before the get-up's end, holding its last pose after
    window = round(falls.window * walk.fps / falls.fps)
    resume = resume_fade_frames(window, walk.fps)
    assert reaction.motion is not None
    played = _trunk_rise(reaction.motion, ragdoll.roles)[seam + overlap : reaction.end_frame + 1 - resume]
    assert np.allclose(played, _trunk_rise(getup, ragdoll.roles)[overlap : getup.num_frames - window], atol=1e-6)


@pytest.mark.mocap
@pytest.mark.parametrize("which", ["falls", "uncut"])
def test_a_calibration_first_frame_is_never_played_or_searched(tmp_path, walk, ragdoll, falls, uncut, which) -> None:
    """Every CMU file opens on a calibration T-pose. It is left out of every clip (searched from
    the file's frame 1, exactly as `frames = [1, N]` would) and every chain (played from frame 1, or
    from its `frames`). The lying body is not lifted where the get-up fades in: the pelvis stays
    within a few centimetres of where the fall left it (it rose 0.8 m there, and the get-up floated
    0.8-1.0 m above the floor)."""
    library = {"falls": falls, "uncut": uncut}[which]
    assert all(clip.source_start == 1 for clip in library.clips)
    if which == "uncut":
        assert library.chain_frames == {str(require_mocap(GETUP_FROM_GROUND)): (1, 654)}
        face = require_mocap(FALL_ON_FACE)
        listed = _library(tmp_path, [{"file": face, "class": "fall_forward_hands", "frames": [1, 725]}], [])
        assert np.array_equal(library.pos_local, listed.pos_local) and np.array_equal(library.rot, listed.rot)
    reaction, _, seam = _fall_and_get_up(walk, ragdoll, library)
    assert reaction.motion is not None
    pelvis = _pelvis_height(reaction.motion, ragdoll.roles)
    fade = pelvis[seam : seam + round(ReactionSettings().chain_blend * walk.fps) + 1]
    assert fade.max() - pelvis[seam] < 0.03, fade  # not lifted (0.8 m with the calibration frame)
    assert np.abs(fade - pelvis[seam]).max() < 0.15, fade  # the two captures lie a few cm apart
    lying = pelvis[seam : seam + round(0.5 * walk.fps)]
    assert lying.max() < 0.25, lying.max()  # still lying half a second into the get-up (no float)


@pytest.mark.mocap
@pytest.mark.parametrize("push", ["behind", "front"])
def test_a_push_that_keeps_its_feet_is_no_fall_with_a_library_of_falls(walk, ragdoll, classifier, falls, push):
    """40 N·s on the chest of a walker: the outcome rule says it keeps its feet (a step), and the
    library has falls only. Every such push used to become a fall. Now the walk is kept: the hit
    is simulated, CD tracks back to the walk and, from F, the walk plays on as it was (moved over
    the floor by the push); the note (for the bake summary's line) says what was done: the walk
    kept for a sway or single step on a walk, whatever the library has, else what it lacked."""
    ahead = ground_axes(walk, B)[0]
    direction = ahead if push == "behind" else -ahead
    r = react(walk, Impact(B, ragdoll.roles["chest"], tuple(direction), 40.0), falls, classifier, ragdoll=ragdoll)
    assert r.predicted is not None and not r.predicted.startswith("fall_")
    assert r.kept_motion and r.clip == KEPT_CLIP and not r.reaction_class.startswith("fall_")
    missing = r.note.startswith("the library has no step or sway clips: kept the original motion")
    assert missing or r.note.endswith("on a walk: kept the walk, the hit simulated"), r.note
    assert r.chained is None and r.end_frame == r.frame_f
    out = r.motion
    assert out is not None and out.num_frames == walk.num_frames
    pelvis = _pelvis_height(out, ragdoll.roles)
    assert pelvis[B:].min() > 0.75, pelvis[B:].min()  # on its feet (walking: 0.88-0.93)
    hit = np.abs(out.global_positions()[B : r.frame_c + 1] - walk.global_positions()[B : r.frame_c + 1]).max()
    assert hit > 0.03, hit  # the hit shows
    assert np.array_equal(pelvis[r.frame_f :], _pelvis_height(walk, ragdoll.roles)[r.frame_f :])
    settled = r.frame_f + round(walk.fps)  # the held feet let go within a second
    assert np.array_equal(out.local_rot[settled:], walk.local_rot[settled:])


# ---------------------------------------------------------------------------------------------
# The class policy without shared mocap: libraries cut from the sample clips

SAMPLE = REPO / "sample_clips"
FALLS = ("fall_forward_roll", "fall_forward_hands", "fall_backward_sit", "fall_backward_hands", "fall_side_knees")
SAMPLE_B = 40  # a frame of the sample walk with a foot planted


@pytest.fixture(scope="module")
def sample_walk() -> Motion:
    return bvh.read_bvh(SAMPLE / "walk.bvh")


@pytest.fixture(scope="module")
def sample_ragdoll(sample_walk):
    return character_ragdoll(sample_walk)


def _sample_library(folder: Path, classes: tuple[str, ...]) -> Library:
    """The sample library's clips of `classes` (falls keep their get-ups), named where they are."""
    manifest = tomllib.loads((SAMPLE / "library.toml").read_text(encoding="utf-8"))
    clips = [{**c, "file": SAMPLE / c["file"], **({"next": SAMPLE / c["next"]} if "next" in c else {})}
             for c in manifest["clip"] if c["class"] in classes]  # fmt: skip
    return _library(folder, clips, [{"file": SAMPLE / c["file"]} for c in manifest["chain"]])


@pytest.fixture(scope="module")
def sample_idle() -> Motion:
    return bvh.read_bvh(SAMPLE / "idle.bvh")


@pytest.mark.parametrize(
    ("have", "push", "played", "note"),
    [
        ((), "behind", None, "the library has no step or sway clips: kept the original motion"),
        (("sway_balance",), "behind", "sway_balance", "the library has no step_forward clips: played sway_balance"),
        (("steps_forward",), "front", None, "the library has no step_back, steps_back or sway_balance clips: kept"),
        (("steps_forward",), "behind", "steps_forward", "the library has no step_forward clips: played steps_forward"),
    ],
)
def test_a_push_that_keeps_its_feet_plays_the_nearest_class_that_does(
    tmp_path, sample_idle, classifier, have, push, played, note
) -> None:
    """A push the classifier and the rule call a single step, with a library that lacks its class:
    the same way with more steps, or a sway, if the library has one (never a step the other way,
    never a fall), else the motion is kept; the note says which. On the sample idle at 60 N·s (a
    walker pushed into a single step keeps its walk whatever the library has: test_react.py)."""
    library = _sample_library(tmp_path / "lib", FALLS + have)
    ahead = ground_axes(sample_idle, SAMPLE_B)[0]
    direction = ahead if push == "behind" else -ahead
    r = react(sample_idle, Impact(SAMPLE_B, "chest", tuple(direction), 60.0), library, classifier)
    assert r.predicted == ("step_forward" if push == "behind" else "step_back")
    assert r.note.startswith(note), r.note
    if played is None:
        assert r.kept_motion and r.reaction_class == r.predicted and r.clip == KEPT_CLIP and r.cost == 0.0
    else:
        assert not r.kept_motion and r.reaction_class == played and r.scope.startswith(played)


def test_a_push_that_falls_still_falls_and_a_library_with_the_class_is_unchanged(
    tmp_path, sample_walk, sample_ragdoll, sample_idle, classifier
) -> None:
    """A push the library has the class for is searched as before, with no note (the sample
    library's results are unchanged); a hard shove with a falls-only library still falls."""
    falls_only = _sample_library(tmp_path / "falls", FALLS)
    ahead = ground_axes(sample_walk, SAMPLE_B)[0]
    shove = react(sample_walk, Impact(SAMPLE_B, "chest", tuple(ahead), 300.0), falls_only, classifier,
                  ragdoll=sample_ragdoll)  # fmt: skip
    assert shove.reaction_class.startswith("fall_") and not shove.kept_motion and shove.note == ""
    full = load_library(SAMPLE, cache_dir=tmp_path / "cache")
    back = -ground_axes(sample_idle, SAMPLE_B)[0]
    nudge = react(sample_idle, Impact(SAMPLE_B, "chest", tuple(back), 60.0), full, classifier)
    assert nudge.reaction_class == nudge.predicted == "step_back" and nudge.note == "" and not nudge.kept_motion


@pytest.mark.parametrize(("classes", "side"), [(("fall_forward_roll", "fall_forward_hands"), "front"),
                                            (("fall_side_knees",), "behind")])  # fmt: skip
def test_a_library_with_only_classes_off_the_push_plays_what_it_has(
    tmp_path, sample_walk, sample_ragdoll, classifier, classes, side
) -> None:
    """A 300 N·s shove whose every likely class the library lacks, and whose classes go across or
    against the push (react._off_push): the likeliest class the library has is played, and the
    note says what it lacked, as before classes off the push were left out (then it was a
    LibraryError: "no usable class")."""
    library = _sample_library(tmp_path / "lib", classes)
    ahead = ground_axes(sample_walk, SAMPLE_B)[0]
    push = ahead if side == "behind" else -ahead
    r = react(sample_walk, Impact(SAMPLE_B, "chest", tuple(push), 300.0), library, classifier, ragdoll=sample_ragdoll)
    assert r.reaction_class in classes and not r.kept_motion, r.reaction_class
    assert r.note.startswith("the library has no ") and f"played {r.reaction_class}" in r.note, r.note


def test_without_a_classifier_a_falls_only_library_keeps_a_nudged_walk(tmp_path, sample_walk, sample_ragdoll):
    """With no classifier the whole library is searched; a library of falls alone would give a
    nudge a fall, so the outcome rule decides there too."""
    library = _sample_library(tmp_path / "lib", FALLS)
    ahead = tuple(ground_axes(sample_walk, SAMPLE_B)[0])
    r = react(sample_walk, Impact(SAMPLE_B, "chest", ahead, 40.0), library, None, ragdoll=sample_ragdoll)
    assert r.kept_motion and r.predicted is None and r.reaction_class == "step_forward"
    assert r.note.startswith("the library has no step or sway clips: kept the original motion"), r.note


def test_a_missing_class_is_never_made_up_by_a_class_off_the_push(tmp_path, sample_walk, sample_ragdoll) -> None:
    """The nearest class for a push the library lacks (react._missing_class) leaves out classes off
    the push's way, the outcome rule's own included: pushed from behind, with a library whose only
    standing class is a step to the left and a rule that read the walker's gait as a step left, the
    walk is kept and the note names what is missing; with nothing left out, the step left plays."""
    library = _sample_library(tmp_path / "lib", FALLS + ("step_left",))
    ahead = ground_axes(sample_walk, SAMPLE_B)[0]
    impact = Impact(SAMPLE_B, "chest", tuple(ahead), 40.0)
    off = _off_push(sample_walk, impact, sample_ragdoll.rig)
    assert "step_left" in off and "step_forward" not in off
    casting = Casting.between(sample_walk, sample_ragdoll.rig, library)
    query = _query_ending_at(sample_walk, SAMPLE_B + 8, casting, impact)
    verdict = Outcome("step_left", 1, "left", np.array([0.0, 0.1]), 0.05, 0.4, False)
    settings = ReactionSettings()
    kept = _missing_class(library, query, "step_forward", verdict, settings, off)
    assert kept is not None and kept.match is None and kept.kept_class == "step_forward"
    assert kept.note.startswith("the library has no step_forward, steps_forward or sway_balance clips: kept"), kept.note
    across = _missing_class(library, query, "step_forward", verdict, settings, frozenset())
    assert across is not None and across.match is not None and across.match.reaction_class == "step_left"
