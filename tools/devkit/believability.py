"""Believability measures: how a reaction compares with real capture (../shared/DESIGN.md, "Tests and
benchmarks"; the `quality` benchmark, tools/benchmarks/quality.py).

Every measure is a small numpy function over positions a core Motion gives (forward kinematics:
Motion.global_transforms), so the reactions and the real takes they are held against go through
the same code. Units metres, seconds, Z up. Shapes: T frames, P points, J joints.

The measures, per reaction over its window (the impact B to the end of the reaction + 0.5 s):
- Foot skid (skid_steps): horizontal travel of a foot's lowest point while within CONTACT of the
  floor, summed over the window (both feet); and per fade of the reaction, how far a foot planted
  at the fade's start (down and still) slides before it first lifts (planted_slide: a swinging toe
  that skims the floor, as in real shuffling walks, is no planted foot).
- Depth under the floor (depth_under_floor): how far the lowest joint or end site gets under the
  character's floor (the lowest its feet get in its own motion); a ground root bone (Bandai Namco's
  joint_Root, iClone's RL_BoneRoot: the root's only child is the hips) is no body part and is left out.
- Joint acceleration (acceleration) over a stride of STRIDE seconds, the hit's own frames left out
  (hit_mask); the body's joints are the ragdoll's role joints (CMU's finger joints carry no capture).
- Seams: pelvis acceleration within a frame of each seam (reaction_seams: C, F, the get-up's fade,
  the resume's fade) and the largest one-frame joint move there (frame_moves).
- Momentum: the pelvis along the push against the unpushed take at B + 0.5 s (ahead), and the
  longest the pelvis stands still (longest_still).
- Class sense: whether the reaction's class goes the way of the push (push_side, right_direction).

A calibration first frame (some joint leaving it faster than CALIBRATION_JUMP, the core's rule in
core/library.take_start) is never part of a take: take_start says where a take begins, and Profile
leaves everything before it out (NaN or zero).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from reactive_anim.core.model import quat
from reactive_anim.core.model.classes import reaction_class
from reactive_anim.core.model.floor import FOOT_ON_FLOOR
from reactive_anim.core.model.roles import SIDES
from reactive_anim.core.model.skeleton import Motion, root_child
from reactive_anim.core.transition.retarget import foot_points

STRIDE = 1.0 / 30.0  # s: the stride of speeds and accelerations (mocap noise is not acceleration)
CONTACT = FOOT_ON_FLOOR  # m over the floor: a foot point this low stands on it (the core's one definition)
# m/s: a foot down and slower than this stands (real stance feet 0.1-0.47; a toe skimming the floor in a
# shuffle's swing 2-3)
PLANTED_SPEED = 0.5
STILL_SPEED = 0.25  # m/s: a pelvis slower than this over the floor stands still ...
STILL_TIME = 0.2  # s: ... and this long is a visible stop
CALIBRATION_JUMP = 20.0  # m/s: the core's rule (library.take_start): faster than any joint in a take


def stride_frames(fps: float, stride: float = STRIDE) -> int:
    """The stride in frames at `fps` (at least one)."""
    return max(1, round(fps * stride))


def take_start(positions: np.ndarray, fps: float) -> int:
    """1 when some joint leaves frame 0 faster than CALIBRATION_JUMP (a calibration pose, not the
    take), else 0. positions: (T, J, 3)."""
    if len(positions) < 2:
        return 0
    return int(np.linalg.norm(positions[1] - positions[0], axis=-1).max() * fps > CALIBRATION_JUMP)


def end_site_positions(motion: Motion, positions: np.ndarray, rotations: np.ndarray) -> np.ndarray:
    """(T, E, 3) the BVH End Sites (leaf tips) of the motion's skeleton, from its global transforms."""
    sites = motion.skeleton.end_sites
    if not sites:
        return np.zeros((len(positions), 0, 3))
    joints = np.array(list(sites))
    offsets = np.broadcast_to(np.array([sites[j] for j in joints]), positions[:, joints].shape)
    return positions[:, joints] + quat.rotate(rotations[:, joints], offsets)


