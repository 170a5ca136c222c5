"""Headless entry point: `python -m reactive_anim <command>` with the bpy module (or inside `blender -b`).

Errors from the core arrive as ReactiveAnimError and are printed in one line, with exit code 2;
the input files are never modified (unless `bake --overwrite` asks for it). `bake` goes on with
the other files when one fails and exits with 1 (see _bake_command).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import traceback
from collections.abc import Iterator
from contextlib import contextmanager
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

    Each file is opened, each armature that impact markers name is baked, in every scene that has
    such markers (the reactive_anim.bake operator's work: a new `<action>.reacted` action, the
    original kept), and the result is saved next to the input, or in --out-dir, as
    `<name>.reacted.blend`; --overwrite saves over the input instead. Inputs that cannot be baked
    (a folder, a missing file, two inputs that would write the same output) are reported before
    anything is baked. A file that fails (cannot be read, a bad marker, markers naming an armature
    the file lacks, ...) is not written and the others still bake. Progress goes to stderr, a
    summary table to stdout. Exit code 0 when every file baked, 1 if any failed, 2 if the library
    or the classifier model cannot be opened.

    The same bake inside Blender, with the extension installed and enabled (one armature; save
    explicitly, and `--python-exit-code 1` makes a failed bake a non-zero exit):

        blender -b A.blend --python-exit-code 1 --python-expr "import bpy; \\
            bpy.ops.reactive_anim.bake(armature_name='walk'); \\
            bpy.ops.wm.save_as_mainfile(filepath='A.reacted.blend')"

    The operator also takes library_path='...' and model_path='...'; a failed bake raises
    RuntimeError with the message naming the marker, clip or file, and leaves the file as it was.
    """
    inputs = list(dict.fromkeys(p.resolve() for p in args.blend))  # an input given twice is baked once
    plan = _plan_outputs(inputs, args)
    outcomes: dict[Path, _FileOutcome] = {}
    for path, why in plan.items():
        if isinstance(why, str):
            print(f"error: {why}", file=sys.stderr)
            outcomes[path] = _FileOutcome(path, result=why, failed=True)
    to_bake = {path: out for path, out in plan.items() if isinstance(out, Path)}
    if to_bake:
        try:
            library, classifier = _open_library_and_model(args)
        except (ReactiveAnimError, OSError) as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 2
        for k, (path, out) in enumerate(to_bake.items(), 1):
            print(f"[{k}/{len(to_bake)}] {path}", file=sys.stderr)
            outcome = outcomes[path] = _bake_file(path, out, library, classifier)
            status = ("FAILED: " if outcome.failed else "") + outcome.result
            print(f"  {status} ({outcome.seconds:.1f} s)", file=sys.stderr)
    _print_table([outcomes[path] for path in plan])
    return 1 if any(o.failed for o in outcomes.values()) else 0


def _open_library_and_model(args: argparse.Namespace) -> tuple[Library, tuple[ReactionClassifier | None, str]]:
    """Opened once, only when some input is left to bake: every file bakes with the same ones."""
    from .blender import resources

    library = resources.open_library(args.library.resolve() if args.library else None)
    classifier = resources.open_classifier(args.model.resolve() if args.model else None)
    print(f"library: {len(library.clips)} clips; {classifier[1]}", file=sys.stderr)
    return library, classifier


def _plan_outputs(inputs: list[Path], args: argparse.Namespace) -> dict[Path, Path | str]:
    """Each input's output file, or why it is refused, decided before anything is baked: a folder
    or a missing file; an output that would overwrite an input without --overwrite; an output that
    two inputs would write (`a/shot.blend` and `b/shot.blend` into one --out-dir): neither is baked,
    rather than the second silently replacing the first."""
    folder = args.out_dir.resolve() if args.out_dir else None
    outs = [path if args.overwrite else (folder or path.parent) / f"{path.stem}.reacted.blend" for path in inputs]
    writers: dict[str, list[Path]] = {}
    for path, out in zip(inputs, outs, strict=True):
        if path.is_file():
            writers.setdefault(os.path.normcase(out), []).append(path)
    plan: dict[Path, Path | str] = {}
    for path, out in zip(inputs, outs, strict=True):
        same = writers.get(os.path.normcase(out), [])
        if path.is_dir():
            plan[path] = f"{path} is a folder; give .blend files"
        elif not path.is_file():
            plan[path] = f"file not found: {path}"
        elif len(same) > 1:
            plan[path] = f"{out} would be written by {len(same)} inputs ({', '.join(map(str, same))}): none is baked"
        elif out in inputs and not args.overwrite:
            plan[path] = f"the output would overwrite the input {out.name} (use --overwrite)"
        else:
            plan[path] = out
    return plan


