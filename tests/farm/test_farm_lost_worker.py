"""A worker killed (SIGKILL) while it bakes: its Blender process dies with it, the scheduler gives
the file to another worker, and every output is complete and the same as a one-process bake. The
cluster is a `dask scheduler` and two `dask worker`s started from the command line, as on a farm
(`bake --scheduler`)."""

from __future__ import annotations

import os
import signal
import subprocess
import time
from pathlib import Path

from tests.farm.support import (
    ENVIRONMENT,
    REPO,
    bake_processes,
    command,
    dask_cluster,
    partial_files,
    process_gone,
    reacted_keys,
    report,
)


def _kill_a_worker_mid_bake(inputs: list[Path], baking_for: float) -> tuple[int, Path]:
    """SIGKILL the worker of the first bake process found running for at least `baking_for`
    seconds: (the bake process's pid, its file). A whole bake of one input (Blender's start, the
    file, two impacts, the save) ran past 1.5 s on the machine this test was written on and ended
    sooner on a faster one (2026-11-28), where waiting 1.5 s found none to interrupt."""
    first_seen: dict[int, float] = {}
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        for pid, (worker, file) in bake_processes(inputs).items():
            if time.monotonic() - first_seen.setdefault(pid, time.monotonic()) >= baking_for:
                os.kill(worker, signal.SIGKILL)
                return pid, file
        time.sleep(0.05)
    raise AssertionError("no bake process ran long enough to be interrupted")


def test_a_worker_killed_mid_bake_loses_nothing(inputs: list[Path], reference: dict, tmp_path: Path) -> None:
    out = tmp_path / "out"
    with dask_cluster(tmp_path, workers=2) as address:
        args = [*map(str, inputs), "--out-dir", str(out), "--scheduler", address, "--report", str(tmp_path / "r.jsonl")]
        run = subprocess.Popen(
            command(*args), cwd=REPO, env=ENVIRONMENT, text=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE
        )
        bake_pid, file = _kill_a_worker_mid_bake(inputs, baking_for=0.3)
        assert process_gone(bake_pid, within=5.0), "the killed worker's Blender process lived on"
        stdout, stderr = run.communicate(timeout=300)

    assert run.returncode == 0, stderr
    assert sorted(p.name for p in out.iterdir()) == sorted(reference)  # complete outputs, nothing partial
    for name, keys in reference.items():
        assert reacted_keys(out / name) == keys, name
    assert partial_files(tmp_path) == [] and partial_files(inputs[0].parent) == []
    rows = report(tmp_path / "r.jsonl")
    assert rows[file.name]["attempts"] == 2 and rows[file.name]["status"] == "baked"
    assert f"started {file.name} on " in stderr and "(attempt 2: its last worker was lost)" in stderr
    assert all(row["status"] == "baked" for row in rows.values()) and "6 of 6 files baked" in stdout
