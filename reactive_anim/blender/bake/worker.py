"""A bake computed in a worker thread, so Blender's UI stays live.

The main thread prepares a BakeJob (bake.prepare_bake reads the .blend) and hands it to a
BackgroundBake; the thread runs only `BakeJob.run`, numpy in and numpy out, and talks back
through a queue. ModalRun is what the modal Bake and Preview operators (bake_ops.py) do with each
event: poll the worker on their timer, pass every other event through, stop on Esc, and write the
result on the main thread in the operator's last step, so the bake is one undo step. It is kept
apart from the operator so that tests can drive it event by event (background mode has no event
loop). One bake runs at a time (`running()`).
"""

from __future__ import annotations

import queue
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from ...core.model.errors import Cancelled, ReactiveAnimError
from ...core.react import Baked
from .bake import BakeJob, BakeResult

POLL_SECONDS = 0.1  # how often the modal operator looks at the worker (cheap: a queue read)
CANCEL_WAIT_S = 0.5  # Esc waits this long for the thread to stop; a longer impact finishes unseen
CANCELLED_TEXT = "Reactions cancelled: nothing was changed"


@dataclass(frozen=True)
class BakeProgress:
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
        self.progress = BakeProgress(0, len(job.impacts), "starting")
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
        busy = running()
        if busy is not None:
            raise RuntimeError(f"a bake is already running on '{busy.job.armature}'")
        _RUNNING = self
        self._start = time.perf_counter()
        self._thread.start()
        return self

    def _run(self) -> None:
        """The worker thread: no bpy here, ever."""
        try:
            baked = self.job.run(
                progress=lambda k, n, what: self._messages.put(("progress", BakeProgress(k, n, what))),
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
            if kind == "progress" and isinstance(value, BakeProgress):
                self.progress = value
            elif kind == "done" and isinstance(value, Baked):
                self._end(baked=value)
            elif isinstance(value, BaseException):
                self._end(error=value)
        return self._ended

    def cancel(self) -> None:
        """Ask the thread to stop before its next impact; nothing is written. Waits CANCEL_WAIT_S at
        most: a thread still in an impact then ends unseen (running() reports it until it has)."""
        self._stop.set()
        self._thread.join(CANCEL_WAIT_S)
        self.poll()
        self._ended = True
        self.baked, self.error = None, Cancelled("bake cancelled")

    @property
    def alive(self) -> bool:
        return self._thread.is_alive()

    def _end(self, baked: Baked | None = None, error: BaseException | None = None) -> None:
        self._thread.join()  # it has sent its last message: this returns at once
        self.baked, self.error = baked, error
        self.seconds = time.perf_counter() - self._start
        self._ended = True


_RUNNING: BackgroundBake | None = None


def running() -> BackgroundBake | None:
    """The bake whose thread runs now, if any."""
    global _RUNNING
    if _RUNNING is not None and _RUNNING._ended and not _RUNNING.alive:
        _RUNNING = None
    return _RUNNING


def cancel_running() -> None:
    """Stop the running bake (the add-on is unregistered, a file is loaded)."""
    busy = running()
    if busy is not None:
        busy.cancel()


@dataclass
class Outcome:
    """What the operator returns for an event, and what it reports."""

    result: str  # "RUNNING_MODAL", "PASS_THROUGH", "FINISHED" or "CANCELLED"
    reports: list[tuple[str, str]] = field(default_factory=list)  # (level, message)


class ModalRun:
    """The modal operator's handling of events around a BackgroundBake.

    window_manager: adds and removes the poll timer (bpy.types.WindowManager, or a stand-in in tests).
    status: shows a text in the status bar, None to clear it. write: the main-thread last step.
    """

    def __init__(
        self,
        background: BackgroundBake,
        write: Callable[[BakeJob, Baked, float], BakeResult],
        window_manager: Any,
        window: Any,
        status: Callable[[str | None], None],
        redraw: Callable[[], None],
    ) -> None:
        self.background = background
        self.write = write
        self.window_manager = window_manager
        self.window = window
        self.status = status
        self.redraw = redraw
        self.timer: Any = None

    def start(self) -> None:
        self.background.start()
        self.timer = self.window_manager.event_timer_add(POLL_SECONDS, window=self.window)
        self._show()

    def handle(self, event_type: str, event_value: str) -> Outcome:
        """One event: Esc cancels; our timer polls the worker; everything else passes through."""
        if event_type == "ESC" and event_value == "PRESS":
            self.cancel()
            return Outcome("CANCELLED", [("WARNING", CANCELLED_TEXT)])
        if event_type != "TIMER":
            return Outcome("PASS_THROUGH")
        if not self.background.poll():
            self._show()
            return Outcome("PASS_THROUGH")
        self.stop()
        return self._write()

    def cancel(self) -> None:
        """Esc, or Blender ending the operator (a file loaded, the window closed): write nothing."""
        self.background.cancel()
        self.stop()

    def stop(self) -> None:
        if self.timer is not None:
            self.window_manager.event_timer_remove(self.timer)
            self.timer = None
        self.status(None)
        self.redraw()

    def _show(self) -> None:
        self.status(self.background.progress.text(self.background.job.armature))
        self.redraw()

    def _write(self) -> Outcome:
        background = self.background
        try:
            if background.error is not None:
                raise background.error
            assert background.baked is not None
            result = self.write(background.job, background.baked, background.seconds)
        except Cancelled:
            return Outcome("CANCELLED", [("WARNING", CANCELLED_TEXT)])
        except (ReactiveAnimError, OSError) as exc:
            return Outcome("CANCELLED", [("ERROR", str(exc))])
        except Exception as exc:  # a bug: reported, never a traceback out of a modal operator
            return Outcome("CANCELLED", [("ERROR", f"reactions failed unexpectedly: {exc!r}")])
        return Outcome("FINISHED", [("INFO", line) for line in result.summary().splitlines()])
