"""What the farm tests share: the input scenes, the command run as a user runs it, a Dask scheduler
and workers started from the command line, and the keys a bake wrote. Imports bpy."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import bpy

from reactive_anim.blender.character import bvh_import
from reactive_anim.blender.impacts import impacts
from reactive_anim.farm.outputs import PARTIAL
from tests.support.actions import keyframes

REPO = Path(__file__).resolve().parents[2]
WALK = REPO / "sample_clips" / "walk.bvh"
INPUTS = 6
ENVIRONMENT = {**os.environ, "PYTHONPATH": str(REPO)}
BIN = Path(sys.executable).parent


def scene_file(path: Path, first_frame: int) -> Path:
    """A .blend with the sample walk and two impact markers (forced classes, so the bake is quick),
    the first at `first_frame`, saved to `path`."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    rig = bvh_import.import_bvh(bpy.context, WALK)
    impacts.add_impact(scene, rig, "chest", first_frame, (0.0, -1.0, 0.0), 120.0, "step_forward")
    impacts.add_impact(scene, rig, "chest", first_frame + 110, (0.0, 1.0, 0.0), 60.0, "sway_balance")
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    return path


def command(*args: str) -> list[str]:
    return [sys.executable, "-m", "reactive_anim", "bake", *args]


def bake_here(*args: str) -> subprocess.CompletedProcess:
    """`python -m reactive_anim bake ARGS` in a new process, as a user runs it."""
    return subprocess.run(command(*args), cwd=REPO, env=ENVIRONMENT, capture_output=True, text=True, timeout=300)


def reacted_keys(path: Path) -> dict[str, dict]:
    """Every key of every reacted action in a baked file, by action name."""
    bpy.ops.wm.open_mainfile(filepath=str(path))
    return {a.name: keyframes(a) for a in bpy.data.actions if a.name.endswith(".reacted")}


def report(path: Path) -> dict[str, dict]:
    """A --report file's rows, by input file name."""
    rows = [json.loads(line) for line in path.read_text().splitlines()]
    return {Path(row["file"]).name: row for row in rows}


def partial_files(folder: Path) -> list[str]:
    """Partial saves (and Blender's own temporaries) anywhere under `folder`."""
    return sorted(str(p) for p in folder.rglob(f"*{PARTIAL}*")) + sorted(str(p) for p in folder.rglob("*@"))


@contextmanager
def dask_cluster(folder: Path, workers: int) -> Iterator[str]:
    """`dask scheduler` on the loopback interface and `workers` x `dask worker --nworkers 1
    --nthreads 1`, as docs/command-line.md starts them on a farm; yields the scheduler's address."""
    address_file = folder / "scheduler.json"
    quiet = {"env": ENVIRONMENT, "cwd": folder, "stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL}
    scheduler = [BIN / "dask", "scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard"]
    started = [subprocess.Popen([*scheduler, "--scheduler-file", address_file], **quiet)]
    try:
        address = json.loads(_wait_for(address_file).read_text())["address"]
        worker = [BIN / "dask", "worker", address, "--nworkers", "1", "--nthreads", "1", "--no-dashboard"]
        started += [subprocess.Popen(worker, **quiet) for _ in range(workers)]
        yield address
    finally:
        for process in reversed(started):
            process.send_signal(signal.SIGTERM)
            process.wait(timeout=60)


def _wait_for(path: Path, timeout: float = 60.0) -> Path:
    deadline = time.monotonic() + timeout
    while not (path.is_file() and path.stat().st_size):
        assert time.monotonic() < deadline, f"{path} never appeared"
        time.sleep(0.1)
    return path


def bake_processes(inputs: list[Path]) -> dict[int, tuple[int, Path]]:
    """The running bake processes a farm task started for one of `inputs`: pid -> (its parent,
    the worker's pid; the file it bakes)."""
    found = {}
    for entry in Path("/proc").iterdir():
        try:
            argv = (entry / "cmdline").read_bytes().split(b"\0")
            parent = int((entry / "stat").read_text().rsplit(")", 1)[1].split()[1])
        except (OSError, ValueError, IndexError):
            continue  # not a process, or one that just ended
        words = [w.decode(errors="replace") for w in argv]
        files = [p for p in inputs if str(p) in words]
        if "reactive_anim" in words and "-" in words and files:  # `... bake FILE ... --report -`
            found[int(entry.name)] = (parent, files[0])
    return found


def process_gone(pid: int, within: float) -> bool:
    """Whether process `pid` ends within `within` seconds (a zombie nobody reaps counts as ended)."""
    deadline = time.monotonic() + within
    while time.monotonic() < deadline:
        try:
            if (Path("/proc") / str(pid) / "stat").read_text().rsplit(")", 1)[1].split()[0] == "Z":
                return True
        except OSError:
            return True
        time.sleep(0.05)
    return False
