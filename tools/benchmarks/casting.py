"""Any-character figures (core/transition/casting.py, core/transition/retarget.py): the jump search's costs for the same
kind of pushes on the sample walk and on walks of other skeletons (the shared iClone, Bandai Namco
and CMU walks, and the sample walk on a T-pose variant of its skeleton), against the sample
library; and the time to retarget each library clip onto those skeletons. Costs of the same size
mean the search compares like with like across skeletons.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from reactive_anim.core.classify.classifier import load_classifier
from reactive_anim.core.model import bvh
from reactive_anim.core.model.rig import Rig
from reactive_anim.core.model.skeleton import Motion
from reactive_anim.core.react import react
from reactive_anim.core.search.library import load_library
from reactive_anim.core.transition import retarget
from tools.devkit.mocap import MOCAP, REPO
from tools.devkit.skeletons import WALK, t_pose_variant

from .common import report, skipped
from .react import push_impacts

WALKS = {
    "iClone (CMU-derived CC rig) 002_01": MOCAP / "cmu_iclone" / "002_01.bvh",
    "Bandai Namco walk_normal_001": MOCAP / "bandai_namco" / "dataset-1" / "dataset-1_walk_normal_001.bvh",
    "CMU 139_16": MOCAP / "cmu" / "139_16.bvh",
}
FRAMES = [60, 90, 120, 150, 180]


def _characters() -> dict[str, Motion]:
    found = {"sample walk": WALK}
    found["sample walk on a T-pose variant"] = retarget.retarget(
        WALK, retarget.retarget_map(Rig.of(WALK.skeleton), Rig.of(t_pose_variant()))
    )
    for label, path in WALKS.items():
        if path.is_file():
            found[label] = bvh.read_bvh(path)
        else:
            skipped("cast", label)
    return found


def _role_named(motion: Motion, impacts: list) -> list:
    roles = Rig.of(motion.skeleton).roles
    return [type(i)(i.frame, roles[i.bone], i.direction, i.strength) for i in impacts]


def bench_casting() -> None:
    """The figures (see the module docstring)."""
    classifier = load_classifier()
    with tempfile.TemporaryDirectory() as cache:
        library = load_library(REPO / "sample_clips", cache_dir=Path(cache))
        for label, motion in _characters().items():
            frames = [f for f in FRAMES if f < motion.num_frames - 60]
            costs = []
            for impact in _role_named(motion, push_impacts(motion, frames)):
                costs.append(react(motion, impact, library, classifier).cost)
            context = {"character": label, "joints": motion.skeleton.num_joints, "pushes": len(costs)}
            report("cast", "search cost, median", float(np.median(costs)), "", **context)
            report("cast", "search cost, max", float(np.max(costs)), "", **context)
            if motion.skeleton.names == WALK.skeleton.names:
                continue
            mapping = retarget.retarget_map(Rig.of(WALK.skeleton), Rig.of(motion.skeleton))
            seconds, frames_done = [], 0
            for clip in library.clips:
                source = library.clip_motion(clip.name, motion.fps)
                start = time.perf_counter()
                retarget.retarget(source, mapping)
                seconds.append(time.perf_counter() - start)
                frames_done += source.num_frames
            report("cast", "retarget one library clip, median", float(np.median(seconds)) * 1e3, "ms",
                   frames_per_clip=round(frames_done / len(seconds)), **context)  # fmt: skip
