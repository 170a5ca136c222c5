"""compat.py on the running Blender: the features it detects are the ones this line has, and the
slot rule (the named slot, else the first object slot) holds where there are slots."""

from __future__ import annotations

import bpy
import pytest

from reactive_anim.blender import compat


def test_the_detected_features_are_this_blenders(empty_scene):
    action = bpy.data.actions.new("probe")
    ob = bpy.data.objects.new("probe", None)
    adt = ob.animation_data_create()
    layered = bpy.app.version >= (4, 4, 0)
    assert compat.has_layers(action) == layered
    assert compat.has_slots(adt) == layered
    assert compat.assigned_slot(adt) is None and compat.object_slot(action) is None
    if bpy.app.version >= (5, 0, 0):
        assert not hasattr(action, "fcurves")  # layered only


def test_the_slot_rule_picks_the_named_slot_else_the_first_object_slot(empty_scene):
    if bpy.app.version < (4, 4, 0):
        pytest.skip("Blender 4.2/4.3 have no slots (the test above holds that)")
    action = compat.layered(bpy.data.actions.new("two slots"))
    first = action.slots.new(id_type="OBJECT", name="first")
    second = action.slots.new(id_type="OBJECT", name="second")
    assert compat.object_slot(action, second.identifier) == second
    assert compat.object_slot(action, "OBnot there") == first
    assert compat.object_slot(action) == first
    ob = bpy.data.objects.new("player", None)
    adt = ob.animation_data_create()
    adt.action = action
    compat.assign_slot(adt, second)
    assert compat.assigned_slot(adt) == second
