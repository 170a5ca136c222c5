"""The simulated stretch of a reaction softened where a joint's acceleration spikes.

A MuJoCo contact stops a limb within a step of 2 ms. Sampled at the frame rate, a swing foot that
strikes the floor goes from 4-8 m/s to rest between two frames: on every shared walk, run and
idle pushed at 40 N·s, 30% of reactions had a joint (a toe, nearly always) accelerate beyond the
largest in the same rig's real walks, and a toe struck in most of them (docs/measurements.md).
Real capture never stops so sharply: soft tissue and shoes round the stop, and so does the
capture's own filtering. So where the sampled simulation's largest joint acceleration (over
model/acceleration.STRIDE, as the quality benchmark measures it) passes SPIKE_FROM, the frames whose
stencil spans it, and SIGMA's reach around them, are averaged over time with a Gaussian of SIGMA
seconds, fully from SPIKE_FULL; elsewhere the simulation plays as it was sampled.

- Only where it spikes: averaged over the whole stretch, a shuffling foot's short, low lifts
  (2-3 cm for a few frames) came down under the floor contact height and read as a slide (one
  fade slid a planted foot 7.7 cm, against 4.7 without softening).
- Only the simulation (BC from the frame after the hit, and CD), before the clip is faded in: the
  clip and the original motion are capture and keep their frames (but for the pass below). The
  hit's own frame stays: averaged with the frames before it, the body would start to move before
  it is hit.
- Repeated while a frame still spikes, PASSES times at most: each pass widens the average where
  it is needed (three passes of a Gaussian are one of sqrt(3) times its width), nowhere else.
- Rotations are averaged as quaternions made continuous in time and normalised (the frames
  averaged are a few degrees apart), the root and any animated offsets linearly.

The whole reaction, once stitched (the simulation, the fades, the clip, the feet held and lifted),
is softened once more where a joint nears or passes the real falls' largest (OUTDONE: from 140
m/s^2, fully from 160, against the falls' 166), from the frame after the hit to the reaction's end
(the take after it keeps its frames). A 300 N·s push can spin a body at two turns a second (a yaw
inertia of about 1.3 kg·m² against a hit a few cm off the centre of mass) or fling its legs
through a fall's fade: hands and toes reached 228 m/s^2, in the stretch no earlier stage owns.
The ramp starts under 166 so that what is softened ends under it; capture played inside a
reaction that goes past 140 is softened too (one Bandai run's own toes reach 159 in a kept run's
fade), and the feet are not held again after it (no fade slid a planted foot further on the whole
shared set: docs/measurements.md).
"""

from __future__ import annotations

import math

import numpy as np

from ..model import quat
from ..model.acceleration import accelerations, stride_frames
from ..model.arrays import FloatArray
from ..model.skeleton import Motion

SIGMA = 1.0 / 30.0  # s: the Gaussian's standard deviation, a frame at 30 fps
# m/s^2: the largest joint acceleration from which a frame is softened, and fully from; the real
# walks of every shared rig reach 28 on one frame in ten, 53 in a hundred and 79 in a thousand
SPIKE_FROM = 40.0
SPIKE_FULL = 70.0
# m/s^2: a whole reaction (the simulation, the fades, the clip, the feet held and lifted) is
# softened where a joint passes the first, fully from the second, up to OUTDONE_PASSES times: the
# largest in the real falls, get-ups and stumble of ../shared/mocap is 166; a 300 N·s push threw
# hands and toes at up to 228 (a body spun by the hit, legs flung through a fall's fade)
OUTDONE = (140.0, 160.0)
OUTDONE_PASSES = 8
# passes at most: a 300 N·s fall's landing stops a limb at up to 400 m/s^2, which one pass of a
# frame's Gaussian leaves over the real falls' largest (166) in 61 of 3264 reactions, three in 41
PASSES = 3


