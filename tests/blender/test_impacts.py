"""Impact markers (blender/impacts/impacts.py) on the real Blender: add, read, remove, save and reload."""

from __future__ import annotations

from pathlib import Path

import bpy
import pytest

from reactive_anim.blender.character import bvh_import
from reactive_anim.blender.impacts import impacts
from reactive_anim.core.model.classes import CLASSES
from reactive_anim.core.model.errors import ImpactError
from reactive_anim.core.model.impact import Impact
from tests.support.actions import action_of
from tools.devkit.operators import addon_ops

WALK = Path(__file__).resolve().parents[2] / "sample_clips" / "walk.bvh"  # 264 frames, keys on frames 1-264
FORWARD = (0.0, -1.0, 0.0)  # the sample walk walks along -Y


def _walker(name: str = "walk") -> bpy.types.Object:
    return bvh_import.import_bvh(bpy.context, WALK, name=name)


def _fields(marker: bpy.types.TimelineMarker) -> tuple:
    p = impacts.impact_data(marker)
    return (
        marker.name,
        marker.frame,
        p.armature,
        p.bone,
        tuple(round(v, 6) for v in p.direction),
        p.strength,
        p.reaction,
        p.uid,
    )


def test_add_read_remove(empty_scene):
    scene = empty_scene
    rig, other = _walker(), _walker("other")
    late = impacts.add_impact(scene, rig, "head", 200, (0.0, 2.0, 0.0), 40.0)
    early = impacts.add_impact(scene, rig, "chest", 41, FORWARD, 150.0, "step_forward", name="shove")
    impacts.add_impact(scene, other, "chest", 100, FORWARD, 80.0)  # another armature's: ignored
    scene.timeline_markers.new("camera cut", frame=120)  # an ordinary marker: ignored

    assert early.name == "shove" and late.name == "hit_01"
    assert impacts.is_impact_marker(early) and not impacts.is_impact_marker(scene.timeline_markers["camera cut"])
    assert len({impacts.impact_data(m).uid for m in scene.timeline_markers if impacts.is_impact_marker(m)}) == 3
    assert [m.name for m in impacts.impact_markers(scene, "walk")] == ["shove", "hit_01"]

    # frame order, frames counted from the action's first frame (1), direction normalised by the core
    assert impacts.read_impacts(scene, rig) == [
        Impact(40.0, "chest", FORWARD, 150.0, "step_forward"),
        Impact(199.0, "head", (0.0, 1.0, 0.0), 40.0, None),
    ]
    assert impacts.read_impacts(scene, rig, frame_range=(11, 264))[0].frame == 30.0

    impacts.remove_impact(scene, impacts.impact_data(early).uid)
    assert [m.name for m in impacts.impact_markers(scene, "walk")] == ["hit_01"]
    impacts.remove_impact(scene, late)
    assert impacts.read_impacts(scene, rig) == []
    assert len(scene.timeline_markers) == 2  # the other armature's impact and the ordinary marker
    with pytest.raises(ImpactError, match="no impact marker with uid 'nope'"):
        impacts.remove_impact(scene, "nope")


def test_markers_with_their_data_survive_save_and_reload(empty_scene, tmp_path):
    scene = empty_scene
    rig = _walker()
    impacts.add_impact(scene, rig, "chest", 41, FORWARD, 250.0, "fall_forward_hands")
    impacts.add_impact(scene, rig, "upper_arm.L", 130, (0.3, 0.4, 0.0), 55.5)
    before = sorted(_fields(m) for m in scene.timeline_markers)
    path = tmp_path / "markers.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    bpy.ops.wm.read_factory_settings(use_empty=True)
    assert len(bpy.context.scene.timeline_markers) == 0

    bpy.ops.wm.open_mainfile(filepath=str(path))
    scene = bpy.context.scene
    assert sorted(_fields(m) for m in scene.timeline_markers) == before
    first, second = impacts.read_impacts(scene, bpy.data.objects["walk"])
    assert first == Impact(40.0, "chest", FORWARD, 250.0, "fall_forward_hands")
    assert (second.frame, second.bone, second.strength, second.reaction) == (129.0, "upper_arm.L", 55.5, None)
    assert second.direction == pytest.approx((0.6, 0.8, 0.0), abs=1e-7)  # stored as float32


def test_a_forced_reaction_is_stored_as_its_classes_fixed_id(empty_scene):
    """A .blend holds the enum's number: each class's is its table id (classes.ReactionClass.enum_id,
    never renumbered), not its position, so adding a class changes no saved marker."""
    reaction = impacts.REACTIVE_ANIM_PG_impact.bl_rna.properties["reaction"]
    assert isinstance(reaction, bpy.types.EnumProperty)
    items = reaction.enum_items
    assert {item.identifier: item.value for item in items} == {"auto": 0} | {c.slug: c.enum_id for c in CLASSES}