def skid_steps(points: np.ndarray, floor: float, contact: float = CONTACT) -> np.ndarray:
    """(T,) horizontal travel of one foot's lowest point into each frame while it is on the floor.

    points: (T, P, 3) the foot's points (ankle, toes, their end sites). For the step from frame t - 1
    to t the lowest point is the one whose higher position of the two is lowest (the point that stays
    down over the step, so a heel-to-toe roll moving which point is lowest is no travel); the step
    counts when that point is within `contact` of `floor` (or under it) at both frames. Row 0 is 0.
    """
    out = np.zeros(len(points))
    if len(points) < 2:
        return out
    high = np.maximum(points[1:, :, 2], points[:-1, :, 2])  # (T-1, P)
    k = np.argmin(high, axis=1)
    rows = np.arange(len(k))
    travel = np.linalg.norm(points[1:, :, :2][rows, k] - points[:-1, :, :2][rows, k], axis=-1)
    out[1:] = np.where(high[rows, k] <= floor + contact, travel, 0.0)
    return out


def contact(points: np.ndarray, floor: float, contact_height: float = CONTACT) -> np.ndarray:
    """(T,) whether one foot's lowest point (points (T, P, 3)) is within `contact_height` of `floor`."""
    return points[..., 2].min(axis=1) <= floor + contact_height


def planted(skid: np.ndarray, down: np.ndarray, fps: float) -> np.ndarray:
    """(T,) whether a foot stands at each frame: down (T,) (contact) and its step into the frame
    (skid (T,), skid_steps) slower than PLANTED_SPEED."""
    return down & (skid * fps < PLANTED_SPEED)


def planted_slide(skid: np.ndarray, down: np.ndarray, a: int, b: int, fps: float) -> float:
    """How far a foot planted at frame a (planted) slides within [a, b) before it first lifts: skid
    (T,) (skid_steps) summed over the steps into a + 1 .. e - 1, e the first frame after a whose
    `down` (T,) (contact) is False, or b; 0 when the foot is not planted at a."""
    a, b = max(a, 0), min(b, len(down))
    if a >= b or not planted(skid[a : a + 1], down[a : a + 1], fps)[0]:
        return 0.0
    lifted = np.flatnonzero(~down[a + 1 : b])
    e = a + 1 + int(lifted[0]) if len(lifted) else b
    return float(skid[a + 1 : e].sum())


def planted_slides(skid: np.ndarray, down: np.ndarray, frames: int, fps: float) -> np.ndarray:
    """(T,) planted_slide(skid, down, t, t + frames, fps) for every start frame t, vectorised."""
    n = len(down)
    cum = np.concatenate([[0.0], np.cumsum(skid)])  # cum[k]: skid into frames < k
    breaks = np.append(np.flatnonzero(~down), n)  # frames where the foot is up (and the end)
    t = np.arange(n)
    e = breaks[np.searchsorted(breaks, t + 1)]  # the first frame after t with the foot up
    e = np.minimum(e, np.minimum(t + frames, n))
    return np.where(planted(skid, down, fps), cum[np.maximum(e, t + 1)] - cum[t + 1], 0.0)


def depth_under_floor(points: np.ndarray, floor: float) -> np.ndarray:
    """(T,) how far the lowest of the points (T, P, 3) is under `floor` (negative: above it)."""
    return floor - points[..., 2].min(axis=1)


def acceleration(positions: np.ndarray, fps: float, stride: float = STRIDE) -> np.ndarray:
    """Acceleration magnitude per frame and point, |p(t + h) - 2 p(t) + p(t - h)| / h^2 with h the
    stride (stride_frames frames), positions (T, ..., 3) -> (T, ...); NaN where the stride leaves the
    frames. A point moving with constant acceleration a gives |a| exactly."""
    s = stride_frames(fps, stride)
    h = s / fps
    out = np.full(positions.shape[:-1], np.nan)
    if len(positions) > 2 * s:
        out[s:-s] = np.linalg.norm(positions[2 * s :] - 2 * positions[s:-s] + positions[: -2 * s], axis=-1) / h**2
    return out


def frame_moves(positions: np.ndarray) -> np.ndarray:
    """(T, ...) how far each point moved from the frame before, positions (T, ..., 3); NaN at 0."""
    out = np.full(positions.shape[:-1], np.nan)
    out[1:] = np.linalg.norm(np.diff(positions, axis=0), axis=-1)
    return out


def hit_mask(num_frames: int, frame_b: float, fps: float, stride: float = STRIDE) -> np.ndarray:
    """(T,) True on the frames whose acceleration stencil (t - h, t, t + h) spans the hit: the impulse
    acts between B and the next frame, and a frame either side is left out too (the simulation
    starts from the mocap's pose and speed at B, which the mocap's own differences only approach)."""
    s = stride_frames(fps, stride)
    b = int(np.floor(frame_b))
    mask = np.zeros(num_frames, dtype=bool)
    mask[max(b - s, 0) : max(b + s + 2, 0)] = True
    return mask


