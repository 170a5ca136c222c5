"""The headless command line, run as a user would run it: a separate Python process."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import bpy
import numpy as np

from reactive_anim.blender.character import action_io
from reactive_anim.core.model import bvh

REPO = Path(__file__).resolve().parents[2]
WALK = REPO / "sample_clips" / "walk.bvh"


def _run(*args: str) -> subprocess.CompletedProcess:
    env = dict(os.environ)
    return subprocess.run(
        [sys.executable, "-m", "reactive_anim", *args], cwd=REPO, env=env, capture_output=True, text=True, timeout=300
    )


def test_import_command_saves_a_blend_with_the_character(tmp_path):
    out = tmp_path / "demo.blend"
    done = _run("import", str(WALK), "--out", str(out))
    assert done.returncode == 0, done.stderr
    assert "armature 'walk' (22 bones)" in done.stdout
    bpy.ops.wm.open_mainfile(filepath=str(out))
    rig = bpy.data.objects["walk"]
    scene = bpy.context.scene
    assert (scene.frame_start, scene.frame_end) == (1, 264)
    motion = action_io.read_motion(rig)
    expected = bvh.read_bvh(WALK)
    assert np.abs(motion.global_positions() - expected.global_positions()).max() < 1e-3


def test_import_command_reports_a_malformed_file_and_writes_nothing(tmp_path):
    out = tmp_path / "never.blend"
    bad = REPO / "tests" / "data" / "malformed" / "wrong_value_count.bvh"
    done = _run("import", str(bad), "--out", str(out))
    assert done.returncode == 2
    assert "wrong_value_count.bvh, line" in done.stderr
    assert not out.exists()
