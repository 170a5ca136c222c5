"""Headless entry point: `python -m reactive_anim <command>` with the bpy module (or inside `blender -b`).

Errors from the core arrive as ReactiveAnimError and are printed in one line, with exit code 2;
the input files are never modified (unless `bake --overwrite` asks for it). `bake` goes on with
the other files when one fails and exits with 1 (see _bake_command).
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
import traceback
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

from .core.model.errors import ReactiveAnimError
from .farm.report import FileOutcome, report_lines
from .farm.task import die_with_parent

if TYPE_CHECKING:  # bpy and the Blender layer are imported by the commands that need them
    import bpy

    from .core.react import ReactionClassifier
    from .core.search.library import Library

    Opened = tuple[Library, tuple[ReactionClassifier | None, str], str]  # library, classifier, settings digest


def _import_command(args: argparse.Namespace) -> int:
    """A new empty scene, the BVH imported as a character, saved as a .blend."""
    import bpy

    from .blender.character import bvh_import

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


def _bake_command(args: argparse.Namespace) -> int:
    """Bake every armature that has impact markers in each .blend; save `<name>.reacted.blend`.

    Each file is opened, each armature that impact markers name is baked, in every scene that has
    such markers (the reactive_anim.bake operator's work: a new `<action>.reacted` action, the
    original kept), and the result is saved next to the input, or in --out-dir, as
    `<name>.reacted.blend`; --overwrite saves over the input instead. Inputs that cannot be baked
    (a folder, a missing file, two inputs that would write the same output) are reported before
    anything is baked. A file that fails (cannot be read, a bad marker, markers naming an armature
    the file lacks, ...) is not written and the others still bake. Progress goes to stderr, a
    summary table to stdout, a JSON line per file to --report. Exit code 0 when every file baked,
    1 if any failed, 2 if the library or the classifier model cannot be opened (or, with
    --scheduler or --workers, Dask is not installed).

    An output is saved whole (a partial file renamed into place) and records the hash of what it
    was made from, so a rerun skips the files whose output is complete for the same inputs
    (--force bakes them again): see farm/outputs.py. --scheduler and --workers bake each file in a
    Blender process of its own on a Dask cluster (farm/cluster.py), with the same outputs.

    The same bake inside Blender, with the extension installed and enabled (one armature; save
    explicitly, and `--python-exit-code 1` makes a failed bake a non-zero exit):

        blender -b A.blend --python-exit-code 1 --python-expr "import bpy; \\
            bpy.ops.reactive_anim.bake(armature_name='walk'); \\
            bpy.ops.wm.save_as_mainfile(filepath='A.reacted.blend')"

    The operator also takes library_path='...' and model_path='...'; a failed bake raises
    RuntimeError with the message naming the marker, clip or file, and leaves the file as it was.
    """
    on_farm = args.scheduler is not None or args.workers is not None
    if on_farm:
        _require_dask()  # before anything else: a farm run without Dask stops here
    inputs = list(dict.fromkeys(p.resolve() for p in args.blend))  # an input given twice is baked once
    plan = _plan_outputs(inputs, args)
    outcomes: dict[Path, FileOutcome] = {}
    with report_lines(args.report) as write:
        for path, why in plan.items():
            if isinstance(why, str):
                print(f"error: {why}", file=sys.stderr)
                outcomes[path] = FileOutcome(path, worker=platform.node(), result=why, failed=True)
                write(outcomes[path])
        to_bake = {path: out for path, out in plan.items() if isinstance(out, Path)}

        def done(outcome: FileOutcome) -> None:
            outcomes[outcome.path] = outcome
            write(outcome)

        bake = _bake_on_cluster if on_farm else _bake_here
        if to_bake and bake(to_bake, args, done):
            return 2
    _print_table([outcomes[path] for path in plan])
    return 1 if any(o.failed for o in outcomes.values()) else 0


def _require_dask() -> None:
    """Dask is optional, needed by --scheduler and --workers only: its absence is said in one line."""
    try:
        from .farm import cluster  # noqa: F401
    except ImportError as exc:
        raise ReactiveAnimError(
            f"--scheduler and --workers need Dask's `distributed` package ({exc}): install it into this Python "
            "with `python -m pip install distributed` (pinned: tools/requirements/farm.txt)"
        ) from None


def _bake_here(to_bake: dict[Path, Path], args: argparse.Namespace, done: Callable[[FileOutcome], None]) -> int:
    """Bake the files one after another in this process; 2 if the library or model cannot be opened."""
    try:
        opened = _open_library_and_model(args)
    except (ReactiveAnimError, OSError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    for k, (path, out) in enumerate(to_bake.items(), 1):
        print(f"[{k}/{len(to_bake)}] {path}", file=sys.stderr)
        outcome = _bake_or_skip(path, out, opened, args.force)
        status = ("FAILED: " if outcome.failed else "") + outcome.result
        print(f"  {status} ({outcome.seconds:.1f} s)", file=sys.stderr)
        done(outcome)
    return 0


def _bake_on_cluster(to_bake: dict[Path, Path], args: argparse.Namespace, done: Callable[[FileOutcome], None]) -> int:
    """One task per file on the Dask cluster, each the one-file command with this run's settings;
    2 if the library or model cannot be opened here (checked once rather than failing every task;
    the farm reads them at the same paths)."""
    import bpy

    from .farm import cluster

    try:
        _open_library_and_model(args)
    except (ReactiveAnimError, OSError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    jobs = {str(path): _one_file_arguments(out, args) for path, out in to_bake.items()}
    for row in cluster.bake_all(jobs, bpy.app.binary_path, args.scheduler, args.workers):
        done(FileOutcome.from_row(row))
    return 0


def _one_file_arguments(out: Path, args: argparse.Namespace) -> list[str]:
    """The arguments after the file name that bake it to `out` with this run's settings."""
    where = ["--overwrite"] if args.overwrite else ["--out-dir", str(out.parent)]
    chosen = [(flag, value) for flag, value in (("--library", args.library), ("--model", args.model)) if value]
    settings = [part for flag, value in chosen for part in (flag, str(value.resolve()))]
    return where + settings + (["--force"] if args.force else [])


