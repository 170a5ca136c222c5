"""The bake tests' scene: the sample walk imported with three impact markers, and a snapshot of
everything a bake that fails, is cancelled or is discarded must leave as it was. Imports bpy: only
for tests/blender."""

from __future__ import annotations

import re
from pathlib import Path

import bpy

from reactive_anim.blender.bake import bake
from reactive_anim.blender.character import bvh_import
from reactive_anim.blender.impacts import impacts
from tests.support.actions import keyframes

WALK = Path(__file__).resolve().parents[2] / "sample_clips" / "walk.bvh"  # 264 frames at 60 fps, keys on 1-264
FORWARD = (0.0, -1.0, 0.0)  # the sample walk walks along -Y: a push from behind


def walk_with_impacts(scene: bpy.types.Scene) -> bpy.types.Object:
    """The sample walk with three impacts: two forced classes and one the pipeline chooses."""
    rig = bvh_import.import_bvh(bpy.context, WALK)
    impacts.add_impact(scene, rig, "chest", 41, FORWARD, 120.0, "step_forward")
    impacts.add_impact(scene, rig, "chest", 131, (0.0, 1.0, 0.0), 60.0, "sway_balance")
    impacts.add_impact(scene, rig, "head", 201, (1.0, 0.0, 0.0), 80.0)
    return rig


def blend_snapshot() -> dict:
    """Everything a failed, cancelled or discarded bake must leave as it was: objects and where they
    are linked, actions and their keys, assignments, markers, rotation modes, every bake-state field."""
    objects = {}
    for ob in bpy.data.objects:
        adt = ob.animation_data
        slot = getattr(adt, "action_slot", None) if adt else None
        state = bake.bake_state(ob)
        objects[ob.name] = (
            adt.action.name if adt and adt.action else None,
            slot.identifier if slot is not None else None,
            tuple(pb.rotation_mode for pb in ob.pose.bones) if ob.pose else (),
            tuple(str(getattr(state, p.identifier)) for p in state.bl_rna.properties if p.identifier != "rna_type"),
            tuple(c.name for c in ob.users_collection),
        )
    markers = []
    for m in bpy.context.scene.timeline_markers:
        p = impacts.impact_data(m)
        markers.append((m.name, m.frame, p.armature, p.bone, tuple(p.direction), p.strength, p.reaction, p.uid))
    actions = {a.name: (a.use_fake_user, keyframes(a)) for a in bpy.data.actions}
    armatures = {a.name: a.users for a in bpy.data.armatures}
    return {"objects": objects, "markers": markers, "actions": actions, "armatures": armatures}


def library_without_falls(folder: Path) -> Path:
    """A library of the sample steps only (absolute paths), so a forced fall has nothing to play."""
    lines = [f'[[clip]]\nfile = "{WALK.parent / f"step_forward_{k}.bvh"}"\nclass = "step_forward"\n' for k in (1, 2, 3)]
    toml = folder / "steps.toml"
    toml.write_text("\n".join(lines), encoding="utf-8")
    return toml


def summary_without_times(summary: str) -> list[str]:
    """A bake summary's lines without the measured times, which differ from run to run: the
    head's " in N s" and each impact's ", N ms" (a note may follow it)."""
    head, *lines = summary.splitlines()
    return [head.split(" in ")[0], *(re.sub(r", \d+ ms", "", line) for line in lines)]
