"""One file's bake as a Dask worker runs it: the one-file command in a Blender process of its own.

A process per file, not the worker's own interpreter: a crash in Blender or the simulator (a
segfault, an abort) ends that process and fails that file, and the worker goes on with the next.
The process is `python -m reactive_anim bake FILE ...` with the worker's Python (the bpy module),
or `blender -b` running the same command when the client runs inside Blender; it prints its
file's report line (`--report -`), which the task hands back to the client. No file of the task's
own: a worker killed mid-task leaves nothing behind on its machine.

A killed worker's process must not outlive it: the scheduler gives the file to another worker, and
a forgotten bake saving later could replace the new output with one of older inputs. On Linux the
process asks the kernel to kill it when its parent dies (prctl PR_SET_PDEATHSIG; the parent is the
worker thread that started it, which waits for it). Elsewhere there is no such call; each attempt
still saves through a partial file of its own (outputs.py), so an output is never half-written.

Nothing here imports bpy: the worker never loads Blender itself.
"""

from __future__ import annotations

import ctypes
import os
import signal
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from .report import failure_row, read_row

PARENT_VARIABLE = "REACTIVE_ANIM_PARENT_PID"  # set for the bake process: the pid it must not outlive
PR_SET_PDEATHSIG = 1  # from <linux/prctl.h>
PACKAGE_ROOT = Path(__file__).resolve().parents[2]  # the folder that holds the reactive_anim package


@dataclass(frozen=True)
class Task:
    """One file to bake: the bake arguments after the file name (output, library, model, ...), the
    Blender binary to run (empty: the worker's Python with the bpy module) and the topic on which
    the task announces that it started."""

    blend: str
    arguments: tuple[str, ...]
    blender: str
    topic: str


def bake(task: Task) -> dict:
    """Run on a Dask worker: bake `task.blend` in a process of its own; its report line, with the
    worker and the task's whole time (Blender's start included)."""
    from distributed import get_worker

    worker = get_worker()
    worker.log_event(task.topic, {"file": task.blend, "worker": worker.address})
    start = time.perf_counter()
    done = subprocess.run(
        command(task), env=_child_environment(), capture_output=True, text=True, stdin=subprocess.DEVNULL
    )
    row = read_row(done.stdout) or failure_row(task.blend, _why_it_ended(done))
    row.update(file=task.blend, worker=worker.address, seconds=round(time.perf_counter() - start, 3))
    return row


def command(task: Task) -> list[str]:
    """The one-file bake command, the one any farm manager runs per task."""
    arguments = ["bake", task.blend, *task.arguments, "--report", "-"]
    if not task.blender:
        return [sys.executable, "-m", "reactive_anim", *arguments]
    script = (
        f"import sys; sys.path.insert(0, {str(PACKAGE_ROOT)!r}); from reactive_anim.cli import main; "
        f"sys.exit(main({arguments!r}))"
    )
    return [task.blender, "-b", "--factory-startup", "--python-exit-code", "1", "--python-expr", script]


def _child_environment() -> dict[str, str]:
    """This environment, the package importable wherever the worker found it, and this process's
    id: the bake process dies with it (die_with_parent)."""
    path = os.pathsep.join(p for p in (str(PACKAGE_ROOT), os.environ.get("PYTHONPATH", "")) if p)
    return {**os.environ, "PYTHONPATH": path, PARENT_VARIABLE: str(os.getpid())}


def _why_it_ended(done: subprocess.CompletedProcess) -> str:
    """Why a bake process ended without a report line: the signal that killed it, or its exit code
    and the last thing it said (an `error:` line when there is one)."""
    if done.returncode < 0:
        return f"the bake process was killed by {signal.Signals(-done.returncode).name}"
    said = [line.strip() for line in done.stderr.splitlines() if line.strip()]
    errors = [line for line in said if line.startswith("error:")]
    last = (errors or said or ["(nothing on stderr)"])[-1]
    return f"the bake process exited with code {done.returncode}: {last}"


def die_with_parent() -> None:
    """In a bake process a farm task started (PARENT_VARIABLE set): have the kernel kill this
    process when its parent dies (Linux), and leave at once if the parent is already gone."""
    parent = os.environ.pop(PARENT_VARIABLE, "")
    if not parent or not sys.platform.startswith("linux"):
        return
    libc = ctypes.CDLL(None, use_errno=True)
    if libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0) != 0:
        raise OSError(ctypes.get_errno(), "prctl(PR_SET_PDEATHSIG) failed")
    if os.getppid() != int(parent):  # it died before the call above: no signal will come
        sys.exit(f"reactive_anim: the worker that started this bake (pid {parent}) is gone")
