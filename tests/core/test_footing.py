"""Planted feet held across a reaction's seams (core/transition/footing.py), on the project's own clips.

- A standing body dragged along the floor while the sources cross-fade keeps its feet where they
  stood, up to the hold's limit (beyond it the feet slide the rest, lifted clear of the floor where
  they go fast), and to the end where they never lift; a walker's hold is let go in the air and
  the walk after it is untouched; a drag outside the fades is the motion's own; a foot lifting off
  is not held for its first slow frames (let go, it jumped); a foot brought down fast is stopped
  over a few frames, not in one.
- Reactions on the sample walk slide their feet less than half as far as without the hold, and
  no foot goes through the floor (without the hold, toes went up to 4 cm under).
- A hand under the floor is lifted straight up onto it, keeping its turn; a hand already under it
  at the hit keeps that depth.
- A body sunk into the floor (knees, hands, a head through a roll's fade) is lifted whole onto it,
  eased in and out; frames before the reaction stay. A foot deep in the floor is lifted by its leg
  only so far; the body's lift takes the rest.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from reactive_anim.core.classify.classifier import load_classifier
from reactive_anim.core.model import bvh, quat
from reactive_anim.core.model.impact import Impact
from reactive_anim.core.model.rig import Rig
from reactive_anim.core.model.skeleton import Motion
from reactive_anim.core.react import ReactionSettings, character_ragdoll, react
from reactive_anim.core.search.library import load_library
from reactive_anim.core.transition.footing import (
    CATCH_UP_FINISH,
    LANDING_ACCEL,
    LIFT_EASE,
    LIMB_LIFT_MOST,
    MAX_OFFSET,
    SWING_BAND,
    SWING_CLEARANCE,
    SWING_SPEED,
    _offsets,
    hold_feet,
    lift_onto_floor,
)
from reactive_anim.core.transition.retarget import foot_points, lowest_foot_point
from tests.support.mocap import REPO
from tools.devkit.poses import ground_axes

IDLE = bvh.read_bvh(REPO / "sample_clips" / "idle.bvh")
WALK = bvh.read_bvh(REPO / "sample_clips" / "walk.bvh")
RIG = Rig.of(IDLE.skeleton)
ROLES = RIG.roles
START, FRAMES = 60, 30  # the drag: frames 60..89


def dragged(distance: float) -> Motion:
    """The standing idle with its root pulled `distance` m forward (x) over FRAMES frames from START."""
    drag = np.zeros_like(IDLE.root_pos)
    drag[:, 0] = np.clip(np.arange(IDLE.num_frames) - START, 0, FRAMES) * distance / FRAMES
    return replace(IDLE, root_pos=IDLE.root_pos + drag)


def sole(motion: Motion) -> float:
    """The lowest any foot point gets in the motion: the character's floor (casting.Casting.sole)."""
    return float(np.min([contact_points(motion, side)[:, 2] for side in "lr"]))


def contact_points(motion: Motion, side: str) -> np.ndarray:
    """(T, 3) the lowest point of a foot per frame."""
    pos, rot = motion.global_transforms()
    points = foot_points(motion.skeleton, motion.skeleton.index(ROLES[f"ankle_{side}"]), pos, rot)
    return points[np.arange(len(points)), points[..., 2].argmin(axis=1)]


def sliding(motion: Motion, first: int, last: int, floor: float) -> float:
    """Metres a foot's contact point travels along the floor over first..last while it touches
    (within 1 cm) and stays the same point, both feet summed: what an animator sees skate."""
    pos, rot = motion.global_transforms()
    total = 0.0
    for side in "lr":
        points = foot_points(motion.skeleton, motion.skeleton.index(ROLES[f"ankle_{side}"]), pos, rot)[first : last + 1]
        lowest = points[..., 2].argmin(axis=1)
        point = points[np.arange(len(points)), lowest]
        touching = point[:, 2] < floor + 0.01
        steady = touching[1:] & touching[:-1] & (lowest[1:] == lowest[:-1])
        total += float(np.sum(np.linalg.norm(np.diff(point[:, :2], axis=0), axis=1) * steady))
    return total


