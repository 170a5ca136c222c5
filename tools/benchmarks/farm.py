"""Farm: `python -m reactive_anim bake` over 20 files of 20 impacts each (the sample walk repeated
to 1,900 frames, pushes every 90 frames from around the character), as a user runs it: one process
baking the files one after another, then a local Dask cluster of 1 and of 2 workers (`--workers`),
each file in a Blender process of its own. Figures: files per minute each way; the cost of the
cluster per task against the plain loop (a Blender process started per file, the task's round
trip), from the per-file times of the --report files and from the wall times; and what a farm of
100 machines like this one would bake per minute by that measure (the scheduler's own cost, a few
milliseconds per task, is left out). Needs bpy and Dask's `distributed` (the farm environment,
tools/requirements/farm.txt); skipped with a note without them. Each run bakes everything anew
(--force), once: a run is minutes long, and the machine's other work shows in the figures.
"""

from __future__ import annotations

import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from importlib.util import find_spec
from pathlib import Path

from tools.devkit.mocap import REPO

from .common import report

GROUP = "farm"
FILES = 20
IMPACTS = 20
SPACING = 90  # frames between pushes: 1.5 s at the walk's 60 fps, each reaction under way as the next lands
FARM_MACHINES = 100


def bench_farm() -> None:
    """Files per minute here and with 1 and 2 workers; the cluster's cost per task; 100 machines."""
    if find_spec("bpy") is None or find_spec("distributed") is None:
        print(f"# {GROUP}: skipped, needs bpy and distributed (tools/setup_env.sh farm)")
        return
    with tempfile.TemporaryDirectory(prefix="reactive_anim_bench_farm_") as name:
        folder = Path(name)
        env = {**os.environ, "PYTHONPATH": str(REPO), "BLENDER_USER_RESOURCES": str(folder / "user")}
        files = _input_files(folder, env)
        plain = _bake(files, folder / "plain", env)
        one = _bake(files, folder / "w1", env, "--workers", "1")
        two = _bake(files, folder / "w2", env, "--workers", "2")
    context = {"files": FILES, "impacts": IMPACTS, "cores": os.cpu_count()}
    for label, (wall, _times) in (("one process", plain), ("1 worker", one), ("2 workers", two)):
        report(GROUP, f"files per minute, {label}", 60.0 * FILES / wall, "files/min", wall_s=round(wall, 1), **context)
    per_task = statistics.median(one[1]) - statistics.median(plain[1])
    report(GROUP, "cluster cost per task (median task - median file)", per_task, "s", **context)
    report(GROUP, "cluster cost per task (wall, 1 worker - one process)", (one[0] - plain[0]) / FILES, "s", **context)
    report(GROUP, "  as a share of a task", per_task / statistics.median(one[1]), "", **context)
    report(GROUP, f"files per minute, {FARM_MACHINES} machines x 2 workers", FARM_MACHINES * 60.0 * FILES / two[0],
           "files/min", **context)  # fmt: skip


def _input_files(folder: Path, env: dict[str, str]) -> list[Path]:
    """FILES copies of one scene: the sample walk repeated, IMPACTS pushes, saved by a Blender
    process of its own (the benchmark's process never loads Blender), which also compiles the
    library into the cache the runs share, so that no run pays for it."""
    scene = folder / "scene.blend"
    script = f"from tools.benchmarks import farm; farm.make_scene({str(scene)!r})"
    subprocess.run([sys.executable, "-c", script], check=True, capture_output=True, cwd=REPO, env=env)
    files = [folder / f"shot_{k:02d}.blend" for k in range(FILES)]
    for path in files:
        shutil.copy(scene, path)
    return files


def make_scene(path: str) -> None:
    """Save the benchmark's scene to `path` and compile the library (run in a Python with bpy)."""
    import bpy

    import reactive_anim
    from reactive_anim.blender.bake import resources
    from reactive_anim.blender.character import action_io, bvh_import
    from reactive_anim.blender.impacts import impacts

    from .react import push_impacts, repeated_walk

    reactive_anim.register()
    try:
        bpy.ops.wm.read_factory_settings(use_empty=True)
        rig = bvh_import.import_bvh(bpy.context, REPO / "sample_clips" / "walk.bvh")
        walk = repeated_walk(action_io.read_motion(rig), SPACING * (IMPACTS + 1) + 10)
        rig.animation_data.action = action_io.write_motion(rig, walk, "long walk")
        scene = bpy.context.scene
        first = int(rig.animation_data.action.frame_range[0])
        scene.frame_start, scene.frame_end = first, first + walk.num_frames - 1
        for impact in push_impacts(walk, [SPACING * (k + 1) for k in range(IMPACTS)]):
            impacts.add_impact(scene, rig, impact.bone, first + int(impact.frame), impact.direction, impact.strength)
        bpy.ops.wm.save_as_mainfile(filepath=path)
        resources.open_library()
    finally:
        reactive_anim.unregister()


def _bake(files: list[Path], out: Path, env: dict[str, str], *farm: str) -> tuple[float, list[float]]:
    """One run of the command: its wall time, and each file's time from its report (a farm task's
    includes its Blender process's start)."""
    rows = out.with_suffix(".jsonl")
    args = [*map(str, files), "--out-dir", str(out), "--force", "--report", str(rows), *farm]
    start = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "reactive_anim", "bake", *args], capture_output=True, text=True,
                          cwd=REPO, env=env)  # fmt: skip
    wall = time.perf_counter() - start
    if done.returncode != 0:
        raise RuntimeError(f"bake {' '.join(farm) or 'here'} failed:\n{done.stderr[-2000:]}")
    lines = [json.loads(line) for line in rows.read_text().splitlines()]
    return wall, [row["seconds"] for row in lines]
