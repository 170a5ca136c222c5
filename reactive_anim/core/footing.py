"""Planted feet stay planted across a reaction's seams.

A reaction is stitched from sources whose feet stand in different places: the ragdoll's simulated
steps, the clip faded in over C..F (blend.py), the original motion faded back in on resume. Where
two sources cross-fade while a foot is on the floor, the foot slides from one footprint to the
other. Measured on nine pushes of the sample walk (contact point of a touching foot, summed over
C..F): 237 cm, of which the simulation itself slid 87 cm; the fade is the rest.

From the impact on, a foot on the floor keeps its footprint. Each frame the touching foot's
contact point (its lowest point: heel, ball or toe) moves along the floor is taken back by an
offset, which the leg's two-bone IK adds to the ankle (the foot keeps its orientation). A foot that
rolls from heel to toe is not sliding: the frame its lowest point changes keeps the offset. While
the foot is in the air the offset is let go at up to CATCH_UP_SPEED, so the next footprint lands
where the motion puts it; what is still left near the end of the range is let go over RELEASE
frames. Where a leg cannot reach, the IK stretches it straight and the foot slides the rest.
"""

from __future__ import annotations

import numpy as np

from . import quat
from .retarget import foot_points, joint_path, leg_length, two_bone_ik
from .skeleton import Motion

CONTACT_HEIGHT = 0.03  # m over the floor: a foot point lower than this stands on it, fully from ...
CONTACT_BAND = 0.02  # ... this much lower (toe clearance in a walk's swing is about 1.5 cm)
LOWEST_SCALE = 0.003  # m: a foot point this much higher than its lowest counts 1/e as much for the slide
SKIM_SPEED = 3.5  # m/s: a point faster than this does not stand, fully below ...
SPEED_BAND = 1.0  # ... this much slower (a swing foot moves at 3-5 m/s; a blend slides it at 0.5-2.5)
CATCH_UP_SPEED = 2.0  # m/s of extra foot travel while in the air (a walk's swing foot moves at 3-5 m/s)
MAX_OFFSET = 0.15  # leg lengths a foot is held away from where the motion puts it; beyond, it slides
FLOOR_PERCENTILE = 2.0  # not the minimum: one frame's dip through the floor must not sink it
FLOOR_SECONDS = 2.0  # of motion before the impact read for the floor
MIN_FLOOR_FRAMES = 10  # fewer frames before the impact: the floor is read over the range itself
SETTLE = 1.0  # s after the stitched part over which a hold is let go (the feet are in the air for part of it)
RELEASE = 10  # frames over which an offset left at the end of the range is let go
SIDES = ("l", "r")


def hold_feet(motion: Motion, roles: dict[str, str], first: int, last: int) -> Motion:
    """`motion` with its feet held to their footprints over frames first..last - 1, the stitched
    part (see the module docstring), and what is left of the hold let go over the SETTLE seconds
    after (the motion there, such as a resumed walk, is clean: its own slides are not taken back);
    frames outside are untouched, bit for bit. roles: role -> joint name (hip_l, knee_l, ankle_l,
    ... pelvis, chest). The floor is where the feet rest: a low percentile of the lower foot's
    lowest point (a foot is on the floor nearly all the time) before `first`."""
    first, stitched = max(first, 1), min(last, motion.num_frames) - max(first, 1)
    last = min(motion.num_frames, first + stitched + round(SETTLE * motion.fps))
    if stitched < 2:
        return motion
    span = motion.slice(first - 1, last)  # one frame before: where the first frame's foot came from
    skeleton = span.skeleton
    joint = {role: skeleton.index(name) for role, name in roles.items()}
    pos, glob = span.global_transforms()
    left = pos[:, joint["hip_l"]] - pos[:, joint["hip_r"]]
    forward = np.cross(left, pos[:, joint["chest"]] - pos[:, joint["pelvis"]])
    points = {side: foot_points(skeleton, joint[f"ankle_{side}"], pos, glob) for side in SIDES}
    floor = _floor(motion, joint, first) if first >= MIN_FLOOR_FRAMES else _lower_foot(points, FLOOR_PERCENTILE)
    leg = leg_length(skeleton, roles)
    moved: list[int] = []
    for side in SIDES:
        ankle = joint[f"ankle_{side}"]
        down, slide = _sliding(points[side], floor, motion.fps)
        slide[stitched:] = 0.0  # clean motion: its own slides stay
        offset = _offsets(down, slide, motion.fps, MAX_OFFSET * leg)
        if not np.abs(offset).max(initial=0.0) > 1e-6:
            continue
        goal = pos[:, ankle].copy()
        goal[:, :2] += offset
        weight = (np.abs(offset).max(axis=1) > 1e-6).astype(float)
        chain = (joint[f"hip_{side}"], joint[f"knee_{side}"], ankle)
        two_bone_ik(skeleton, pos, glob, chain, goal, weight, left, forward)
        moved += joint_path(skeleton, chain[0], ankle)
    if not moved:
        return motion
    return _with_legs(motion, glob[1:], moved, first, last)


