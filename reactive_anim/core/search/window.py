"""Eq. 1 of the paper (section 2.4, Table 2): the distance between two windows of frames.

    D(f_s, f_m) = sum_{i<ws} sum_j  w_p[j] |p_j(f_s+i) - p_j(f_m+i)|  +  w_q[j] |theta_j(f_s+i) - theta_j(f_m+i)|

over the 15 joints of Table 2 (neck, back, waist and both hips, knees, shoulders, elbows, wrists,
ankles; left and right weighted alike). This module is the definition, readable against the paper;
search_index.py makes finding the smallest D fast without changing its value.

Definitions (the paper leaves them open; these are ours):
- Units: positions in metres, angles in radians, so one radian weighs like one metre.
- |theta_a - theta_b| is the rotation angle of q_a^-1 q_b for the joint's *local* rotation (relative
  to its skeleton parent), in [0, pi], q and -q equal. Local rotations do not change when the whole
  character turns or moves, so they need no alignment. The pelvis is not in Table 2 and carries no
  rotation term; its orientation enters through the aligned positions of the joints that hang from it.
- Alignment: before positions are compared, each window is expressed in the heading frame of its
  *first* frame (pelvis ground point at the origin, heading along +X). That is a turn about Z and a
  move on the ground, so where the character stands and which way it faces do not matter, and the
  transform that makes the first frames agree is the placement of the clip (search.Match). Heights
  are not changed (the ground is Z = 0 in both).
- Heading: the twist about world Z of the pelvis' global rotation (yaw = 2 atan2(q_z, q_w) of the
  twist-swing split q = twist * swing) plus the facing of the skeleton's rest pose (perpendicular to
  the rest hip line). Turning the whole character adds exactly that yaw to the twist; unlike a
  projected "forward" axis it stays defined when the pelvis tips far over (falls).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..model.arrays import AnyFloatArray, FloatArray, IndexArray
from ..model.errors import LibraryError
from ..model.rig import Rig
from ..model.skeleton import Motion, resample

# Table 2, per joint row: (position weight w_p, rotation weight w_theta); left and right alike.
TABLE2_POSITION_WEIGHTS: dict[str, float] = {
    "neck": 0.4, "back": 0.4, "waist": 0.6, "hip": 0.8, "knee": 0.6,
    "shoulder": 0.6, "elbow": 0.6, "wrist": 0.2, "ankle": 0.1,
}  # fmt: skip
TABLE2_ROTATION_WEIGHTS: dict[str, float] = {
    "neck": 0.3, "back": 0.4, "waist": 0.6, "hip": 1.0, "knee": 0.8,
    "shoulder": 0.4, "elbow": 0.4, "wrist": 0.2, "ankle": 0.1,
}  # fmt: skip
# The joints Eq. 1 sums over, in feature order (roles.py names).
SEARCH_ROLES: tuple[str, ...] = (
    "neck", "back", "waist", "hip_l", "hip_r", "knee_l", "knee_r", "shoulder_l", "shoulder_r",
    "elbow_l", "elbow_r", "wrist_l", "wrist_r", "ankle_l", "ankle_r",
)  # fmt: skip
NUM_JOINTS = len(SEARCH_ROLES)


def joint_weights(weights: dict[str, float]) -> FloatArray:
    """Per-joint weights (15,) in SEARCH_ROLES order from a Table 2 row -> weight mapping."""
    rows = [role.removesuffix("_l").removesuffix("_r") for role in SEARCH_ROLES]
    missing = sorted({row for row in rows if row not in weights})
    if missing:
        raise LibraryError(f"search weights lack the Table 2 rows: {', '.join(missing)}")
    return np.array([float(weights[row]) for row in rows])


@dataclass
class FrameFeatures:
    """What Eq. 1 reads of each frame, for T frames and the 15 joints of SEARCH_ROLES.

    pos_local: (T, 15, 3) joint positions in the frame's own heading frame (pelvis ground point at
      the origin, heading along +X, Z up, metres).
    heading: (T,) pelvis heading about Z, radians.  ground: (T, 2) pelvis ground point (x, y).
    rot: (T, 15, 4) joint-local rotations (w, x, y, z), w >= 0.
    float64 as computed; a library's are float32 views of its arrays (Library.frames).
    """

    pos_local: AnyFloatArray
    heading: AnyFloatArray
    ground: AnyFloatArray
    rot: AnyFloatArray

    @property
    def num_frames(self) -> int:
        return self.heading.shape[0]

    def rows(self, frames: slice) -> FrameFeatures:
        """The features of some of the frames (a stride, a window)."""
        return FrameFeatures(self.pos_local[frames], self.heading[frames], self.ground[frames], self.rot[frames])

    def world_positions(self) -> FloatArray:
        """Joint positions in world space (T, 15, 3), rebuilt from the heading frames."""
        return yaw_rotate(self.heading[:, None], self.pos_local) + _ground3(self.ground)[:, None]


def yaw_rotate(angle: AnyFloatArray | float, v: AnyFloatArray) -> FloatArray:
    """Rotate vectors (..., 3) about Z by `angle` (broadcast against (...))."""
    c, s = np.cos(angle), np.sin(angle)
    out = np.empty(np.broadcast_shapes(np.shape(angle) + (3,), v.shape))
    out[..., 0] = c * v[..., 0] - s * v[..., 1]
    out[..., 1] = s * v[..., 0] + c * v[..., 1]
    out[..., 2] = v[..., 2]
    return out


def _ground3(ground: AnyFloatArray) -> FloatArray:
    return np.concatenate([ground, np.zeros(ground.shape[:-1] + (1,))], axis=-1)


def rest_heading(motion: Motion, rig: Rig) -> float:
    """Facing of the rest pose: perpendicular to the hip line, on the ground (radians about Z).

    Skeletons differ in which way their rest pose faces (CMU +Z in Y-up files, others -Y or +Y), so
    the pelvis twist alone would not compare across skeletons; adding this makes 0 mean "facing +X".
    """
    rest = motion.skeleton.rest_positions()
    left: FloatArray = rest[rig.joint("hip_l")] - rest[rig.joint("hip_r")]
    forward = np.cross(left, [0.0, 0.0, 1.0])
    if np.hypot(forward[0], forward[1]) < 1e-9:
        return 0.0
    return float(np.arctan2(forward[1], forward[0]))


def frame_features(motion: Motion, rig: Rig) -> FrameFeatures:
    """Eq. 1's per-frame features of a whole motion (see FrameFeatures), by forward kinematics; rig:
    the motion's."""
    joints = [rig.joint(role) for role in SEARCH_ROLES]
    pelvis = rig.joint("pelvis")
    pos, rot = motion.global_transforms()
    q = rot[:, pelvis]
    heading = 2.0 * np.arctan2(q[:, 3], q[:, 0]) + rest_heading(motion, rig)
    heading = np.angle(np.exp(1j * heading))  # wrap to (-pi, pi]
    ground = pos[:, pelvis, :2].copy()
    pos_local = yaw_rotate(-heading[:, None], pos[:, joints] - _ground3(ground)[:, None])
    local = motion.local_rot[:, joints]
    local = np.where(local[..., :1] < 0, -local, local)
    return FrameFeatures(pos_local, heading, ground, local)


