"""The animator's impact tools (blender/impacts/impact_ops.py, marker_sync.py, panels.py) driven through the
real operators: add from the view, edit, aim, jump, remove; markers moved, deleted and duplicated
with Blender's own marker operators; every operator's poll message and its place in the menus."""

from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import contextmanager

import bpy
import numpy as np
import pytest

from reactive_anim.blender import registry
from reactive_anim.blender.impacts import impact_ops, impacts, marker_sync
from reactive_anim.blender.ui import panels, settings
from reactive_anim.core.model import quat
from tests.support.bake_scene import walk_with_impacts
from tools.devkit.blender_types import armature_data, view_3d
from tools.devkit.operators import addon_ops


def _uids(scene: bpy.types.Scene) -> list[str]:
    return [impacts.impact_data(m).uid for m in scene.timeline_markers if impacts.is_impact_marker(m)]


def _view_looking(direction: tuple[float, float, float]) -> tuple[float, ...]:
    """A view rotation (w, x, y, z) whose -Z (into the screen) is `direction`, with Z up on screen
    where possible."""
    into = np.asarray(direction, dtype=float) / np.linalg.norm(direction)
    back = -into
    side = np.cross([0.0, 0.0, 1.0], back)
    side = side / np.linalg.norm(side) if np.linalg.norm(side) > 1e-6 else np.array([1.0, 0.0, 0.0])
    up = np.cross(back, side)
    return tuple(float(v) for v in quat.from_matrix(np.stack([side, up, back], axis=1)))


def test_add_impact_takes_the_direction_from_the_view(empty_scene):
    rig = walk_with_impacts(empty_scene)
    empty_scene.frame_current = 90
    looking_down_at_it = _view_looking((0.0, 1.0, -1.0))  # from the front, 45 deg above

    addon_ops.add_impact(armature_name="walk", bone="head", direction_source="VIEW", view_rotation=looking_down_at_it)
    flat = impacts.impact_data(impacts.impact_markers(empty_scene, "walk")[1])
    assert np.allclose(flat.direction, (0.0, 1.0, 0.0), atol=1e-6)  # laid flat on the ground
    addon_ops.add_impact(
        armature_name="walk", bone="head", direction_source="VIEW", view_rotation=looking_down_at_it, flatten=False,
        frame=91,
    )  # fmt: skip
    steep = impacts.impact_data(impacts.impact_markers(empty_scene, "walk")[2])
    assert np.allclose(steep.direction, (0.0, math.sqrt(0.5), -math.sqrt(0.5)), atol=1e-6)
    # straight down, flattening keeps the view's up direction instead of a zero vector
    assert np.allclose(impact_ops.view_direction(_view_looking((0.0, 0.0, -1.0)), True), (0.0, 1.0, 0.0), atol=1e-6)
    assert rig.name == "walk"


def test_a_button_in_the_sidebar_aims_along_its_own_view(empty_scene):
    window = bpy.context.window
    area = next(a for a in window.screen.areas if a.type == "VIEW_3D")
    sidebar = next(r for r in area.regions if r.type == "UI")
    view_3d(area).region_3d.view_rotation = _view_looking((-1.0, 0.0, 0.0))
    with bpy.context.temp_override(window=window, area=area, region=sidebar):
        assert bpy.context.region_data is None  # a sidebar has no view of its own
        rotation = impact_ops.view_rotation_of(bpy.context)
    assert rotation is not None
    assert np.allclose(impact_ops.view_direction(rotation, True), (-1.0, 0.0, 0.0), atol=1e-6)