def test_a_dragged_stance_keeps_its_footprints_to_the_end():
    """Dragged 9 cm (within the hold) while the sources cross-fade, the feet stay within 5 mm of
    where they stood, where unheld they go along; they never lift, so they are held to the end of
    the motion (no slide when the hold would end). Frames before the range are the input's, bit
    for bit."""
    moved = dragged(0.09)
    held = hold_feet(moved, RIG, (START, START + FRAMES), [(START, START + FRAMES)], sole(moved))
    for side in "lr":
        before, after = contact_points(moved, side), contact_points(held, side)
        assert np.linalg.norm(before[-1, :2] - before[START - 1, :2]) > 0.085
        assert np.linalg.norm(after[START:, :2] - after[START - 1, :2], axis=1).max() < 0.005
    assert np.array_equal(held.local_rot[:START], moved.local_rot[:START])
    assert np.array_equal(held.root_pos, moved.root_pos)


def test_slides_outside_the_fades_are_the_motions_own():
    """The same drag before the fades (a clip's own motion) is not taken back: the feet go along."""
    moved = dragged(0.09)
    held = hold_feet(moved, RIG, (START, START + FRAMES), [(START + FRAMES, START + FRAMES + 5)], sole(moved))
    assert np.array_equal(held.local_rot[: START + FRAMES], moved.local_rot[: START + FRAMES])
    for side in "lr":
        travel = contact_points(held, side)[-1, :2] - contact_points(held, side)[START - 1, :2]
        assert np.linalg.norm(travel) > 0.085


def test_a_walkers_hold_is_let_go_in_the_air_and_the_walk_after_is_untouched():
    """A walk dragged 9 cm over half a second: held while the feet stand, let go while they swing;
    the frames after every foot has let go are the input's, bit for bit."""
    drag = np.zeros_like(WALK.root_pos)
    drag[:, 0] = np.clip(np.arange(WALK.num_frames) - START, 0, FRAMES) * 0.09 / FRAMES
    moved = replace(WALK, root_pos=WALK.root_pos + drag)
    held = hold_feet(moved, RIG, (START, START + FRAMES), [(START, START + FRAMES)], sole(moved))
    changed = np.flatnonzero(np.abs(held.local_rot - moved.local_rot).max(axis=(1, 2)) > 0.0)
    assert changed.size and changed[0] >= START and changed[-1] < WALK.num_frames - 30
    after = changed[-1] + 1
    assert np.array_equal(held.local_rot[after:], moved.local_rot[after:])
    for side in "lr":  # the hold eases out: its last frame is under a millimetre from the motion
        gap = np.linalg.norm(contact_points(held, side)[after - 1] - contact_points(moved, side)[after - 1])
        assert gap <= 2 * CATCH_UP_FINISH / WALK.fps


def test_a_foot_lifting_off_is_not_held_for_its_first_slow_frames():
    """The walk dragged 9 cm over half a second, faded throughout: no foot point accelerates more in
    the held walk than the fastest in the dragged walk itself (plus 5%). A foot lifting off moves
    slowly for a frame or two before it swings; held there and let go, it stood still and then
    jumped (here 162 m/s^2 against the walk's own 80): STAND_AHEAD."""
    drag = np.zeros_like(WALK.root_pos)
    drag[:, 0] = np.clip(np.arange(WALK.num_frames) - START, 0, FRAMES) * 0.09 / FRAMES
    moved = replace(WALK, root_pos=WALK.root_pos + drag)
    held = hold_feet(moved, RIG, (START, START + FRAMES), [(START, START + FRAMES)], sole(moved))
    window = slice(START - 2, START + FRAMES + 10)
    for side in "lr":
        own, kept = (point_acceleration(m, side)[window].max() for m in (moved, held))
        assert kept <= 1.05 * own, (side, kept, own)


