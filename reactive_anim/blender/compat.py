"""What differs between the Blender lines the add-on supports (4.2 LTS to 5.2 LTS), in one place.

Blender has three live action APIs, detected by feature (an attribute or an RNA parameter), never
by version number, so a later line that keeps a feature keeps working:
- 4.2/4.3: legacy actions, F-curves on the action (`action.fcurves`);
- 4.4/4.5: layered actions as well: slots, layers, keyframe strips, channelbags, and the slot an
  object plays (`AnimData.action_slot`);
- 5.0 and newer: layered only (`action.fcurves` is gone); a channelbag's `fcurves.new` takes a
  group name.
The type stubs describe 4.2, so the layered API is reached through `layered` (the object untyped).
"""

from __future__ import annotations

from typing import Any

import bpy


def layered(blender_object: object) -> Any:
    """The object untyped, to reach the layered-action API of 4.4+ once a caller has detected it."""
    return blender_object


def has_layers(action: bpy.types.Action) -> bool:
    """Whether the action is a layered one (4.4+); 4.2/4.3 actions have F-curves only."""
    return hasattr(action, "layers")


def has_slots(adt: bpy.types.AnimData) -> bool:
    """Whether this Blender plays actions through slots (4.4+)."""
    return hasattr(adt, "action_slot")


def assigned_slot(adt: bpy.types.AnimData) -> Any:
    """The slot the object plays its action through (4.4+), or None."""
    return getattr(adt, "action_slot", None)


def slots(action: bpy.types.Action) -> list[Any]:
    """The action's slots (4.4+; none before)."""
    return list(getattr(action, "slots", ()))


def object_slot(action: bpy.types.Action, identifier: str = "") -> Any:
    """The action's slot `identifier`, or (none given or not found) its first object slot: the one
    a bake plays it through when none is named. None without slots (4.2/4.3)."""
    every = slots(action)
    named = [s for s in every if identifier and s.identifier == identifier]
    return next(iter(named or [s for s in every if s.target_id_type in {"OBJECT", "UNSPECIFIED"}]), None)


def assign_slot(adt: bpy.types.AnimData, slot: Any) -> None:
    """Play the assigned action through `slot` (4.4+; nothing to do before, or for None)."""
    if slot is not None and has_slots(adt) and layered(adt).action_slot != slot:
        layered(adt).action_slot = slot


def fcurves_new_takes_group(channelbag: Any) -> bool:
    """Whether a channelbag's `fcurves.new` takes `group_name` (5.0+; 4.4/4.5 group afterwards)."""
    return "group_name" in channelbag.fcurves.bl_rna.functions["new"].parameters
