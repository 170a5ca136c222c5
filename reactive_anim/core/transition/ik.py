"""Two-bone IK: a leg (or an arm) turned so its end reaches toward a goal, and the joint chains it
turns. Used where feet are held and feet and hands are lifted out of the floor (footing.py) and where
a retargeted clip's planted feet are pinned (retarget.py)."""

from __future__ import annotations

import numpy as np

from ..model import quat
from ..model.arrays import FloatArray, unit
from ..model.skeleton import Skeleton

# rad: a knee (an elbow) bent less than this is straight, its plane rebuilt. At 5 degrees, a kept
# walk's knee the IK lifted to 176 degrees was rebuilt for one frame in a plane 80 degrees from its
# own and flicked 13 cm sideways and back (179 m/s^2; kept in its plane, 125 as the lift straightens
# it). A bend of 1 degree still puts the knee 3.5 mm off the hip-ankle line of a leg of two 0.4 m
# bones, far above float noise
STRAIGHT = np.radians(1.0)

# A bent knee (elbow) bends on in its own plane unless that plane's axis turns the wrong way round
# the body's left-right line, square to the thigh (its cosine to it from BACKWARD[0] on), and in the rebuilt plane
# from BACKWARD[1] (73 and 37 degrees from the wrong way); between the two it is turned about the
# thigh from the one toward the other in proportion. A limb swung out to the side bends about an
# axis near right angles to that line, on either side of it from frame to frame. Tested by its
# sign alone, the elbow of a lying body's arm, stretched out 20 degrees bent while a hand was
# lifted out of the floor, crossed it back and forth and flicked between its own plane and the
# rebuilt one (478 m/s^2 in one frame); any single threshold moves that flick, not removes it.
BACKWARD = (0.3, 0.8)


def arc(u: FloatArray, v: FloatArray) -> FloatArray:
    """The smallest rotations taking unit vectors u onto v, (..., 4); opposite vectors turn about
    any axis at right angles."""
    dot = np.sum(u * v, axis=-1)
    axis = np.cross(u, v)
    q = np.concatenate([(1.0 + dot)[..., None], axis], axis=-1)
    opposite = dot < -1.0 + 1e-9
    if np.any(opposite):
        other = np.where(np.abs(u[..., :1]) < 0.9, np.array([1.0, 0, 0]), np.array([0.0, 1, 0]))
        perpendicular = np.cross(u, other)
        perpendicular /= np.linalg.norm(perpendicular, axis=-1, keepdims=True)
        q[opposite] = np.concatenate([np.zeros(perpendicular.shape[:-1] + (1,)), perpendicular], axis=-1)[opposite]
    return quat.normalize(q)


