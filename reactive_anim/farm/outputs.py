"""A baked output written whole and known to be complete: what lets a batch be killed and resumed.

Written whole: the bake saves to a temporary name beside its output, unique to the attempt
(`.NAME.<random>.partial.blend`), and renames it into place with os.replace, atomic within a
folder; so an output exists only when complete, and a bake killed while saving leaves a hidden
partial file, never a half-written NAME. Beside the output rather than in a temporary folder: the
rename never crosses file systems, and Blender remaps relative paths (textures, linked libraries)
for the folder the file ends up in. The next complete save of the same output removes the partial
files earlier attempts left.

Known complete: the output carries the hash of everything it was made from (the input .blend's
bytes, the library, the classifier model, the add-on's code and Blender's, MuJoCo's, onnxruntime's
and numpy's versions) in a custom property of the scene it opens on, saved in the same rename. A
rerun skips a file whose output records the hash its inputs have now; an output made from other
inputs, or without the record, is baked again. Inside the output, not in a sidecar file, so there
is no moment at which the two disagree: a crash anywhere leaves either the old output with its own
record or the new one with its own.
"""

from __future__ import annotations

import glob
import hashlib
import json
import os
import shutil
import uuid
from pathlib import Path

from .report import FileOutcome

PARTIAL = ".partial.blend"
RECORD = "reactive_anim_bake"  # the scene property holding the record
PACKAGE_DIR = Path(__file__).resolve().parents[1]


def settings_digest(library: Path, model: Path) -> str:
    """The hash of everything but the .blend that decides a bake's result: computed once per run,
    after the library opened (the model may be missing: the bake then runs without one)."""
    import bpy
    import mujoco
    import numpy
    import onnxruntime

    from ..core.search.library import LibrarySettings, cache_key
    from ..core.search.manifest import read_chain_entries, read_manifest

    parts = {
        "library": cache_key(read_manifest(library), LibrarySettings(), {}, read_chain_entries(library)),
        "model": _file_digest(model) if model.is_file() else None,
        "code": _code_digest(),
        "versions": [bpy.app.version_string, mujoco.__version__, onnxruntime.__version__, numpy.__version__],
    }
    return hashlib.sha256(json.dumps(parts, sort_keys=True).encode()).hexdigest()


def inputs_hash(blend: Path, settings: str) -> str:
    """The hash an output of `blend` records: its bytes and the run's settings digest."""
    return hashlib.sha256(f"{_file_digest(blend)} {settings}".encode()).hexdigest()


def _file_digest(path: Path) -> str:
    digest = hashlib.sha256()
    with path.open("rb") as stream:
        while chunk := stream.read(1 << 20):
            digest.update(chunk)
    return digest.hexdigest()


def _code_digest() -> str:
    """The add-on's own Python source: a changed bake (a fix, an edit) makes earlier outputs stale,
    even where the version number did not change."""
    digest = hashlib.sha256()
    for path in sorted(PACKAGE_DIR.rglob("*.py")):
        digest.update(path.relative_to(PACKAGE_DIR).as_posix().encode() + b"\0" + path.read_bytes())
    return digest.hexdigest()


def complete_output(path: Path, out: Path, inputs: str) -> FileOutcome | None:
    """The outcome of `path` when `out` is a complete bake of these inputs (its record's hash is
    `inputs`): what it holds, read from the record; else None. Opens `out` in Blender."""
    import bpy

    if not out.is_file():
        return None
    try:
        bpy.ops.wm.open_mainfile(filepath=str(out), load_ui=False)
        record = json.loads(str(bpy.context.scene.get(RECORD, "{}")))
    except (RuntimeError, ValueError):  # not a .blend Blender reads, or a record that is not ours
        return None
    if not isinstance(record, dict) or record.get("inputs") != inputs:
        return None
    held = {k: record.get(k, default) for k, default in (("impacts", 0), ("classes", []), ("clips", []))}
    return FileOutcome(path, out, inputs, skipped=True, result=f"{out} is complete for these inputs: skipped", **held)


def write_record(outcome: FileOutcome) -> None:
    """Record in the open file (the scene it opens on) what it was baked from and what it holds."""
    import bpy

    fields = {"inputs": outcome.inputs, "impacts": outcome.impacts, "classes": outcome.classes, "clips": outcome.clips}
    bpy.context.scene[RECORD] = json.dumps(fields)


def save_whole(out: Path) -> None:
    """Save the open file as `out` through a partial file of this attempt's own and a rename."""
    import bpy

    out.parent.mkdir(parents=True, exist_ok=True)
    partial = out.with_name(f".{out.name}.{uuid.uuid4().hex[:16]}{PARTIAL}")
    try:
        bpy.ops.wm.save_as_mainfile(filepath=str(partial), check_existing=False, copy=True)
        _keep_previous(out, bpy.context.preferences.filepaths.save_version)
        os.replace(partial, out)
    finally:
        _remove_partial(partial)
    for leftover in out.parent.glob(f".{glob.escape(out.name)}.*{PARTIAL}*"):
        _remove_partial(leftover)


def _keep_previous(out: Path, versions: int) -> None:
    """Keep the file being replaced as `NAME1` (`.blend1`) when Blender's preferences keep saved
    versions, as a save straight over it would (with --overwrite it is the input). One version only."""
    if versions < 1 or not out.is_file():
        return
    backup = out.with_name(out.name + "1")
    backup.unlink(missing_ok=True)
    try:
        os.link(out, backup)  # the old bytes under a second name: instant, and `out` never missing
    except OSError:  # a file system without hard links
        shutil.copy2(out, backup)


def _remove_partial(partial: Path) -> None:
    """Remove a partial file and Blender's own temporary beside it (`...@`, the file being written)."""
    for path in (partial, partial.with_name(partial.name + "@")):
        path.unlink(missing_ok=True)