def horizontal_speed(positions: np.ndarray, fps: float, stride: float = STRIDE) -> np.ndarray:
    """(T,) speed over the floor of a point (T, 3), central over the stride; NaN at the ends."""
    s = stride_frames(fps, stride)
    out = np.full(len(positions), np.nan)
    if len(positions) > 2 * s:
        out[s:-s] = np.linalg.norm(positions[2 * s :, :2] - positions[: -2 * s, :2], axis=-1) * fps / (2 * s)
    return out


def longest_still(speed: np.ndarray, fps: float, limit: float = STILL_SPEED) -> float:
    """Seconds of the longest run of frames whose speed (T,) is under `limit` (a frame holds 1/fps;
    NaN frames break a run)."""
    still = np.concatenate([[False], speed < limit, [False]])
    edges = np.flatnonzero(np.diff(still.astype(np.int8)))
    runs = edges[1::2] - edges[0::2]
    return float(runs.max() / fps) if len(runs) else 0.0


def ahead(reacted: np.ndarray, unpushed: np.ndarray, direction: np.ndarray) -> float:
    """How far (m) a point (3,) of the reacted motion is ahead of the unpushed one along the push's
    horizontal direction (3,)."""
    flat = np.array([direction[0], direction[1], 0.0])
    return float((reacted - unpushed) @ flat / np.linalg.norm(flat))


def push_side(direction: np.ndarray, forward: np.ndarray) -> str:
    """Where a push comes from, seen by the character facing `forward` (horizontal unit, 3,):
    "behind" (it pushes forward, within 45 degrees), "front", "left" (pushing to its right) or "right"."""
    left = np.cross([0.0, 0.0, 1.0], forward)
    along, across = float(direction @ forward), float(direction @ left)
    if abs(along) >= abs(across):
        return "behind" if along > 0 else "front"
    return "right" if across > 0 else "left"


def right_direction(side: str, slug: str) -> bool:
    """Whether a reaction of class `slug` goes the way a push from `side` sends the body: from behind
    forward, from the front backward, from the left to the right (a step right or the side fall,
    which goes either way), from the right to the left; a sway (keeping balance where it stands) is
    never the wrong way."""
    way = reaction_class(slug).way
    wanted = {"behind": "forward", "front": "backward", "left": "right", "right": "left"}[side]
    return way in (wanted, "side", "") if wanted in ("left", "right") else way in (wanted, "")


@dataclass
class Profile:
    """Per-frame series of one motion (T frames) that the measures sum or take the largest of over a
    window. Frames before `start` (a calibration first frame) are NaN, or 0 in the sums.

    skid: (T, 2) skid_steps of the left and right foot; down: (T, 2) their contact.
    depth: (T,) depth_under_floor of every joint and end site (a ground root left out).
    accel: (T,) the largest acceleration of the body's joints; pelvis_accel: (T,) the pelvis'.
    move: (T,) the largest one-frame move of the body's joints.  pelvis: (T, 3) positions.
    speed: (T,) horizontal_speed of the pelvis.
    """

    fps: float
    start: int
    floor: float
    skid: np.ndarray
    down: np.ndarray
    depth: np.ndarray
    accel: np.ndarray
    pelvis_accel: np.ndarray
    move: np.ndarray
    pelvis: np.ndarray
    speed: np.ndarray

    @property
    def num_frames(self) -> int:
        return len(self.depth)

    def skid_in(self, a: int, b: int) -> np.ndarray:
        """(2,) each foot's skid over frames [a, b): the steps into frames a + 1 .. b - 1."""
        return self.skid[max(a + 1, 0) : max(b, 0)].sum(axis=0)

    def largest(self, series: np.ndarray, a: int, b: int, leave_out: np.ndarray | None = None) -> tuple[float, int]:
        """The largest of a per-frame series over [a, b) (frames in `leave_out` skipped, NaN ignored) and
        its frame; (nan, -1) when there is nothing."""
        a, b = max(a, 0), min(b, len(series))
        values = series[a:b].copy() if b > a else np.zeros(0)
        if leave_out is not None and len(values):
            values[leave_out[a:b]] = np.nan
        if not len(values) or np.all(np.isnan(values)):
            return float("nan"), -1
        k = int(np.nanargmax(values))
        return float(values[k]), a + k


def body_joints(roles: dict[str, str], motion: Motion) -> np.ndarray:
    """The body's joints: those the ragdoll's roles name (sorted indices)."""
    return np.array(sorted({motion.skeleton.index(name) for name in roles.values()}))


