"""How long a CD tracking run keeps the character up, the measure of CD's balance.

Kept up: the pelvis within 10 cm of the target's height at every frame, and the mean joint error
(role joints, relative to the pelvis' ground point, so a walker the physics slowed or sped is not
counted as wrong) under 5 cm averaged over the run so far.
"""

from __future__ import annotations

import numpy as np

from reactive_anim.core.model.skeleton import Motion
from reactive_anim.core.physics.ragdoll import Ragdoll
from reactive_anim.core.physics.simulate import SimResult

HEIGHT_BOUND = 0.10  # m
ERROR_BOUND = 0.05  # m


def kept_up_seconds(result: SimResult, target: Motion, ragdoll: Ragdoll) -> float:
    """Seconds from the run's start to the first frame outside the bounds (its length if none)."""
    frames = np.minimum(result.frames.astype(int), target.num_frames - 1)
    sk = target.skeleton
    joints = [sk.index(n) for n in ragdoll.roles.values()]
    pelvis = sk.index(ragdoll.roles["pelvis"])
    sim, ref = result.motion.global_positions(), target.global_positions()[frames]
    flat = np.array([1.0, 1.0, 0.0])
    pose_error = np.linalg.norm(
        (sim[:, joints] - sim[:, pelvis : pelvis + 1] * flat) - (ref[:, joints] - ref[:, pelvis : pelvis + 1] * flat),
        axis=-1,
    ).mean(axis=1)
    running = np.cumsum(pose_error) / np.arange(1, len(pose_error) + 1)
    height = np.abs(sim[:, pelvis, 2] - ref[:, pelvis, 2])
    bad = np.flatnonzero((running > ERROR_BOUND) | (height > HEIGHT_BOUND))
    return (bad[0] if len(bad) else len(frames)) / target.fps