def _open_library_and_model(args: argparse.Namespace) -> Opened:
    """Opened once, only when some input is left to bake: every file bakes with the same ones, and
    their digest goes into the hash each output records (farm/outputs.py)."""
    from .blender.bake import resources
    from .farm import outputs

    library_path = args.library.resolve() if args.library else None
    model_path = args.model.resolve() if args.model else None
    library = resources.open_library(library_path)
    classifier = resources.open_classifier(model_path)
    print(f"library: {len(library.clips)} clips; {classifier[1]}", file=sys.stderr)
    source = library_path or resources.default_library_path()
    assert source is not None  # open_library found it
    return library, classifier, outputs.settings_digest(source, model_path or resources.default_model_path())


def _bake_or_skip(path: Path, out: Path, opened: Opened, force: bool) -> FileOutcome:
    """The outcome of a file whose output is already complete for its inputs (unless `force`), or
    of its bake."""
    from .farm import outputs

    start = time.perf_counter()
    try:
        inputs = outputs.inputs_hash(path, opened[2])
    except OSError as exc:
        return FileOutcome(path, worker=platform.node(), result=f"cannot read {path.name}: {exc}", failed=True)
    outcome = None if force else outputs.complete_output(path, out, inputs)
    if outcome is None:
        return _bake_file(path, out, opened, inputs)
    outcome.worker, outcome.seconds = platform.node(), time.perf_counter() - start
    return outcome


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


def _bake_file(path: Path, out: Path, opened: Opened, inputs: str) -> FileOutcome:
    """Open one .blend, bake the armatures its impact markers name in every scene, save it whole to
    `out` with the hash of its inputs (farm/outputs.py)."""
    import bpy

    from .farm import outputs

    library, classifier, _settings = opened
    start = time.perf_counter()
    outcome = FileOutcome(path, out, inputs, worker=platform.node())
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
            outputs.write_record(outcome)
            outputs.save_whole(out)
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
    outcome: FileOutcome,
) -> None:
    """Bake one armature with its scene active: the bake reads the context scene's frame rate and
    evaluates its view layer, as when the animator bakes in that scene."""
    from .blender.bake import bake

    print(f"  scene '{scene.name}', armature '{armature.name}'", file=sys.stderr)
    with _scene_active(scene):
        result = bake.bake_armature(scene, armature, library, classifier=classifier, progress=_print_progress)
    for line in result.impact_lines():
        print(f"    {line}", file=sys.stderr)
    outcome.impacts += len(result.reactions)
    outcome.classes += [r.reaction_class for r in result.reactions]
    outcome.clips += [r.clip for r in result.reactions]


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
    from .blender.impacts import impacts

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


def _print_table(outcomes: list[FileOutcome]) -> None:
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
    failed, skipped = sum(o.failed for o in outcomes), sum(o.skipped for o in outcomes)
    print(
        f"{len(outcomes) - failed} of {len(outcomes)} files baked"
        + (f" ({skipped} complete already: skipped)" if skipped else "")
        + (f", {failed} failed" if failed else "")
    )


def _unit(text: str) -> str | float:
    """A unit name, or a number of metres per file unit."""
    try:
        return float(text)
    except ValueError:
        return text


def _count(text: str) -> int:
    """A number of workers: a whole number of at least 1."""
    if not text.isdigit() or int(text) < 1:
        raise argparse.ArgumentTypeError(f"give a number of workers of at least 1, not {text!r}")
    return int(text)


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
    bake.add_argument("--force", action="store_true", help="bake even a file whose output is complete for its inputs")
    bake.add_argument("--report", type=Path, help="write one JSON line per file here (docs/command-line.md)")
    farm = bake.add_mutually_exclusive_group()
    farm.add_argument("--scheduler", metavar="tcp://HOST:PORT", help="bake each file as a task on this Dask scheduler")
    farm.add_argument("--workers", type=_count, metavar="N", help="bake on a Dask cluster of N workers started here")
    bake.set_defaults(run=_bake_command)
    return p


def main(argv: list[str] | None = None) -> int:
    die_with_parent()  # a farm task's bake process: never outlive the worker that started it
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
