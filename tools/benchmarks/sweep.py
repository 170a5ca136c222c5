"""Robustness sweep: random pushes baked on every shared mocap file, counting what fails and how fast
anything moves away from the hits (a pop shows there as a joint crossing the floor in a frame).

Per file (../shared/mocap, test and benchmark data only): PUSHES impacts at random frames (10-85% of
the clip), on random role bones, from random directions up to ELEVATION radians off horizontal,
log-uniform STRENGTHS N·s, baked together (bake_reactions, the sample library, the shipped classifier).
An impact refused as too strong for its bone (ImpactError: it would start the body part faster than
watch.MAX_HIT_SPEED) is halved and the bake tried again, up to RETRIES halvings; any other error
is counted and printed. The time is that of the bake that went through. Speeds are the fastest joint
per frame, leaving out the root and the frames from one before each impact to three after it (the
hit itself moves a hand at up to 50 m/s). Under the floor: the lowest joint (root left out) from
the first impact on, under the character's own floor (its lowest foot point, Casting.sole).
Seeded: the same pushes every run.
"""

from __future__ import annotations

import time
from collections import Counter

import numpy as np

from reactive_anim.core.classify.classifier import load_classifier
from reactive_anim.core.model import bvh
from reactive_anim.core.model.errors import ImpactError, ReactiveAnimError
from reactive_anim.core.model.impact import Impact
from reactive_anim.core.model.rig import Rig
from reactive_anim.core.model.skeleton import Motion
from reactive_anim.core.react import Baked, bake_reactions, character_ragdoll
from reactive_anim.core.search.library import load_library
from reactive_anim.core.transition.casting import Casting
from tools.devkit.mocap import REPO, mocap_files

from .common import report, skipped

GROUP = "sweep"
SEED = 11
PUSHES = 4
STRENGTHS = (20.0, 400.0)  # N·s, log-uniform
ELEVATION = 0.4  # radians either side of horizontal
RETRIES = 6
HIT_FRAMES = (1, 4)  # frames before and after each impact left out of the speeds


def random_impacts(motion: Motion, roles: list[str], rng: np.random.Generator) -> list[Impact]:
    """PUSHES impacts on the motion (see the module docstring)."""
    n = motion.num_frames
    impacts = []
    for _ in range(PUSHES):
        frame = float(rng.integers(int(0.1 * n), max(int(0.1 * n) + 1, int(0.85 * n))))
        azimuth, elevation = rng.uniform(0, 2 * np.pi), rng.uniform(-ELEVATION, ELEVATION)
        direction = (np.cos(azimuth) * np.cos(elevation), np.sin(azimuth) * np.cos(elevation), np.sin(elevation))
        strength = float(np.exp(rng.uniform(*np.log(STRENGTHS))))
        impacts.append(Impact(frame, roles[int(rng.integers(len(roles)))], direction, strength))
    return impacts


def bake_halving(motion: Motion, impacts: list[Impact], library, classifier) -> tuple[Baked, int, float]:
    """The bake, halving any impact refused as too strong for its bone; how many were halved, and
    the seconds the bake that went through took."""
    halved = 0
    while True:
        start = time.perf_counter()
        try:
            return bake_reactions(motion, impacts, library, classifier), halved, time.perf_counter() - start
        except ImpactError as error:
            if halved == RETRIES or not isinstance(error.impact, Impact) or error.impact not in impacts:
                raise
            k = impacts.index(error.impact)
            impacts[k] = Impact(impacts[k].frame, impacts[k].bone, impacts[k].direction, impacts[k].strength / 2)
            halved += 1


def fastest_away_from_hits(baked: Baked) -> float:
    """The fastest joint (m/s), root left out, on frames away from the impacts."""
    motion = baked.motion
    speed = np.linalg.norm(np.diff(motion.global_positions()[:, 1:], axis=0), axis=-1).max(axis=1) * motion.fps
    for reaction in baked.reactions:
        b = int(np.ceil(reaction.frame_b))
        speed[max(b - HIT_FRAMES[0], 0) : b + HIT_FRAMES[1]] = 0.0
    speed[0] = 0.0  # some files' first frame is a T-pose
    return float(speed.max())


def deepest_under_floor(baked: Baked, floor: float) -> float:
    """How far (m) the lowest joint, root left out, gets under the character's floor (its lowest
    foot point in its own motion, Casting.sole) from the first impact on."""
    first = int(np.ceil(min(reaction.frame_b for reaction in baked.reactions)))
    return float(floor - baked.motion.global_positions()[first:, 1:, 2].min())


def bench_sweep() -> None:
    """The sweep's figures (see the module docstring)."""
    files = mocap_files()
    if not files:
        skipped(GROUP)
        return
    library, classifier = load_library(REPO / "sample_clips" / "library.toml"), load_classifier()
    rng = np.random.default_rng(SEED)
    errors, fastest, under, halved, impacts, seconds = Counter(), [], [], 0, 0, 0.0
    for path in files:
        motion = bvh.read_bvh(path)
        roles = character_ragdoll(motion).roles
        pushes = random_impacts(motion, list(roles.values()), rng)
        try:
            baked, refused, took = bake_halving(motion, pushes, library, classifier)
        except ReactiveAnimError as error:
            errors[type(error).__name__] += 1
            print(f"# sweep: {path.name}: {type(error).__name__}: {error}")
            continue
        seconds += took
        impacts += len(baked.reactions)
        halved += refused
        fastest.append(fastest_away_from_hits(baked))
        under.append(deepest_under_floor(baked, Casting.between(motion, Rig(motion.skeleton, roles), library).sole))
    context = {"files": len(files), "pushes_per_file": PUSHES, "seed": SEED}
    report(GROUP, "impacts baked", impacts, "impacts", **context)
    report(GROUP, "bakes failed", sum(errors.values()), "bakes", by_error=dict(errors), **context)
    report(GROUP, "impacts halved as too strong for their bone", halved, "impacts", **context)
    report(GROUP, "fastest joint away from the hits, median over files", float(np.median(fastest)), "m/s",
           max=round(max(fastest), 1), **context)  # fmt: skip
    report(GROUP, "bakes with a joint over 5 cm under the floor", sum(d > 0.05 for d in under), "bakes",
           deepest_cm=round(max(under) * 100, 1), **context)  # fmt: skip
    report(GROUP, "bake time per impact", seconds / max(impacts, 1) * 1e3, "ms", **context)
