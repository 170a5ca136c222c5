"""Simulated pushes on locomotion clips, labelled by their physical outcome (core.outcome).

Each push: a clip, an impact frame B, a hit bone (head, chest, pelvis, an upper arm, a thigh), a
direction all around the character (relative to its facing at B) with some vertical spread, and a
strength from MIN_STRENGTH to MAX_STRENGTH N·s, log-uniform (half the pushes below 63 N·s, where
sway, one step and several steps part; about one in six still ends in a fall). Every random number
is drawn up front from one seeded generator, in a fixed order, so the data set does not depend on
how many worker processes simulate it; a worker simulates whole impact frames, so the motion's own
state at a frame is read once (features.FeatureReader keeps it).

Samples are grouped by impact frame: pushes on one frame share the pre-impact state, so the train,
validation and test splits keep whole frames apart (no state seen in training is tested).
"""

from __future__ import annotations

import math
import multiprocessing
import os
from collections.abc import Callable, Iterator
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from reactive_anim.core.classify.features import EXTENDED_FEATURES, FeatureReader, reaction_features
from reactive_anim.core.classify.outcome import simulate_outcome
from reactive_anim.core.model import bvh
from reactive_anim.core.model.classes import CLASS_SLUGS
from reactive_anim.core.model.errors import ReactiveAnimError
from reactive_anim.core.model.impact import Impact
from reactive_anim.core.model.skeleton import Motion
from reactive_anim.core.physics.ragdoll import build_ragdoll
from reactive_anim.core.physics.simulate import REACTION_WINDOW
from reactive_anim.core.physics.workspace import Workspace

HIT_ROLES = ("head", "chest", "pelvis", "shoulder_l", "shoulder_r", "hip_l", "hip_r")  # upper arms, thighs
MIN_STRENGTH, MAX_STRENGTH = 10.0, 400.0  # N·s
MAX_ELEVATION_DEGREES = 30.0  # push directions from 30 degrees below to 30 above horizontal
PUSHES_PER_FRAME = 30  # pushes on each impact frame
EDGE_TIME = 0.3  # s kept clear at both ends of a clip (the ground search and C must fit)

Progress = Callable[[int, int], None]


@dataclass(frozen=True)
class Push:
    """One push to simulate: the clip's index, B, the hit role, azimuth from the facing (radians,
    counter-clockwise seen from above, 0 = from behind, pushing forward), elevation, strength."""

    clip: int
    frame: float
    role: str
    azimuth: float
    elevation: float
    strength: float


@dataclass
class PushSet:
    """Simulated pushes: features (N, len(EXTENDED_FEATURES)), labels (N,) as CLASS_SLUGS indices,
    groups (N,) one id per (clip, impact frame), and the pushes themselves."""

    features: np.ndarray
    labels: np.ndarray
    groups: np.ndarray
    pushes: list[Push]
    clips: list[str]
    failed: int = 0
    details: list[dict] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.labels)

    def subset(self, keep: np.ndarray) -> PushSet:
        """The samples where `keep` is True (the failed count stays)."""
        index = np.flatnonzero(keep)
        return PushSet(
            self.features[index],
            self.labels[index],
            self.groups[index],
            [self.pushes[i] for i in index],
            self.clips,
            self.failed,
            [self.details[i] for i in index],
        )

    def class_counts(self) -> dict[str, int]:
        counts = np.bincount(self.labels, minlength=len(CLASS_SLUGS))
        return {slug: int(n) for slug, n in zip(CLASS_SLUGS, counts, strict=True)}


def plan_pushes(
    clip_frames: list[int],
    clip_fps: list[float],
    count: int,
    seed: int,
    per_frame: int = PUSHES_PER_FRAME,
    max_strength: float = MAX_STRENGTH,
) -> list[Push]:
    """`count` pushes spread evenly over the clips, `per_frame` on each impact frame (a frame drawn
    uniformly between EDGE_TIME from either end of its clip), strengths up to `max_strength`."""
    rng = np.random.default_rng(seed)
    elevation = math.radians(MAX_ELEVATION_DEGREES)
    pushes: list[Push] = []
    frames_needed = math.ceil(count / per_frame)
    for n in range(frames_needed):
        clip = n % len(clip_frames)
        edge = EDGE_TIME * clip_fps[clip]
        frame = float(rng.uniform(edge, clip_frames[clip] - 1 - edge - REACTION_WINDOW * clip_fps[clip]))
        for _ in range(min(per_frame, count - len(pushes))):
            pushes.append(
                Push(
                    clip=clip,
                    frame=frame,
                    role=str(rng.choice(HIT_ROLES)),
                    azimuth=float(rng.uniform(0.0, 2.0 * math.pi)),
                    elevation=float(rng.uniform(-elevation, elevation)),
                    strength=float(math.exp(rng.uniform(math.log(MIN_STRENGTH), math.log(max_strength)))),
                )
            )
    return pushes


