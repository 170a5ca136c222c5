"""Type stubs for the part of onnxruntime this project uses. Ours, hand-written, not onnxruntime's.

onnxruntime ships no type information (its classes come from a compiled pybind11 module), so pyright
in strict mode reads every member as unknown. tools/lint.sh copies this folder into pyright's
stubPath (.venv/lint/typings), beside the mujoco stubs it generates; a stub package stands for the
whole module, so it declares everything the project touches and nothing else:
reactive_anim/core/classify/classifier.py (the session), reactive_anim/farm/outputs.py and
tests/blender/test_extension.py (the version and the providers).

Signatures follow onnxruntime 1.32: capi/onnxruntime_inference_collection.py (InferenceSession, its
base Session) and the pybind11 module capi/onnxruntime_pybind11_state (SessionOptions, ExecutionMode,
ModelMetadata, NodeArg: their docstrings). Extend this file when the code uses more of onnxruntime.
"""

import os
from collections.abc import Mapping, Sequence
from typing import Any, ClassVar

import numpy.typing as npt

__version__: str

def get_available_providers() -> list[str]: ...

class ExecutionMode:
    """pybind11 enum: sequential or parallel execution of the graph's nodes."""

    ORT_SEQUENTIAL: ClassVar[ExecutionMode]
    ORT_PARALLEL: ClassVar[ExecutionMode]
    @property
    def name(self) -> str: ...
    @property
    def value(self) -> int: ...

class SessionOptions:
    def __init__(self) -> None: ...
    @property
    def intra_op_num_threads(self) -> int: ...
    @intra_op_num_threads.setter
    def intra_op_num_threads(self, value: int) -> None: ...
    @property
    def inter_op_num_threads(self) -> int: ...
    @inter_op_num_threads.setter
    def inter_op_num_threads(self, value: int) -> None: ...
    @property
    def execution_mode(self) -> ExecutionMode: ...
    @execution_mode.setter
    def execution_mode(self, value: ExecutionMode) -> None: ...
    @property
    def log_severity_level(self) -> int: ...
    @log_severity_level.setter
    def log_severity_level(self, value: int) -> None: ...

class ModelMetadata:
    @property
    def custom_metadata_map(self) -> dict[str, str]: ...

class NodeArg:
    @property
    def name(self) -> str: ...
    @property
    def type(self) -> str: ...
    @property
    def shape(self) -> list[int | str | None]:
        """Per dimension its size, or its symbolic name, or None when unknown."""

class InferenceSession:
    def __init__(
        self,
        path_or_bytes: str | bytes | os.PathLike[str],
        sess_options: SessionOptions | None = None,
        providers: Sequence[str | tuple[str, dict[Any, Any]]] | None = None,
        provider_options: Sequence[dict[Any, Any]] | None = None,
        **kwargs: Any,
    ) -> None: ...
    def get_inputs(self) -> Sequence[NodeArg]: ...
    def get_outputs(self) -> Sequence[NodeArg]: ...
    def get_modelmeta(self) -> ModelMetadata: ...
    def run(
        self, output_names: Sequence[str] | None, input_feed: Mapping[str, npt.NDArray[Any]], run_options: None = None
    ) -> Sequence[npt.NDArray[Any] | list[Any] | dict[Any, Any]]:
        """One result per output name: a numpy array for a tensor output (a list or a dict for
        sequence and map outputs; sparse tensors are not declared here)."""
