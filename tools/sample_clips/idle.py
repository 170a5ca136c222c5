"""The idle: standing at rest, breathing and shifting the weight, looping; the stand every
reaction starts from (and the falls' ragdoll takes its neutral pose from)."""

from __future__ import annotations

import numpy as np

from reactive_anim.core.model import quat
from reactive_anim.core.model.skeleton import Motion

from .ik import leg_ik
from .poses import PARAMS, STAND, pose_vector, posed, standing_ankles
from .skeleton import FPS, clip_motion, sample_skeleton


def idle_clip(seconds: float = 6.0) -> Motion:
    """Standing at rest: a breath every 3 s, the weight shifting from foot to foot every 6 s.

    Every oscillation has a whole number of periods in the clip, so it loops. The feet stay
    where they are (legs by IK), so the weight shift bends the knees, not the floor.
    """
    skeleton = sample_skeleton()
    count = round(seconds * FPS)
    t = np.arange(count) / FPS
    breath = np.sin(2 * np.pi * t / 3.0)
    shift = np.sin(2 * np.pi * t / seconds)
    values = np.tile(pose_vector(STAND), (count, 1))
    changes = {
        "x": 0.018 * shift,
        "z": -0.004 * (1.0 - np.cos(4 * np.pi * t / seconds)),
        "pelvis_roll": -1.5 * shift,
        "spine_roll": 2.0 * shift,
        "spine_pitch": -1.2 * breath,
        "neck_pitch": 1.0 * breath + 1.5 * shift,
        "arm_flex_L": 1.5 * breath,
        "arm_flex_R": 1.5 * breath,
        "elbow_L": 2.0 * shift,
        "elbow_R": -2.0 * shift,
        "pelvis_yaw": 1.5 * np.sin(2 * np.pi * t / seconds + 1.0),
    }
    for name, delta in changes.items():
        values[:, PARAMS.index(name)] += delta
    root, local = posed(skeleton, values)
    for side, ankle in standing_ankles(count).items():
        leg_ik(skeleton, root, local, side, ankle, quat.identity((count,)))
    return clip_motion(skeleton, root, local)
