"""A bake computed in a worker thread, so Blender's UI stays live (issue: "a bake that never freezes").

The main thread prepares a BakeJob (bake.prepare_bake reads the .blend), starts a BackgroundBake,
and polls it from a window-manager timer (the modal operators in bake_ops.py); the thread runs
only `BakeJob.run`, numpy in and numpy out, and talks back through a queue. Writing the result
happens on the main thread after the last poll, inside the operator, so it is one undo step.
One bake runs at a time (`running()`): the opened library is shared between bakes.
"""

from __future__ import annotations

import queue
import threading
import time
from dataclasses import dataclass

from ..core.errors import Cancelled
from ..core.react import Baked
from .bake import BakeJob


@dataclass(frozen=True)
class Progress:
    """Where a running bake is: before impact `done + 1` of `total`, on the marker `what` names."""

    done: int
    total: int
    what: str

    def text(self, armature: str) -> str:
        if self.done >= self.total:
            return f"Reactions on '{armature}': writing the result"
        return f"Reactions on '{armature}': impact {self.done + 1} of {self.total} ({self.what}) - Esc to cancel"

    @property
    def fraction(self) -> float:
        return self.done / max(self.total, 1)


class BackgroundBake:
    """One BakeJob in a daemon thread. poll() on the main thread returns True once it has ended;
    then exactly one of `baked` and `error` is set (error is Cancelled after cancel())."""

    def __init__(self, job: BakeJob) -> None:
        self.job = job
        self.progress = Progress(0, len(job.impacts), "starting")
        self.baked: Baked | None = None
        self.error: BaseException | None = None
        self.seconds = 0.0
        self._messages: queue.SimpleQueue[tuple[str, object]] = queue.SimpleQueue()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=f"reactive_anim bake {job.armature}", daemon=True)
        self._start = 0.0
        self._ended = False

    def start(self) -> BackgroundBake:
        global _RUNNING
        if _RUNNING is not None:
            raise RuntimeError(f"a bake is already running on '{_RUNNING.job.armature}'")
        _RUNNING = self
        self._start = time.perf_counter()
        self._thread.start()
        return self

    def _run(self) -> None:
        """The worker thread: no bpy here, ever."""
        try:
            baked = self.job.run(
                progress=lambda k, n, what: self._messages.put(("progress", Progress(k, n, what))),
                cancel=self._stop.is_set,
            )
            self._messages.put(("done", baked))
        except BaseException as exc:  # handed to the main thread, which reports it
            self._messages.put(("error", exc))

    def poll(self) -> bool:
        """Take in what the thread has said; True once it has finished (or failed, or was cancelled)."""
        while not self._ended:
            try:
                kind, value = self._messages.get_nowait()
            except queue.Empty:
                break
            if kind == "progress" and isinstance(value, Progress):
                self.progress = value
            elif kind == "done" and isinstance(value, Baked):
                self.baked = value
                self._finish()
            elif isinstance(value, BaseException):
                self.error = value
                self._finish()
        return self._ended

    def cancel(self, timeout: float = 10.0) -> None:
        """Ask the thread to stop before its next impact and wait for it; nothing is written."""
        self._stop.set()
        self._thread.join(timeout)
        self.poll()
        if not self._ended:  # a stuck thread: forget it rather than block Blender
            self._finish()
        if self.baked is not None or self.error is None:
            self.baked, self.error = None, Cancelled("bake cancelled")

    def _finish(self) -> None:
        global _RUNNING
        self._ended = True
        self.seconds = time.perf_counter() - self._start
        if _RUNNING is self:
            _RUNNING = None


_RUNNING: BackgroundBake | None = None


def running() -> BackgroundBake | None:
    """The bake running now, if any."""
    return _RUNNING


def cancel_running() -> None:
    """Stop the running bake (a file is being loaded: its result would have nowhere to go)."""
    if _RUNNING is not None:
        _RUNNING.cancel()
