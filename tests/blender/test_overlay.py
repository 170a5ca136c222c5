"""The impact overlay (blender/ui/overlay.py): arrow geometry on a real armature, registration in background mode."""

from __future__ import annotations

import math

import bpy
import numpy as np
import pytest
from mathutils import Euler

from reactive_anim.blender.impacts import impacts
from reactive_anim.blender.ui import overlay, settings
from tools.devkit.blender_types import armature_data

PUSH = (0.0, 1.0, 0.0)  # pushed along +Y: the arrow comes from -Y


def _rig(name: str = "rig") -> bpy.types.Object:
    """An armature with two bones standing on the Z axis: hips 1.0-1.2 m, chest 1.2-1.6 m."""
    rig = bpy.data.objects.new(name, bpy.data.armatures.new(name))
    bpy.context.scene.collection.objects.link(rig)
    bpy.context.view_layer.objects.active = rig
    bpy.ops.object.mode_set(mode="EDIT")
    edit_bones = armature_data(rig).edit_bones
    hips = edit_bones.new("hips")
    hips.head, hips.tail = (0.0, 0.0, 1.0), (0.0, 0.0, 1.2)
    chest = edit_bones.new("chest")
    chest.head, chest.tail = (0.0, 0.0, 1.2), (0.0, 0.0, 1.6)
    chest.parent = hips
    bpy.ops.object.mode_set(mode="OBJECT")
    bpy.context.view_layer.update()
    return rig


def _middle(rig: bpy.types.Object, bone: str) -> np.ndarray:
    pose_bone = rig.pose.bones[bone]
    return np.array(rig.matrix_world @ ((pose_bone.head + pose_bone.tail) / 2))


def _only(arrows: list[overlay.Arrow]) -> overlay.Arrow:
    assert len(arrows) == 1
    return arrows[0]


def test_tip_at_the_bone_middle_shaft_upstream(empty_scene):
    scene = empty_scene
    rig = _rig()
    marker = impacts.add_impact(scene, rig, "chest", 50, (0.0, 3.0, 0.0), 100.0)

    arrow = _only(overlay.impact_arrows(scene, 50))
    assert arrow.uid == impacts.impact_data(marker).uid
    np.testing.assert_allclose(arrow.tip, (0.0, 0.0, 1.4), atol=1e-6)
    # the tail lies upstream: from the tip along -direction (normalised), at the strength's length
    np.testing.assert_allclose(arrow.tail, np.array(arrow.tip) - np.array(PUSH) * overlay.arrow_length(100.0))
    # the shaft meets the head on the same line, between tail and tip
    np.testing.assert_allclose((arrow.neck[0], arrow.neck[2]), (0.0, 1.4), atol=1e-6)
    assert arrow.tail[1] < arrow.neck[1] < arrow.tip[1]

    # the head: whole triangles, all within the cone's reach of the tip, behind it along the push
    assert len(arrow.head) % 3 == 0 and len(arrow.head) >= 3 * overlay.HEAD_SEGMENTS
    offsets = np.array(arrow.head) - np.array(arrow.tip)
    head_length = overlay.HEAD_LENGTH_FRACTION * overlay.arrow_length(100.0)
    assert np.linalg.norm(offsets, axis=1).max() <= head_length * math.hypot(1.0, overlay.HEAD_RADIUS_FRACTION) + 1e-6
    assert (offsets @ np.array(PUSH) <= 1e-9).all()


def test_tip_follows_the_object_and_the_pose(empty_scene):
    scene = empty_scene
    rig = _rig()
    impacts.add_impact(scene, rig, "chest", 50, PUSH, 100.0)

    # Move and turn the armature object: chest middle (0, 0, 1.4) turns to (0, -1.4, 0), then +2 in X.
    rig.location = (2.0, 0.0, 0.0)
    rig.rotation_euler = Euler((math.pi / 2, 0.0, 0.0))
    bpy.context.view_layer.update()
    arrow = _only(overlay.impact_arrows(scene, 50))
    np.testing.assert_allclose(arrow.tip, (2.0, -1.4, 0.0), atol=1e-6)
    np.testing.assert_allclose(arrow.tip, _middle(rig, "chest"), atol=1e-6)
    # the direction is in world space: the shaft does not turn with the object
    np.testing.assert_allclose(np.array(arrow.tip) - arrow.tail, np.array(PUSH) * overlay.arrow_length(100.0))

    # Bend the hips: the chest's middle moves with the pose the armature shows.
    rig.pose.bones["hips"].rotation_mode = "XYZ"
    rig.pose.bones["hips"].rotation_euler = (math.radians(40.0), 0.0, 0.0)
    bpy.context.view_layer.update()
    moved = _only(overlay.impact_arrows(scene, 50)).tip
    assert np.linalg.norm(np.array(moved) - (2.0, -1.4, 0.0)) > 0.05
    np.testing.assert_allclose(moved, _middle(rig, "chest"), atol=1e-6)


