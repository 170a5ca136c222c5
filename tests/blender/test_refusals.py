"""Bakes refused before anything is written (issue "Production scenes", items 4, 5, 10, 11): a linked
character, a zero or mirroring scale, a strength not above 0, an empty action, a reaction this version
does not know, motion in NLA strips, a model path that is a folder. Each through the real operator:
CANCELLED, a message naming the cause and the fix, the .blend as it was."""

from __future__ import annotations

from pathlib import Path

import bpy
import pytest

from reactive_anim.blender.bake import bake, bake_ops
from reactive_anim.blender.character import bvh_import
from reactive_anim.blender.impacts import impacts
from tests.support.actions import action_of
from tests.support.bake_scene import FORWARD, WALK, blend_snapshot, walk_with_impacts
from tools.devkit.operators import addon_ops


@pytest.fixture
def bake_results(monkeypatch):
    """What the bake operator's execute returned, call by call: bpy.ops raises on an error report
    and so hides the result."""
    results = []
    execute = bake_ops.REACTIVE_ANIM_OT_bake.execute

    def recording(self, context):
        results.append(execute(self, context))
        return results[-1]

    monkeypatch.setattr(bake_ops.REACTIVE_ANIM_OT_bake, "execute", recording)
    return results


def assert_refused(results: list, expected: str, **options) -> None:
    """The bake operator returns CANCELLED with an error matching `expected`, changing nothing."""
    before = blend_snapshot()
    with pytest.raises(RuntimeError, match=expected):
        addon_ops.bake(**options)
    assert results == [{"CANCELLED"}]
    assert blend_snapshot() == before


def _linked_hero(tmp_path: Path) -> bpy.types.Object:
    """A fresh file with the sample walk, as 'hero', linked from tmp_path/chars.blend into its scene."""
    bvh_import.import_bvh(bpy.context, WALK, name="hero")
    library = tmp_path / "chars.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(library))
    bpy.ops.wm.read_factory_settings(use_empty=True)
    with bpy.data.libraries.load(str(library), link=True) as (_, linked):
        linked.objects = ["hero"]
    hero = linked.objects[0]  # the names given become the objects loaded
    assert isinstance(hero, bpy.types.Object)
    bpy.context.scene.collection.objects.link(hero)
    return hero


def test_a_linked_character_is_refused(tmp_path, bake_results):
    hero = _linked_hero(tmp_path)
    assert hero.library is not None and action_of(hero).name == "walk"
    impacts.add_impact(bpy.context.scene, hero, "chest", 41, FORWARD, 120.0, "step_forward")

    assert_refused(
        bake_results,
        r"^Error: 'hero' is linked from 'chars.blend': make a library override \(Object > Library Override > Make\) "
        "to bake it",
        armature_name="hero",
    )
    assert "walk.reacted" not in bpy.data.actions


def test_a_library_override_bakes_and_keeps_its_bake_after_reload(tmp_path, bake_results):
    hero = _linked_hero(tmp_path)
    override = hero.override_create(remap_local_usages=True)
    assert override.library is None and override.data.library is not None  # its armature data stays linked
    impacts.add_impact(bpy.context.scene, override, "chest", 41, FORWARD, 120.0, "step_forward")

    assert addon_ops.bake() == {"FINISHED"}  # the override, not the linked object it overrides
    assert bake_results == [{"FINISHED"}] and override.animation_data.action.name == "walk.reacted"

    shot = tmp_path / "shot.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(shot))
    bpy.ops.wm.open_mainfile(filepath=str(shot))
    reloaded = next(ob for ob in bpy.data.objects if ob.override_library is not None)
    assert action_of(reloaded).name == "walk.reacted"