def _with_legs(motion: Motion, glob: np.ndarray, joints: list[int], first: int, last: int) -> Motion:
    """`motion` with the local rotations of `joints` over first..last - 1 taken from global ones,
    each on the same side of the quaternion sphere as the rotation it replaces."""
    parents = motion.skeleton.parents[joints]
    local = quat.normalize(quat.mul(quat.conj(glob[:, parents]), glob[:, joints]))
    old = motion.local_rot[first:last, joints]
    local_rot = motion.local_rot.copy()
    local_rot[first:last, joints] = np.where(np.sum(local * old, axis=-1, keepdims=True) < 0.0, -local, local)
    return Motion(skeleton=motion.skeleton, fps=motion.fps, root_pos=motion.root_pos, local_rot=local_rot,
                  local_pos=motion.local_pos)  # fmt: skip


def _floor(motion: Motion, joint: dict[str, int], first: int) -> float:
    """Where the feet rest in the motion's last FLOOR_SECONDS before `first` (a reaction's feet may
    dip through the floor, so the floor is read before it)."""
    before = motion.slice(max(0, first - round(FLOOR_SECONDS * motion.fps)), first)
    pos, glob = before.global_transforms()
    points = {side: foot_points(motion.skeleton, joint[f"ankle_{side}"], pos, glob) for side in SIDES}
    return _lower_foot(points, FLOOR_PERCENTILE)


def _lower_foot(points: dict[str, np.ndarray], percentile: float) -> float:
    """A percentile of the lower foot's lowest point over the frames of its points (T, P, 3) per side."""
    return float(np.percentile(np.minimum(*(p[..., 2].min(axis=1) for p in points.values())), percentile))


def _sliding(points: np.ndarray, floor: float, fps: float) -> tuple[np.ndarray, np.ndarray]:
    """From a foot's points (T, P, 3), per frame from the second: how much it is on the floor (0..1,
    by height: CONTACT_HEIGHT) and the slide to take back (T - 1, 2), counted as much as the foot
    stands: on the floor and slow (a swing foot skimming the floor is fast). Ramps rather than
    thresholds, so a millimetre more or less changes the result by little; a foot rolling from heel
    to toe stands on the point that stays."""
    height = points[..., 2]
    firm = np.clip((floor + CONTACT_HEIGHT - height) / CONTACT_BAND, 0.0, 1.0)  # (T, P)
    step = np.diff(points[..., :2], axis=0)  # (T - 1, P, 2)
    slow = np.clip((SKIM_SPEED - np.linalg.norm(step, axis=-1) * fps) / SPEED_BAND, 0.0, 1.0)
    weight = np.minimum(firm[1:], firm[:-1]) * slow
    # The slide is the lowest point's: a point a few millimetres higher (the ball as the heel of a
    # toe-off rises) counts for little, so a roll is not taken for a slide.
    low = np.exp(-(height[1:] - height[1:].min(axis=1, keepdims=True)) / LOWEST_SCALE)
    share = weight * low
    slide = (share[..., None] * step).sum(axis=1) / np.maximum(share.sum(axis=1), 1e-12)[:, None]
    return firm[1:].max(axis=1), weight.max(axis=1)[:, None] * slide


def _offsets(down: np.ndarray, slide: np.ndarray, fps: float, most: float) -> np.ndarray:
    """(T, 2) the ankle's ground offset per frame (row 0, the frame before the range, is zero): the
    slide taken back, at most `most` (m; a foot held further would leave its leg stretched out
    straight); let go in the air (1 - down) at CATCH_UP_SPEED, and over the last RELEASE frames."""
    offset = np.zeros((len(slide) + 1, 2))
    catch_up = CATCH_UP_SPEED / fps
    for t in range(1, len(offset)):
        held = offset[t - 1] - slide[t - 1]
        size = float(np.linalg.norm(held))
        if size > 0.0:
            held *= min(most, max(0.0, size - (1.0 - down[t - 1]) * catch_up)) / size
        offset[t] = held
    release = min(RELEASE, len(offset) - 1)
    offset[len(offset) - release :] *= np.linspace(1.0, 0.0, release + 1)[1:, None]
    return offset
