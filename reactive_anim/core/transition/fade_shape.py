"""The shape of a fall's C..F fade, chosen by how the output will move.

A slerp toward a still pose from a body still turning fast (thrown flat by a hard push, faded into
a kneeling fall) adds the fade's slope times the body's turn: on a Bandai walk pushed at 300 N·s
from the side, a toe accelerated at 282 m/s^2 in the blend where the simulation alone reached 109
and the clip 4 (276 in the output, once the feet were held). Which shape is calmest depends on when
the body turns: a fade that leaves the simulation later, while the body still tumbles, or sooner,
while it is slow. So where the plain smootherstep makes the rig's joints accelerate faster than
either source on its own, the fade takes whichever of FADE_SHAPES accelerates them least at its
peak. A fade that leaves later is steeper as it ends, and the pelvis jolts at F: only shapes that
move it there no harder than real motion mostly does (SEAM_PELVIS) or than the plain fade are
tried. Used for falls only (react.py); the choice is made on the blend, before the feet are held.
"""

from __future__ import annotations

import numpy as np

from ..model.acceleration import accelerations, stride_frames
from ..model.arrays import FloatArray, IndexArray
from ..model.rig import Rig
from ..model.skeleton import Motion
from .blend import blend, fade_weights

# m/s^2: the pelvis' acceleration in real walks and runs stays under this in 99 frames of 100
# (docs/measurements.md); a fade may move it so much as it ends, or as much as the plain one does.
SEAM_PELVIS = 16.5

# The shapes (lag, delay) tried (blend.fade_weights), the plain smootherstep first. Held back for
# half of C..F, the fade then took the clip in over 7 frames: a snap, not tried.
FADE_SHAPES = ((1.0, 0.0), (1.5, 0.0), (2.0, 0.0), (2.5, 0.0), (0.75, 0.0), (1.0, 0.2), (1.0, 0.35))

# A shape replaces the plain one only where it is calmer by more than this share, and the plain
# one is replaced only where it outdoes both sources by more: float noise decides nothing.
MARGIN = 0.01


def fade_context(fps: float) -> tuple[int, int]:
    """Frames calmest_fade reads before the fade's first (a stride's) and after its last (a stride's,
    and one more: the pelvis is checked on F's frame and the frames either side)."""
    stride = stride_frames(fps)
    return stride, stride + 1


def calmest_fade(sim: Motion, clip: Motion, rig: Rig) -> FloatArray:
    """The weights of the C..F fade from `sim` into `clip`: `sim` from fade_context's frames
    before C to F (its own frames only), `clip` from as many before C to fade_context's frames
    after F; judged on the joints the rig's roles name. The other shapes are blended only where
    the plain one adds to what the sources do."""
    before, after = fade_context(sim.fps)
    inner = sim.num_frames - before
    if inner <= before:  # a fade within a stride: nothing to judge the simulation on
        return fade_weights(inner)
    joints = np.array(sorted(set(rig.joints.values())))
    pelvis = int(np.searchsorted(joints, rig.joint("pelvis")))
    held = sim.frames(0, sim.num_frames + after)  # weighed 1 there: the clip's frames
    shapes = [np.concatenate([np.zeros(before), fade_weights(inner, *shape), np.ones(after)]) for shape in FADE_SHAPES]
    plain = _accelerations(blend(held, clip, shapes[0]), joints)
    alone = max(float(np.nanmax(_accelerations(sim, joints))), float(np.nanmax(_accelerations(clip, joints))))
    if np.nanmax(plain) <= alone * (1.0 + MARGIN):
        return shapes[0][before:-after]
    moves = [plain] + [_accelerations(blend(held, clip, weights), joints) for weights in shapes[1:]]
    peaks = [float(np.nanmax(m)) for m in moves]
    f = before + inner - 1
    at_f = [float(np.nanmax(m[f - 1 : f + 2, pelvis])) for m in moves]
    calm = [k for k in range(1, len(shapes)) if at_f[k] <= max(at_f[0], SEAM_PELVIS)]
    best = min(calm, key=lambda k: peaks[k], default=0)
    chosen = best if peaks[best] < peaks[0] * (1.0 - MARGIN) else 0
    return shapes[chosen][before:-after]


def _accelerations(motion: Motion, joints: IndexArray) -> FloatArray:
    """(T, J) the acceleration's size of each of `joints` (model/acceleration.py)."""
    return accelerations(motion.global_positions()[:, joints], motion.fps)
