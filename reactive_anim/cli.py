"""Headless entry point: `python -m reactive_anim <command>` with the bpy module (or inside `blender -b`).

Errors from the core arrive as ReactiveAnimError and are printed in one line, with exit code 2;
the input files are never modified.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from .core.errors import ReactiveAnimError


def _import_command(args: argparse.Namespace) -> int:
    """A new empty scene, the BVH imported as a character, saved as a .blend."""
    import bpy

    from .blender import bvh_import

    bpy.ops.wm.read_factory_settings(use_empty=True)
    armature = bvh_import.import_bvh(bpy.context, args.bvh, unit=args.unit, up=args.up)
    scene = bpy.context.scene
    data, action = armature.data, armature.animation_data.action
    assert isinstance(data, bpy.types.Armature) and action is not None  # import_bvh made both
    scene.frame_start, scene.frame_end = (int(f) for f in action.frame_range)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    bpy.ops.wm.save_as_mainfile(filepath=str(args.out.resolve()), check_existing=False)
    fps = scene.render.fps / scene.render.fps_base
    print(
        f"saved {args.out}: armature '{armature.name}' ({len(data.bones)} bones), "
        f"action '{action.name}' frames {scene.frame_start}-{scene.frame_end} at {fps:g} fps"
    )
    return 0


def _unit(text: str) -> str | float:
    """A unit name, or a number of metres per file unit."""
    try:
        return float(text)
    except ValueError:
        return text


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m reactive_anim", description=__doc__.splitlines()[0] if __doc__ else None
    )
    commands = p.add_subparsers(dest="command", required=True)
    imp = commands.add_parser("import", help="import a BVH into a new scene and save it as a .blend")
    imp.add_argument("bvh", type=Path)
    imp.add_argument("--out", type=Path, required=True, help="the .blend to write")
    imp.add_argument("--unit", default="auto", type=_unit, help="auto, m, cm, mm, in, cmu or metres per file unit")
    imp.add_argument("--up", default="Y", choices=("Y", "Z"))
    imp.set_defaults(run=_import_command)
    return p


def main(argv: list[str] | None = None) -> int:
    args = parser().parse_args(argv)
    from . import register, unregister

    register()
    try:
        return args.run(args)
    except ReactiveAnimError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    finally:
        # The bpy module crashes (4.2) or hangs (4.5) at exit while add-on classes stay registered.
        unregister()
