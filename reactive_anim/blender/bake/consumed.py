"""What a bake consumes: the bone constraints and drivers whose effect is already in its keys.

A character whose pose Blender evaluates (constraints, drivers) is read as it plays, and the
reacted action keys that evaluated pose. Left active, those constraints and drivers would act on the
keys a second time (a Child Of to a moving vehicle doubled, an additive Copy Rotation added twice)
or override them (a driver on a rotation channel hides the reaction). As Blender's own Bake Action
does with Visual Keying and Clear Constraints, they are switched off while the reacted action plays:
muted, not removed, so Clear Reactions turns them back on. Only those of the bones the bake keys;
the list is kept in the bake state as JSON.
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from typing import Any

import bpy

# A driver on one of these channels of a keyed bone decides what the reacted keys would say.
_CHANNELS = "rotation_quaternion|rotation_euler|rotation_axis_angle|location"
_TRANSFORM_PATH = re.compile(rf'^pose\.bones\["(.+)"\]\.({_CHANNELS})$')


def consumed(armature: bpy.types.Object, bones: Iterable[str]) -> list[list[Any]]:
    """The active constraints and drivers on the keyed `bones`: [["constraint", bone, name], ...,
    ["driver", data_path, index], ...]."""
    keyed = set(bones)
    found: list[list[Any]] = [
        ["constraint", pose_bone.name, constraint.name]
        for pose_bone in armature.pose.bones
        if pose_bone.name in keyed
        for constraint in pose_bone.constraints
        if not constraint.mute
    ]
    adt = armature.animation_data
    for driver in adt.drivers if adt is not None else ():
        match = _TRANSFORM_PATH.match(driver.data_path)
        if match and match.group(1) in keyed and not driver.mute:
            found.append(["driver", driver.data_path, driver.array_index])
    return found


def set_muted(armature: bpy.types.Object, items: list[list[Any]], mute: bool) -> None:
    """Mute (or unmute) what `consumed` listed; what is gone since is skipped."""
    adt = armature.animation_data
    for kind, owner, key in items:
        if kind == "constraint":
            pose_bone = armature.pose.bones.get(owner)
            constraint = pose_bone.constraints.get(key) if pose_bone is not None else None
            if constraint is not None:
                constraint.mute = mute
        elif adt is not None:
            driver = adt.drivers.find(owner, index=key)
            if driver is not None:
                driver.mute = mute


def to_json(items: list[list[Any]]) -> str:
    return json.dumps(items) if items else ""


def from_json(text: str) -> list[list[Any]]:
    return json.loads(text) if text else []


@contextmanager
def active_while(armature: bpy.types.Object, text: str) -> Iterator[None]:
    """Switch what a bake muted (its JSON `text`) back on for the block: a rebake reads the
    original motion as the original played, constraints and drivers included."""
    items = from_json(text)
    set_muted(armature, items, False)
    try:
        yield
    finally:
        set_muted(armature, items, True)
