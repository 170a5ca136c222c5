"""Planted feet stay planted across a reaction's seams, and feet and hands stay out of the floor.

A reaction is stitched from sources whose feet stand in different places: the ragdoll's simulated
steps, the clip faded in over C..F (blend.py), the original motion faded back in on resume. Where
two sources cross-fade while a foot is on the floor, the foot slides from one footprint to the
other; the fade slides a standing foot far more than the simulation does (docs/measurements.md).

Where the sources cross-fade (`fades`: C..F, a chained get-up fading in, the resume; react.py also
passes B..C, where the ragdoll's soles creep under the push), the part of
a standing foot's motion along the floor is taken back by an offset, which the leg's two-bone IK
adds to the ankle (the foot keeps its orientation). Outside the fades the motion's own steps play
as they are (a clip's or a get-up's drawn-up heel is meant to slide) and the offset is only carried:
kept while the foot stands, let go in the air (CATCH_UP_RATE), so the next footprint lands
where the motion puts it. A foot the fade carries fast along the floor (a swing faded into a
stance) is not held but lifted clear of it, as a step would (_swing_lift): measured, most of
what the fades slid was such sweeps (docs/measurements.md). The hold runs on until every offset
is let go (a foot that never lifts keeps it to the end of the motion). A foot stands by ramps,
not thresholds (see _sliding), so a millimetre's difference in the motion moves the result by
little, and the hold stops a foot no more sharply than LANDING_ACCEL (a foot a fade brings in
fast lands over a few frames, not in one). Where a leg cannot reach, the offset is capped
(MAX_OFFSET) and the foot slides the rest.
From the impact to the end of the reaction, a foot whose lowest point is under the character's
floor (the lowest its feet get in its own motion) is also lifted onto it: the ragdoll's soles and
the skeleton's toes do not quite agree, and toes went centimetres under the floor in transitions.
That lift is eased in and out over SWING_EASE like the swing's: dropped in the frame a foot rose
out of the floor by itself, it turned a knee from 1 to 11 rad/s in a frame at C. The leg lifts a
foot by LIMB_LIFT_MOST at most; the body's lift below takes the rest. A hand under the
floor there is lifted onto it by the arm's IK, as a foot is, and as far: a fade between two poses
whose hands both clear the floor can pass one under it, and a clip cast onto longer arms puts the
hands a few cm under (docs/measurements.md). Knees a fade puts under the floor cannot be lifted so:
with the hip and the ankle where they are, a kneeling knee at the bottom of its circle about them can only
move sideways, by far more than its depth. What is still under the floor after the feet and hands
(a knee, a head through a fade of a roll, a kneeling clip cast onto longer shins) lifts the whole
body instead (lift_onto_floor), eased in and out so the lift adds no pop.
"""

from __future__ import annotations

import math

import numpy as np

from ..model.arrays import BoolArray, FloatArray
from ..model.floor import on_floor
from ..model.rig import Rig
from ..model.roles import SIDES
from ..model.skeleton import Motion, Skeleton, root_child
from .ik import joint_path, two_bone_ik
from .retarget import foot_points, local_rotations, lowest_foot_point

