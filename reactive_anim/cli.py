"""Headless entry point: `python -m reactive_anim <command>` with the bpy module (or inside `blender -b`).

Errors from the core arrive as ReactiveAnimError and are printed in one line, with exit code 2;
the input files are never modified (unless `bake --overwrite` asks for it). `bake` goes on with
the other files when one fails and exits with 1 (see _bake_command).
"""

from __future__ import annotations

import argparse
import sys
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from .core.errors import ReactiveAnimError

if TYPE_CHECKING:  # bpy and the Blender layer are imported by the commands that need them
    import bpy

    from .core.library import Library
    from .core.react import ReactionClassifier


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


@dataclass
class _FileOutcome:
    """One input file of `bake`: what was baked, or why not."""

    path: Path
    impacts: int = 0
    classes: list[str] = field(default_factory=list)
    seconds: float = 0.0
    result: str = ""
    failed: bool = False


def _bake_command(args: argparse.Namespace) -> int:
    """Bake every armature that has impact markers in each .blend; save `<name>.reacted.blend`.

    Each file is opened, each armature of its scene with impact markers is baked (the
    reactive_anim.bake operator's work: a new `<action>.reacted` action, the original kept), and the
    result is saved next to the input, or in --out-dir, as `<name>.reacted.blend`; --overwrite saves
    over the input instead. A file that fails (cannot be read, a bad marker, ...) is not written
    and the others still bake. Progress goes to stderr, a summary table to stdout. Exit code 0 when
    every file baked, 1 if any failed, 2 if the library or the classifier model cannot be opened.

    The same bake inside Blender, with the extension installed and enabled (one armature; save
    explicitly, and `--python-exit-code 1` makes a failed bake a non-zero exit):

        blender -b A.blend --python-exit-code 1 --python-expr "import bpy; \\
            bpy.ops.reactive_anim.bake(armature_name='walk'); \\
            bpy.ops.wm.save_as_mainfile(filepath='A.reacted.blend')"

    The operator also takes library_path='...' and model_path='...'; a failed bake raises
    RuntimeError with the message naming the marker, clip or file, and leaves the file as it was.
    """
    from .blender import resources

    inputs = [p.resolve() for p in args.blend]
    try:
        library = resources.open_library(args.library.resolve() if args.library else None)
        classifier = resources.open_classifier(args.model.resolve() if args.model else None)
    except (ReactiveAnimError, OSError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(f"library: {len(library.clips)} clips; {classifier[1]}", file=sys.stderr)
    outcomes = []
    for k, path in enumerate(inputs, 1):
        print(f"[{k}/{len(inputs)}] {path}", file=sys.stderr)
        outcome = _bake_file(path, _bake_output(path, args, inputs), library, classifier)
        print(f"  {'FAILED: ' if outcome.failed else ''}{outcome.result} ({outcome.seconds:.1f} s)", file=sys.stderr)
        outcomes.append(outcome)
    _print_table(outcomes)
    return 1 if any(o.failed for o in outcomes) else 0


def _bake_output(path: Path, args: argparse.Namespace, inputs: list[Path]) -> Path | None:
    """Where a baked file goes; None when that would overwrite an input without --overwrite."""
    if args.overwrite:
        return path
    out = (args.out_dir.resolve() if args.out_dir else path.parent) / f"{path.stem}.reacted.blend"
    return None if out in inputs else out


def _bake_file(
    path: Path, out: Path | None, library: Library, classifier: tuple[ReactionClassifier | None, str]
) -> _FileOutcome:
    """Open one .blend, bake its armatures with impact markers, save it to `out`."""
    import bpy

    from .blender import bake

    start = time.perf_counter()
    outcome = _FileOutcome(path)
    try:
        if out is None:
            raise ReactiveAnimError(f"the output would overwrite the input {path.stem}.reacted.blend (use --overwrite)")
        if not path.is_file():
            raise ReactiveAnimError(f"file not found: {path}")
        try:
            bpy.ops.wm.open_mainfile(filepath=str(path), load_ui=False)
        except RuntimeError as exc:
            reason = str(exc).strip().removeprefix("Error: ")
            raise ReactiveAnimError(f"cannot open {path.name}: {reason}") from None
        scene = bpy.context.scene
        for name in _armatures_with_impacts(scene):
            armature = scene.objects[name]
            print(f"  armature '{name}'", file=sys.stderr)
            result = bake.bake_armature(scene, armature, library, classifier=classifier, progress=_print_progress)
            for line in result.impact_lines():
                print(f"    {line}", file=sys.stderr)
            outcome.impacts += len(result.reactions)
            outcome.classes += [r.reaction_class for r in result.reactions]
        if not outcome.impacts:
            outcome.result = "no impact markers: nothing baked, nothing written"
        else:
            out.parent.mkdir(parents=True, exist_ok=True)
            bpy.ops.wm.save_as_mainfile(filepath=str(out), check_existing=False)
            outcome.result = f"saved {out}"
    except (ReactiveAnimError, OSError, RuntimeError) as exc:
        outcome.failed, outcome.result = True, str(exc)
    except Exception as exc:  # a bug, not the file's fault: show it, and still bake the other files
        traceback.print_exc(file=sys.stderr)
        outcome.failed, outcome.result = True, f"internal error: {type(exc).__name__}: {exc}"
    outcome.seconds = time.perf_counter() - start
    return outcome


def _print_progress(k: int, n: int, what: str) -> None:
    if k < n:
        print(f"    impact {k + 1}/{n}: {what}", file=sys.stderr)


def _armatures_with_impacts(scene: bpy.types.Scene) -> list[str]:
    """Armatures of the scene that impact markers name; markers naming no such armature are reported."""
    from .blender import impacts

    named = {impacts.impact_data(m).armature for m in scene.timeline_markers if impacts.is_impact_marker(m)}
    found = sorted(n for n in named if n in scene.objects and scene.objects[n].type == "ARMATURE")
    for missing in sorted(named - set(found)):
        print(f"  warning: impact markers name '{missing}', not an armature of this scene: ignored", file=sys.stderr)
    return found


def _print_table(outcomes: list[_FileOutcome]) -> None:
    rows = [("file", "impacts", "classes chosen", "time", "result")] + [
        (
            o.path.name,
            str(o.impacts),
            ", ".join(o.classes) or "-",
            f"{o.seconds:.1f} s",
            ("FAILED: " if o.failed else "") + o.result,
        )
        for o in outcomes
    ]
    widths = [max(len(row[c]) for row in rows) for c in range(4)]
    for row in rows:
        print("  ".join(cell.ljust(w) for cell, w in zip(row, widths, strict=False)) + "  " + row[4])
    failed = sum(o.failed for o in outcomes)
    print(f"{len(outcomes) - failed} of {len(outcomes)} files baked" + (f", {failed} failed" if failed else ""))


def _train_command(args: argparse.Namespace) -> int:
    """Train the reaction classifier: tools/train_classifier.py with the arguments after `train`
    (from the repository, which holds tools/; the extension does not ship them)."""
    try:
        from tools.train_classifier import main as train
    except ImportError:
        raise ReactiveAnimError("`train` runs tools/train_classifier.py: run it from the repository root") from None
    return train(args.arguments)


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
    bake = commands.add_parser("bake", help="bake the impact markers of .blend files into reacted copies")
    bake.add_argument("blend", type=Path, nargs="+", help="the .blend files to bake")
    bake.add_argument("--library", type=Path, help="reaction library folder or .toml (default: the sample library)")
    bake.add_argument("--model", type=Path, help="ONNX classifier model (default: the shipped one, if present)")
    where = bake.add_mutually_exclusive_group()
    where.add_argument("--out-dir", type=Path, help="write <name>.reacted.blend here (default: beside each input)")
    where.add_argument("--overwrite", action="store_true", help="save the baked scene over each input file")
    bake.set_defaults(run=_bake_command)
    train = commands.add_parser(
        "train", prefix_chars="+", help="train the reaction classifier (python -m tools.train_classifier --help)"
    )
    train.add_argument("arguments", nargs=argparse.REMAINDER, help="passed on, e.g. --quick --clips walk.bvh")
    train.set_defaults(run=_train_command)
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