# ---------------------------------------------------------------------------------------------
# One worker's clips


@dataclass
class _Clip:
    motion: Motion
    reader: FeatureReader
    workspace: Workspace


_CLIPS: dict[str, _Clip] = {}


def _clip(path: str) -> _Clip:
    """A clip with its ragdoll (neutral pose from the clip itself) and feature reader, once per process."""
    if path not in _CLIPS:
        motion = bvh.read_bvh(path)
        ragdoll = build_ragdoll(motion.skeleton, reference=motion)
        _CLIPS[path] = _Clip(motion, FeatureReader(ragdoll), Workspace(ragdoll))
    return _CLIPS[path]


def push_direction(reader: FeatureReader, motion: Motion, push: Push) -> np.ndarray:
    """The push's world direction from its azimuth and elevation relative to the facing at B."""
    frame = reader.facing(motion, push.frame)
    horizontal = math.cos(push.azimuth) * frame[0] + math.sin(push.azimuth) * frame[1]
    return math.cos(push.elevation) * horizontal + math.sin(push.elevation) * frame[2]


def simulate_push(path: str, push: Push) -> tuple[np.ndarray, int, dict]:
    """Features, label and the outcome's numbers of one push on the clip at `path`."""
    clip = _clip(path)
    role = clip.reader.ragdoll.roles[push.role]
    impact = Impact(push.frame, role, tuple(push_direction(clip.reader, clip.motion, push)), push.strength)
    _, state, outcome = simulate_outcome(clip.reader, clip.motion, impact, workspace=clip.workspace)
    details = {
        "steps": outcome.steps,
        "direction": outcome.direction,
        "excess": outcome.excess,
        "speed": outcome.speed,
        "shift": outcome.xcom_shift,
        "down": outcome.down,
        "omega": state.omega(),
        "leg": clip.reader.rig.leg_length,
    }
    return reaction_features(clip.reader.rig, state), CLASS_SLUGS.index(outcome.reaction), details


def _simulate_group(args: tuple[str, list[Push]]) -> list[tuple[np.ndarray, int, dict] | None]:
    """The pushes of one impact frame; a simulation that fails (SimulationError) is None."""
    path, pushes = args
    out: list[tuple[np.ndarray, int, dict] | None] = []
    for push in pushes:
        try:
            out.append(simulate_push(path, push))
        except ReactiveAnimError:
            out.append(None)
    return out


def _groups(pushes: list[Push]) -> Iterator[list[int]]:
    """Indices of consecutive pushes on the same clip and frame."""
    start = 0
    for i in range(1, len(pushes) + 1):
        if i == len(pushes) or (pushes[i].clip, pushes[i].frame) != (pushes[start].clip, pushes[start].frame):
            yield list(range(start, i))
            start = i


def simulate_pushes(
    paths: list[Path], pushes: list[Push], workers: int = 1, progress: Progress | None = None
) -> PushSet:
    """Simulate and label every push (in `workers` processes); results in the pushes' order."""
    groups = list(_groups(pushes))
    jobs = [(str(paths[pushes[g[0]].clip]), [pushes[i] for i in g]) for g in groups]
    results: list[tuple[np.ndarray, int, dict] | None] = []
    done = 0
    for batch in _run(jobs, workers):
        results.extend(batch)
        done += len(batch)
        if progress:
            progress(done, len(pushes))
    keep = [i for i, r in enumerate(results) if r is not None]
    group_of = np.empty(len(pushes), dtype=int)
    for g, members in enumerate(groups):
        group_of[members] = g
    return PushSet(
        features=np.array([results[i][0] for i in keep]).reshape(-1, len(EXTENDED_FEATURES)),  # type: ignore[index]
        labels=np.array([results[i][1] for i in keep], dtype=int),  # type: ignore[index]
        groups=group_of[keep],
        pushes=[pushes[i] for i in keep],
        clips=[str(p) for p in paths],
        failed=len(pushes) - len(keep),
        details=[results[i][2] for i in keep],  # type: ignore[index]
    )


def _run(jobs: list[tuple[str, list[Push]]], workers: int) -> Iterator[list]:
    if workers <= 1:
        yield from map(_simulate_group, jobs)
        return
    # forkserver: fork() from a process whose MuJoCo/onnxruntime threads are running can deadlock
    # (Python 3.13 warns; 3.14 makes it the default on Linux).
    with ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("forkserver")) as pool:
        yield from pool.map(_simulate_group, jobs)


def default_workers() -> int:
    """Both cores of a 2-core machine, one if only one is there."""
    return max(1, min(2, os.cpu_count() or 1))
