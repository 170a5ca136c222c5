"""Limb IK: analytic two-bone IK (law of cosines) and its use for the legs and arms of the sample
skeleton, so a planted hand or foot stays exactly where it was planned.

The functions that pose a limb work in place on a clip's local rotations (T, J, 4), given its root
positions (T, 3): forward kinematics (reactive_anim.core.model.skeleton) finds where the limb starts.
"""

from __future__ import annotations

import numpy as np

from reactive_anim.core.model import quat
from reactive_anim.core.model.skeleton import Skeleton, forward_kinematics

from .skeleton import FORWARD, SIDES, X_AXIS


def bone_frame(axis: np.ndarray, lateral: np.ndarray) -> np.ndarray:
    """Orthonormal matrices (..., 3, 3) whose columns are the lateral, the bone axis and their cross."""
    axis = axis / np.linalg.norm(axis, axis=-1, keepdims=True)
    lateral = lateral - np.sum(lateral * axis, axis=-1, keepdims=True) * axis
    lateral = lateral / np.linalg.norm(lateral, axis=-1, keepdims=True)
    return np.stack([lateral, axis, np.cross(lateral, axis)], axis=-1)


def two_bone_ik(
    root: np.ndarray,
    target: np.ndarray,
    rest_upper: np.ndarray,
    rest_lower: np.ndarray,
    pole: np.ndarray,
    rest_pole: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Global rotations (T, 4) of the upper and lower bone of a limb so its end reaches `target`.

    Analytic (law of cosines), so a planted foot stays exactly where it was planned. root,
    target: (T, 3) world positions; rest_upper, rest_lower: the bones' rest vectors (the child
    offsets); pole: (3,), the direction the middle joint (knee) should point. The hinge
    axis is the pole crossed with the root-to-target line, so the middle joint bends towards the
    pole and the two bones share the hinge. Out-of-reach targets are clamped just short of a
    straight limb. `rest_pole` is where the pole points in the rest pose (default: `pole`); pass
    it when the pole turns with the body (a lying character's knees point at the floor).
    """
    len1 = float(np.linalg.norm(rest_upper))
    len2 = float(np.linalg.norm(rest_lower))
    reach = target - root
    dist = np.linalg.norm(reach, axis=-1, keepdims=True)
    along = reach / dist
    dist = np.clip(dist, abs(len1 - len2) + 1e-6, (len1 + len2) * (1.0 - 1e-6))
    hinge = np.cross(np.broadcast_to(pole, reach.shape), along)
    hinge /= np.linalg.norm(hinge, axis=-1, keepdims=True)
    bend = np.cross(along, hinge)  # towards the pole, perpendicular to the root-target line
    cos_a = (len1 * len1 + dist * dist - len2 * len2) / (2.0 * len1 * dist)
    middle = root + len1 * (cos_a * along + np.sqrt(1.0 - cos_a * cos_a) * bend)
    end = root + dist * along
    rest_hinge = np.cross(pole if rest_pole is None else rest_pole, rest_upper + rest_lower)
    upper = bone_frame(middle - root, hinge) @ np.swapaxes(bone_frame(rest_upper, rest_hinge), -1, -2)
    lower = bone_frame(end - middle, hinge) @ np.swapaxes(bone_frame(rest_lower, rest_hinge), -1, -2)
    return quat.from_matrix(upper), quat.from_matrix(lower)


def solve_limb(
    skeleton: Skeleton,
    root: np.ndarray,
    local: np.ndarray,
    chain: tuple[str, str, str],
    target: np.ndarray,
    end_world: np.ndarray | None,
    pole: np.ndarray,
    rest_pole: np.ndarray,
) -> None:
    """Turn a limb's two bones (in place) so its end joint reaches `target` (T, 3).

    pole: (T, 3) world direction the middle joint points; rest_pole: the same in the rest pose.
    end_world: (T, 4) world rotation to give the end joint (a planted foot stays flat), or None
    to keep its local rotation.
    """
    upper, middle, end = (skeleton.index(n) for n in chain)
    parent = skeleton.parents[upper]
    pos, rot = forward_kinematics(skeleton, root, local, skeleton.offsets)
    upper_rot, lower_rot = two_bone_ik(
        pos[:, upper], target, skeleton.offsets[middle], skeleton.offsets[end], pole, rest_pole
    )
    local[:, upper] = quat.mul(quat.conj(rot[:, parent]), upper_rot)
    local[:, middle] = quat.mul(quat.conj(upper_rot), lower_rot)
    if end_world is not None:
        local[:, end] = quat.mul(quat.conj(lower_rot), end_world)


def leg_ik(
    skeleton: Skeleton, root: np.ndarray, local: np.ndarray, side: str, ankle: np.ndarray, foot_world: np.ndarray
) -> None:
    """Legs by IK, knees pointing where the pelvis faces (so they stay right when it pitches)."""
    pole = quat.rotate(local[:, 0], FORWARD)
    solve_limb(
        skeleton, root, local, (f"thigh.{side}", f"shin.{side}", f"foot.{side}"), ankle, foot_world, pole, FORWARD
    )


def arm_ik(
    skeleton: Skeleton, root: np.ndarray, local: np.ndarray, side: str, hand: np.ndarray, hand_world: np.ndarray
) -> None:
    """Arms by IK, elbows pointing back and a little out from the chest (a push-up's elbows),
    turning outwards when the back faces the floor (lying face up) so they stay above it."""
    _, rot = forward_kinematics(skeleton, root, local, skeleton.offsets)
    chest = rot[:, skeleton.index("chest")]
    back, out = quat.rotate(chest, -FORWARD), quat.rotate(chest, SIDES[side] * X_AXIS)
    pole = back + (0.5 + 3.0 * np.maximum(-back[:, 2:], 0.0)) * out
    solve_limb(
        skeleton,
        root,
        local,
        (f"upper_arm.{side}", f"forearm.{side}", f"hand.{side}"),
        hand,
        hand_world,
        pole,
        -FORWARD,
    )