def soften(
    motion: Motion,
    first: int,
    spike: tuple[float, float] = (SPIKE_FROM, SPIKE_FULL),
    passes: int = PASSES,
    last: int | None = None,
) -> Motion:
    """`motion` with its frames first..last - 1 (to the end by default) averaged over time where a
    joint's acceleration spikes, up to `passes` times while one still does (see the module
    docstring); the frames around them are read (context_frames of them before `first`), never
    changed, and so is every frame not softened. spike: the accelerations (m/s^2) from which a frame
    is softened, and fully (a fall's clip, made by the same physics, spikes only where it outdoes
    real falls; a whole reaction only where it nears or passes them: OUTDONE)."""
    for _ in range(passes):
        softened = _pass(motion, first, motion.num_frames if last is None else last, spike)
        if softened is motion:
            break
        motion = softened
    return motion


def context_frames(fps: float) -> int:
    """How many frames before `first` soften reads: a caller need pass no more of what came before."""
    return stride_frames(fps) + _reach(fps)


def _reach(fps: float) -> int:
    return max(1, math.ceil(2.0 * SIGMA * fps))


def _pass(motion: Motion, first: int, last: int, spike: tuple[float, float]) -> Motion:
    """One pass of soften: `motion` itself where nothing spikes."""
    n = motion.num_frames
    last = min(last, n)
    if first >= last:
        return motion
    stride, reach = stride_frames(motion.fps), _reach(motion.fps)
    lo, hi = max(first - stride, 0), min(last + 2 * stride + reach, n)  # what a row softened can read
    spikes = np.zeros(hi)
    spikes[lo:] = _spikes(motion.slice(lo, hi).global_positions(), motion.fps, spike)
    amount = _widened(spikes, stride + reach)
    rows = first + np.flatnonzero(amount[first:last] > 0)  # the frames softened: no other is written
    if not len(rows):
        return motion
    taps = np.arange(-reach, reach + 1)
    weights = np.exp(-0.5 * (taps / (SIGMA * motion.fps)) ** 2)
    weights /= weights.sum()
    near = np.clip(rows[:, None] + taps, 0, hi - 1)  # (rows, taps)
    share = amount[rows]
    base = max(first - reach, 0)  # the first frame read: signs made continuous from there on
    rot = quat.make_continuous(motion.local_rot[base:hi])
    mean_rot = quat.normalize(_mean(rot[near - base], weights))
    local_rot = motion.local_rot.copy()
    turn = np.repeat(share[:, None], motion.skeleton.num_joints, 1)
    local_rot[rows] = quat.slerp(rot[rows - base], mean_rot, turn)
    root = motion.root_pos.copy()
    root[rows] += share[:, None] * (_mean(motion.root_pos[near], weights) - root[rows])
    local_pos = None
    if motion.local_pos is not None:
        local_pos = motion.local_pos.copy()
        local_pos[rows] += share[:, None, None] * (_mean(motion.local_pos[near], weights) - local_pos[rows])
    return Motion(motion.skeleton, motion.fps, root, local_rot, local_pos)


def _mean(values: FloatArray, weights: FloatArray) -> FloatArray:
    """The weighted mean over axis 1 (the taps) of values (frames, taps, ...)."""
    return np.moveaxis(values, 1, -1) @ weights


def _spikes(positions: FloatArray, fps: float, spike: tuple[float, float]) -> FloatArray:
    """(T,) how much each frame's largest joint acceleration (positions (T, J, 3)) calls for
    softening: 0 up to spike[0], 1 from spike[1]; 0 where the stride leaves the frames."""
    largest = np.max(accelerations(positions, fps), axis=1)
    return np.nan_to_num(np.clip((largest - spike[0]) / (spike[1] - spike[0]), 0.0, 1.0))


def _widened(values: FloatArray, half: int) -> FloatArray:
    """(T,) the largest of `values` (T,) within `half` frames either side of each frame."""
    padded = np.pad(values, half)
    return np.lib.stride_tricks.sliding_window_view(padded, 2 * half + 1).max(axis=1)
