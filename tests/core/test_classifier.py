"""The reaction classifier: the shipped model, every ClassifierError, and training end to end.

- The shipped model (reactive_anim/models/reaction_classifier.onnx) loads, names every class,
  and agrees with the outcome rule on at least 95 % of 200 fresh pushes from a seed never used in
  training.
- Each problem a model file can have is a ClassifierError naming the file and the problem.
- A tiny training run (3 classes, about 300 pushes on the sample idle) goes end to end, simulation
  to ONNX, and its model beats chance clearly on its held-out split. It needs the `onnx` package
  (the training tool's writer); without it the test is skipped with the reason.
- Training is deterministic: the same seed plans the same pushes, simulates them to the same
  features whatever the number of worker processes, and trains the same weights.
- The real reaction captures of ../shared/mocap get a class each (skipped where it is absent).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from reactive_anim.core.classify.classifier import DEFAULT_MODEL, Classifier, load_classifier
from reactive_anim.core.classify.features import EXTENDED_FEATURES, FeatureReader
from reactive_anim.core.model import bvh
from reactive_anim.core.model.classes import CLASS_SLUGS
from reactive_anim.core.model.errors import ClassifierError
from reactive_anim.core.model.impact import Impact
from reactive_anim.core.physics.ragdoll import build_ragdoll
from reactive_anim.core.physics.simulate import simulate_push
from tests.support.mocap import require_mocap
from tools.classifier import nets
from tools.classifier.pushes import plan_pushes, simulate_pushes

REPO = Path(__file__).resolve().parents[2]
SAMPLE_CLIPS = tuple(REPO / "sample_clips" / f"{name}.bvh" for name in ("walk", "run", "idle"))
FRESH_SEED = 90210  # never a training seed
FRESH_PUSHES = 200
AGREEMENT = 0.95  # the goal: the shipped model agrees with the rule on at least 95 % of fresh pushes
TINY_CLASSES = ("step_forward", "step_back", "sway_balance")


@pytest.fixture(scope="module")
def shipped() -> Classifier:
    return load_classifier()


def test_the_shipped_model_loads_once_with_every_class(shipped):
    assert shipped.path == DEFAULT_MODEL
    assert shipped.classes == CLASS_SLUGS
    assert set(shipped.feature_names) <= set(EXTENDED_FEATURES)
    assert load_classifier() is shipped  # kept per file version
    assert shipped.trained_on["samples"] >= 5000


def test_the_shipped_model_agrees_with_the_outcome_rule_on_fresh_pushes(shipped):
    pushes = plan_pushes([bvh.read_bvh(p).num_frames for p in SAMPLE_CLIPS], [60.0] * 3, FRESH_PUSHES, FRESH_SEED)
    data = simulate_pushes(list(SAMPLE_CLIPS), pushes)
    predicted = np.argmax(shipped.class_probabilities(data.features), axis=1)
    agreement = float(np.mean(predicted == data.labels))
    assert len(data) >= 0.95 * FRESH_PUSHES
    assert agreement >= AGREEMENT, agreement


def test_classify_reads_a_simulation_and_returns_a_probability_per_class(shipped):
    motion = bvh.read_bvh(SAMPLE_CLIPS[0])
    ragdoll = build_ragdoll(motion.skeleton, reference=motion)
    forward = FeatureReader(ragdoll).facing(motion, 60.9)[0]
    bc = simulate_push(ragdoll, motion, Impact(60.9, ragdoll.roles["chest"], tuple(forward), 250.0))
    probabilities = shipped.classify(motion, bc, ragdoll)
    assert probabilities.shape == (len(CLASS_SLUGS),)
    assert probabilities.sum() == pytest.approx(1.0, abs=1e-5)
    assert "forward" in CLASS_SLUGS[int(np.argmax(probabilities))]  # a hard shove from behind


# ---------------------------------------------------------------------------------------------
# ClassifierError


def test_a_missing_file_is_named(tmp_path):
    missing = tmp_path / "nowhere.onnx"
    for load in (Classifier, load_classifier):
        with pytest.raises(ClassifierError, match=f"{missing}: no such model file"):
            load(missing)


def test_a_file_that_is_not_onnx_is_named(tmp_path):
    junk = tmp_path / "junk.onnx"
    junk.write_bytes(b"this is not a model\x00\xff" * 10)
    with pytest.raises(ClassifierError, match=f"{junk}: not an ONNX model onnxruntime can load"):
        Classifier(junk)


def test_a_wrong_input_shape_is_named(shipped):
    width = len(shipped.feature_names)
    with pytest.raises(ClassifierError, match=f"takes {width} features per row, got an array of shape \\(5,\\)"):
        shipped.probabilities(np.zeros(5))
    with pytest.raises(ClassifierError, match=rf"shape \(2, 3, {width}\)"):
        shipped.probabilities(np.zeros((2, 3, width)))
    with pytest.raises(ClassifierError, match=f"rows of {len(EXTENDED_FEATURES)}, got an array of shape \\(9,\\)"):
        shipped.class_probabilities(np.zeros(9))
    with pytest.raises(ClassifierError, match="NaN"):
        shipped.probabilities(np.full(width, np.nan))


def _with_metadata_key_renamed(tmp_path: Path, key: bytes, to: bytes) -> Path:
    """A copy of the shipped model whose metadata key `key` is renamed (same length, so the
    protobuf stays valid: a metadata entry's key is field 1, tag 0x0a, then its length)."""
    data = DEFAULT_MODEL.read_bytes()
    old, new = b"\x0a" + bytes([len(key)]) + key, b"\x0a" + bytes([len(to)]) + to
    assert data.count(old) == 1 and len(key) == len(to)
    path = tmp_path / "renamed.onnx"
    path.write_bytes(data.replace(old, new))
    return path


def test_metadata_without_the_class_list_is_named(tmp_path):
    path = _with_metadata_key_renamed(tmp_path, b"classes", b"klasses")
    with pytest.raises(ClassifierError, match=f"{path}: the model's metadata has no 'classes' list"):
        Classifier(path)


def test_metadata_without_the_normalisation_is_named(tmp_path):
    path = _with_metadata_key_renamed(tmp_path, b"input_mean", b"input_mode")
    with pytest.raises(ClassifierError, match=f"{path}: the model's metadata has no 'input_mean' list"):
        Classifier(path)


# ---------------------------------------------------------------------------------------------
# Training


def test_training_a_tiny_model_runs_end_to_end_and_beats_chance(tmp_path):
    pytest.importorskip("onnx", reason="the training tool writes models with the onnx package (tools/requirements)")
    from tools.classifier.pipeline import Config, run

    config = Config(
        clips=(SAMPLE_CLIPS[2],),
        samples=360,
        seed=4,
        workers=1,
        classes=TINY_CLASSES,
        max_strength=80.0,
        hidden_choices=((16,),),
        epochs=60,
        out=tmp_path / "tiny.onnx",
    )
    result = run(config, log=lambda message: None)
    model = Classifier(config.out)
    assert model.classes == tuple(c for c in CLASS_SLUGS if c in TINY_CLASSES)
    assert len(result.data) >= 250
    test = result.splits["test"]
    labels = np.array([model.classes.index(CLASS_SLUGS[k]) for k in result.data.labels[test]])
    predicted = np.argmax(
        model.class_probabilities(result.data.features[test])[:, [CLASS_SLUGS.index(c) for c in model.classes]], axis=1
    )
    assert np.mean(predicted == labels) > 0.75  # chance: one in three


def test_pushes_plan_and_simulate_the_same_whatever_the_workers():
    pushes = plan_pushes([264, 360], [60.0, 60.0], 8, seed=5, per_frame=4)
    assert pushes == plan_pushes([264, 360], [60.0, 60.0], 8, seed=5, per_frame=4)
    paths = [SAMPLE_CLIPS[0], SAMPLE_CLIPS[2]]
    one, two = simulate_pushes(paths, pushes, workers=1), simulate_pushes(paths, pushes, workers=2)
    np.testing.assert_array_equal(one.features, two.features)
    np.testing.assert_array_equal(one.labels, two.labels)


def test_the_same_seed_trains_the_same_weights():
    rng = np.random.default_rng(0)
    x, y = rng.normal(size=(200, 5)), rng.integers(0, 3, 200)
    first = nets.fit_softmax(x[:150], y[:150], x[150:], y[150:], 3, (8,), seed=7, epochs=20)
    second = nets.fit_softmax(x[:150], y[:150], x[150:], y[150:], 3, (8,), seed=7, epochs=20)
    for a, b in zip(first.weights + first.biases, second.weights + second.biases, strict=True):
        np.testing.assert_array_equal(a, b)


@pytest.mark.mocap
def test_the_real_reaction_captures_each_get_a_class(shipped):
    require_mocap("cmu/90_18.bvh")
    from tools.classifier.real_mocap import CAPTURES, real_reactions

    predictions = real_reactions(shipped)
    assert [p.capture for p in predictions] == list(CAPTURES)
    for p in predictions:
        assert p.top[0][0] in CLASS_SLUGS and 0.0 <= p.top[0][1] <= 1.0


def test_mirror_images_train_with_the_other_sides_label_and_untrained_mirrors_are_left_out():
    """Training's mirror images (pipeline.with_mirrors): a side step's mirror is labelled with the
    other side, any other class with its own; where the other side is not trained, the mirror is
    left out rather than mislabelled."""
    from tools.classifier.pipeline import with_mirrors

    rows = np.arange(3 * len(EXTENDED_FEATURES), dtype=float).reshape(3, -1)
    classes = ("step_left", "step_right", "sway_balance")
    both, labels = with_mirrors(rows, np.array([0, 1, 2]), classes)
    assert len(both) == 6 and list(labels) == [0, 1, 2, 1, 0, 2]
    one_side, labels = with_mirrors(rows, np.array([0, 1, 1]), ("step_left", "sway_balance"))
    assert len(one_side) == 5 and list(labels) == [0, 1, 1, 1, 1]  # step_left's mirror has no class here
