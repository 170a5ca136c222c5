"""Blender actions in tests: their F-curves whichever action API this Blender has (4.2's
action.fcurves, 4.4+'s layers, strips and channel bags), and their keys as bytes to compare
exactly. Imports bpy: only for tests/blender."""

from __future__ import annotations

import bpy
import numpy as np

from reactive_anim.blender import compat
from tools.devkit.blender_types import as_buffer


def action_of(ob: bpy.types.Object) -> bpy.types.Action:
    """The action the object plays (the test expects one)."""
    action = ob.animation_data.action
    assert action is not None, f"object '{ob.name}' plays no action"
    return action


def fcurves(action: bpy.types.Action) -> list[bpy.types.FCurve]:
    """Every F-curve of an action."""
    layered = compat.layered(action)
    if compat.has_layers(action) and (layered.layers or not hasattr(action, "fcurves")):
        return [
            fc for layer in layered.layers for strip in layer.strips for bag in strip.channelbags for fc in bag.fcurves
        ]
    return list(action.fcurves)


def keyframes(action: bpy.types.Action) -> dict[tuple[str, int], bytes]:
    """Every key (frame, value, handles, interpolation) of every F-curve, as bytes to compare exactly."""
    out = {}
    for fc in fcurves(action):
        points = fc.keyframe_points
        data = []
        for name, width, dtype in (
            ("co", 2, np.float32),
            ("handle_left", 2, np.float32),
            ("handle_right", 2, np.float32),
            ("interpolation", 1, np.int32),
        ):
            values = np.empty(len(points) * width, dtype=dtype)
            points.foreach_get(name, as_buffer(values))
            data.append(values.tobytes())
        out[(fc.data_path, fc.array_index)] = b"".join(data)
    return out


def values_before(co: np.ndarray, frame: float) -> np.ndarray:
    """The values of an F-curve's keys (co: frame, value pairs flattened, as foreach_get gives them)
    on frames before `frame`."""
    pairs = np.asarray(co).reshape(-1, 2)
    return pairs[pairs[:, 0] < frame, 1]
