"""Where a character faces in a motion, for aiming pushes in tests and benchmarks; which joints are its limbs."""

from __future__ import annotations

import numpy as np

from reactive_anim.core.model.rig import Rig
from reactive_anim.core.model.roles import SIDES
from reactive_anim.core.model.skeleton import Motion, Skeleton
from reactive_anim.core.transition.ik import joint_path

UP = np.array([0.0, 0.0, 1.0])


def ground_axes(motion: Motion, frame: float, roles: dict[str, str] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(forward, left) horizontal unit vectors of the character at a frame: left along the hip line
    (left hip minus right hip, flattened), forward = left x up."""
    rig = Rig.of(motion.skeleton, roles)
    pos = motion.global_positions()[round(frame)]
    left = pos[rig.joint("hip_l")] - pos[rig.joint("hip_r")]
    left[2] = 0.0
    left /= np.linalg.norm(left)
    return np.cross(left, UP), left


def leg_joints(skeleton: Skeleton) -> list[int]:
    """Every joint from the hips down (what the feet hold, core/transition/footing.py, may turn)."""
    return _below(skeleton, "hip")


def limb_joints(skeleton: Skeleton) -> list[int]:
    """Every joint from the hips or the shoulders down (what core/transition/footing.py may turn: the feet held,
    and legs and arms brought out of the floor)."""
    return sorted(_below(skeleton, "hip") + _below(skeleton, "shoulder"))


def _below(skeleton: Skeleton, role: str) -> list[int]:
    rig = Rig.of(skeleton)
    tops = {rig.joint(f"{role}_{s}") for s in SIDES}
    return [j for j in range(skeleton.num_joints) if tops & set(joint_path(skeleton, 0, j))]
