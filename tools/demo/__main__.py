"""Run the demo: build the sample scene, add the impacts, bake, save out/demo.blend, render the filmstrip.

    .venv/bpy-5.0/bin/python -m tools.demo                      # from the repository root
    .venv/bpy-5.0/bin/python -m tools.demo --classes model      # never force the expected classes
    .venv/bpy-5.0/bin/python -m tools.demo --no-render          # scene, bake and .blend only

Everything goes through the add-on as an animator's script would: the importer builds the
character, impacts.add_impact adds the markers, and `bpy.ops.reactive_anim.bake` bakes them into
`<action>.reacted`. The bake's own per-impact lines (frame, marker, bone, class and how it was
chosen, clip, cost, ms) are printed as the bake stored them. Blender's user folders point at
out/demo_blender_user (unless BLENDER_USER_RESOURCES is set), so nothing lands in the user's own
configuration and the compiled reaction library is cached between runs.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path

os.environ.setdefault("BLENDER_USER_RESOURCES", str(Path(__file__).resolve().parents[2] / "out" / "demo_blender_user"))

import bpy  # after BLENDER_USER_RESOURCES: Blender reads it when the module loads
import numpy as np

import reactive_anim
from reactive_anim.blender.bake import bake, resources
from reactive_anim.blender.impacts import impacts
from reactive_anim.core.model.errors import ReactiveAnimError
from reactive_anim.core.react import ReactionSettings
from tools.devkit.operators import addon_ops

from . import markers, render
from . import scene as demo_scene

REPO = Path(__file__).resolve().parents[2]
BEFORE = 5  # frames before the hit in the filmstrip's first tile
LATER = (30, 90)  # frames after C + the transition of its last two tiles


def main(argv: list[str] | None = None) -> int:
    assert __doc__ is not None
    parser = argparse.ArgumentParser(prog="python -m tools.demo", description=__doc__.split("\n\n")[0])
    parser.add_argument("--out-dir", type=Path, default=REPO / "out", help="where demo.blend and the PNG go")
    parser.add_argument(
        "--classes",
        choices=("auto", "expected", "model"),
        default="auto",
        help="force each impact's expected class (expected), let the classifier or the whole-library "
        "search choose (model), or force only while no classifier model is usable (auto, the default)",
    )
    parser.add_argument("--no-render", action="store_true", help="skip the filmstrip")
    args = parser.parse_args(argv)
    reactive_anim.register()
    try:
        return run(args.out_dir, args.classes, render_filmstrip=not args.no_render)
    except ReactiveAnimError as exc:  # from the bakes that aim the later hits; the operator reports its own
        print(f"demo: error: {exc}", file=sys.stderr)
        return 2
    finally:
        reactive_anim.unregister()  # the bpy module can hang at exit with add-on classes registered


def run(out_dir: Path, classes: str, render_filmstrip: bool = True) -> int:
    clock = time.perf_counter()
    armature = demo_scene.build_scene(REPO / "sample_clips" / "walk.bvh")
    scene = bpy.context.scene
    fps = scene.render.fps / scene.render.fps_base
    print(f"scene: '{armature.name}' walks, frames {scene.frame_start}-{scene.frame_end} at {fps:g} fps", flush=True)

    classifier, note = resources.open_classifier()
    force = classes == "expected" or (classes == "auto" and classifier is None)
    if force:
        print(f"classes: forced to each impact's expected class ({note})")
    # Aiming each hit from the pose it lands on needs the earlier hits baked: quick bakes in between,
    # then the demo's bake through the operator, with everything in place.
    markers.add_demo_impacts(scene, armature, lambda: bake.bake_armature(scene, armature), force_classes=force)
    print("bake: bpy.ops.reactive_anim.bake, which reports one line per impact:", flush=True)
    bake_with_operator(armature)
    state = bake.bake_state(armature)
    demo_scene.fit_frame_range(scene, state.reacted_action.frame_range)
    scene.frame_set(scene.frame_start)

    out_dir.mkdir(parents=True, exist_ok=True)
    blend = out_dir / "demo.blend"
    blend.unlink(missing_ok=True)  # replaced, not kept as a demo.blend1 backup
    bpy.ops.wm.save_as_mainfile(filepath=str(blend.resolve()), check_existing=False)
    print(f"saved {blend}: frames {scene.frame_start}-{scene.frame_end} ({time.perf_counter() - clock:.1f} s so far)")

    if render_filmstrip:
        started = time.perf_counter()
        rows = filmstrip_rows(scene, armature, state.summary)
        png = out_dir / "demo_filmstrip.png"
        engine = render.render_filmstrip(scene, rows, png)
        print(f"rendered {png}: {len(rows)} impacts x {len(rows[0])} frames with {engine} "
              f"in {time.perf_counter() - started:.1f} s")  # fmt: skip
        compared = out_dir / "demo_before_after.png"
        render.write_png(render.compose(before_and_after(scene, armature, rows[-1])), compared)
        print(f"rendered {compared}: the last impact's frames without and with the bake")
    print(f"demo: {time.perf_counter() - clock:.1f} s")
    return 0


def before_and_after(scene: bpy.types.Scene, armature: bpy.types.Object, row: list[render.Tile]) -> list[list]:
    """The same frames twice: the character playing its original action (as before the bake), then
    the reacted one."""
    before = [replace(tile, caption=f"before the bake, {tile.caption.split()[-1]}") for tile in row]
    after = [replace(tile, caption=f"after: {tile.caption}") for tile in row]
    with playing_original(armature):
        pictures = render.render_rows(scene, [before])
    return pictures + render.render_rows(scene, [after])


@contextmanager
def playing_original(armature: bpy.types.Object) -> Iterator[None]:
    """The baked character plays its original action meanwhile (with the rotation modes it keys)."""
    state = bake.bake_state(armature)
    modes = {pb.name: pb.rotation_mode for pb in armature.pose.bones}
    bake.restore_rotation_modes(armature, json.loads(state.rotation_modes))
    bake.assign_action(armature, state.original_action)
    try:
        yield
    finally:
        bake.restore_rotation_modes(armature, modes)
        bake.assign_action(armature, state.reacted_action)


def bake_with_operator(armature: bpy.types.Object) -> None:
    """`bpy.ops.reactive_anim.bake` on the armature; a refused bake stops the demo with its report."""
    if addon_ops.bake(armature_name=armature.name) != {"FINISHED"}:
        raise ReactiveAnimError(f"the bake of '{armature.name}' failed (its report is above)")


def filmstrip_rows(scene: bpy.types.Scene, armature: bpy.types.Object, summary: str) -> list[list[render.Tile]]:
    """Per impact marker: just before the hit, C (end of the free-physics window), C + the
    transition (F, where the transition has reached the clip, but for a fall, whose F may come
    later: ReactionSettings.fall_transition), then LATER frames after it, seen square to the push
    so that it goes across the picture. C and the transition follow from the bake's settings (the
    operator bakes with the defaults); the class is read from the bake's summary line."""
    settings = ReactionSettings()
    fps = scene.render.fps / scene.render.fps_base
    rows = []
    for marker in impacts.impact_markers(scene, armature.name):
        b = marker.frame
        c = b + round(settings.reaction_window * fps)
        f = c + max(1, round(settings.transition * fps))
        found = re.search(rf"'{re.escape(marker.name)}' \S+: (\w+)", summary)
        label = f"{marker.name} ({found.group(1) if found else '?'})"
        forward, left = markers.facing(armature, b)
        view = markers.view_across(np.array(impacts.impact_data(marker).direction), forward, left)
        moments = [(b - BEFORE, f"B-{BEFORE}"), (c, "C")] + [(f + k, f"C+{(f + k - c) / fps:g}s") for k in (0, *LATER)]
        rows.append(
            [
                render.Tile(min(frame, scene.frame_end), f"{label} {moment}", (float(view[0]), float(view[1])))
                for frame, moment in moments
            ]
        )
    return rows


if __name__ == "__main__":
    sys.exit(main())
