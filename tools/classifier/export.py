"""The trained MLP as an ONNX file: Gemm and Tanh layers, a Softmax over the classes.

Written with the `onnx` package, the only place that needs it (imported inside `write_onnx`, so
importing this module, and everything at run time, works without it). The IR version comes from
`helper.make_model_gen_version` for opset OPSET: the package's own default IR is newer than
onnxruntime reads (../shared/DESIGN.md). The file describes itself in its metadata_props (METADATA_KEYS,
read by core.classifier): the class list, the feature names, the input normalisation
(x - mean) / scale applied before the graph, and what it was trained on.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from reactive_anim.core.classify.classifier import INPUT_NAME, METADATA_KEYS, OUTPUT_NAME

from .nets import Net

OPSET = 17  # ai.onnx opset; Gemm, Tanh and Softmax(axis) are stable since 13


def write_onnx(net: Net, path: Path, classes: tuple[str, ...], features: tuple[str, ...], trained_on: dict) -> int:
    """Write `net` (softmax output over `classes`, inputs `features`) to `path`; returns the file's IR version."""
    import onnx
    from onnx import TensorProto, helper, numpy_helper

    nodes, initializers = [], []
    current = INPUT_NAME
    for k, (weight, bias) in enumerate(zip(net.weights, net.biases, strict=True)):
        initializers += [
            numpy_helper.from_array(weight.astype(np.float32), f"W{k}"),
            numpy_helper.from_array(bias.astype(np.float32), f"b{k}"),
        ]
        nodes.append(helper.make_node("Gemm", [current, f"W{k}", f"b{k}"], [f"z{k}"], name=f"layer{k}"))
        current = f"z{k}"
        if k < len(net.weights) - 1:
            nodes.append(helper.make_node("Tanh", [current], [f"h{k}"], name=f"tanh{k}"))
            current = f"h{k}"
    nodes.append(helper.make_node("Softmax", [current], [OUTPUT_NAME], axis=1, name="softmax"))
    graph = helper.make_graph(
        nodes,
        "reaction_classifier",
        [helper.make_tensor_value_info(INPUT_NAME, TensorProto.FLOAT, ["batch", len(features)])],
        [helper.make_tensor_value_info(OUTPUT_NAME, TensorProto.FLOAT, ["batch", len(classes)])],
        initializers,
    )
    model = helper.make_model_gen_version(
        graph, producer_name="reactive_anim", opset_imports=[helper.make_opsetid("", OPSET)]
    )
    model.doc_string = (
        "Reaction class probabilities from the state at C (paper section 2.3); see reaction_classifier.md."
    )
    metadata = {
        METADATA_KEYS["classes"]: json.dumps(list(classes)),
        METADATA_KEYS["features"]: json.dumps(list(features)),
        METADATA_KEYS["mean"]: json.dumps([float(v) for v in net.mean]),
        METADATA_KEYS["scale"]: json.dumps([float(v) for v in net.scale]),
        METADATA_KEYS["trained_on"]: json.dumps(trained_on, sort_keys=True),
    }
    helper.set_model_props(model, metadata)
    onnx.checker.check_model(model)
    path.parent.mkdir(parents=True, exist_ok=True)
    onnx.save_model(model, str(path))
    return int(model.ir_version)
