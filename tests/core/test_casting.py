"""A character on another skeleton than the library's (core/transition/casting.py, wired into react.py): the
query is retargeted onto the library's skeleton, the chosen clip onto the character's."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from reactive_anim.core.classify.classifier import load_classifier
from reactive_anim.core.model import bvh, quat
from reactive_anim.core.model.impact import Impact
from reactive_anim.core.model.rig import Rig
from reactive_anim.core.model.roles import assign_roles
from reactive_anim.core.model.skeleton import Motion
from reactive_anim.core.react import ReactionSettings, character_ragdoll, react
from reactive_anim.core.search.library import load_library
from reactive_anim.core.search.search import search
from reactive_anim.core.transition import retarget
from reactive_anim.core.transition.casting import Casting
from tests.support.mocap import REPO, require_mocap
from tools.devkit.library_clips import write_toml
from tools.devkit.poses import limb_joints
from tools.devkit.skeletons import WALK, t_pose_variant

PUSHES = [
    (50, "chest", (0.0, -1.0, 0.0), 120.0),
    (90, "pelvis", (1.0, 0.0, 0.0), 250.0),
    (130, "head", (0.0, 1.0, 0.0), 80.0),
]


@pytest.fixture(scope="module")
def library(tmp_path_factory):
    return load_library(REPO / "sample_clips", cache_dir=tmp_path_factory.mktemp("library_cache"))


@pytest.fixture(scope="module")
def classifier():
    return load_classifier(REPO / "reactive_anim" / "models" / "reaction_classifier.onnx")


def _renamed():
    """The sample skeleton under other names (its roles given, as the role editor would): the
    same body, so everything but the names must come out as on the sample walk."""
    names = [f"Bone{k:02d}" for k in range(WALK.skeleton.num_joints)]
    roles = {role: names[WALK.skeleton.index(n)] for role, n in assign_roles(WALK.skeleton).items()}
    skeleton = replace(WALK.skeleton, names=names, roles=roles)
    return retarget.retarget(WALK, retarget.retarget_map(Rig.of(WALK.skeleton), Rig.of(skeleton))), roles


def test_on_the_librarys_skeleton_nothing_is_converted(library):
    casting = Casting.between(WALK, Rig.of(WALK.skeleton), library)
    assert casting.same_skeleton
    assert casting.clip("step_back_1.bvh", 60.0) is library.clip_motion("step_back_1.bvh", 60.0)


@pytest.mark.parametrize("push", PUSHES, ids=[f"{p[1]}-{p[3]:g}" for p in PUSHES])
def test_the_same_push_on_a_renamed_skeleton_picks_the_same_class_clip_and_frame(library, classifier, push):
    renamed, roles = _renamed()
    frame, role, direction, strength = push
    here = react(WALK, Impact(frame, role, direction, strength), library, classifier)
    there = react(renamed, Impact(frame, roles[role], direction, strength), library, classifier)

    assert (there.reaction_class, there.clip, there.jump_frame) == (here.reaction_class, here.clip, here.jump_frame)
    assert there.cost == pytest.approx(here.cost, abs=1e-3)
    assert there.motion is not None and here.motion is not None
    assert there.motion.skeleton.names == renamed.skeleton.names
    moved = np.linalg.norm(there.motion.global_positions() - here.motion.global_positions(), axis=-1)
    limbs = limb_joints(WALK.skeleton)
    body = np.setdiff1d(np.arange(WALK.skeleton.num_joints), limbs)
    assert moved[:, body].max() < 0.005  # retargeting the clip onto the same body changes it by IK round-off
    # The feet hold (footing.py) weighs a foot's contact over a 2 cm band of height, and brings
    # limbs out of the floor where they are under it: the clip's millimetres of round-off move a
    # held foot or a hand on the floor by up to a few times as much. It also turns a foot no faster
    # than LANDING_ACCEL, which carries a foot's pace on for a few frames: round-off in the frame a
    # held foot lifts moved it in the air by 3.6 cm (the fall at 250 N·s; 1.3 cm without that
    # limit). Without the hold, every joint stays within the round-off.
    assert moved[:, limbs].max() < 0.04
    raw = ReactionSettings(hold_feet=False)
    here = react(WALK, Impact(frame, role, direction, strength), library, classifier, raw)
    there = react(renamed, Impact(frame, roles[role], direction, strength), library, classifier, raw)
    assert there.motion is not None and here.motion is not None
    assert np.abs(there.motion.global_positions() - here.motion.global_positions()).max() < 0.005


def test_a_t_pose_character_reacts_with_a_clip_recorded_arms_down(library, classifier):
    target = t_pose_variant()
    mapping = retarget.retarget_map(Rig.of(WALK.skeleton), Rig.of(target))
    character = retarget.retarget(WALK, mapping)
    reaction = react(character, Impact(60, "chest", (0.0, -1.0, 0.0), 120.0), library, classifier)

    assert reaction.reaction_class.startswith("step") and reaction.motion is not None
    out = reaction.motion
    assert out.skeleton.names == target.names
    # the clip plays on the character: its arms hang as the clip's do, not out in its T-pose rest
    pos = out.global_positions()[reaction.frame_f + 5]
    upper, lower = target.index("upper_arm.L"), target.index("forearm.L")
    assert (pos[lower] - pos[upper])[2] < -0.2
    ragdoll = character_ragdoll(character)
    assert ragdoll.skeleton.names == target.names  # the physics is the character's own body
    assert np.isfinite(quat.normalize(out.local_rot)).all()


REAL_WALKS = ["cmu_iclone/002_01.bvh", "bandai_namco/dataset-1/dataset-1_walk_normal_001.bvh"]


@pytest.mark.parametrize("relative", REAL_WALKS)
def test_real_walks_of_other_skeletons_find_windows_as_close_as_the_sample_walk(library, relative):
    """Both files rest in poses that are no standing body (legs up, legs apart): lined up at a rest
    pose, their bones would turn by up to 180 degrees about themselves and every search cost would
    be about 100. Lined up at their first frames, their walking windows are about as close to the
    library's as the sample walk's (which the library's own generator made)."""
    walk = bvh.read_bvh(require_mocap(relative))
    roles = assign_roles(walk.skeleton)
    casting = Casting.between(walk, Rig(walk.skeleton, roles), library)
    assert not casting.same_skeleton
    sample = Casting.between(WALK, Rig.of(WALK.skeleton), library)

    def median_cost(cast: Casting, motion) -> float:
        starts = np.linspace(motion.fps, motion.num_frames - motion.fps, 6)
        return float(np.median([search(library, cast.query(motion, s)).cost for s in starts]))

    theirs, ours = median_cost(casting, walk), median_cost(sample, WALK)
    assert theirs < 2.5 * ours and theirs < 40.0, (theirs, ours)


def test_the_librarys_joint_names_on_other_proportions_are_retargeted(library):
    """Another subject of the same rig (the sample's names, legs 15% longer) is not the library's
    skeleton: its clips come scaled to its legs."""
    offsets = WALK.skeleton.offsets.copy()
    for name in ("shin.L", "shin.R", "foot.L", "foot.R"):
        offsets[WALK.skeleton.index(name)] *= 1.15
    taller = replace(WALK.skeleton, offsets=offsets, roles={})
    character = retarget.retarget(WALK, retarget.retarget_map(Rig.of(WALK.skeleton), Rig.of(taller)))
    casting = Casting.between(character, Rig.of(taller), library)
    assert not casting.same_skeleton
    clip = casting.clip("step_back_1.bvh", 60.0)
    source = library.clip_motion("step_back_1.bvh", 60.0)
    assert clip.skeleton is taller or np.allclose(clip.skeleton.offsets, taller.offsets)
    assert clip.root_pos[:, 2].mean() > source.root_pos[:, 2].mean() + 0.03  # the hips stand higher


def test_a_clips_role_overrides_reach_the_bake(tmp_path):
    """A library.toml entry's `roles` decide the clip's joints for its features; the bake must read
    the clip with the same roles (the query is retargeted onto them)."""
    clip = REPO / "sample_clips" / "step_back_1.bvh"
    write_toml(tmp_path, [{"file": str(clip), "class": "step_back", "roles": {"chest": "spine.001"}}])
    library = load_library(tmp_path, cache_dir=tmp_path / "cache")
    assert library.clip_motion(library.clips[0].name, 60.0).skeleton.roles["chest"] == "spine.001"
    renamed, roles = _renamed()
    casting = Casting.between(renamed, Rig(renamed.skeleton, roles), library)
    assert casting._rig(casting.reference.skeleton).roles["chest"] == "spine.001"


def _opening_on(drop: float) -> Motion:
    """The walk after a first frame of its own opening pose `drop` metres lower (a calibration pose
    under the floor, as CMU 139_16 and 140_01 open with)."""
    first = WALK.slice(0, 1)
    first = replace(first, root_pos=first.root_pos - np.array([0.0, 0.0, drop]))
    return first.concat(WALK)


def test_a_calibration_pose_on_frame_0_is_not_the_characters_floor(library):
    """A first frame left at 48 m/s (0.8 m in a frame) is no part of the take: the floor the cast
    clips stand on is the walk's. One left at a walking pace still counts (5 cm lower: 3 m/s)."""
    walk = Casting.between(WALK, Rig.of(WALK.skeleton), library).sole
    calibrated = Casting.between(_opening_on(0.8), Rig.of(WALK.skeleton), library).sole
    stepped = Casting.between(_opening_on(0.05), Rig.of(WALK.skeleton), library).sole
    assert calibrated == walk
    assert stepped < walk - 0.04


def test_a_take_opening_on_a_calibration_pose_keeps_its_reactions_on_its_floor(library, classifier):
    """CMU 139_16 opens on a pose with the feet 0.83 m under the floor of the rest of the take; the
    clip a push there picked was held that far down for the whole reaction."""
    take = bvh.read_bvh(require_mocap("cmu/139_16.bvh"))
    roles = assign_roles(take.skeleton)
    reaction = react(take, Impact(560, roles["chest"], (1.0, 0.0, 0.0), 100.0), library, classifier)
    frames = slice(reaction.frame_c, reaction.end_frame + 1)
    assert reaction.motion is not None
    pos, rot = reaction.motion.global_transforms()
    lowest = min(
        retarget.lowest_foot_point(take.skeleton, take.skeleton.index(roles[f"ankle_{s}"]), pos, rot)[frames].min()
        for s in "lr"
    )
    assert lowest > -0.03, lowest
