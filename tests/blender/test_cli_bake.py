"""`python -m reactive_anim bake`, run as a user would: a separate Python process over .blend files."""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
from pathlib import Path

import bpy

from reactive_anim.blender import bake, bvh_import, impacts

REPO = Path(__file__).resolve().parents[2]
WALK = REPO / "sample_clips" / "walk.bvh"
FORWARD = (0.0, -1.0, 0.0)  # the sample walk walks along -Y


def _run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "reactive_anim", *args],
        cwd=REPO,
        env=dict(os.environ),
        capture_output=True,
        text=True,
        timeout=300,
    )


def _scene_file(path: Path, bad_bone: bool = False) -> Path:
    """A .blend with the sample walk and two impact markers (forced classes); optionally one marker
    on a bone the armature lacks."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    rig = bvh_import.import_bvh(bpy.context, WALK)
    impacts.add_impact(scene, rig, "chest", 41, FORWARD, 120.0, "step_forward")
    late = impacts.add_impact(scene, rig, "chest", 151, (0.0, 1.0, 0.0), 60.0, "sway_balance")
    if bad_bone:
        impacts.impact_data(late).bone = "tail"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    return path


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_bake_command_bakes_the_good_files_and_reports_the_broken_ones(tmp_path):
    good = _scene_file(tmp_path / "good.blend")
    bad = _scene_file(tmp_path / "bad_marker.blend", bad_bone=True)
    corrupt = tmp_path / "corrupt.blend"
    corrupt.write_bytes(b"BLENDER-v402" + bytes(range(256)) * 8)
    inputs = {p: _digest(p) for p in (good, bad, corrupt)}
    out_dir = tmp_path / "out"

    done = _run("bake", str(bad), str(good), str(corrupt), "--out-dir", str(out_dir))

    assert done.returncode == 1, done.stderr
    assert {p: _digest(p) for p in inputs} == inputs  # inputs untouched
    assert sorted(p.name for p in out_dir.iterdir()) == ["good.reacted.blend"]
    # progress per file and impact on stderr, errors naming the marker and the file
    err = done.stderr
    assert "[1/3]" in err and "[3/3]" in err
    assert "impact 1/2: impact marker 'hit_01' at frame 41" in err
    assert "impact marker 'hit_02' at frame 151 is on bone 'tail', which armature 'walk' does not have" in err
    assert "cannot open corrupt.blend" in err
    # the summary table: file, impacts, classes chosen, time, result
    lines = done.stdout.splitlines()  # Blender's own messages ("Read blend: ...") come first
    table = lines[next(k for k, line in enumerate(lines) if line.startswith("file ")) :]
    assert table[0].split() == ["file", "impacts", "classes", "chosen", "time", "result"]
    rows = {line.split()[0]: line for line in table[1:4]}
    assert rows["good.blend"].split()[1:3] == ["2", "step_forward,"] and "sway_balance" in rows["good.blend"]
    assert "saved " in rows["good.blend"] and "FAILED" in rows["bad_marker.blend"] and "FAILED" in rows["corrupt.blend"]
    assert table[4] == "1 of 3 files baked, 2 failed"

    bpy.ops.wm.open_mainfile(filepath=str(out_dir / "good.reacted.blend"))
    rig = bpy.data.objects["walk"]
    assert rig.animation_data.action.name == "walk.reacted"
    assert bpy.data.actions["walk"].use_fake_user
    assert bake.bake_state(rig).summary.count("(override)") == 2
    assert bpy.ops.reactive_anim.clear_bake(armature_name="walk") == {"FINISHED"}  # the state survived saving
    assert rig.animation_data.action.name == "walk" and "walk.reacted" not in bpy.data.actions


def test_bake_command_writes_beside_the_input_and_never_over_it(tmp_path):
    good = _scene_file(tmp_path / "scene.blend")
    before = _digest(good)
    done = _run("bake", str(good))
    assert done.returncode == 0, done.stderr
    assert _digest(good) == before and (tmp_path / "scene.reacted.blend").is_file()
    assert done.stdout.rstrip().endswith("1 of 1 files baked")
    # an input that is another input's output is refused without --overwrite, the other still baked
    done = _run("bake", str(good), str(tmp_path / "scene.reacted.blend"))
    assert done.returncode == 1
    assert "the output would overwrite the input scene.reacted.blend (use --overwrite)" in done.stderr


def test_bake_command_overwrites_the_input_only_when_asked(tmp_path):
    scene_file = _scene_file(tmp_path / "scene.blend")
    done = _run("bake", str(scene_file), "--overwrite")
    assert done.returncode == 0, done.stderr
    assert sorted(p.name for p in tmp_path.glob("*.blend")) == ["scene.blend"]
    bpy.ops.wm.open_mainfile(filepath=str(scene_file))
    assert bpy.data.objects["walk"].animation_data.action.name == "walk.reacted"
    assert bpy.data.actions["walk"].use_fake_user