LOWEST_SCALE = 0.003  # m: a foot point this much higher than its lowest counts 1/e as much for the slide
SKIM_SPEED = 3.5  # m/s: a point faster than this does not stand, fully below ...
SPEED_BAND = 1.0  # ... this much slower (a swing foot moves at 3-5 m/s; a blend slides it at 0.5-2.5)
# s: a point stands in a step only if it stays slow for the next round(STAND_AHEAD * fps) steps too
# (2 at 30 fps, 3 at 60). A foot lifting off moves slowly for a frame or two, then fast: held in
# those frames and let go, it stood still, then jumped 15 cm in one frame (a toe at 142 m/s^2 at C,
# docs/measurements.md)
STAND_AHEAD = 0.05
CATCH_UP_RATE = 7.0  # 1/s: in the air an offset shrinks by this fraction a second, smoothly (143 ms time constant) ...
CATCH_UP_FINISH = 0.05  # m/s: ... and by this much more, so it ends (the last step is under a millimetre)
SOFT_REACH = 0.95  # of a leg's length: a held foot asking more of it reaches less, smoothly (_eased_reach)
# leg lengths a foot is held away from where the motion puts it; beyond, it slides. A fade from a
# walking stride into a clip's standing start or a side step's wide stance moves a foot that far;
# a held foot costs some joint acceleration when it is let go (docs/measurements.md)
MAX_OFFSET = 0.4
# m/s over the ground, held: a foot a fade still moves faster than this along the floor is lifted ...
# (at 1.0 m/s with a 0.5 band, fades slid planted feet up to 8.8 cm at 0.5-0.9 m/s, under the lift,
# the hold letting them go as the fade swept them at 2-3 m/s; at 0.4, a held foot the leg could
# no longer reach slid 5.2 cm at 0.3 m/s just before it lifted: docs/measurements.md)
SWING_SPEED = 0.25
# m/s^2: the hold changes a foot's velocity over the ground at most this fast (or as fast as the
# motion itself does). A held foot the fade brought down at 4 m/s was stopped in one frame: a toe
# at 126 m/s^2 (kept runs; over the walks' largest in 57 of 272 40 N·s pushes on runs where the
# unpushed run was not). At 40, the same within a point; docs/measurements.md
LANDING_ACCEL = 60.0
SWING_BAND = 0.3  # ... fully from this much faster (a held foot moves at a few cm/s; a swing at 3-5 m/s) ...
SWING_CLEARANCE = 0.04  # m: ... to this over the floor (above model/floor.py's ramp: it no longer stands) ...
SWING_EASE = 0.08  # s: ... eased in and out over this either side (a foot's lift onto the floor too)
# m: the most the leg lifts a foot (the arm a hand) out of the floor (a sweep's SWING_CLEARANCE may
# come on top); deeper, the body is lifted (lift_onto_floor). A fade from a body the push threw flat
# into a kneeling clip put a foot 30 cm under the floor: the leg lifting it all folded the knee up
# over the hip and dropped it 70 cm in three frames (240 m/s^2; four of the reactions over the real
# falls' largest). An arm lifting a hand 29 cm onto the floor beside a shoulder on it folded the
# elbow shut for a frame (214 m/s^2), and the body's lift raised the shoulder that much after it
# (docs/measurements.md)
LIMB_LIFT_MOST = 0.15
UP = np.array([0.0, 0.0, 1.0])
SETTLE = 1.0  # s after the reaction first looked at for the offsets to be let go (a walker's feet lift in it)
LIFT_EASE = 0.15  # s over which the body is lifted onto the floor before and after the deepest frame
LIFT_MIN = 0.002  # m: less under the floor than this is left as it is


def hold_feet(motion: Motion, rig: Rig, frames: tuple[int, int], fades: list[tuple[int, int]], floor: float) -> Motion:
    """`motion` with its feet held (see the module docstring) from frame `first` on, frames =
    (first, last): slides taken back within `fades` (frame ranges [a, b)) and carried until let go,
    looking at least to `last` plus SETTLE; feet and hands lifted out of the floor over
    first..last - 1. Frames before `first` and after the hold are untouched, bit for bit. rig: the
    motion's (hips, knees, ankles, shoulders, elbows, wrists, pelvis and chest are read); floor: the
    height of the character's lowest foot point in its own motion (casting.Casting.sole)."""
    first, last = max(frames[0], 1), min(frames[1], motion.num_frames)
    if last - first < 2:
        return motion
    end = min(motion.num_frames, last + round(SETTLE * motion.fps))
    while True:
        held = _hold(motion, rig, (first, last, end), fades, floor)
        if held is None or end == motion.num_frames or not held[1]:
            break
        end = min(motion.num_frames, end + (end - first))  # a foot still held: look further
    if held is None:
        return motion
    glob, _, moved = held
    return _with_limbs(motion, glob, moved, first)