@pytest.mark.parametrize("frame", [0, 265, 400])
def test_a_marker_outside_the_animation_is_reported_by_name(empty_scene, frame):
    rig = _walker()
    impacts.add_impact(empty_scene, rig, "chest", 100, FORWARD)
    impacts.add_impact(empty_scene, rig, "chest", frame, FORWARD, name="too_far")
    with pytest.raises(ImpactError, match=rf"impact marker 'too_far' at frame {frame} is outside .* frames 1-264"):
        impacts.read_impacts(empty_scene, rig)


def test_bad_marker_data_is_reported_by_name(empty_scene):
    """Markers edited after they were made (a renamed bone, a zeroed direction) are named when read."""
    rig = _walker()
    marker = impacts.add_impact(empty_scene, rig, "chest", 100, FORWARD, name="edited")
    impacts.impact_data(marker).bone = "tail"
    with pytest.raises(
        ImpactError, match="impact marker 'edited' at frame 100 is on bone 'tail', which armature 'walk' does not have"
    ):
        impacts.read_impacts(empty_scene, rig)
    impacts.impact_data(marker).bone = "chest"
    impacts.impact_data(marker).direction = (0.0, 0.0, 0.0)
    with pytest.raises(ImpactError, match=r"impact marker 'edited' at frame 100: .*has no length"):
        impacts.read_impacts(empty_scene, rig)


def test_add_impact_refuses_bad_values(empty_scene):
    rig = _walker()
    with pytest.raises(ImpactError, match="armature 'walk' has no bone 'tail'"):
        impacts.add_impact(empty_scene, rig, "tail", 10, FORWARD)
    with pytest.raises(ImpactError, match="unknown reaction 'dance'"):
        impacts.add_impact(empty_scene, rig, "chest", 10, FORWARD, reaction="dance")
    with pytest.raises(ImpactError, match="has no length"):
        impacts.add_impact(empty_scene, rig, "chest", 10, (0.0, 0.0, 0.0))
    assert len(empty_scene.timeline_markers) == 0


def test_add_impact_operator_for_scripts(empty_scene):
    _walker()
    empty_scene.frame_current = 77
    result = addon_ops.add_impact(
        armature_name="walk", bone="head", direction=(0.0, 1.0, 0.0), strength=30.0, reaction="sway_balance"
    )
    assert result == {"FINISHED"}
    addon_ops.add_impact(armature_name="walk", bone="chest", frame=150, marker_name="late")
    fields = [_fields(m)[:7] for m in impacts.impact_markers(empty_scene, "walk")]
    assert fields == [
        ("hit_01", 77, "walk", "head", (0.0, 1.0, 0.0), 30.0, "sway_balance"),
        ("late", 150, "walk", "chest", (1.0, 0.0, 0.0), 100.0, "auto"),
    ]
    with pytest.raises(RuntimeError, match="armature 'walk' has no bone 'tail'"):
        addon_ops.add_impact(armature_name="walk", bone="tail")
    with pytest.raises(RuntimeError, match="there is no armature called 'nobody'"):
        addon_ops.add_impact(armature_name="nobody", bone="chest")
    assert len(empty_scene.timeline_markers) == 2


def test_impacts_follow_their_character_through_a_rename(empty_scene, tmp_path):
    """Renaming the armature used to orphan its impacts ("armature 'hero' has no impact markers")."""
    scene = empty_scene
    rig, other = _walker(), _walker("other")
    impacts.add_impact(scene, rig, "chest", 41, FORWARD, 120.0, "step_forward")
    impacts.add_impact(scene, other, "head", 90, FORWARD, 60.0)
    rig.name = "hero"
    assert [m.frame for m in impacts.impact_markers(scene, "hero")] == [41]
    assert impacts.impact_markers(scene, "walk") == []
    assert [m.frame for m in impacts.impact_markers(scene, "other")] == [90]
    path = tmp_path / "renamed.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    bpy.ops.wm.open_mainfile(filepath=str(path))
    scene = bpy.context.scene
    assert addon_ops.bake(armature_name="hero") == {"FINISHED"}
    assert action_of(bpy.data.objects["hero"]).name == "walk.reacted"


def test_an_impact_saved_with_only_its_armature_s_name_still_finds_it(empty_scene):
    """Files saved before impacts held their character: the name is what they have."""
    rig = _walker()
    marker = impacts.add_impact(empty_scene, rig, "chest", 41, FORWARD, 120.0)
    impacts.impact_data(marker).character = None
    assert impacts.impact_markers(empty_scene, "walk") == [marker]
    bpy.data.objects.remove(rig)  # deleted: the name is left, and names what is missing
    assert impacts.character_name(marker) == "walk"