def test_add_impact_defaults_to_the_current_frame_the_active_bone_and_the_panel_character(empty_scene):
    rig = walk_with_impacts(empty_scene)
    settings.scene_settings(empty_scene).character = rig
    empty_scene.frame_current = 77
    bones = armature_data(rig).bones
    bones.active = bones["upper_arm.L"]

    assert addon_ops.add_impact(strength=30.0) == {"FINISHED"}

    marker = next(m for m in empty_scene.timeline_markers if m.frame == 77)
    props = impacts.impact_data(marker)
    assert (props.armature, props.bone, props.strength) == ("walk", "upper_arm.L", 30.0)
    assert marker.select and sum(m.select for m in empty_scene.timeline_markers) == 1
    assert empty_scene.timeline_markers[settings.scene_settings(empty_scene).active_impact] == marker
    bones.active = None
    addon_ops.add_impact(frame=80)  # no active bone: the chest, by its role
    assert impacts.impact_data(next(m for m in empty_scene.timeline_markers if m.frame == 80)).bone == "chest"


def test_edit_aim_jump_and_remove_the_active_impact(empty_scene):
    walk_with_impacts(empty_scene)
    markers = empty_scene.timeline_markers
    second = markers["hit_02"]
    uid = impacts.impact_data(second).uid

    assert addon_ops.jump_to_impact(uid=uid) == {"FINISHED"}
    assert empty_scene.frame_current == 131 and second.select
    assert markers[settings.scene_settings(empty_scene).active_impact] == second
    # edit the fields the panel shows
    second.frame = 140
    impacts.impact_data(second).strength = 250.0
    assert [(i.frame, i.strength) for i in impacts.read_impacts(empty_scene, bpy.data.objects["walk"])][1] == (
        139.0,
        250.0,
    )
    # aim the active impact (no uid: the list's active row) from a view looking along +X
    assert addon_ops.aim_impact(view_rotation=_view_looking((1.0, 0.0, 0.0))) == {"FINISHED"}
    assert np.allclose(impacts.impact_data(second).direction, (1.0, 0.0, 0.0), atol=1e-6)
    # remove it: the marker and the impact go together
    assert addon_ops.remove_impact() == {"FINISHED"}
    assert uid not in _uids(empty_scene) and "hit_02" not in markers
    with pytest.raises(RuntimeError, match="no impact marker with uid"):
        addon_ops.jump_to_impact(uid=uid)


@contextmanager
def _in_timeline() -> Iterator[None]:
    """A context whose area is a Dope Sheet, where Blender's marker operators run."""
    window = bpy.context.window
    area = next(a for a in window.screen.areas if a.type == "DOPESHEET_EDITOR")
    region = next(r for r in area.regions if r.type == "WINDOW")
    with bpy.context.temp_override(window=window, area=area, region=region):
        yield


def _select_only(scene: bpy.types.Scene, name: str) -> None:
    for m in scene.timeline_markers:
        m.select = m.name == name


def test_markers_moved_deleted_and_duplicated_in_the_timeline(empty_scene):
    rig = walk_with_impacts(empty_scene)
    marker_sync.sync_all()
    uids = _uids(empty_scene)

    _select_only(empty_scene, "hit_02")
    with _in_timeline():
        bpy.ops.marker.move(frames=9)
    assert marker_sync.sync_all()  # the poll sees the change (and redraws)
    assert not marker_sync.sync_all()  # and nothing more the next time
    assert [i.frame for i in impacts.read_impacts(empty_scene, rig)] == [40.0, 139.0, 200.0]

    with _in_timeline():
        bpy.ops.marker.duplicate(frames=20)  # the copy carries the impact, uid included
    copy = next(m for m in empty_scene.timeline_markers if m.frame == 160)
    original = next(m for m in empty_scene.timeline_markers if m.frame == 140)
    assert impacts.impact_data(copy).uid == impacts.impact_data(original).uid
    marker_sync.sync_all()
    assert impacts.impact_data(original).uid == uids[1]  # the original keeps its uid
    assert impacts.impact_data(copy).uid not in uids and len(set(_uids(empty_scene))) == 4
    assert impacts.impact_data(copy).bone == "chest"

    _select_only(empty_scene, "hit_01")
    with _in_timeline():
        bpy.ops.marker.delete()
    assert marker_sync.sync_all()
    assert uids[0] not in _uids(empty_scene)
    assert [i.frame for i in impacts.read_impacts(empty_scene, rig)] == [139.0, 159.0, 200.0]