def test_a_foot_the_fade_brings_down_fast_is_stopped_over_a_few_frames():
    """The stance dragged at up to 4.2 m/s, then at 2.4 m/s slowing evenly to a stop,
    while the sources cross-fade: a landing foot, as a fade brings one in (fast, so not held, then
    slow at once). Held from its first slow frame, it stopped from 4.2 m/s in one frame (252 m/s^2
    along the floor, the motion's own change there 108); now the hold turns it no faster than the
    motion does or LANDING_ACCEL, whichever is more, nothing sharper than the motion's own drop
    from 4.2 to 2.4 m/s, and it stands within a few frames."""
    pace = np.zeros(IDLE.num_frames)  # m per frame at the idle's 60 fps
    slowing = np.arange(0.04, 0.0, -0.005)
    pace[START : START + 12 + len(slowing)] = np.r_[np.linspace(0.01, 0.07, 7), [0.07] * 5, slowing]
    moved = replace(IDLE, root_pos=IDLE.root_pos + np.c_[np.cumsum(pace), np.zeros((IDLE.num_frames, 2))])
    held = hold_feet(moved, RIG, (START - 10, START + FRAMES), [(START - 10, START + FRAMES)], sole(moved))
    for side in "lr":
        own, kept = (np.linalg.norm(np.diff(contact_points(m, side)[:, :2], 2, axis=0), axis=1) * IDLE.fps**2
                     for m in (moved, held))  # fmt: skip
        assert (kept - np.maximum(own, LANDING_ACCEL)).max() <= 1.0, (side, kept[START - 2 : START + 12].round(1))
        assert kept.max() <= own.max() + 1.0  # nothing sharper than the motion's own drop to 2.4 m/s
        rest = contact_points(held, side)[START + 13 :, :2]  # the motion goes on 10.5 cm from here
        assert np.linalg.norm(rest - rest[0], axis=1).max() < 0.01


def point_acceleration(motion: Motion, side: str) -> np.ndarray:
    """(T - 2,) the largest acceleration of a foot's points per frame, from its second frame."""
    pos, rot = motion.global_transforms()
    points = foot_points(motion.skeleton, motion.skeleton.index(ROLES[f"ankle_{side}"]), pos, rot)
    return np.linalg.norm(points[2:] - 2 * points[1:-1] + points[:-2], axis=-1).max(axis=1) * motion.fps**2


def test_a_drag_beyond_the_hold_slides_the_feet_by_the_rest():
    """Dragged 15 cm further than the hold, the feet are held back by at most MAX_OFFSET leg lengths
    and slide the rest."""
    most = MAX_OFFSET * RIG.leg_length
    moved = dragged(most + 0.15)
    held = hold_feet(moved, RIG, (START, START + FRAMES), [(START, START + FRAMES)], sole(moved))
    for side in "lr":
        points = contact_points(held, side)
        travel = np.linalg.norm(points[START + FRAMES - 1, :2] - points[START - 1, :2])
        assert travel == pytest.approx(0.15, abs=0.01)


def test_the_hold_never_passes_its_cap_while_it_eases_a_foot_to_a_stop():
    """A standing foot dragged at 4.8 m/s for half a second, all of it taken back: the offset grows
    to the cap and stays there (beyond it the foot slides). Limiting how sharply the hold stops a
    foot (LANDING_ACCEL) once carried the offset on past the cap, to 0.47 m against 0.36."""
    steps = np.zeros((60, 2))
    steps[10:40, 0] = 0.08  # m per frame at 60 fps
    offset = _offsets(np.ones(60), steps.copy(), steps, 60.0, 0.36)
    assert np.linalg.norm(offset, axis=1).max() <= 0.36 + 1e-9
    assert np.linalg.norm(offset[40]) == pytest.approx(0.36)


