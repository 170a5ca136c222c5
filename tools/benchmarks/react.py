"""Reaction pipeline figures (core/react.py): the time of each step of one impact (BC, classify,
search, CD, blend, splice) on the sample walk with the sample library and the shipped classifier,
and a bake of 20 impacts
on a 3,000-frame motion (the sample walk repeated), all in the core (the Blender bake, with its
keyframe writes, is in the `blender` group). Warm: the library index, the ragdoll and the
simulation workspace are built once, as a bake reuses them.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from reactive_anim.core.classify.classifier import load_classifier
from reactive_anim.core.model import bvh
from reactive_anim.core.model.impact import Impact
from reactive_anim.core.model.skeleton import Motion
from reactive_anim.core.physics.workspace import Workspace
from reactive_anim.core.react import bake_reactions, character_ragdoll, react
from reactive_anim.core.search.library import load_library
from tools.devkit.mocap import REPO
from tools.devkit.poses import ground_axes

from .common import report

STEPS = ("bc", "classify", "search", "cd", "blend", "splice", "total")


def push_impacts(motion: Motion, frames: list[int]) -> list[Impact]:
    """Chest and pelvis pushes from around the character, 40-250 N·s, at the given frames."""
    out = []
    for k, frame in enumerate(frames):
        forward, left = ground_axes(motion, frame)
        angle = 2.0 * np.pi * k / 7.0
        direction = np.cos(angle) * forward + np.sin(angle) * left
        bone = ("chest", "pelvis")[k % 2]
        out.append(Impact(frame, bone, tuple(direction), 40.0 + 30.0 * (k % 8)))
    return out


def repeated_walk(motion: Motion, frames: int) -> Motion:
    """The motion played again and again, each copy starting where the last one ended."""
    out = motion
    while out.num_frames < frames:
        step = out.root_pos[-1] - motion.root_pos[0]
        step[2] = 0.0
        out = out.concat(Motion(motion.skeleton, motion.fps, motion.root_pos + step, motion.local_rot))
    return out.slice(0, frames)


def bench_react() -> None:
    """The pipeline figures (see the module docstring)."""
    walk = bvh.read_bvh(REPO / "sample_clips" / "walk.bvh")
    with tempfile.TemporaryDirectory() as cache:
        library = load_library(REPO / "sample_clips", cache_dir=Path(cache))
        library.search_index()
        ragdoll = character_ragdoll(walk)
        workspace = Workspace(ragdoll)
        classifier = load_classifier()
        times: dict[str, list[float]] = {step: [] for step in STEPS}
        for impact in push_impacts(walk, [40, 60, 80, 100, 120, 140, 160]):
            reaction = react(walk, impact, library, classifier, ragdoll=ragdoll, workspace=workspace)
            for step in STEPS:
                times[step].append(reaction.timings.get(step, 0.0))
        context = {"clip": "sample walk", "impacts": len(times["total"]), "classifier": "shipped"}
        for step in STEPS:
            report("react", f"one impact: {step}, median", float(np.median(times[step])) * 1e3, "ms", **context)
        long = repeated_walk(walk, 3000)
        impacts = push_impacts(long, list(np.linspace(60, 2900, 20).astype(int)))
        start = time.perf_counter()
        baked = bake_reactions(long, impacts, library, classifier)
        report("react", "bake of 20 impacts, core only", time.perf_counter() - start, "s",
               clip="sample walk x 11", frames=long.num_frames, output_frames=baked.motion.num_frames)  # fmt: skip