def profile(motion: Motion, roles: dict[str, str], floor: float, start: int | None = None) -> Profile:
    """The per-frame series of `motion` (see Profile). roles: role -> joint name (pelvis, ankle_l, ...);
    floor: the character's floor (the lowest its feet get in its own motion); start: the take's first
    frame (default take_start: 1 after a calibration frame, else 0)."""
    pos, rot = motion.global_transforms()
    sk, fps = motion.skeleton, motion.fps
    start = take_start(pos, fps) if start is None else start
    body = body_joints(roles, motion)
    pelvis = pos[:, sk.index(roles["pelvis"])]
    feet = [foot_points(sk, sk.index(roles[f"ankle_{s}"]), pos, rot) for s in SIDES]
    ground_root = root_child(sk) is not None
    points = np.concatenate([pos[:, int(ground_root) :], end_site_positions(motion, pos, rot)], axis=1)
    series = Profile(
        fps=fps,
        start=start,
        floor=floor,
        skid=np.stack([skid_steps(f, floor) for f in feet], axis=1),
        down=np.stack([contact(f, floor) for f in feet], axis=1),
        depth=depth_under_floor(points, floor),
        accel=acceleration(pos[:, body], fps).max(axis=1),  # NaN where the stride leaves the frames
        pelvis_accel=acceleration(pelvis, fps),
        move=frame_moves(pos[:, body]).max(axis=1),
        pelvis=pelvis,
        speed=horizontal_speed(pelvis, fps),
    )
    if start:
        s = stride_frames(fps)
        series.skid[: start + 1] = 0.0
        series.down[:start] = False
        for name in ("depth", "move"):
            getattr(series, name)[: start + 1 if name == "move" else start] = np.nan
        for name in ("accel", "pelvis_accel", "speed"):
            getattr(series, name)[: start + s] = np.nan
    return series


def lowest_floor(motion: Motion, roles: dict[str, str], start: int | None = None) -> float:
    """The character's floor: the lowest any foot point gets in the motion (its first `start` frames,
    by default a calibration frame, left out), as the core's Casting.sole."""
    pos, rot = motion.global_transforms()
    sk = motion.skeleton
    start = take_start(pos, motion.fps) if start is None else start
    feet = np.concatenate([foot_points(sk, sk.index(roles[f"ankle_{s}"]), pos, rot) for s in SIDES], axis=1)
    return float(feet[start:, :, 2].min())


class Seamed(Protocol):
    """What reaction_seams reads of a core Reaction."""

    @property
    def frame_c(self) -> int: ...
    @property
    def frame_f(self) -> int: ...
    @property
    def end_frame(self) -> int: ...
    @property
    def chained(self) -> str | None: ...
    @property
    def resumed_at(self) -> int | None: ...


def reaction_seams(
    reaction: Seamed,
    resume_fade: int,
    getup_frames: int | None = None,
    getup_fade: int = 0,
    resume_window: int | None = None,
) -> dict[str, int]:
    """Where a core Reaction's sources meet, as frames of the output: C and F (the transition's fade),
    the get-up's fade-in start and end (getup_frames: the chained clip's length at the output's rate,
    getup_fade: its fade's frames), the resume's fade start and end (resume_fade: its frames;
    resume_window: the re-entry's Eq. 1 window, default the fade). react.py builds them so: a
    resume fades over the last `resume_fade` frames to end_frame and the source plays on from
    end_frame + 1; a chained get-up starts its fade where the fall ends and plays on to the
    resume's start plus the window (its last pose held through the rest of the resume's fade), or
    to end_frame when nothing resumes."""
    seams = {"C": int(reaction.frame_c), "F": int(reaction.frame_f)}
    end = int(reaction.end_frame)
    resumed = reaction.resumed_at is not None
    if reaction.chained is not None and getup_frames:
        getup_end = end + 1 - resume_fade + (resume_fade if resume_window is None else resume_window)
        seams["get-up start"] = (getup_end if resumed else end + 1) - getup_frames
        if getup_fade:
            seams["get-up end"] = seams["get-up start"] + getup_fade
    if resumed:
        seams["resume start"] = end + 1 - resume_fade
        seams["resume end"] = end + 1
    return seams


def quantile(values: list[float] | np.ndarray, q: float) -> float:
    """The q-quantile (0..1) of the finite values, NaN for none."""
    values = np.asarray(values, dtype=float)
    values = values[np.isfinite(values)]
    return float(np.quantile(values, q)) if len(values) else float("nan")