def test_a_foot_a_fade_sweeps_along_the_floor_is_lifted_clear_and_eased():
    """Dragged 1.5 m in a second while the sources cross-fade, the straight-legged stance cannot hold
    its feet back and they go along at about 1.5 m/s: each is lifted clear of the floor
    (SWING_CLEARANCE) while it sweeps, eased in by at most a centimetre a frame from before the
    fade; the frames before the range are the input's, bit for bit."""
    moved = dragged(1.5)
    floor = sole(moved)
    held = hold_feet(moved, RIG, (START - 10, START + FRAMES), [(START, START + FRAMES)], floor)
    assert np.array_equal(held.local_rot[: START - 10], moved.local_rot[: START - 10])
    for side in "lr":
        before, after = contact_points(moved, side)[:, 2] - floor, contact_points(held, side)
        speed = np.r_[0.0, np.linalg.norm(np.diff(after[:, :2], axis=0), axis=1)] * IDLE.fps
        sweeping = speed > SWING_SPEED + SWING_BAND
        assert sweeping.sum() > FRAMES // 2, speed[START : START + FRAMES]
        assert (after[sweeping, 2] - floor).min() >= SWING_CLEARANCE - 1e-6
        assert before[sweeping].max() < 0.01  # the motion had the foot on the floor
        assert np.abs(np.diff(after[:, 2])).max() <= 0.0101


@pytest.fixture(scope="module")
def reactions():
    library = load_library(REPO / "sample_clips")
    classifier = load_classifier(REPO / "reactive_anim" / "models" / "reaction_classifier.onnx")
    ragdoll = character_ragdoll(WALK)
    out = []
    for frame, role, towards, strength in [(100, "chest", "front", 80.0), (120, "head", "behind", 50.0),
                                           (130, "pelvis", "left", 90.0)]:  # fmt: skip
        forward, left = ground_axes(WALK, frame)
        direction = {"front": -forward, "behind": forward, "left": -left}[towards]
        impact = Impact(frame, ROLES[role], tuple(direction), strength)
        out.append(
            [
                react(WALK, impact, library, classifier, ReactionSettings(hold_feet=hold), ragdoll=ragdoll)
                for hold in (False, True)
            ]
        )
    return out


def test_reactions_on_the_walk_slide_their_feet_less_than_half_as_far(reactions):
    """Measured over B..F + 20 frames (the simulation, the fade into the clip, its first steps) on
    three pushes: 198 cm without the hold, 81 cm with it when written (most of it in BC, the
    simulation's own slip under the shove, which the hold leaves)."""
    floor = float(np.min([contact_points(WALK, side)[:, 2] for side in "lr"]))
    without = sum(sliding(r.motion, round(r.frame_b), r.frame_f + 20, floor) for r, _ in reactions)
    held = sum(sliding(r.motion, round(r.frame_b), r.frame_f + 20, floor) for _, r in reactions)
    assert held < 0.5 * without, (held, without)
    for free, kept in reactions:  # the hold changes the feet, not what was chosen
        assert (kept.reaction_class, kept.clip, kept.jump_frame) == (free.reaction_class, free.clip, free.jump_frame)


def test_no_foot_goes_through_the_floor_in_a_reaction(reactions):
    """The floor is the lowest the walk's feet get (casting.Casting.sole)."""
    floor = sole(WALK)
    for _, kept in reactions:
        lowest = np.min([contact_points(kept.motion, side)[round(kept.frame_b) :, 2] for side in "lr"])
        assert lowest > floor - 0.001, (lowest, floor)
    assert (
        min(np.min([contact_points(free.motion, side)[:, 2] for side in "lr"]) for free, _ in reactions) < floor - 0.01
    )