def _hold(
    motion: Motion,
    rig: Rig,
    frames: tuple[int, int, int],
    fades: list[tuple[int, int]],
    floor: float,
) -> tuple[FloatArray, bool, list[tuple[list[int], BoolArray]]] | None:
    """The global rotations over first - 1..end - 1 with the feet held and feet and hands out of the
    floor, whether a foot is still held at end - 1, and per limb turned its joints and the rows
    it turned; None where nothing moves."""
    first, last, end = frames
    span = motion.slice(first - 1, end)  # one frame before: where the first frame's foot came from
    skeleton = span.skeleton
    pos, glob = span.global_transforms()
    joint = rig.joints
    left = pos[:, joint["hip_l"]] - pos[:, joint["hip_r"]]
    forward = np.cross(left, pos[:, joint["chest"]] - pos[:, joint["pelvis"]])
    points = {side: foot_points(skeleton, joint[f"ankle_{side}"], pos, glob) for side in SIDES}
    fading = np.zeros(len(pos) - 1, dtype=bool)  # per step into frame first + i
    for a, b in fades:
        fading[max(a - first, 0) : max(b - first, 0)] = True
    leg = rig.leg_length
    moved: list[tuple[list[int], BoolArray]] = []
    still_held = False
    reaction = np.zeros(len(pos), dtype=bool)  # the frames lifted out of the floor: first..last - 1
    reaction[1 : last - first + 1] = True  # (after the reaction the motion is its own)
    ease = max(2, round(SWING_EASE * motion.fps))
    for side in SIDES:
        ankle = joint[f"ankle_{side}"]
        down, slide = _sliding(points[side], floor, motion.fps)
        steps = np.diff(pos[:, ankle, :2], axis=0)
        offset = _offsets(down, np.where(fading[:, None], slide, 0.0), steps, motion.fps, MAX_OFFSET * leg)
        sunk = np.minimum(np.maximum(floor - points[side][..., 2].min(axis=1), 0.0), LIMB_LIFT_MOST)
        lift = _eased_lift(np.where(reaction, sunk, 0.0), ease)
        lift += _swing_lift(points[side] + lift[:, None, None] * UP, offset, fading, floor, ease, motion.fps)
        moves = (np.abs(offset).max(axis=1) > 1e-6) | (lift > 1e-6)
        still_held = still_held or bool(np.abs(offset[-1]).max() > 1e-6)
        if not moves.any():
            continue
        goal = pos[:, ankle].copy()
        goal[:, :2] += offset
        goal[:, 2] += lift
        chain = (joint[f"hip_{side}"], joint[f"knee_{side}"], ankle)
        goal = _eased_reach(goal, *(pos[:, j] for j in chain))
        two_bone_ik(skeleton, pos, glob, chain, goal, moves.astype(np.float64), left, forward)
        moved.append((joint_path(skeleton, chain[0], ankle), moves))
    moved += _hands_out_of_the_floor(skeleton, pos, glob, joint, (left, forward), reaction, floor)
    return (glob, still_held, moved) if moved else None


