"""What every bake writes, with or without a farm: outputs saved whole (a partial file renamed into
place, relative paths right), the hash of their inputs inside them (a rerun skips exactly the
complete ones), the report; the bake process that never outlives its worker; Dask optional."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import time
from pathlib import Path

import bpy

from reactive_anim.farm import outputs, task
from reactive_anim.farm.report import read_row
from tests.farm.support import (
    ENVIRONMENT,
    REPO,
    bake_here,
    partial_files,
    process_gone,
    reacted_keys,
    report,
    scene_file,
)


def test_an_output_is_saved_whole_with_its_relative_paths_right(tmp_path: Path) -> None:
    """Saved as a partial file beside the output and renamed: a texture given relative to the input
    still resolves from the output's folder; the partial files a killed attempt left are removed."""
    (tmp_path / "shots" / "tex").mkdir(parents=True)
    source = scene_file(tmp_path / "shots" / "shot.blend", first_frame=41)
    image = bpy.data.images.new("skin", 4, 4)
    image.filepath_raw = str(tmp_path / "shots" / "tex" / "skin.png")
    image.file_format = "PNG"
    image.save()
    image.use_fake_user = True
    bpy.ops.file.make_paths_relative()
    bpy.ops.wm.save_mainfile()
    out = tmp_path / "out"
    out.mkdir()
    leftovers = [
        out / f".shot.reacted.blend.0123abcd{outputs.PARTIAL}",
        out / f".shot.reacted.blend.4567{outputs.PARTIAL}@",
    ]
    for leftover in leftovers:
        leftover.write_bytes(b"half a file")

    done = bake_here(str(source), "--out-dir", str(out))

    assert done.returncode == 0, done.stderr
    assert sorted(p.name for p in out.iterdir()) == ["shot.reacted.blend"]
    bpy.ops.wm.open_mainfile(filepath=str(out / "shot.reacted.blend"))
    skin = bpy.data.images["skin"]
    assert skin.filepath == "//../shots/tex/skin.png"
    assert Path(bpy.path.abspath(skin.filepath)).resolve() == tmp_path / "shots" / "tex" / "skin.png"
    record = json.loads(bpy.context.scene[outputs.RECORD])
    assert record["impacts"] == 2 and len(record["inputs"]) == 64


def test_a_rerun_skips_only_outputs_complete_for_the_same_inputs(tmp_path: Path) -> None:
    """Skipped: an output recording its inputs' hash. Baked again: an edited input, an output
    recording other inputs (another file's copied over it), and anything under --force."""
    kept, edited, replaced = (tmp_path / f"{name}.blend" for name in ("kept", "edited", "replaced"))
    for k, path in enumerate((kept, edited, replaced)):
        scene_file(path, first_frame=41 + 10 * k)
    files = [str(kept), str(edited), str(replaced)]
    out = tmp_path / "out"
    assert bake_here(*files, "--out-dir", str(out)).returncode == 0
    stamps = {p.name: p.stat().st_mtime_ns for p in out.iterdir()}
    scene_file(edited, first_frame=70)
    shutil.copy(out / "kept.reacted.blend", out / "replaced.reacted.blend")
    replaced_stamp = (out / "replaced.reacted.blend").stat().st_mtime_ns

    done = bake_here(*files, "--out-dir", str(out), "--report", str(tmp_path / "r.jsonl"))

    assert done.returncode == 0, done.stderr
    rows = report(tmp_path / "r.jsonl")
    assert {name: row["status"] for name, row in rows.items()} == {
        "kept.blend": "skipped", "edited.blend": "baked", "replaced.blend": "baked"
    }  # fmt: skip
    assert (out / "kept.reacted.blend").stat().st_mtime_ns == stamps["kept.reacted.blend"]
    assert (out / "replaced.reacted.blend").stat().st_mtime_ns != replaced_stamp
    assert reacted_keys(out / "replaced.reacted.blend") != reacted_keys(out / "kept.reacted.blend")
    forced = bake_here(str(kept), "--out-dir", str(out), "--force", "--report", "-")
    assert (read_row(forced.stdout) or {}).get("status") == "baked"
    assert (out / "kept.reacted.blend").stat().st_mtime_ns != stamps["kept.reacted.blend"]
    assert partial_files(tmp_path) == []