def _bake_file(
    path: Path, out: Path, library: Library, classifier: tuple[ReactionClassifier | None, str]
) -> _FileOutcome:
    """Open one .blend, bake the armatures its impact markers name in every scene, save it to `out`."""
    import bpy

    start = time.perf_counter()
    outcome = _FileOutcome(path)
    try:
        try:
            bpy.ops.wm.open_mainfile(filepath=str(path), load_ui=False)
        except RuntimeError as exc:
            reason = str(exc).strip().removeprefix("Error: ")
            raise ReactiveAnimError(f"cannot open {path.name}: {reason}") from None
        for scene, armature in _bake_targets():
            _bake_armature(scene, armature, library, classifier, outcome)
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


def _bake_armature(
    scene: bpy.types.Scene,
    armature: bpy.types.Object,
    library: Library,
    classifier: tuple[ReactionClassifier | None, str],
    outcome: _FileOutcome,
) -> None:
    """Bake one armature with its scene active: the bake reads the context scene's frame rate and
    evaluates its view layer, as when the animator bakes in that scene."""
    from .blender import bake

    print(f"  scene '{scene.name}', armature '{armature.name}'", file=sys.stderr)
    with _scene_active(scene):
        result = bake.bake_armature(scene, armature, library, classifier=classifier, progress=_print_progress)
    for line in result.impact_lines():
        print(f"    {line}", file=sys.stderr)
    outcome.impacts += len(result.reactions)
    outcome.classes += [r.reaction_class for r in result.reactions]


@contextmanager
def _scene_active(scene: bpy.types.Scene) -> Iterator[None]:
    """Make `scene` the context's scene, and put the file's own back (it is saved as the scene
    the file opens on). Without a window (`blender -b`), a context override does it."""
    import bpy

    window = bpy.context.window
    if window is None:
        with bpy.context.temp_override(scene=scene, view_layer=scene.view_layers[0]):
            yield
        return
    before = window.scene
    window.scene = scene
    try:
        yield
    finally:
        window.scene = before


def _print_progress(k: int, n: int, what: str) -> None:
    if k < n:
        print(f"    impact {k + 1}/{n}: {what}", file=sys.stderr)


def _bake_targets() -> list[tuple[bpy.types.Scene, bpy.types.Object]]:
    """Each scene's armatures that its impact markers name, across every scene of the open file.

    Raises ReactiveAnimError, before anything is baked, naming the markers that name an armature
    the scene lacks (renamed or deleted: baking the rest would drop those hits unnoticed) and an
    armature with markers in two scenes (a bake reads one scene's markers: the second would
    replace the first's reactions).
    """
    import bpy

    targets, problems, baked_in = [], [], {}
    for scene in bpy.data.scenes:
        for name, markers in _impact_markers_by_armature(scene).items():
            armature = scene.objects.get(name)
            if armature is None or armature.type != "ARMATURE":
                problems.append(_orphan_message(scene, name, markers))
            elif name in baked_in:
                problems.append(
                    f"armature '{name}' has impact markers in scenes '{baked_in[name]}' and '{scene.name}'; "
                    "a bake reads one scene's markers: move them into one scene"
                )
            else:
                baked_in[name] = scene.name
                targets.append((scene, armature))
    if problems:
        raise ReactiveAnimError("; ".join(problems))
    return targets


def _impact_markers_by_armature(scene: bpy.types.Scene) -> dict[str, list[str]]:
    """The names of the scene's impact markers, by the armature each names, armatures sorted."""
    from .blender import impacts

    found: dict[str, list[str]] = {}
    for marker in scene.timeline_markers:
        if impacts.is_impact_marker(marker):
            found.setdefault(impacts.character_name(marker), []).append(marker.name)
    return dict(sorted(found.items()))


def _orphan_message(scene: bpy.types.Scene, name: str, markers: list[str]) -> str:
    """Markers naming an armature the scene lacks: which markers, which armature, and why it is missing."""
    import bpy

    found = bpy.data.objects.get(name)
    if found is None:
        why = "which the file does not have (renamed or deleted?)"
    elif found.type != "ARMATURE":
        why = f"but '{name}' is a {found.type.lower()}, not an armature"
    else:
        why = f"which is not in scene '{scene.name}'"
    if len(markers) == 1:
        return f"impact marker '{markers[0]}' in scene '{scene.name}' names armature '{name}', {why}"
    listed = ", ".join(f"'{m}'" for m in markers)
    return f"impact markers {listed} in scene '{scene.name}' name armature '{name}', {why}"


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