def _hands_out_of_the_floor(
    skeleton: Skeleton,
    pos: FloatArray,
    glob: FloatArray,
    joint: dict[str, int],
    axes: tuple[FloatArray, FloatArray],
    rows: BoolArray,
    floor: float,
) -> list[tuple[list[int], BoolArray]]:
    """Per arm whose hand (the wrist, the joints below it and their end sites) a fade or a cast clip
    put through the floor on `rows`, its joints and the rows turned (in place on pos and glob): the hand lifted
    straight up onto the floor by the arm's two-bone IK, as a foot is (an elbow bends the other way
    from a knee: the body's axes turned round), keeping its turn in the world. A hand the motion
    already has under the floor at the hit (row 0) keeps that depth, so nothing jumps there. axes:
    the body's left and forward per frame."""
    left, forward = axes
    moved: list[tuple[list[int], BoolArray]] = []
    for side in SIDES:
        chain = (joint[f"shoulder_{side}"], joint[f"elbow_{side}"], joint[f"wrist_{side}"])
        wrist = chain[2]
        lowest = lowest_foot_point(skeleton, wrist, pos, glob)  # a hand's points as a foot's: fingers, tips
        need = np.where(rows, np.clip(min(floor, float(lowest[0])) - lowest, 0.0, LIMB_LIFT_MOST), 0.0)
        turned = need > 1e-6
        if turned.any():
            goal = pos[:, wrist].copy()
            goal[:, 2] += need
            goal = _eased_reach(goal, *(pos[:, j] for j in chain))
            two_bone_ik(skeleton, pos, glob, chain, goal, turned.astype(np.float64), -left, -forward)
            moved.append((joint_path(skeleton, chain[0], wrist), turned))
    return moved


def _eased_reach(goal: FloatArray, hip: FloatArray, knee: FloatArray, ankle: FloatArray) -> FloatArray:
    """The goals (T, 3) pulled in where they would straighten the limb past SOFT_REACH of its length
    (or past the motion's own stretch, where that is more): the last few per cent of a knee's (an
    elbow's) extension turn it fast for a small move of the foot, which shows as a kick of the knee;
    eased, the foot falls a little short and slides that much instead. Continuous: a goal at the
    motion's own ankle is left where it is."""
    length = np.linalg.norm(knee - hip, axis=-1) + np.linalg.norm(ankle - knee, axis=-1)
    start = np.maximum(SOFT_REACH * length, np.linalg.norm(ankle - hip, axis=-1))
    room = np.maximum(length - start, 1e-6)
    distance = np.linalg.norm(goal - hip, axis=-1)
    beyond = np.maximum(distance - start, 0.0)  # zero where the goal is within reach: exp stays finite
    eased = np.where(distance > start, start + room * (1.0 - np.exp(-beyond / room)), distance)
    return hip + (goal - hip) * (eased / np.maximum(distance, 1e-9))[:, None]


def _with_limbs(motion: Motion, glob: FloatArray, limbs: list[tuple[list[int], BoolArray]], first: int) -> Motion:
    """`motion` with each limb's local rotations taken from `glob` (rows from frame first - 1) on
    the rows it was turned (the others stay the input's, bit for bit), each on the same side of
    the quaternion sphere as the rotation it replaces."""
    local = local_rotations(motion.skeleton, glob)
    local_rot = motion.local_rot.copy()
    for joints, rows in limbs:
        turned = np.flatnonzero(rows)
        new, old = local[turned][:, joints], local_rot[first - 1 + turned][:, joints]
        local_rot[(first - 1 + turned)[:, None], joints] = np.where(np.sum(new * old, -1, keepdims=True) < 0, -new, new)
    return Motion(skeleton=motion.skeleton, fps=motion.fps, root_pos=motion.root_pos, local_rot=local_rot,
                  local_pos=motion.local_pos)  # fmt: skip


