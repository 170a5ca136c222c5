"""A ragdoll posed without stepping: where its capsules and its centre of mass are for some joint
positions. What the classifier reads at C (classify/capture.py, classify/features.py) without
touching the engine itself."""

from __future__ import annotations

import mujoco
import numpy as np

from ..model.arrays import FloatArray
from .ragdoll import Ragdoll


class PoseProbe:
    """Kinematics of a ragdoll at given joint positions (qpos). Holds its own MjData: one per thread.

    geoms: the ragdoll's geoms (the floor left out); geom_body: each one's body (index into
    Ragdoll.bodies); radii: each one's radius (m)."""

    def __init__(self, ragdoll: Ragdoll):
        model = ragdoll.model
        self.model = model
        self.data = mujoco.MjData(model)
        self.root_body = int(ragdoll.index.body_ids[0])
        self.geoms = np.flatnonzero(np.isin(model.geom_bodyid, ragdoll.index.body_ids))
        body_index = {int(b): k for k, b in enumerate(ragdoll.index.body_ids)}
        self.geom_body = np.array([body_index[int(model.geom_bodyid[g])] for g in self.geoms])
        self.radii: FloatArray = model.geom_size[self.geoms, 0]

    def capsule_ends(self, qpos: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Both end centres of each capsule (a sphere: its centre twice), (2G, 3), and the height of
        the surface's lowest point below each, (2G,), in the pose qpos."""
        model, data, geoms = self.model, self.data, self.geoms
        data.qpos[:] = qpos
        mujoco.mj_kinematics(model, data)
        centre = data.geom_xpos[geoms]
        axis = data.geom_xmat[geoms].reshape(-1, 3, 3)[:, :, 2]
        half = np.where(model.geom_type[geoms] == mujoco.mjtGeom.mjGEOM_CAPSULE, model.geom_size[geoms, 1], 0.0)
        ends = np.stack([centre - axis * half[:, None], centre + axis * half[:, None]], axis=1).reshape(-1, 3)
        return ends, ends[:, 2] - np.repeat(model.geom_size[geoms, 0], 2)

    def centre_of_mass(self, qpos: FloatArray) -> FloatArray:
        """(3,) the whole ragdoll's centre of mass in the pose qpos."""
        self.data.qpos[:] = qpos
        mujoco.mj_kinematics(self.model, self.data)
        mujoco.mj_comPos(self.model, self.data)
        return self.data.subtree_com[self.root_body].copy()
