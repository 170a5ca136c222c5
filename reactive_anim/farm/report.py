"""One input file's outcome, the same whether it was baked here or on a farm worker: a row of the
summary table and one JSON line of the machine-readable report (`bake --report FILE`).

A farm task's Blender process writes its file's line to its stdout (`--report -`) and the task hands
that line back to the client, so the report of a farm run and of a one-process run have one format:

    {"file": ..., "output": ..., "status": "baked" | "skipped" | "nothing to bake" | "failed",
     "inputs": the hash of everything the output is made from, "worker": the host or Dask worker,
     "attempts": how many times a farm started it, "seconds": ..., "impacts": ..., "classes": [...],
     "clips": [...], "result": the summary's text, "error": the reason when it failed, else null}
"""

from __future__ import annotations

import json
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import TextIO


@dataclass
class FileOutcome:
    """One input file of `bake`: what was baked, or why not."""

    path: Path
    output: Path | None = None
    inputs: str = ""
    worker: str = ""
    attempts: int = 1
    impacts: int = 0
    classes: list[str] = field(default_factory=list)
    clips: list[str] = field(default_factory=list)
    seconds: float = 0.0
    result: str = ""
    failed: bool = False
    skipped: bool = False

    @property
    def status(self) -> str:
        if self.failed:
            return "failed"
        if self.skipped:
            return "skipped"
        return "baked" if self.impacts else "nothing to bake"

    def row(self) -> dict:
        """The report's JSON object for this file."""
        return {
            "file": str(self.path),
            "output": str(self.output) if self.output else None,
            "status": self.status,
            "inputs": self.inputs or None,
            "worker": self.worker,
            "attempts": self.attempts,
            "seconds": round(self.seconds, 3),
            "impacts": self.impacts,
            "classes": self.classes,
            "clips": self.clips,
            "result": self.result,
            "error": self.result if self.failed else None,
        }

    @classmethod
    def from_row(cls, row: dict) -> FileOutcome:
        """The outcome a report line describes (a farm task's line, read back by the client)."""
        return cls(
            Path(row["file"]),
            Path(row["output"]) if row.get("output") else None,
            inputs=row.get("inputs") or "",
            worker=row.get("worker", ""),
            attempts=row.get("attempts", 1),
            impacts=row.get("impacts", 0),
            classes=list(row.get("classes", [])),
            clips=list(row.get("clips", [])),
            seconds=row.get("seconds", 0.0),
            result=row.get("result", ""),
            failed=row.get("status") == "failed",
            skipped=row.get("status") == "skipped",
        )


def failure_row(path: str, why: str, worker: str = "") -> dict:
    """The report line of a file whose bake ended without writing one (its process was killed, or
    its worker lost every time)."""
    return FileOutcome(Path(path), worker=worker, result=why, failed=True).row()


def read_row(text: str) -> dict | None:
    """The last report line in `text` (a bake process's stdout, where Blender prints too), or None."""
    for line in reversed(text.splitlines()):
        if line.startswith('{"file": '):
            try:
                return json.loads(line)
            except ValueError:
                continue
    return None


@contextmanager
def report_lines(path: Path | None) -> Iterator[Callable[[FileOutcome], None]]:
    """A function that writes one outcome's JSON line to `path` ("-": stdout; None: no report),
    flushed as each file ends, so a batch that is killed still leaves the lines of the files done."""
    if path is None:
        yield lambda _outcome: None
        return
    if str(path) == "-":
        yield lambda outcome: _write_line(sys.stdout, outcome)
        return
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", encoding="utf-8") as stream:
        yield lambda outcome: _write_line(stream, outcome)


def _write_line(stream: TextIO, outcome: FileOutcome) -> None:
    """One line in one write: on stdout, Blender's own messages go between lines, never into one."""
    stream.flush()
    stream.write(json.dumps(outcome.row()) + "\n")
    stream.flush()
