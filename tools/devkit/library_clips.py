"""Library clips for tests and benchmarks: wobbled variants of the sample walk written as BVH, a
library.toml writer, classes for the shared mocap files, and perturbed query windows."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from reactive_anim.core.model import bvh, quat
from reactive_anim.core.model.skeleton import Motion
from reactive_anim.core.search.window import FrameFeatures, Query
from tools.devkit.mocap import REPO

WALK = REPO / "sample_clips" / "walk.bvh"


def make_clip(path: Path, seed: int, frames: int = 120, fps: float = 60.0) -> Path:
    """A variant of the sample walk: smooth seeded joint wobble, given length and frame rate."""
    walk = bvh.read_bvh(WALK)
    rng = np.random.default_rng(seed)
    start = int(rng.integers(0, walk.num_frames - frames)) if frames < walk.num_frames else 0
    motion = walk.slice(start, start + min(frames, walk.num_frames))
    t = np.arange(motion.num_frames)[:, None]
    joints = motion.skeleton.num_joints
    amp = rng.uniform(0.0, 0.25, (1, joints))
    phase = rng.uniform(0, 2 * np.pi, (1, joints))
    axis = rng.normal(size=(joints, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    wobble = quat.from_axis_angle(np.broadcast_to(axis, (len(t), joints, 3)), amp * np.sin(0.07 * t + phase))
    local_rot = quat.mul(motion.local_rot, wobble)
    motion = Motion(motion.skeleton, fps, motion.root_pos, local_rot, motion.local_pos)
    bvh.write_bvh(path, motion)
    return path


def write_toml(folder: Path, clips: list[dict]) -> Path:
    lines = []
    for clip in clips:
        lines.append("[[clip]]")
        for key, value in clip.items():
            if isinstance(value, str):
                lines.append(f'{key} = "{value}"')
            elif isinstance(value, dict):
                inner = ", ".join(f'{k} = "{v}"' for k, v in value.items())
                lines.append(f"{key} = {{ {inner} }}")
            else:
                lines.append(f"{key} = {value}")
        lines.append("")
    path = folder / "library.toml"
    path.write_text("\n".join(lines), encoding="utf-8")
    return path


def mocap_class(path: Path) -> str:
    """Classes for the shared locomotion clips, by file name (what is measured is the search)."""
    name = path.name
    if name in ("90_18.bvh",):
        return "fall_backward_sit"
    if name in ("91_59.bvh",):
        return "fall_side_knees"
    if name in ("139_16.bvh",):
        return "fall_forward_hands"
    if "walk-back" in name:
        return "steps_back"
    if "turn" in name or "walk-left" in name or "walk-right" in name:
        return "sway_balance"
    if "walk" in name:
        return "steps_forward"
    if "run" in name or "dash" in name:
        return "step_forward"
    if path.parent.name == "cmu_iclone":
        return "step_back"
    return "fall_forward_roll"  # kick, punch, slash, respond


def perturbed(f: FrameFeatures, rng: np.random.Generator, noise_m: float, noise_rad: float) -> Query:
    """Joint positions moved by noise_m (random directions), rotations by noise_rad, heading by
    noise_rad, and the whole window turned by a random yaw and moved up to 50 m on the ground."""
    shape = f.pos_local.shape[:-1]
    direction = rng.normal(size=shape + (3,))
    direction /= np.linalg.norm(direction, axis=-1, keepdims=True)
    pos_local = f.pos_local + noise_m * direction
    axis = rng.normal(size=shape + (3,))
    axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
    rot = quat.mul(f.rot, quat.from_axis_angle(axis, np.full(shape, noise_rad)))
    yaw = rng.uniform(-np.pi, np.pi)
    c, s = np.cos(yaw), np.sin(yaw)
    ground = f.ground @ np.array([[c, s], [-s, c]]) + rng.uniform(-50, 50, 2)
    heading = f.heading + yaw + rng.normal(0.0, noise_rad, f.heading.shape)
    return Query(FrameFeatures(pos_local, heading, ground, rot))
