"""Poses by parameters: the keyframed clips (idle, steps, sways, get-ups) and the falls' servo
targets describe a body with a few named angles instead of 22 quaternions, so a key pose is a short
dict and a variant a row.

Pose parameters are degrees, except x, fwd, z: the root in metres (x to the character's left,
fwd along FORWARD). Signs: pitch and flexion forward, roll to the left, yaw to the left; ankle
positive points the toes down; toe positive curls them. A side parameter (arm_flex, knee, ...)
exists per side as `<name>_L` and `<name>_R`.
"""

from __future__ import annotations

import numpy as np

from reactive_anim.core.model import quat
from reactive_anim.core.model.skeleton import Skeleton

from .skeleton import ANKLE_HEIGHT, FORWARD, HEIGHT, PELVIS_Z, SIDES, about_x, about_y, about_z

SIDE_PARAMS = ("arm_flex", "arm_abd", "elbow", "wrist", "hip_flex", "hip_abd", "knee", "ankle", "toe")
BODY_PARAMS = (
    "x",
    "fwd",
    "z",
    "pelvis_pitch",
    "pelvis_roll",
    "pelvis_yaw",
    "spine_pitch",
    "spine_roll",
    "spine_yaw",
    "neck_pitch",
)
PARAMS = BODY_PARAMS + tuple(f"{p}_{side}" for side in SIDES for p in SIDE_PARAMS)
STAND_WIDTH = 0.20  # ankle centres apart when standing at rest, m
STAND_DROP = 0.012  # the pelvis sits this far below its rest height: soft knees, not locked


def pose(base: dict[str, float] | None = None, **changes: float) -> dict[str, float]:
    """A copy of `base` (default: STAND) with `changes`; a side parameter without _L/_R sets both sides."""
    out = dict(STAND if base is None else base)
    for name, value in changes.items():
        if name in SIDE_PARAMS:
            for side in SIDES:
                out[f"{name}_{side}"] = value
        elif name in out:
            out[name] = value
        else:
            raise KeyError(f"unknown pose parameter {name!r}")
    return out


# The standing pose every reaction starts and ends in and the idle breathes around.
STAND = pose(
    dict.fromkeys(PARAMS, 0.0),
    z=PELVIS_Z * HEIGHT - STAND_DROP,
    pelvis_pitch=3.0,
    spine_pitch=1.0,
    neck_pitch=-4.0,
    arm_flex=4.0,
    arm_abd=6.0,
    elbow=14.0,
    wrist=4.0,
)


def pose_vector(p: dict[str, float]) -> np.ndarray:
    """A pose dict as a row (len(PARAMS),), in PARAMS order: rows ease and blend as arrays."""
    return np.array([p[name] for name in PARAMS])


def posed(skeleton: Skeleton, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Root position (T, 3) and local rotations (T, J, 4) for parameter rows (T, len(PARAMS)).

    The spine's angles are shared over its three joints and the neck's over neck and head, as a
    real spine bends along its length.
    """
    count = len(values)
    idx = skeleton.index
    col = {name: values[:, k] for k, name in enumerate(PARAMS)}
    rad = {name: np.radians(v) for name, v in col.items()}
    local = quat.identity((count, skeleton.num_joints))
    root = np.stack([col["x"], np.zeros(count), col["z"]], axis=-1) + col["fwd"][:, None] * FORWARD
    local[:, 0] = quat.mul(
        quat.mul(about_z(rad["pelvis_yaw"]), about_y(rad["pelvis_roll"])), about_x(rad["pelvis_pitch"])
    )
    for j in ("spine", "spine.001", "chest"):
        local[:, idx(j)] = quat.mul(
            quat.mul(about_z(rad["spine_yaw"] / 3), about_y(rad["spine_roll"] / 3)), about_x(rad["spine_pitch"] / 3)
        )
    for j in ("neck", "head"):
        local[:, idx(j)] = about_x(rad["neck_pitch"] / 2)
    for side, s in SIDES.items():
        r = {p: rad[f"{p}_{side}"] for p in SIDE_PARAMS}
        local[:, idx(f"upper_arm.{side}")] = quat.mul(about_x(-r["arm_flex"]), about_y(-s * r["arm_abd"]))
        local[:, idx(f"forearm.{side}")] = about_x(-r["elbow"])
        local[:, idx(f"hand.{side}")] = about_x(-r["wrist"])
        local[:, idx(f"thigh.{side}")] = quat.mul(about_x(-r["hip_flex"]), about_y(-s * r["hip_abd"]))
        local[:, idx(f"shin.{side}")] = about_x(r["knee"])
        local[:, idx(f"foot.{side}")] = about_x(r["ankle"])
        local[:, idx(f"toe.{side}")] = about_x(r["toe"])
    return root, local


def standing_ankles(count: int) -> dict[str, np.ndarray]:
    """Ankle positions (T, 3) of the standing pose: under the hips, a little wider."""
    return {side: np.tile([s * STAND_WIDTH / 2, 0.0, ANKLE_HEIGHT], (count, 1)) for side, s in SIDES.items()}
