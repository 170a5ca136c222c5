"""`python -m reactive_anim bake`, run as a user would: a separate Python process over .blend files."""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
from pathlib import Path

import bpy
import numpy as np

from reactive_anim import cli
from reactive_anim.blender.bake import bake
from reactive_anim.blender.character import action_io, bvh_import
from reactive_anim.blender.impacts import impacts
from tests.support.actions import action_of
from tools.devkit.operators import addon_ops

REPO = Path(__file__).resolve().parents[2]
WALK = REPO / "sample_clips" / "walk.bvh"
FORWARD = (0.0, -1.0, 0.0)  # the sample walk walks along -Y


def _run(*args: str, cwd: Path = REPO, **env: str) -> subprocess.CompletedProcess:
    """The CLI in a new process, in `cwd`, with `env` added to this process's environment."""
    return subprocess.run(
        [sys.executable, "-m", "reactive_anim", *args],
        cwd=cwd,
        env={**os.environ, "PYTHONPATH": str(REPO), **env},
        capture_output=True,
        text=True,
        timeout=300,
    )


def _listing(folder: Path) -> list[str]:
    """Every file and folder under `folder`, relative: what a run wrote shows as the difference."""
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*"))


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
    assert action_of(rig).name == "walk.reacted"
    assert bpy.data.actions["walk"].use_fake_user
    assert bake.bake_state(rig).summary.count("(override)") == 2
    assert addon_ops.clear_bake(armature_name="walk") == {"FINISHED"}  # the state survived saving
    assert action_of(rig).name == "walk" and "walk.reacted" not in bpy.data.actions


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
    assert action_of(bpy.data.objects["walk"]).name == "walk.reacted"
    assert bpy.data.actions["walk"].use_fake_user


def _second_scene(name: str, fps: int) -> bpy.types.Scene:
    """A new scene, made the context's, at its own frame rate."""
    scene = bpy.data.scenes.new(name)
    bpy.context.window.scene = scene
    scene.render.fps, scene.render.fps_base = fps, 1.0
    return scene