def test_a_hand_under_the_floor_is_lifted_onto_it_keeping_its_turn():
    """The idle sunk 0.75 m over the drag's frames: the hanging hands' fingers up to about 10 cm under
    the floor (within LIMB_LIFT_MOST)."""
    sunk = replace(IDLE, root_pos=IDLE.root_pos - np.array([0.0, 0.0, 0.75]) * _drag_rows()[:, None])
    floor = sole(IDLE)
    index = IDLE.skeleton.index
    wrists = [index(ROLES[f"wrist_{s}"]) for s in "lr"]
    shoulders = [index(ROLES[f"shoulder_{s}"]) for s in "lr"]
    pos, glob = sunk.global_transforms()
    rows = slice(START, START + FRAMES)
    lowest = np.stack([_lowest_of_hand(sunk, s)[rows] for s in "lr"])
    assert lowest.max() < floor and lowest.min() > floor - LIMB_LIFT_MOST  # the pose the test needs
    held = hold_feet(sunk, RIG, (START, START + FRAMES), [], floor)
    new_pos, new_glob = held.global_transforms()
    assert min(_lowest_of_hand(held, s)[rows].min() for s in "lr") > floor - 1e-6
    assert np.allclose(new_pos[rows][:, wrists, :2], pos[rows][:, wrists, :2], atol=1e-6)  # lifted straight up
    assert np.allclose(new_pos[rows][:, shoulders], pos[rows][:, shoulders], atol=1e-6)
    assert np.allclose(quat.angle_between(new_glob[rows][:, wrists], glob[rows][:, wrists]), 0.0, atol=1e-6)
    assert np.array_equal(held.local_rot[:START], sunk.local_rot[:START])


def test_a_foot_deep_in_the_floor_is_lifted_by_the_leg_only_so_far_and_the_body_takes_the_rest():
    """The idle sunk 0.3 m into the floor, eased over 20 frames (a fade of a thrown body into a
    kneeling clip put a foot that deep): the legs lift the feet by LIMB_LIFT_MOST at most (lifting
    it all, a knee folded up over the hip and dropped 70 cm in three frames), and the body's lift
    (lift_onto_floor) brings every foot point onto the floor."""
    depth = 0.3 * np.clip((np.arange(IDLE.num_frames) - START) / 20.0, 0.0, 1.0)
    sunk = replace(IDLE, root_pos=IDLE.root_pos - np.c_[np.zeros((IDLE.num_frames, 2)), depth])
    floor, frames = sole(IDLE), (START - 10, IDLE.num_frames)
    held = hold_feet(sunk, RIG, frames, [], floor)
    raised = held.global_positions() - sunk.global_positions()
    ankles = [RIG.joints[f"ankle_{side}"] for side in "lr"]
    assert raised[:, ankles, 2].max() == pytest.approx(LIMB_LIFT_MOST, abs=0.005)
    lifted = lift_onto_floor(held, frames, floor)
    for side in "lr":
        assert contact_points(lifted, side)[START - 10 :, 2].min() > floor - 1e-6


def test_a_hand_deep_in_the_floor_is_lifted_by_the_arm_only_so_far_and_the_body_takes_the_rest():
    """The idle sunk 1.1 m, eased over 20 frames, its hanging hands about 45 cm under the floor (a
    fade swung an arm that deep beside a shoulder lying on the floor: lifting it all, the elbow
    folded shut for a frame): the arms lift the hands by LIMB_LIFT_MOST at most, and the body's
    lift brings every hand point onto the floor."""
    depth = 1.1 * np.clip((np.arange(IDLE.num_frames) - START) / 20.0, 0.0, 1.0)
    sunk = replace(IDLE, root_pos=IDLE.root_pos - np.c_[np.zeros((IDLE.num_frames, 2)), depth])
    floor, frames = sole(IDLE), (START - 10, IDLE.num_frames)
    assert min(_lowest_of_hand(sunk, s).min() for s in "lr") < floor - 2 * LIMB_LIFT_MOST  # the pose the test needs
    held = hold_feet(sunk, RIG, frames, [], floor)
    wrists = [IDLE.skeleton.index(ROLES[f"wrist_{s}"]) for s in "lr"]
    raised = held.global_positions()[:, wrists, 2] - sunk.global_positions()[:, wrists, 2]
    assert raised.max() == pytest.approx(LIMB_LIFT_MOST, abs=0.005)
    lifted = lift_onto_floor(held, frames, floor)
    for side in "lr":
        assert _lowest_of_hand(lifted, side)[START - 10 :].min() > floor - 1e-6


