"""Blends between motions: theta_blend for the CD servo targets, and the CF fade (paper 2.5, step 6).

The paper drives the transition (CD) with PD servos toward theta_blend(t), "the desired trajectory
blended from the two mocap sequences" (the motion before the impact and Sequence-2), and then fades
the simulated CD into Sequence-2's EF: root position linearly, joint rotations by quaternion slerp,
so that at F the pose is Sequence-2's. Both use `blend` with `fade_weights`.

What we choose where the paper is silent, and why:
- The fade weight goes from 0 at the first frame to 1 at the last along the quintic smootherstep
  6s^5 - 15s^4 + 10s^3: its first and second derivatives are zero at both ends, so at C the output
  leaves CD with CD's own velocity and at F it joins the clip with the clip's velocity (a linear
  fade would add a velocity step of (clip - CD) / duration at both ends). A fall's C..F may take
  it on a warped clock instead (fade_shape.py): a body thrown flat and still tumbling, slerped
  toward a still clip along the plain curve, turns its limbs faster than either source.
- Joint offsets (animated bone lengths, as in the Bandai Namco files) are lerped like the root.
- Each joint's arc stays the same from frame to frame: the shorter one where the weight is
  nearest 1/2, and from there whichever continues it. Taking the shorter arc on every frame flips
  to the other way round wherever the two sources' rotations pass half a turn apart (a leg the
  simulation kicked high faded into a planted clip leg: the foot jumped 1.3 m in a frame).
- A root with a single child (a ground bone above the hips: Bandai Namco's joint_Root, iClone's
  BoneRoot) has that child faded in world space, its position lerped and its rotation slerped.
  Blended through the root, the root's turn swings the hips on an arc as wide as their offset from
  the root, which in the Bandai files carries the walk (4.5 m in a shared run): two sources half a
  turn apart put the hips metres off their path for a few frames, far faster than anyone runs, and
  a next push simulated from there exploded. Where a source animates that offset (position channels), the
  offset takes up the difference; where both hang the hips on the rest bone, the root moves.
"""

from __future__ import annotations

import numpy as np

from ..model import quat
from ..model.arrays import FloatArray
from ..model.ease import smootherstep
from ..model.errors import SkeletonError
from ..model.skeleton import Motion, child_in_world, root_child
from ..search.window import yaw_rotate


def fade_weights(frames: int, lag: float = 1.0, delay: float = 0.0) -> FloatArray:
    """(frames,) weights from 0 (first frame) to 1 (last) with zero slope and curvature at both ends.
    A fade held back: `delay` (0 <= delay < 1), the share of the frames still all the first source's
    before it starts; `lag` (> 0) over 1, the smootherstep of time to the power `lag`, slower to
    leave the first source and faster toward the end (under 1 the other way round)."""
    if not (0.0 <= delay < 1.0 and lag > 0.0):
        raise ValueError(f"a fade needs 0 <= delay < 1 and lag > 0, not delay {delay}, lag {lag}")
    if frames < 2:
        return np.ones(max(frames, 0))
    t = np.linspace(0.0, 1.0, frames)
    return smootherstep(np.clip((t - delay) / (1.0 - delay), 0.0, 1.0) ** lag)


def carry(motion: Motion, pose: Motion, frames: int) -> Motion:
    """`motion` with its first frame turned into `pose`'s first frame: each joint's turn from the
    one to the other carried on and let go over `frames` frames (1 - fade_weights), after which the
    motion is its own. The root's position stays the motion's. theta_blend starts so from the
    simulated body at C rather than from the motion it was pushed off: CD's stiff servos, stiffening
    from C on, no longer pull the body back toward the unpushed pose in its first frames, and the
    motion's own pace comes back once they hold (docs/measurements.md)."""
    delta = quat.mul(quat.conj(motion.local_rot[0]), pose.local_rot[0])
    kept = np.zeros(motion.num_frames)
    span = min(max(frames, 2), motion.num_frames)
    kept[:span] = 1.0 - fade_weights(max(frames, 2))[:span]
    turn = quat.slerp(np.broadcast_to(quat.identity(), delta.shape), delta, np.repeat(kept[:, None], len(delta), 1))
    return Motion(motion.skeleton, motion.fps, motion.root_pos, quat.mul(motion.local_rot, turn), motion.local_pos)


def blend(a: Motion, b: Motion, weights: FloatArray) -> Motion:
    """Per frame, `a` faded into `b` by weights (T,) in [0, 1]: root and joint offsets lerped, joint
    rotations slerped (one arc per joint, see the module docstring), a root's single child in world
    space. Weight 0 gives `a`'s frame exactly, 1 gives `b`'s."""
    if a.skeleton.names != b.skeleton.names:
        raise SkeletonError("can only blend motions of the same skeleton")
    if not (a.num_frames == b.num_frames == len(weights)):
        raise SkeletonError(
            f"blend needs equal lengths: {a.num_frames} and {b.num_frames} frames, {len(weights)} weights"
        )
    w = np.asarray(weights, dtype=np.float64)
    root = a.root_pos + (b.root_pos - a.root_pos) * w[:, None]
    arcs = _continuous_arcs(a.local_rot, b.local_rot, w)
    rot = quat.slerp(a.local_rot, arcs, np.broadcast_to(w[:, None], a.local_rot.shape[:2]), shortest=False)
    rot[w == 0] = a.local_rot[w == 0]
    rot[w == 1] = b.local_rot[w == 1]
    root[w == 1] = b.root_pos[w == 1]
    local_pos = None
    if a.local_pos is not None or b.local_pos is not None:
        pa, pb = a.joint_offsets(), b.joint_offsets()
        local_pos = pa + (pb - pa) * w[:, None, None]
        local_pos[w == 1] = pb[w == 1]
    local_pos = _single_child_in_world(a, b, w, root, rot, local_pos)
    return Motion(a.skeleton, a.fps, root, rot, local_pos)


