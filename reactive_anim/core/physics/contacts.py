"""The floor: where the mocap's ground is, which bodies touch it, and the lowest point of a pose.

The floor is put at the mocap's ground near the start (the lowest sole per frame, median over
GROUND_SPAN either side, never above the start frame's lowest sole), not at z = 0: mocap floors
drift by centimetres, and a character starting in the air or in the floor falls or pops before
anything else happens.
"""

from __future__ import annotations

import mujoco
import numpy as np

from ..model.arrays import BoolArray, FloatArray
from ..model.skeleton import Motion
from .joints import HeldPose, MocapTable, mocap_table
from .ragdoll import Ragdoll
from .workspace import Workspace, place_bodies, reset_data, workspace_for

GROUND_SPAN = 0.25  # s either side of the start frame in which the stance sole finds the ground


def ground_level(
    ragdoll: Ragdoll, motion: Motion, frame: float, span: float = GROUND_SPAN, workspace: Workspace | None = None
) -> float:
    """Height of the ground the mocap walks on near `frame`: the lowest point of the ragdoll's soles,
    per frame, within `span` seconds either side, and of those the median.

    Mocap floors are rarely at exactly z = 0 (and our soles are guesses), so the simulated floor is
    put where the soles touch rather than the character dropped or lifted onto z = 0.
    """
    reach = span * motion.fps
    table = mocap_table(ragdoll, motion, frame - reach, frame + reach)
    with workspace_for(ragdoll, workspace) as ws:
        return ground_from_table(ws, table, frame, table.held(round(frame)), reach)


def ground_from_table(ws: Workspace, table: MocapTable, frame: float, held: HeldPose, reach: float) -> float:
    place_bodies(ws, held)
    model = ws.model
    data = reset_data(ws.kin_data)
    soles = ws.ragdoll.index.sole_geoms
    numbers = table.first + np.arange(len(table.qpos))
    rows = np.flatnonzero(np.abs(numbers - frame) <= reach)
    # Per frame only the kinematics; the sole heights of all frames at once afterwards.
    sole_z = np.empty((len(rows), len(soles)))
    sole_axis_z = np.empty((len(rows), len(soles)))
    for n, i in enumerate(rows):
        data.qpos[:] = table.qpos[i]
        mujoco.mj_kinematics(model, data)
        sole_z[n] = data.geom_xpos[soles, 2]
        sole_axis_z[n] = data.geom_xmat[soles, 8]  # the capsule axis' z: row-major (3, 3), [2, 2]
    size = model.geom_size[soles]
    heights = sole_z - np.abs(sole_axis_z * size[:, 1]) - size[:, 0]
    lowest: FloatArray = heights.min(axis=1)
    # The median frame's lowest sole: the standing foot, robust to heel-strike dips and flight
    # phases; but never above the start frame's lowest sole, so the start does not pop out of the
    # floor, nor above any body at the start (a character lying or kneeling with its feet up).
    start = int(np.argmin(np.abs(numbers[rows] - round(frame))))
    return float(min(np.median(lowest), lowest[start], _lowest_body_point(ws, data, table.qpos[rows[start]])))


def _lowest_body_point(ws: Workspace, data: mujoco.MjData, qpos: FloatArray) -> float:
    """The lowest point of any ragdoll geom (capsules and spheres) in the pose `qpos`."""
    model = ws.model
    data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    geoms = np.flatnonzero(ws.ragdoll.index.body_of_geom >= 0)
    size = model.geom_size[geoms]
    half = np.where(model.geom_type[geoms] == mujoco.mjtGeom.mjGEOM_CAPSULE, size[:, 1], 0.0)
    return float(np.min(data.geom_xpos[geoms, 2] - np.abs(data.geom_xmat[geoms, 8] * half) - size[:, 0]))


def floor_contacts(ws: Workspace, data: mujoco.MjData) -> BoolArray:
    """(B,) which ragdoll bodies touch the floor now (a contact between the floor and their geom)."""
    touching = np.zeros(len(ws.ragdoll.bodies), dtype=bool)
    if data.ncon:
        geoms = data.contact.geom[: data.ncon]
        floor = ws.ragdoll.index.floor_geom
        other = np.where(geoms[:, 0] == floor, geoms[:, 1], geoms[:, 0])[np.any(geoms == floor, axis=1)]
        touching[ws.ragdoll.index.body_of_geom[other]] = True
    return touching