def test_the_report_has_a_line_per_file(tmp_path: Path) -> None:
    good = scene_file(tmp_path / "good.blend", first_frame=41)
    done = bake_here(str(good), str(tmp_path / "missing.blend"), "--report", str(tmp_path / "r.jsonl"))
    assert done.returncode == 1
    rows = report(tmp_path / "r.jsonl")
    assert set(rows["good.blend"]) == {"file", "output", "status", "inputs", "worker", "attempts", "seconds",
                                       "impacts", "classes", "clips", "result", "error"}  # fmt: skip
    assert rows["good.blend"]["output"] == str(tmp_path / "good.reacted.blend")
    assert rows["good.blend"]["classes"] == ["step_forward", "sway_balance"] and rows["good.blend"]["error"] is None
    assert rows["good.blend"]["clips"][0].startswith("step_forward_") and rows["good.blend"]["seconds"] > 0
    assert rows["missing.blend"]["status"] == "failed" and rows["missing.blend"]["error"].startswith("file not found")


def test_without_dask_the_farm_options_say_what_is_missing(tmp_path: Path) -> None:
    """Dask made unimportable in this Python: the farm options fail in one line naming it, before
    anything is baked; the plain command never imports it."""
    good = scene_file(tmp_path / "good.blend", first_frame=41)
    block = (
        "import sys; sys.modules['distributed'] = None; from reactive_anim import cli; sys.exit(cli.main(sys.argv[1:]))"
    )
    run = [sys.executable, "-c", block, "bake", str(good)]
    farm = subprocess.run([*run, "--workers", "2"], cwd=REPO, env=ENVIRONMENT, capture_output=True, text=True)
    assert farm.returncode == 2 and "Traceback" not in farm.stderr
    assert "--scheduler and --workers need Dask's `distributed` package" in farm.stderr
    assert not (tmp_path / "good.reacted.blend").exists()
    plain = subprocess.run(run, cwd=REPO, env=ENVIRONMENT, capture_output=True, text=True)
    assert plain.returncode == 0, plain.stderr
    assert (tmp_path / "good.reacted.blend").is_file()


def test_the_extension_zip_cannot_bundle_dask() -> None:
    """build_extension.py bundles the wheels pinned by the bpy-<line> files only, and no such file
    pins Dask; the farm environment is not a Blender line."""
    from tools import build_extension as build

    assert "farm" not in build.blender_lines()
    for line in build.python_lines():
        assert line.pins_file.name.startswith("bpy-")
        assert not {"dask", "distributed"} & set(build.read_pins(line.pins_file)), line.pins_file


def test_a_bake_process_dies_with_the_process_that_started_it(tmp_path: Path) -> None:
    """PR_SET_PDEATHSIG: the parent killed, the child is killed too; a child whose parent is
    already gone leaves at once."""
    starter = (
        "import os, subprocess, sys, time; "
        f"env = dict(os.environ, {task.PARENT_VARIABLE}=str(os.getpid())); "
        "code = 'from reactive_anim.farm import task; task.die_with_parent(); import time; time.sleep(60)'; "
        "child = subprocess.Popen([sys.executable, '-c', code], env=env); print(child.pid, flush=True); time.sleep(60)"
    )
    parent = subprocess.Popen([sys.executable, "-c", starter], env=ENVIRONMENT, stdout=subprocess.PIPE, text=True)
    assert parent.stdout is not None
    child = int(parent.stdout.readline())
    time.sleep(1.0)  # the child has called prctl by now
    assert Path(f"/proc/{child}").exists()
    parent.kill()
    parent.wait()
    assert process_gone(child, within=5.0)

    orphan = subprocess.run(
        [sys.executable, "-c", "from reactive_anim.farm import task; task.die_with_parent(); print('went on')"],
        env={**ENVIRONMENT, task.PARENT_VARIABLE: "1"}, capture_output=True, text=True, timeout=30,
    )  # fmt: skip
    assert orphan.returncode == 1 and "went on" not in orphan.stdout
    assert "the worker that started this bake (pid 1) is gone" in orphan.stderr