def blend_travel(
    a: Motion, b: Motion, weights: FloatArray, pelvis: int, travel: FloatArray | None = None
) -> tuple[Motion, tuple[float, float]]:
    """`blend`, with the pelvis' travel over the floor faded by velocity rather than by position, and
    the ground offset (x, y) by which `b` must be moved to carry on from the fade's last frame.
    travel: the weights the travel fades by (default `weights`): the resume takes up the walk's
    pace over a shorter fade than its pose, so that a walker does not dawdle through it.

    For the resume, where a reaction hands back to the motion it interrupted: a position fade from
    a stumble into a walk placed at the fade's first frame pulls the body from one path onto the
    other, and the pelvis gains the fade's curvature times the paths' gap, which grows with the
    speed gap; a planted foot slides with it. Faded by velocity, each frame's step over the floor
    is the weighted mix of the two sources' steps: the pace changes by the fade's slope times the
    speed gap, never by the gap in place, and the body ends where the mixed steps take it; `b` goes
    on from there. Heights stay faded by position (the floor is where both sources put it). Not
    used for C..F: there the body would carry the hit's pace further than the clip's legs step,
    and the feet skid."""
    out = blend(a, b, weights)
    w = np.asarray(weights if travel is None else travel, dtype=np.float64)
    if len(w) < 2:
        return out, (0.0, 0.0)
    pa, pb, po = (m.global_positions()[:, pelvis, :2] for m in (a, b, out))
    mid = ((w[1:] + w[:-1]) / 2.0)[:, None]
    steps = (1.0 - mid) * np.diff(pa, axis=0) + mid * np.diff(pb, axis=0)
    shift = po[0] + np.concatenate([np.zeros((1, 2)), np.cumsum(steps, axis=0)]) - po
    root = out.root_pos.copy()
    root[:, :2] += shift
    end = shift[-1] + po[-1] - pb[-1]  # zero when the fade's last frame is b's own
    return Motion(out.skeleton, out.fps, root, out.local_rot, out.local_pos), (float(end[0]), float(end[1]))


def _continuous_arcs(a: FloatArray, b: FloatArray, w: FloatArray) -> FloatArray:
    """`b` (T, ..., 4) signed so that slerping from `a` takes, per joint, the shorter arc on the
    frame whose weight is nearest 1/2 and an arc continuous in time from there: the relative
    rotation a^-1 b keeps its sign from one frame to the next."""
    if len(w) == 0:
        return b
    relative = quat.mul(quat.conj(a), b)
    steady = quat.make_continuous(relative)
    middle = int(np.argmin(np.abs(w - 0.5)))
    steady *= np.where(steady[middle, ..., :1] < 0, -1.0, 1.0)
    return np.where(np.sum(steady * relative, axis=-1, keepdims=True) < 0, -b, b)


def _single_child_in_world(
    a: Motion, b: Motion, w: FloatArray, root: FloatArray, rot: FloatArray, offsets: FloatArray | None
) -> FloatArray | None:
    """The root's only child faded in world space (see the module docstring), in place on root and
    rot, on the frames strictly between the sources (weights 0 and 1 keep a source's frame).
    Returns the offsets: where either source animates the child's offset, it takes up the
    difference and the root goes straight; where both hang it on its rest bone, the bone keeps its
    length and the root moves to hang it there."""
    kid = root_child(a.skeleton)
    between = np.flatnonzero((w > 0) & (w < 1))
    if kid is None or len(between) == 0:
        return offsets
    (world_a, turn_a), (world_b, turn_b) = child_in_world(a, between, kid), child_in_world(b, between, kid)
    t = w[between]
    world = world_a + (world_b - world_a) * t[:, None]
    turn = rot[between, 0]
    rest = a.skeleton.offsets[kid]
    if offsets is None or all(
        np.array_equal(m.joint_offsets()[between, kid], np.broadcast_to(rest, world.shape)) for m in (a, b)
    ):
        root[between] = world - quat.rotate(turn, np.broadcast_to(rest, world.shape))
    else:
        offsets[between, kid] = quat.rotate(quat.conj(turn), world - root[between])
    arcs = _continuous_arcs(turn_a, turn_b, t)
    rot[between, kid] = quat.mul(quat.conj(turn), quat.slerp(turn_a, arcs, t, shortest=False))
    return offsets


def place(motion: Motion, yaw: float, offset: tuple[float, float]) -> Motion:
    """The motion turned by `yaw` about the world Z axis through the origin, then moved on the
    ground by `offset` (x, y): how a matched clip is put where the character is (search.Match)."""
    turn = quat.from_axis_angle(np.array([0.0, 0.0, 1.0]), np.float64(yaw))
    root = yaw_rotate(yaw, motion.root_pos)
    root[:, :2] += np.asarray(offset, dtype=np.float64)
    rot = motion.local_rot.copy()
    rot[:, 0] = quat.mul(np.broadcast_to(turn, rot[:, 0].shape), rot[:, 0])
    return Motion(motion.skeleton, motion.fps, root, rot, None if motion.local_pos is None else motion.local_pos.copy())