def test_undo_and_load_handlers_are_registered_and_the_poll_is_a_timer():
    assert marker_sync._after_undo in bpy.app.handlers.undo_post
    assert marker_sync._after_undo in bpy.app.handlers.redo_post
    assert marker_sync._after_load in bpy.app.handlers.load_post
    assert bpy.app.timers.is_registered(marker_sync._poll)


# Every operator, the call that must fail on an empty file, and the poll message it must give.
POLL_MESSAGES = [
    ("add_impact", "There is no armature to hit: import a BVH first"),
    ("aim_impact", "Add an impact first"),
    ("jump_to_impact", "Add an impact first"),
    ("remove_impact", "Add an impact first"),
    ("bake", "Select an armature with an action"),
    ("preview", "Select an armature with an action"),
    ("accept_preview", "There is no preview to accept: click Preview first"),
    ("discard_preview", "There is no preview to discard"),
    ("clear_bake", "There are no baked reactions to clear"),
    ("detect_roles", "There is no armature in this file: import a BVH first"),
    ("role_preset", "There is no armature in this file: import a BVH first"),
    ("clear_roles", "There is no armature in this file: import a BVH first"),
]


@pytest.mark.parametrize(("name", "message"), POLL_MESSAGES)
def test_every_operator_says_why_it_cannot_run(empty_scene, name, message):
    with pytest.raises(RuntimeError, match=rf"{name}\.poll\(\) {message}"):
        getattr(addon_ops, name)()


def test_bake_says_add_an_impact_first_on_a_character_without_impacts(empty_scene):
    walk_with_impacts(empty_scene)
    for marker in list(empty_scene.timeline_markers):
        impacts.remove_impact(empty_scene, marker)
    with pytest.raises(RuntimeError, match=r"bake\.poll\(\) Add an impact first"):
        addon_ops.bake()


def test_every_operator_has_a_tooltip_a_poll_and_a_menu_entry():
    operators = [cls for cls in registry.CLASSES if issubclass(cls, bpy.types.Operator)]
    assert {cls.bl_idname.split(".")[1] for cls in operators} == {n for n, _ in POLL_MESSAGES} | {"import_bvh"}
    for cls in operators:
        assert cls.__doc__ and len(cls.__doc__.split()) >= 5, cls.__name__
    assert set(panels.MENU_OPERATORS) == set(operators)
    for menu, entry in registry.MENUS[1:]:
        assert entry == panels.draw_menu_entry and menu in (bpy.types.VIEW3D_MT_object, bpy.types.VIEW3D_MT_pose)


@pytest.mark.parametrize(
    ("operator", "per_call"),
    [
        ("add_impact", ("armature_name", "bone", "frame", "direction_source", "direction", "view_rotation",
                        "reaction", "marker_name")),
        ("aim_impact", ("uid", "view_rotation")),
        ("remove_impact", ("uid",)),
        ("bake", ("armature_name", "library_path", "model_path")),
        ("preview", ("armature_name", "library_path", "model_path")),
        ("import_bvh", ("armature_name",)),
    ],
)  # fmt: skip
def test_what_one_call_is_about_is_not_carried_to_the_next(operator, per_call):
    """An operator invoked from the UI gets its last call's values for every property that is not
    SKIP_SAVE (in a window only: background mode never does it): in a real window the second + hit
    the first impact's bone. The strength, an animator's preference, is carried over."""
    properties = getattr(addon_ops, operator).get_rna_type().properties
    assert [name for name in per_call if not properties[name].is_skip_save] == []
    if operator == "add_impact":
        assert not properties["strength"].is_skip_save
