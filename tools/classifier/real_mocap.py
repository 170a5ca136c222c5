"""Figures on real motion capture from ../shared/mocap (test and benchmark data, never shipped).

Generalisation: the same pushes and labels as training (pushes.py, outcome.py), on real walks and
runs of skeletons the model never saw (Bandai Namco, CMU through iClone), classified by the shipped
ONNX model. Real reactions: what the model says for the onset of the real reaction captures in
../shared/mocap/cmu, the features taken over their first 0.25 s (features.FeatureReader.captured),
beside what the outcome rule says of the same state. Both are skipped where ../shared is absent.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from reactive_anim.core.classify.classifier import Classifier
from reactive_anim.core.classify.features import FeatureReader, ReactionState, reaction_features
from reactive_anim.core.classify.outcome import judge
from reactive_anim.core.model import bvh
from reactive_anim.core.model.classes import CLASS_SLUGS
from reactive_anim.core.model.skeleton import Motion
from reactive_anim.core.physics.ragdoll import build_ragdoll
from reactive_anim.core.physics.simulate import REACTION_WINDOW
from tools.devkit.mocap import MOCAP

from .pushes import plan_pushes, simulate_pushes

WALKS = (
    "bandai_namco/dataset-1/dataset-1_walk_normal_001.bvh",
    "bandai_namco/dataset-2/dataset-2_walk_elderly_001.bvh",
    "cmu_iclone/002_01.bvh",
    "cmu_iclone/007_01.bvh",
)
RUNS = (
    "bandai_namco/dataset-2/dataset-2_run_normal_001.bvh",
    "bandai_namco/dataset-1/dataset-1_run_tired_001.bvh",
    "bandai_namco/dataset-2/dataset-2_run_exhausted_001.bvh",
    "cmu_iclone/002_03.bvh",
)
PUSHES_PER_CLIP = 120


@dataclass(frozen=True)
class Capture:
    """A real reaction capture and its onset B (seconds), found by reading its centre of mass track
    (height, horizontal and vertical speed) and stated with the reason."""

    file: str
    onset: float
    what: str


CAPTURES = (
    Capture(
        "cmu/90_18.bvh",
        0.48,
        "rug pull: stands still, the feet go out at 0.48 s (CoM speed 0 -> 0.24 m/s), falls backwards onto the back",
    ),
    Capture(
        "cmu/91_59.bvh",
        1.11,
        "lands at 1.11 s from a jumping 360 spin (CoM falling at 1.1 m/s), dips and stumbles about 24 cm to its left",
    ),
    Capture(
        "cmu/90_16.bvh",
        3.21,
        "stunt fall: at the top of a leap (3.21 s, CoM 1.68 m) it pitches forward and lands on its front",
    ),
)
NOT_REACTIONS = ("cmu/139_16.bvh", "cmu/140_01.bvh")  # get-ups: no impact to react to
ONSET_SHIFTS = (-0.1, 0.0, 0.1)  # s: the prediction's sensitivity to where B is put


def available() -> bool:
    return MOCAP.is_dir()


@dataclass
class Generalisation:
    """Per clip: (file, kind, samples, accuracy, group accuracy); and the totals per kind."""

    rows: list[tuple[str, str, int, float, float]]
    totals: dict[str, tuple[int, float, float]]


def generalisation(classifier: Classifier, seed: int, workers: int, groups: dict[str, str]) -> Generalisation:
    """Push real walks and runs, label by the outcome rule, score the classifier."""
    rows = []
    pooled: dict[str, list[tuple[np.ndarray, np.ndarray]]] = {"walk": [], "run": []}
    for kind, files in (("walk", WALKS), ("run", RUNS)):
        for k, file in enumerate(files):
            path = MOCAP / file
            motion = bvh.read_bvh(path)
            pushes = plan_pushes([motion.num_frames], [motion.fps], PUSHES_PER_CLIP, seed + 1000 + k)
            data = simulate_pushes([path], pushes, workers)
            predicted = np.argmax(classifier.class_probabilities(data.features), axis=1)
            pooled[kind].append((predicted, data.labels))
            rows.append((file, kind, len(data), *_scores(predicted, data.labels, groups)))
    totals = {}
    for kind, parts in pooled.items():
        predicted = np.concatenate([p for p, _ in parts])
        truth = np.concatenate([t for _, t in parts])
        totals[kind] = (len(truth), *_scores(predicted, truth, groups))
    return Generalisation(rows, totals)


def _scores(predicted: np.ndarray, truth: np.ndarray, groups: dict[str, str]) -> tuple[float, float]:
    group = np.array([groups[c] for c in CLASS_SLUGS])
    return float(np.mean(predicted == truth)), float(np.mean(group[predicted] == group[truth]))


@dataclass
class CapturePrediction:
    capture: Capture
    top: list[tuple[str, float]]  # the three most probable classes at the onset
    shifted: list[tuple[float, str]]  # (onset shift s, most probable class)
    rule: str  # what the outcome rule says of the same state


def real_reactions(classifier: Classifier) -> list[CapturePrediction]:
    """The model's and the rule's classes at the onset of each real reaction capture."""
    out = []
    for capture in CAPTURES:
        motion = bvh.read_bvh(MOCAP / capture.file)
        reader = FeatureReader(build_ragdoll(motion.skeleton, reference=motion))
        probabilities = _probabilities(classifier, reader, motion, capture.onset)
        top = [(CLASS_SLUGS[k], float(probabilities[k])) for k in np.argsort(-probabilities)[:3]]
        shifted = []
        for shift in ONSET_SHIFTS:
            p = _probabilities(classifier, reader, motion, capture.onset + shift)
            shifted.append((shift, CLASS_SLUGS[int(np.argmax(p))]))
        rule = judge(reader.rig, _state(reader, motion, capture.onset)).reaction
        out.append(CapturePrediction(capture, top, shifted, rule))
    return out


def _state(reader: FeatureReader, motion: Motion, onset: float) -> ReactionState:
    return reader.captured(motion, round(onset * motion.fps), REACTION_WINDOW)


def _probabilities(classifier: Classifier, reader: FeatureReader, motion: Motion, onset: float) -> np.ndarray:
    return classifier.class_probabilities(reaction_features(reader.rig, _state(reader, motion, onset)))