def _one_walk(path: Path, fps: int) -> Path:
    """A .blend whose only scene runs at `fps` and holds the walk with one impact at frame 151."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    rig = bvh_import.import_bvh(bpy.context, WALK, set_scene_fps=False)
    bpy.context.scene.render.fps, bpy.context.scene.render.fps_base = fps, 1.0
    impacts.add_impact(bpy.context.scene, rig, "chest", 151, (0.0, 1.0, 0.0), 60.0, "sway_balance")
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    return path


def _reacted_positions(path: Path, scene: str, rig: str) -> np.ndarray:
    """The reacted motion of `rig` in a baked file, read with its scene active."""
    bpy.ops.wm.open_mainfile(filepath=str(path))
    bpy.context.window.scene = bpy.data.scenes[scene]
    armature = bpy.data.objects[rig]
    assert action_of(armature).name.endswith(".reacted")
    return action_io.read_motion(armature).global_positions()


def test_bake_command_bakes_every_scene_with_impact_markers(tmp_path):
    """A second scene at another frame rate is baked as if the animator baked it there: its result
    equals the same scene baked alone in its own file."""
    shots = _scene_file(tmp_path / "shots.blend")  # scene 'Scene': 'walk', two impacts
    scene = _second_scene("Shot2", fps=30)
    rig = bvh_import.import_bvh(bpy.context, WALK, set_scene_fps=False)  # 'walk.001', only in Shot2
    impacts.add_impact(scene, rig, "chest", 151, (0.0, 1.0, 0.0), 60.0, "sway_balance")
    bpy.context.window.scene = bpy.data.scenes["Scene"]
    bpy.ops.wm.save_as_mainfile(filepath=str(shots))
    alone = _one_walk(tmp_path / "alone.blend", fps=30)
    before = _listing(tmp_path)

    done = _run("bake", str(shots), str(alone), "--out-dir", str(tmp_path / "out"))

    assert done.returncode == 0, done.stderr
    assert "scene 'Scene', armature 'walk'" in done.stderr and "scene 'Shot2', armature 'walk.001'" in done.stderr
    rows = {line.split()[0]: line.split() for line in done.stdout.splitlines() if line.endswith(".reacted.blend")}
    assert rows["shots.blend"][1] == "3"  # two impacts in Scene, one in Shot2
    assert _listing(tmp_path) == sorted([*before, "out", "out/alone.reacted.blend", "out/shots.reacted.blend"])
    bpy.ops.wm.open_mainfile(filepath=str(tmp_path / "out" / "shots.reacted.blend"))
    assert bpy.context.scene.name == "Scene"  # the file still opens on its own scene
    assert action_of(bpy.data.objects["walk"]).name == "walk.reacted"
    baked = _reacted_positions(tmp_path / "out" / "shots.reacted.blend", "Shot2", "walk.001")
    expected = _reacted_positions(tmp_path / "out" / "alone.reacted.blend", "Scene", "walk")
    assert baked.shape == expected.shape and np.allclose(baked, expected, atol=1e-5)


def test_bake_command_fails_a_file_whose_markers_name_a_missing_armature(tmp_path):
    """Markers left naming a deleted character (a renamed one takes its markers along), and one
    character with markers in two scenes, fail the file before anything in it is baked: nothing is
    written."""
    orphans = _scene_file(tmp_path / "orphans.blend")
    hero = bvh_import.import_bvh(bpy.context, WALK, name="hero")
    impacts.add_impact(bpy.context.scene, hero, "chest", 41, FORWARD, 120.0, "step_forward")  # hero's own: hit_03
    bpy.data.objects.remove(bpy.data.objects["walk"])  # hit_01 and hit_02 still name 'walk'
    bpy.ops.wm.save_as_mainfile(filepath=str(orphans))
    shared = _scene_file(tmp_path / "shared.blend")
    scene = _second_scene("Shot2", fps=60)
    scene.collection.objects.link(bpy.data.objects["walk"])
    impacts.add_impact(scene, bpy.data.objects["walk"], "chest", 41, FORWARD, 120.0, "step_forward")
    bpy.ops.wm.save_as_mainfile(filepath=str(shared))
    before = _listing(tmp_path)

    done = _run("bake", str(orphans), str(shared), "--out-dir", str(tmp_path / "out"))

    assert done.returncode == 1, done.stderr
    assert (
        "impact markers 'hit_01', 'hit_02' in scene 'Scene' name armature 'walk', "
        "which the file does not have (renamed or deleted?)" in done.stderr
    )
    assert "armature 'walk' has impact markers in scenes 'Scene' and 'Shot2'" in done.stderr
    assert "armature 'hero'" not in done.stderr and "impact 1/" not in done.stderr  # nothing baked
    assert done.stdout.rstrip().endswith("0 of 2 files baked, 2 failed")
    assert _listing(tmp_path) == before


def test_bake_command_refuses_outputs_that_collide_before_baking_anything(tmp_path):
    """Two inputs of the same name from different folders would write one --out-dir file: both are
    refused up front (neither silently replaces the other); the other inputs still bake."""
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    first, second = _scene_file(tmp_path / "a" / "shot.blend"), _scene_file(tmp_path / "b" / "shot.blend")
    other = _scene_file(tmp_path / "other.blend")
    out = tmp_path / "out"
    before = _listing(tmp_path)

    done = _run("bake", str(first), str(second), str(other), "--out-dir", str(out))

    assert done.returncode == 1, done.stderr
    message = f"{out / 'shot.reacted.blend'} would be written by 2 inputs ({first}, {second}): none is baked"
    err = done.stderr.splitlines()
    said = [k for k, line in enumerate(err) if line == f"error: {message}"]
    assert len(said) == 2 and said[-1] < next(k for k, line in enumerate(err) if line.startswith("library:"))
    assert done.stdout.count(f"FAILED: {message}") == 2 and "1 of 3 files baked, 2 failed" in done.stdout
    assert _listing(tmp_path) == sorted([*before, "out", "out/other.reacted.blend"])


def test_bake_command_says_a_folder_is_a_folder(tmp_path):
    folder = tmp_path / "shots"
    folder.mkdir()
    _scene_file(folder / "shot.blend")
    before = _listing(tmp_path)
    done = _run("bake", str(folder))
    assert done.returncode == 1
    assert f"error: {folder} is a folder; give .blend files" in done.stderr
    assert "not found" not in done.stderr + done.stdout
    assert _listing(tmp_path) == before


def test_bake_command_on_a_read_only_user_folder_caches_in_the_temporary_folder(tmp_path):
    """A farm node whose home cannot be written (as root nothing is read-only, so the user folder
    lies under a regular file: it cannot be made): one warning, the cache in this user's temporary
    folder, never in the current folder, no traceback."""
    scene_file = _scene_file(tmp_path / "scene.blend")
    (tmp_path / "not_a_folder").write_text("")
    (tmp_path / "cwd").mkdir()
    (tmp_path / "temp").mkdir()
    before = _listing(tmp_path)

    done = _run(
        "bake", str(scene_file), "--out-dir", str(tmp_path / "out"), cwd=tmp_path / "cwd",
        BLENDER_USER_RESOURCES=str(tmp_path / "not_a_folder" / "blender"), TMPDIR=str(tmp_path / "temp"),
    )  # fmt: skip

    assert done.returncode == 0, done.stderr
    assert "Traceback" not in done.stderr
    warnings = [line for line in done.stderr.splitlines() if "warning" in line]
    cache = tmp_path / "temp" / f"reactive_anim_library_cache-{os.getuid()}"
    assert warnings == [
        f"reactive_anim: warning: cannot write the library cache in {tmp_path / 'not_a_folder' / 'blender'}"
        f"/datafiles/reactive_anim/library_cache (Not a directory); caching it in {cache}"
    ]
    assert not list((tmp_path / "cwd").iterdir())
    written = sorted(set(_listing(tmp_path)) - set(before))
    assert [p for p in written if not p.startswith(("out", "temp"))] == []  # onnxruntime leaves temp/.ses
    assert "out/scene.reacted.blend" in written and f"temp/{cache.name}/file-hashes.json" in written


def test_a_scene_is_made_active_with_or_without_a_window():
    """The bake reads the context's scene: with a window (the bpy module) the window shows the
    scene and is put back; without one (`blender -b`), a context override stands in."""
    first = bpy.context.scene
    second = bpy.data.scenes.new("Shot2")
    second.render.fps = 30
    with cli._scene_active(second):
        assert bpy.context.scene == second and bpy.context.scene.render.fps == 30
    assert bpy.context.scene == first and bpy.context.window.scene == first
    with bpy.context.temp_override(window=None):
        with cli._scene_active(second):
            assert bpy.context.window is None and bpy.context.scene == second
            assert bpy.context.view_layer == second.view_layers[0]
        assert bpy.context.scene == first