def _drag_rows() -> np.ndarray:
    """(T,) 1 on the drag's frames, else 0."""
    rows = np.zeros(IDLE.num_frames)
    rows[START : START + FRAMES] = 1.0
    return rows


def test_a_hand_the_motion_has_under_the_floor_at_the_hit_keeps_that_depth():
    """Sunk before the hold starts (row 0 of the hold, the hit, already under): nothing to jump
    from. The hands are left as they are where no deeper than there, and lifted to that depth where
    the idle's sway takes them deeper."""
    sunk = replace(IDLE, root_pos=IDLE.root_pos - np.array([0.0, 0.0, 0.85]) * _drag_rows()[:, None])
    held = hold_feet(sunk, RIG, (START + 5, START + FRAMES), [], sole(IDLE))
    rows = slice(START + 4, START + FRAMES)
    raw = np.stack([_lowest_of_hand(sunk, s)[rows] for s in "lr"], axis=1)
    out = np.stack([_lowest_of_hand(held, s)[rows] for s in "lr"], axis=1)
    at_hit = raw[0]
    assert np.all(raw < sole(IDLE)) and (raw < at_hit - 0.003).any()  # the pose the test needs
    assert np.all(out > at_hit - 1e-9) and np.all(out < at_hit + 1e-9)  # lifted to the hit's depth only
    kept = raw >= at_hit
    assert np.allclose(out[kept], raw[kept], atol=1e-9)


def _lowest_of_hand(motion: Motion, side: str) -> np.ndarray:
    """(T,) the lowest point of a hand: the wrist, the joints below it and their end sites."""
    pos, rot = motion.global_transforms()
    return lowest_foot_point(motion.skeleton, motion.skeleton.index(ROLES[f"wrist_{side}"]), pos, rot)


def test_a_body_sunk_into_the_floor_is_lifted_onto_it_eased_in_and_out():
    """The idle dropped 0.3 m into the floor over the drag's frames, from one frame to the next (as a
    fade through a roll's headstand, only worse): every joint and end site is lifted onto the floor,
    the root only moves up, by an eased lift (its acceleration about the depth over LIFT_EASE
    squared, where the drop itself is 0.3 m in a frame), and the frames before the hold stay."""
    sunk = replace(IDLE, root_pos=IDLE.root_pos - np.array([0.0, 0.0, 0.3]) * _drag_rows()[:, None])
    floor, first = sole(IDLE), START - 20
    pos = sunk.global_positions()
    assert pos[START + FRAMES // 2, :, 2].min() < floor - 0.2  # the pose the test needs
    lifted = lift_onto_floor(sunk, (first, IDLE.num_frames), floor)
    new = lifted.global_positions()
    assert new[first:, :, 2].min() > floor - 1e-9
    assert np.array_equal(lifted.root_pos[:first], sunk.root_pos[:first])
    assert np.array_equal(lifted.local_rot, sunk.local_rot)
    lift = lifted.root_pos[:, 2] - sunk.root_pos[:, 2]
    assert np.all(lift >= 0.0) and np.allclose(lifted.root_pos[:, :2], sunk.root_pos[:, :2])
    accel = np.abs(np.diff(lift, 2)).max() * IDLE.fps**2
    assert accel < 4.0 * 0.3 / LIFT_EASE**2 < 0.3 * IDLE.fps**2 / 4, accel
    assert lift[first] == 0.0 and lift[-1] == 0.0  # eased back out after the drop