def _sliding(points: FloatArray, floor: float, fps: float) -> tuple[FloatArray, FloatArray]:
    """From a foot's points (T, P, 3), per frame from the second: how much it is on the floor (0..1,
    by height: model/floor.py) and the slide to take back (T - 1, 2), counted as much as the foot
    stands: on the floor and slow (a swing foot skimming the floor is fast), and staying slow for
    STAND_AHEAD (a foot lifting off is not held for its first slow frames). Ramps rather than
    thresholds, so a millimetre more or less changes the result by little; a foot rolling from heel
    to toe stands on the point that stays."""
    height = points[..., 2]
    firm = on_floor(height, floor)  # (T, P)
    step = np.diff(points[..., :2], axis=0)  # (T - 1, P, 2)
    slow = np.clip((SKIM_SPEED - np.linalg.norm(step, axis=-1) * fps) / SPEED_BAND, 0.0, 1.0)
    ahead = round(STAND_AHEAD * fps)  # a foot about to swing does not stand: see STAND_AHEAD
    slow = np.lib.stride_tricks.sliding_window_view(np.pad(slow, ((0, ahead), (0, 0)), mode="edge"), ahead + 1, 0)
    slow = slow.min(axis=-1)
    weight = np.minimum(firm[1:], firm[:-1]) * slow
    # The slide is the lowest point's: a point a few millimetres higher (the ball as the heel of a
    # toe-off rises) counts for little, so a roll is not taken for a slide.
    low = np.exp(-(height[1:] - height[1:].min(axis=1, keepdims=True)) / LOWEST_SCALE)
    share = weight * low
    slide = (share[..., None] * step).sum(axis=1) / np.maximum(share.sum(axis=1), 1e-12)[:, None]
    return firm[1:].max(axis=1), weight.max(axis=1)[:, None] * slide


def _swing_lift(
    points: FloatArray, offset: FloatArray, fading: BoolArray, floor: float, ease: int, fps: float
) -> FloatArray:
    """(T,) how far to raise a foot (points (T, P, 3), held by `offset`) that a fade sweeps fast
    along the floor (`fading`: per step into frame 1..T - 1): its lowest point lifted to
    SWING_CLEARANCE over the floor (raised by that much at most) as its speed over the ground
    passes SWING_SPEED, eased in and out over `ease` frames (SWING_EASE). Two sources cross-faded
    while one swings a foot and the other stands on it carry the foot forward at walking speed but
    at the standing foot's height: the sweep reads as a skate, and lifted clear it reads as the
    step it is. The points come already lifted onto the floor (this lift goes on top); row 0 (the
    frame before) stays."""
    height = points[..., 2]
    high = np.maximum(height[1:], height[:-1])  # the point that stays lowest over a step (a roll is no sweep)
    rows, k = np.arange(len(high)), np.argmin(high, axis=1)
    ground = points[..., :2] + offset[:, None]
    speed = np.linalg.norm(ground[1:][rows, k] - ground[:-1][rows, k], axis=-1) * fps
    sweeping = np.clip((speed - SWING_SPEED) / SWING_BAND, 0.0, 1.0) * fading
    need = np.zeros(len(points))
    need[1:] = sweeping * np.clip(floor + SWING_CLEARANCE - height[1:].min(axis=1), 0.0, SWING_CLEARANCE)
    return _eased_lift(need, ease)


def _eased_lift(need: FloatArray, ease: int) -> FloatArray:
    """A foot's lift per frame (T,), at least `need`, eased over `ease` frames (_eased); row 0, the
    frame before the range, stays. Nothing to lift costs nothing (most frames of most feet)."""
    if need.max() <= 0.0:
        return need
    lift = _eased(need, ease)
    lift[0] = 0.0
    return lift


def _offsets(down: FloatArray, slide: FloatArray, steps: FloatArray, fps: float, most: float) -> FloatArray:
    """(T, 2) the ankle's ground offset per frame (row 0, the frame before the range, is zero): the
    slide taken back, at most `most` (m; beyond, the foot slides: MAX_OFFSET); let go in the air
    (1 - down) at CATCH_UP_RATE, fast while it is large and slowing as it shrinks, so the foot
    eases onto the motion's path instead of stopping short on it; never changing the foot's
    velocity over the ground faster than the motion does (`steps`: the ankle's own steps over the
    ground, (T - 1, 2)) or LANDING_ACCEL, whichever is more (_landing). Each frame's offset follows
    from the one before, so the loop runs on Python complex numbers (x + iy), not 2-vectors: a
    quarter of a reaction's time went to numpy's per-call overhead here."""
    slides, moves, downs = _complex(slide), _complex(steps), down.tolist()
    decay, finish, landing = CATCH_UP_RATE / fps, CATCH_UP_FINISH / fps, LANDING_ACCEL / fps**2
    offset = [0j] * (len(slides) + 1)
    for t in range(1, len(offset)):
        held = offset[t - 1] - slides[t - 1]
        size = abs(held)
        if size > 0.0:
            air = 1.0 - downs[t - 1]
            held *= max(0.0, size * math.exp(-air * decay) - air * finish) / size
        if t >= 2:
            held = _landing(held, (offset[t - 2], offset[t - 1]), (moves[t - 2], moves[t - 1]), landing)
        offset[t] = held * min(1.0, most / max(abs(held), 1e-12))  # the cap last: beyond it, the foot slides
    values = np.array(offset)
    return np.stack([values.real, values.imag], axis=1)