@pytest.mark.parametrize(
    ("case", "expected"),
    [
        ("zero", r"armature 'walk' has a zero scale \('walk' scale \(0, 0, 0\)\): give it a scale above 0"),
        ("flat", r"armature 'walk' has a zero scale \('walk' scale \(1, 1, 0\)\): give it a scale above 0"),
        (
            "mirrored",
            r"armature 'walk' is mirrored by a negative scale \('walk' scale \(-1, 1, 1\)\), which the bake does "
            r"not support: apply the scale \(Object > Apply > Scale\) or un-mirror it",
        ),
        ("mirrored parent", r"armature 'walk' is mirrored by a negative scale \('stage' scale \(-1, 1, 1\)\)"),
    ],
)
def test_a_zero_or_mirroring_scale_is_refused(empty_scene, bake_results, case, expected):
    rig = walk_with_impacts(empty_scene)
    if case == "mirrored parent":
        stage = bpy.data.objects.new("stage", None)
        empty_scene.collection.objects.link(stage)
        stage.scale = (-1.0, 1.0, 1.0)
        rig.parent = stage
    else:
        rig.scale = {"zero": (0.0, 0.0, 0.0), "flat": (1.0, 1.0, 0.0), "mirrored": (-1.0, 1.0, 1.0)}[case]

    assert_refused(bake_results, expected, armature_name="walk")


@pytest.mark.parametrize("strength", [0.0, -50.0])
def test_a_strength_not_above_zero_is_refused(empty_scene, bake_results, strength):
    walk_with_impacts(empty_scene)
    props = impacts.impact_data(empty_scene.timeline_markers["hit_02"])
    props.strength = strength
    assert props.strength == strength  # a typed negative value is kept as typed, not clamped to 0
    assert "above 0" in type(props).bl_rna.properties["strength"].description
    turn = r" \(to push the other way, turn its direction around\)" if strength < 0 else "$"

    assert_refused(
        bake_results,
        rf"impact marker 'hit_02' at frame 131 has strength {strength:g} N·s: give it a strength above 0{turn}",
        armature_name="walk",
    )


def test_an_empty_action_is_refused(empty_scene, bake_results):
    rig = walk_with_impacts(empty_scene)
    bake.assign_action(rig, bpy.data.actions.new("blocking"))

    assert_refused(bake_results, r"action 'blocking' has no keyframes: key the motion", armature_name="walk")


def test_a_reaction_this_version_does_not_know_is_refused(empty_scene, bake_results):
    walk_with_impacts(empty_scene)
    props = impacts.impact_data(empty_scene.timeline_markers["hit_02"])
    props["reaction"] = 99  # the number a newer version's class would be stored as
    assert props.reaction == ""  # what reading the enum gives: nothing to name

    assert_refused(
        bake_results,
        r"impact marker 'hit_02' at frame 131 has reaction number 99, which this version of the add-on does not "
        r"know \(saved by a newer version\?\): pick its reaction again",
        armature_name="walk",
    )


def test_motion_in_nla_strips_is_explained(empty_scene, bake_results):
    rig = walk_with_impacts(empty_scene)
    adt = rig.animation_data
    adt.nla_tracks.new().strips.new("walk_strip", 1, action_of(rig))
    adt.action = None
    expected = (
        r"armature 'walk' plays its motion from NLA strips \(walk_strip\), not from an action: bake them into one "
        r"action \(Object > Animation > Bake Action\), or make a strip's action the active action"
    )
    before = blend_snapshot()
    with pytest.raises(RuntimeError, match=r"bake.poll\(\) " + expected):  # the button's tooltip says it
        addon_ops.bake(armature_name="walk")
    assert bake_results == [] and blend_snapshot() == before

    bvh_import.import_bvh(bpy.context, WALK, name="other")  # another character with an action: the poll passes
    assert_refused(bake_results, expected, armature_name="walk")


def test_a_model_path_that_is_a_folder_is_refused(empty_scene, bake_results, tmp_path):
    walk_with_impacts(empty_scene)

    assert_refused(
        bake_results,
        rf"classifier model {tmp_path} is a folder, not an \.onnx file: pick the model file in it, or clear",
        armature_name="walk",
        model_path=str(tmp_path),
    )
