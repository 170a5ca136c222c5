"""The reaction classifier at run time (paper section 2.3): an ONNX model run by onnxruntime.

The model file describes itself (written by tools/classifier/export.py): its metadata_props hold
the class list, the names of its input features (features.py), and the input normalisation
(x - mean) / scale, applied here before the graph runs. The paper's network binary-codes 10
classes on 4 sigmoid outputs; ours gives a probability per class (softmax), so the search can fall
back to the next probable class.

One onnxruntime session per model file, made once (load_classifier keeps it per path and file
version), on the CPU with one thread: a call is a few small matrix products, far below the cost of
spinning up a thread pool, and the bake already runs beside Blender's own threads. Sessions are
safe to run from several threads; the feature readers (one MjData each) are kept per thread.

Errors name the file and the problem: a missing file, a file onnxruntime cannot read as ONNX,
metadata without the class list (or with unknown classes or features), inputs of the wrong shape.
"""

from __future__ import annotations

import json
import threading
from functools import lru_cache
from pathlib import Path
from typing import cast

import numpy as np
import onnxruntime

from ..model.arrays import AnyFloatArray, FloatArray
from ..model.classes import CLASS_SLUGS
from ..model.errors import ClassifierError
from ..model.skeleton import Motion
from ..physics.ragdoll import Ragdoll
from ..physics.simulate import SimResult
from .features import EXTENDED_FEATURES, FeatureReader, reaction_features, select

DEFAULT_MODEL = Path(__file__).resolve().parents[2] / "models" / "reaction_classifier.onnx"
INPUT_NAME = "features"
OUTPUT_NAME = "probabilities"
METADATA_KEYS = {
    "classes": "classes",  # JSON list of class slugs, in the order of the model's outputs
    "features": "feature_names",  # JSON list of features.EXTENDED_FEATURES names, the input's order
    "mean": "input_mean",  # JSON list: the model sees (x - input_mean) / input_scale
    "scale": "input_scale",
    "trained_on": "trained_on",  # JSON object: data, seed, accuracy (informative)
}


class Classifier:
    """A loaded reaction classifier: `classes` and `feature_names` from its metadata."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        if not self.path.is_file():
            raise ClassifierError(f"{self.path}: no such model file")
        self.session = _session(self.path)
        metadata = self.session.get_modelmeta().custom_metadata_map
        self.classes = _class_list(self.path, metadata)
        self.feature_names = _feature_list(self.path, metadata)
        self.mean = _numbers(self.path, metadata, "mean", len(self.feature_names))
        self.scale = _numbers(self.path, metadata, "scale", len(self.feature_names))
        self.trained_on = json.loads(metadata.get(METADATA_KEYS["trained_on"], "{}"))
        self._check_graph()
        self._columns = [CLASS_SLUGS.index(c) for c in self.classes]
        self._local = threading.local()

    def _check_graph(self) -> None:
        inputs, outputs = self.session.get_inputs(), self.session.get_outputs()
        if len(inputs) != 1 or inputs[0].shape[-1] != len(self.feature_names):
            shapes = [i.shape for i in inputs]
            raise ClassifierError(
                f"{self.path}: the model's input {shapes} does not take the "
                f"{len(self.feature_names)} features its metadata names"
            )
        if len(outputs) != 1 or outputs[0].shape[-1] != len(self.classes):
            raise ClassifierError(
                f"{self.path}: the model's output {[o.shape for o in outputs]} does not give the "
                f"{len(self.classes)} classes its metadata names"
            )

    def probabilities(self, x: AnyFloatArray) -> AnyFloatArray:
        """Probabilities over `classes`, (C,) or (N, C), of inputs (F,) or (N, F) in the order of
        `feature_names` (features.select(reaction_features(...), classifier.feature_names)); of the
        model's float width (float32 for ours)."""
        x = np.asarray(x, dtype=np.float64)
        width = len(self.feature_names)
        if x.ndim not in (1, 2) or x.shape[-1] != width:
            raise ClassifierError(
                f"{self.path}: the model takes {width} features per row, got an array of shape {x.shape}"
            )
        if not np.all(np.isfinite(x)):
            raise ClassifierError(f"{self.path}: the input features hold NaN or infinite values")
        rows = ((x.reshape(-1, width) - self.mean) / self.scale).astype(np.float32)
        out = np.asarray(self.session.run([OUTPUT_NAME], {INPUT_NAME: rows})[0])
        return out[0] if x.ndim == 1 else out

    def class_probabilities(self, features: AnyFloatArray) -> FloatArray:
        """Probabilities in CLASS_SLUGS order, (K,) or (N, K) for K classes, of EXTENDED_FEATURES rows; a class
        the model does not know gets 0."""
        features = np.asarray(features, dtype=np.float64)
        if features.shape[-1:] != (len(EXTENDED_FEATURES),):
            raise ClassifierError(
                f"{self.path}: reaction features come in rows of {len(EXTENDED_FEATURES)}, "
                f"got an array of shape {features.shape}"
            )
        known = self.probabilities(select(features, self.feature_names))
        out = np.zeros(known.shape[:-1] + (len(CLASS_SLUGS),))
        out[..., self._columns] = known
        return out

    def classify(self, before: Motion, bc: SimResult, ragdoll: Ragdoll) -> FloatArray:
        """The pipeline's call (react.ReactionClassifier): class probabilities in CLASS_SLUGS order
        of a BC simulation of `before` on `ragdoll`."""
        reader = self._reader(ragdoll)
        return self.class_probabilities(reaction_features(reader.rig, reader.simulated(before, bc)))

    def _reader(self, ragdoll: Ragdoll) -> FeatureReader:
        """This thread's feature reader for a ragdoll (the last one used is kept)."""
        reader = getattr(self._local, "reader", None)
        if reader is None or reader.ragdoll is not ragdoll:
            reader = self._local.reader = FeatureReader(ragdoll)
        return reader