def test_stronger_push_longer_arrow(empty_scene):
    scene = empty_scene
    rig = _rig()
    weak = impacts.add_impact(scene, rig, "chest", 50, PUSH, 30.0)
    strong = impacts.add_impact(scene, rig, "chest", 50, PUSH, 300.0)
    by_uid = {a.uid: a for a in overlay.impact_arrows(scene, 50)}

    def length(marker: bpy.types.TimelineMarker) -> float:
        arrow = by_uid[impacts.impact_data(marker).uid]
        return float(np.linalg.norm(np.subtract(arrow.tip, arrow.tail)))

    assert length(weak) < length(strong)
    assert overlay.arrow_length(0.0) == overlay.ARROW_BASE_LENGTH
    assert overlay.arrow_length(10_000.0) == overlay.ARROW_BASE_LENGTH + overlay.ARROW_STRENGTH_LENGTH


def test_fades_with_distance_and_shows_only_in_its_window(empty_scene):
    scene = empty_scene
    rig = _rig()
    impacts.add_impact(scene, rig, "hips", 50, PUSH, 100.0)
    first, last = 50 - overlay.IMPACT_FRAMES_BEFORE, 50 + overlay.IMPACT_FRAMES_AFTER

    alphas = {frame: [a.color[3] for a in overlay.impact_arrows(scene, frame)] for frame in range(first - 5, last + 6)}
    assert alphas[50] == [1.0]
    for frame in range(first, last + 1):
        assert len(alphas[frame]) == 1, frame
    assert alphas[first - 1] == [] and alphas[last + 1] == [] and alphas[first - 5] == []
    # strictly fading away from the impact frame, on both sides, still visible at the window's ends
    before = [alphas[f][0] for f in range(first, 51)]
    after = [alphas[f][0] for f in range(50, last + 1)]
    assert before == sorted(set(before)) and after == sorted(set(after), reverse=True)
    assert 0.0 < alphas[first][0] < 1.0 and 0.0 < alphas[last][0] < 1.0


def test_colour_by_reaction_and_active(empty_scene):
    scene = empty_scene
    rig = _rig()
    auto = impacts.add_impact(scene, rig, "hips", 50, PUSH, 100.0)
    forced = impacts.add_impact(scene, rig, "chest", 50, PUSH, 100.0, "step_forward")
    auto_uid = impacts.impact_data(auto).uid

    by_uid = {a.uid: a for a in overlay.impact_arrows(scene, 50)}
    plain, other = by_uid[auto_uid], by_uid[impacts.impact_data(forced).uid]
    assert plain.color[:3] == pytest.approx(overlay.AUTO_COLOR) and not plain.active
    assert other.color[:3] == pytest.approx(overlay.OVERRIDDEN_COLOR)

    lit = {a.uid: a for a in overlay.impact_arrows(scene, 50, active_uid=auto_uid)}[auto_uid]
    assert lit.active and sum(lit.color[:3]) > sum(plain.color[:3])

    # the draw callback highlights the impact selected in the panel's list (a marker index)
    panel = settings.scene_settings(scene)
    panel.active_impact = list(scene.timeline_markers).index(forced)
    assert overlay.active_impact_uid(scene) == impacts.impact_data(forced).uid
    scene.timeline_markers.new("camera cut", frame=10)
    panel.active_impact = len(scene.timeline_markers) - 1  # an ordinary marker: no impact is active
    assert overlay.active_impact_uid(scene) is None
    panel.active_impact = 99
    assert overlay.active_impact_uid(scene) is None


def test_missing_bone_or_armature_is_skipped(empty_scene):
    scene = empty_scene
    rig, other = _rig(), _rig("other")
    impacts.add_impact(scene, rig, "chest", 50, PUSH, 100.0)
    impacts.add_impact(scene, rig, "hips", 50, PUSH, 100.0)
    impacts.add_impact(scene, other, "chest", 50, PUSH, 100.0)
    zero = impacts.add_impact(scene, rig, "hips", 50, PUSH, 100.0)
    impacts.impact_data(zero).direction = (0.0, 0.0, 0.0)  # edited to nothing after adding
    scene.timeline_markers.new("camera cut", frame=50)  # an ordinary marker
    assert len(overlay.impact_arrows(scene, 50)) == 3

    # remove the chest bone
    bpy.context.view_layer.objects.active = rig
    bpy.ops.object.mode_set(mode="EDIT")
    edit_bones = armature_data(rig).edit_bones
    edit_bones.remove(edit_bones["chest"])
    bpy.ops.object.mode_set(mode="OBJECT")
    arrows = overlay.impact_arrows(scene, 50)
    assert len(arrows) == 2
    np.testing.assert_allclose(arrows[0].tip, _middle(rig, "hips"), atol=1e-6)

    # delete the other armature, then unlink the first from the scene
    bpy.data.objects.remove(other)
    assert len(overlay.impact_arrows(scene, 50)) == 1
    scene.collection.objects.unlink(rig)
    assert overlay.impact_arrows(scene, 50) == []


def test_no_draw_handler_in_background_and_draw_never_raises(empty_scene, monkeypatch, capsys):
    assert bpy.app.background
    overlay.register()
    assert overlay._handle is None  # one left installed crashes a background Blender 4.2 at exit
    overlay.unregister()
    overlay.tag_redraw()  # no windows: nothing to tag, no error

    # The callback swallows gpu's "not available in background mode" after one warning.
    impacts.add_impact(empty_scene, _rig(), "chest", empty_scene.frame_current, PUSH, 100.0)
    monkeypatch.setattr(overlay, "_warned", False)
    overlay.draw_callback()
    overlay.draw_callback()
    assert capsys.readouterr().out.count("impact overlay could not draw") == 1
