"""What every benchmark shares: the figure report (a JSON line per figure and a closing table),
best-of-N timing, and where the shared mocap is."""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from pathlib import Path

from tools.devkit.mocap import MOCAP, mocap_files

FIGURES: list[dict] = []


def report(group: str, name: str, value: float, unit: str, **context: object) -> None:
    """One figure: kept for the closing table and printed at once as a JSON line."""
    row = {"group": group, "name": name, "value": round(value, 6), "unit": unit, **context}
    FIGURES.append(row)
    print(json.dumps(row), flush=True)


def best_of(fn: Callable[[], object], runs: int) -> float:
    """Fastest wall time of `runs` calls, in seconds (the run least disturbed by other work)."""
    times = []
    for _ in range(runs):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return min(times)


def print_table() -> None:
    """The figures reported so far, as a table a person can read."""
    print()
    print(f"{'group':8s} {'figure':58s} {'value':>14s}  {'unit':9s} on")
    for row in FIGURES:
        on = row.get("clip") or row.get("file") or row.get("library") or ""
        print(f"{row['group']:8s} {row['name']:58s} {row['value']:14.4f}  {row['unit']:9s} {on}")


def largest_mocap() -> Path | None:
    """The largest shared BVH file (by bytes), or None where ../shared/mocap is absent."""
    files = sorted(mocap_files(), key=lambda p: p.stat().st_size)
    return files[-1] if files else None


def skipped(group: str, what: str = "") -> None:
    """Say that a group (or part of one) is skipped for want of the shared mocap."""
    print(f"# {group}: {what + ' ' if what else ''}skipped, no mocap at {MOCAP}")