def _session(path: Path) -> onnxruntime.InferenceSession:
    options = onnxruntime.SessionOptions()
    options.intra_op_num_threads = 1
    options.inter_op_num_threads = 1
    options.execution_mode = onnxruntime.ExecutionMode.ORT_SEQUENTIAL
    options.log_severity_level = 3  # errors only: the file's problems come back as ClassifierError
    try:
        return onnxruntime.InferenceSession(str(path), sess_options=options, providers=["CPUExecutionProvider"])
    except Exception as exc:  # onnxruntime raises its own exception types for unreadable files
        reason = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise ClassifierError(f"{path}: not an ONNX model onnxruntime can load ({reason})") from None


def _json_list(path: Path, metadata: dict[str, str], key: str) -> list[object]:
    name = METADATA_KEYS[key]
    if name not in metadata:
        raise ClassifierError(f"{path}: the model's metadata has no '{name}' list")
    try:
        value = json.loads(metadata[name])
    except json.JSONDecodeError as exc:
        raise ClassifierError(f"{path}: the model's metadata '{name}' is not JSON ({exc})") from None
    if not isinstance(value, list) or not value:
        raise ClassifierError(f"{path}: the model's metadata '{name}' is not a non-empty list")
    return cast(list[object], value)  # a JSON array: its items of any JSON type


def _class_list(path: Path, metadata: dict[str, str]) -> tuple[str, ...]:
    classes = _json_list(path, metadata, "classes")
    slugs = [c for c in classes if isinstance(c, str) and c in CLASS_SLUGS]
    if len(slugs) != len(classes) or len(set(slugs)) != len(slugs):
        raise ClassifierError(
            f"{path}: the model's classes {classes} must be distinct reaction classes of: {', '.join(CLASS_SLUGS)}"
        )
    return tuple(slugs)


def _feature_list(path: Path, metadata: dict[str, str]) -> tuple[str, ...]:
    names = _json_list(path, metadata, "features")
    known = [n for n in names if isinstance(n, str) and n in EXTENDED_FEATURES]
    if len(known) != len(names):
        unknown = [n for n in names if n not in EXTENDED_FEATURES]
        raise ClassifierError(
            f"{path}: the model asks for features this version does not compute: {', '.join(map(str, unknown))}"
        )
    return tuple(known)


def _numbers(path: Path, metadata: dict[str, str], key: str, count: int) -> FloatArray:
    values = np.asarray(_json_list(path, metadata, key), dtype=np.float64)
    if values.shape != (count,) or not np.all(np.isfinite(values)) or (key == "scale" and np.any(values == 0)):
        raise ClassifierError(f"{path}: the model's metadata '{METADATA_KEYS[key]}' must be {count} finite numbers")
    return values


@lru_cache(maxsize=8)
def _cached(path: str, version: tuple[int, int]) -> Classifier:
    return Classifier(path)


def load_classifier(path: str | Path = DEFAULT_MODEL) -> Classifier:
    """The classifier of a model file, loaded once per path and file version (size, mtime)."""
    resolved = Path(path).resolve()
    if not resolved.is_file():
        raise ClassifierError(f"{resolved}: no such model file")
    stat = resolved.stat()
    return _cached(str(resolved), (stat.st_size, stat.st_mtime_ns))