def aligned_window(pos_local: FloatArray, heading: FloatArray, ground: FloatArray) -> FloatArray:
    """Window positions in the heading frame of its first frame: (..., W, 15, 3) from
    pos_local (..., W, 15, 3), heading (..., W), ground (..., W, 2)."""
    rel = heading - heading[..., :1]
    offset = ground - ground[..., :1, :]
    back = -heading[..., :1]
    c, s = np.cos(back), np.sin(back)
    shift = np.stack([c * offset[..., 0] - s * offset[..., 1], s * offset[..., 0] + c * offset[..., 1]], axis=-1)
    out = yaw_rotate(rel[..., None], pos_local)
    out[..., :2] += shift[..., None, :]
    return out


@dataclass
class Query:
    """A query window of W frames at the library's rate: FrameFeatures plus its aligned positions."""

    features: FrameFeatures
    aligned: FloatArray = field(init=False)

    def __post_init__(self) -> None:
        f = self.features
        self.aligned = aligned_window(
            f.pos_local.astype(np.float64), f.heading.astype(np.float64), f.ground.astype(np.float64)
        )

    @property
    def window(self) -> int:
        return self.features.num_frames


def query_from_motion(motion: Motion, start_frame: float, window: int, fps: float, rig: Rig | None = None) -> Query:
    """The query window starting at `start_frame` (the motion's frames): `window` frames at `fps`.

    rig: the motion's; default its skeleton's own roles, else found by name (Rig.of).
    """
    rig = rig or Rig.of(motion.skeleton)
    times = start_frame / motion.fps + np.arange(window) / fps
    end = (motion.num_frames - 1) / motion.fps
    if start_frame < 0 or times[-1] > end + 1e-9:
        raise LibraryError(
            f"the query window ({window} frames at {fps:g} fps from frame {start_frame:g}) runs past the "
            f"motion's {motion.num_frames} frames at {motion.fps:g} fps"
        )
    return Query(frame_features(resample(motion, times), rig))


