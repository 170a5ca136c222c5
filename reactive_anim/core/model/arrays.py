"""Array type aliases for annotations: a bare `np.ndarray` says nothing of its element type, so
pyright (strict) cannot check what is done with its elements; these name the dtypes the code makes.

Arrays are made with `dtype=np.float64` rather than `dtype=float`: numpy gives the same float64 array
for both, but its stubs type only the first as float64 (the second as an array of Any, whose
arithmetic they then take for booleans).

Also `unit`, the one unit-vector helper, kept here so that physics and transition share it."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import numpy.typing as npt

# Positions, rotations, angles, weights: everything numeric the core computes is float64 (numpy's
# default for float literals).
FloatArray = npt.NDArray[np.float64]
# The search's compact arrays: a library's stored features and the bounds computed from them.
Float32Array = npt.NDArray[np.float32]
# Either float width, where a function takes both (a library's float32 features, float64 computed ones).
AnyFloatArray = npt.NDArray[np.floating[Any]]
# Stored integer tables (parent indices, frame numbers): built with dtype=np.int64.
IntArray = npt.NDArray[np.int64]
# A library's per-frame clip and frame numbers, stored compact.
Int32Array = npt.NDArray[np.int32]
# Indices as numpy makes them: positions (flatnonzero, argsort, arange: np.intp) and arrays of Python
# ints (np.int_: int64 on Linux and macOS, int32 on Windows under numpy 1.x); the stubs make both any width.
IndexArray = npt.NDArray[np.intp]
# Masks: comparisons and np.isfinite and the like.
BoolArray = npt.NDArray[np.bool_]

# np.einsum, typed once: numpy 1.26's stub for it has unparameterised generics that pyright's strict
# mode reads as partly unknown wherever it is named. Every call in the core sums float64 arrays into
# a float64 array, which is what this says; the function is numpy's own (looked up in the module's
# namespace, which has no static type, so only this annotation types it).
einsum: Callable[..., FloatArray] = vars(np)["einsum"]


def unit(v: FloatArray) -> FloatArray:
    """Vectors (..., 3) scaled to length 1 (a zero vector stays zero)."""
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-12)