def two_bone_ik(
    skeleton: Skeleton,
    pos: FloatArray,
    glob: FloatArray,
    joints: tuple[int, int, int],
    goal: FloatArray,
    weight: FloatArray,
    left: FloatArray,
    forward: FloatArray,
) -> None:
    """Turn hip and knee (global rotations, in place) so the ankle reaches toward `goal` by `weight`.
    A knee bent forward or sideways keeps its plane; a straight one (whose plane is float noise) or
    one bent backward bends about the body's left-right line (`left`, per frame), its shin toward
    the back (`forward` is the body's front), and one between the two turns gradually from the one
    plane to the other (BACKWARD). The foot keeps its world orientation."""
    hip, knee, ankle = joints
    t = np.flatnonzero(weight > 0)
    if not len(t):
        return
    h, k, a = pos[t, hip], pos[t, knee], pos[t, ankle]
    target = a + weight[t, None] * (goal[t] - a)
    thigh, shin = np.linalg.norm(k - h, axis=-1), np.linalg.norm(a - k, axis=-1)
    reach = np.clip(np.linalg.norm(target - h, axis=-1), np.abs(thigh - shin) + 1e-4, thigh + shin - 1e-4)
    want = np.arccos(np.clip((thigh**2 + shin**2 - reach**2) / (2 * thigh * shin), -1.0, 1.0))
    # A knee bent forward (or sideways) enough turns in its own plane (the source's, kept); a
    # straight or backward one is rebuilt about the left-right line, shin to the back; one between
    # is turned about the thigh from the kept toward the rebuilt (BACKWARD).
    plane = np.cross(h - k, a - k)
    now = np.arccos(np.clip(np.sum(unit(h - k) * unit(a - k), axis=-1), -1.0, 1.0))
    along = unit(k - h)
    hinge = left[t] - along * np.sum(left[t] * along, axis=-1, keepdims=True)
    sideways = np.linalg.norm(hinge, axis=-1) < 1e-6  # a thigh along the hips: its own plane
    hinge = np.where(sideways[:, None], plane, hinge)
    # against the hinge, not the left-right line itself: a thigh swung out to the side leaves less
    # of that line square to it, and a knee bent straight back read under BACKWARD[1]
    tilt = np.where(sideways, -1.0, np.sum(unit(plane) * unit(hinge), axis=-1))
    rebuilt_share = np.clip((tilt - BACKWARD[0]) / (BACKWARD[1] - BACKWARD[0]), 0.0, 1.0)
    rebuilt_share[np.pi - now <= STRAIGHT] = 1.0
    bend = np.pi - want  # 0: straight
    rebuilt = [quat.rotate(quat.from_axis_angle(unit(hinge), sign * bend), along) for sign in (1.0, -1.0)]
    backward = np.sum(rebuilt[0] * forward[t], axis=-1) <= np.sum(rebuilt[1] * forward[t], axis=-1)
    rebuilt_dir = np.where(backward[:, None], rebuilt[0], rebuilt[1])
    kept = quat.rotate(quat.from_axis_angle(unit(plane), want - now), unit(a - k))  # opens the angle to want
    shin_dir = np.where(
        (rebuilt_share < 1.0)[:, None], _turned_toward(kept, rebuilt_dir, along, rebuilt_share), rebuilt_dir
    )
    turn_knee = arc(unit(a - k), shin_dir)
    new_a = k + shin_dir * shin[:, None]
    swing = arc(unit(new_a - h), unit(target - h))
    foot = glob[t, ankle].copy()
    chain = joint_path(skeleton, hip, ankle)  # ankle, ..., knee, ..., hip
    for j in chain[1 : chain.index(knee) + 1]:  # the shin's joints: bent, then swung
        glob[t, j] = quat.mul(swing, quat.mul(turn_knee, glob[t, j]))
    for j in chain[chain.index(knee) + 1 :]:  # the thigh's: swung
        glob[t, j] = quat.mul(swing, glob[t, j])
    glob[t, ankle] = foot
    pos[t, knee] = h + quat.rotate(swing, k - h)
    pos[t, ankle] = h + quat.rotate(swing, new_a - h)


def _turned_toward(u: FloatArray, v: FloatArray, axis: FloatArray, share: FloatArray) -> FloatArray:
    """`u` turned about `axis` by `share` of the angle about it that takes it to `v` (both on one
    cone about the axis, so at 1 it is `v`)."""
    u_across = u - axis * np.sum(u * axis, axis=-1, keepdims=True)
    v_across = v - axis * np.sum(v * axis, axis=-1, keepdims=True)
    angle = np.arctan2(np.sum(axis * np.cross(u_across, v_across), axis=-1), np.sum(u_across * v_across, axis=-1))
    return quat.rotate(quat.from_axis_angle(axis, share * angle), u)


def joint_path(skeleton: Skeleton, top: int, bottom: int) -> list[int]:
    """Joints from `bottom` up to `top`, both included."""
    chain = [bottom]
    while chain[-1] != top and skeleton.parents[chain[-1]] >= 0:
        chain.append(int(skeleton.parents[chain[-1]]))
    return chain