def window_costs(frames: FrameFeatures, starts: IndexArray, query: Query, wp: FloatArray, wq: FloatArray) -> FloatArray:
    """Eq. 1 (float64, (n,)) between the query and the windows of `frames` starting at `starts` (n,).

    wp, wq: per-joint weights (15,) from joint_weights."""
    return Windows.of(frames, starts, query.window).costs(query, wp, wq)


@dataclass(frozen=True)
class Windows:
    """Eq. 1's candidate side, aligned once: several queries (the resume's fade starts) compare
    against the same windows without aligning them again. aligned (n, W, 15, 3); rot (4, n, W, 15),
    the local rotations as component planes."""

    aligned: FloatArray
    rot: FloatArray

    @classmethod
    def of(cls, frames: FrameFeatures, starts: IndexArray, window: int) -> Windows:
        """The `window`-frame windows of `frames` starting at `starts` (n,)."""
        index = np.asarray(starts)[:, None] + np.arange(window)
        aligned = aligned_window(
            *(a[index].astype(np.float64) for a in (frames.pos_local, frames.heading, frames.ground))
        )
        return cls(aligned, frames.rot[index].astype(np.float64).transpose(3, 0, 1, 2))

    def costs(self, query: Query, wp: FloatArray, wq: FloatArray, count: int | None = None) -> FloatArray:
        """Eq. 1 of the first `count` windows (default all) against `query`."""
        dist = np.sqrt(np.sum((self.aligned[:count] - query.aligned) ** 2, axis=-1))  # (n, W, 15)
        angle = rotation_angles(query.features.rot.astype(np.float64).transpose(2, 0, 1), self.rot[:, :count])
        # Row-wise sums (not BLAS), so identical windows get bit-identical costs and ties stay ties.
        return ((dist * wp).sum(axis=-1) + (angle * wq).sum(axis=-1)).sum(axis=1)


def rotation_angles(a: FloatArray, b: FloatArray) -> FloatArray:
    """Rotation angle of a^-1 b for quaternions given as component planes (w, x, y, z, ...):
    2 atan2(|vector part|, |scalar part|), as quat.angle_between but without its stacking, which
    costs several times more on the few windows the search evaluates exactly."""
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    w = aw * bw + ax * bx + ay * by + az * bz
    vx = aw * bx - bw * ax - (ay * bz - az * by)
    vy = aw * by - bw * ay - (az * bx - ax * bz)
    vz = aw * bz - bw * az - (ax * by - ay * bx)
    return 2.0 * np.arctan2(np.sqrt(vx * vx + vy * vy + vz * vz), np.abs(w))