def _complex(xy: FloatArray) -> list[complex]:
    """Rows (x, y) of `xy` (N, 2) as x + iy."""
    return (xy[:, 0] + 1j * xy[:, 1]).tolist()


def _landing(held: complex, before: tuple[complex, complex], steps: tuple[complex, complex], most: float) -> complex:
    """The offset `held` into a frame moved back toward the step it continues so that the foot's step into
    the frame differs from its step into the frame before by at most `most` (m per frame per
    frame) or by what the motion's own steps differ, whichever is more: a foot the fade brings down
    fast is then stopped over two or three frames, a few cm further on, as a landing foot is,
    rather than in one. before: the offsets into the two frames before; steps: the motion's steps
    into the frame before and into this one (all as x + iy)."""
    change = steps[1] - steps[0] + held - 2.0 * before[1] + before[0]
    size = abs(change)
    allowed = max(abs(steps[1] - steps[0]), most)
    return held if size <= allowed else held - change * (1.0 - allowed / size)


def lift_onto_floor(motion: Motion, frames: tuple[int, int], floor: float) -> Motion:
    """`motion` with the root raised wherever a joint or end site is under `floor` on frames
    [first, last), by at least that depth: the depth's running maximum over LIFT_EASE either side,
    smoothed, so the lift eases in and out (a lift of d over LIFT_EASE accelerates the body by
    about d / LIFT_EASE^2: 4 m/s^2 for 10 cm) and a knee on the floor stays on it rather than
    sinking. The lift may run on up to LIFT_EASE past `last` (easing out), never before `first`;
    a ground root bone (root_child) is not the body and does not count."""
    first, last = max(frames[0], 0), min(frames[1], motion.num_frames)
    if last <= first:
        return motion
    depth = np.zeros(motion.num_frames)
    depth[first:last] = np.maximum(floor - _lowest_points(motion.slice(first, last)), 0.0)
    if depth.max() < LIFT_MIN:
        return motion
    lift = _eased(depth, max(2, round(LIFT_EASE * motion.fps)))
    lift[:first] = 0.0
    root = motion.root_pos.copy()
    root[:, 2] += lift
    return Motion(motion.skeleton, motion.fps, root, motion.local_rot, motion.local_pos)


def _eased(values: FloatArray, reach: int) -> FloatArray:
    """At least `values` everywhere, eased in and out over `reach` frames either side: the running
    maximum over 2 reach + 1 frames, smoothed by two boxes that stay within its plateaus."""
    held = np.lib.stride_tricks.sliding_window_view(np.pad(values, reach, mode="edge"), 2 * reach + 1).max(axis=1)
    return _box(_box(held, reach // 2), reach // 2)


def _box(values: FloatArray, half: int) -> FloatArray:
    """The running mean over 2 half + 1 frames, the ends held."""
    return np.convolve(np.pad(values, half, mode="edge"), np.ones(2 * half + 1) / (2 * half + 1), mode="valid")


def _lowest_points(motion: Motion) -> FloatArray:
    """(T,) the height of the lowest joint or end site per frame, a ground root bone left out."""
    pos, rot = motion.global_transforms()
    return lowest_foot_point(motion.skeleton, root_child(motion.skeleton) or 0, pos, rot)
