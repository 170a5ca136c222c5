"""The batch on a Dask cluster: one task per .blend, progress on stderr, a row per file as it ends.

`--scheduler tcp://HOST:PORT` connects to a running scheduler (its workers started with `dask
worker`); `--workers N` starts a cluster of N worker processes on this machine for the run. A
worker runs one task at a time (one thread): a bake is a Blender process that keeps a core busy.

Retries: a worker that dies mid-task (killed, out of memory, its machine lost) is Dask's to
handle: the scheduler gives its tasks to other workers, up to `distributed.scheduler.allowed-
failures` times (3 by default) before it gives up on the task (KilledWorker). A file whose bake
fails (a broken file, a crash in Blender) fails its task's process, not the worker: the task
returns that file's failed row, which is reported and never retried, so a file that fails every
time costs one attempt and the others finish.

Dask is imported with this module, which only a farm run imports: the plain command, the
extension and the tests of the Blender layer run without it.
"""

from __future__ import annotations

import logging
import sys
import threading
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import cast

from distributed import Client, LocalCluster, as_completed

from . import task as task_module
from .report import FileOutcome, failure_row


def bake_all(jobs: dict[str, list[str]], blender: str, scheduler: str | None, workers: int | None) -> Iterator[dict]:
    """Bake each file of `jobs` (file -> its bake arguments) as a task of its own; yield each
    file's report row as it ends, with how many times a worker started it."""
    topic = f"reactive_anim-bake-{uuid.uuid4().hex}"  # this run's start events, not another client's
    tasks = [task_module.Task(blend, tuple(arguments), blender, topic) for blend, arguments in jobs.items()]
    with _connect(scheduler, workers) as client:
        progress = Progress(len(tasks), str(client.scheduler_info().get("address", scheduler)))
        client.subscribe_topic(topic, progress.started)
        futures = {
            client.submit(task_module.bake, t, key=f"bake-{Path(t.blend).name}-{uuid.uuid4().hex[:8]}", pure=False): t
            for t in tasks
        }
        for future in as_completed(futures):
            row = _row(future, futures[future].blend)
            row["attempts"] = max(progress.starts.get(row["file"], 0), 1)
            progress.finished(row)
            yield row


@contextmanager
def _connect(scheduler: str | None, workers: int | None) -> Iterator[Client]:
    """A client of the scheduler at `scheduler`, or of a cluster of `workers` local worker
    processes on the loopback interface, started for this run and stopped after it."""
    if scheduler:
        with Client(scheduler, timeout="30s") as client:
            yield client
        return
    with (
        LocalCluster(
            n_workers=workers,
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            dashboard_address=cast(str, None),  # annotated str, but None is what turns the dashboard off
            silence_logs=logging.ERROR,
        ) as cluster,
        Client(cluster) as client,
    ):
        yield client


def _row(future, blend: str) -> dict:
    """The task's row, or a failed one when the task raised: every worker it ran on died
    (KilledWorker), the scheduler was lost, or the task itself broke."""
    try:
        return future.result()
    except Exception as exc:
        return failure_row(blend, f"the farm could not bake it: {type(exc).__name__}: {exc}")


class Progress:
    """Files done, failed and running (which file on which worker), printed to stderr as tasks
    start (their workers' events, on the client's thread) and end (on the caller's)."""

    def __init__(self, total: int, scheduler: str) -> None:
        self.total, self.done, self.failed = total, 0, 0
        self.running: dict[str, str] = {}  # file -> worker
        self.starts: dict[str, int] = {}  # file -> times a worker started it
        self.lock = threading.Lock()
        print(f"farm: {total} files, scheduler {scheduler}", file=sys.stderr)

    def started(self, event: tuple[float, dict]) -> None:
        file, worker = event[1]["file"], event[1]["worker"]
        with self.lock:
            again = self.starts.get(file, 0)
            self.starts[file] = again + 1
            self.running[file] = worker
            note = f" (attempt {again + 1}: its last worker was lost)" if again else ""
            print(f"  started {Path(file).name} on {worker}{note}", file=sys.stderr)

    def finished(self, row: dict) -> None:
        outcome = FileOutcome.from_row(row)
        with self.lock:
            self.running.pop(row["file"], None)
            self.done += 1
            self.failed += outcome.failed
            status = ("FAILED: " if outcome.failed else "") + outcome.result
            print(
                f"[{self.done}/{self.total}] {outcome.path.name} on {outcome.worker or '-'}: {status}", file=sys.stderr
            )
            print(f"  {self.summary()}", file=sys.stderr)

    def summary(self) -> str:
        """`done, failed, running` and, per worker, the file it is baking."""
        per_worker = ", ".join(f"{worker}: {Path(file).name}" for file, worker in sorted(self.running.items()))
        return (
            f"{self.done - self.failed} done, {self.failed} failed, {len(self.running)} running"
            + (f" ({per_worker})" if per_worker else "")
            + f", {self.total - self.done - len(self.running)} waiting"
        )
