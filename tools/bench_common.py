"""What every benchmark shares: one core for BLAS, paths, timing, and the figure report.

Import this before numpy (it limits BLAS threads, since figures are for one core).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable  # noqa: E402
from pathlib import Path  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
MOCAP = REPO.parent / "shared" / "mocap"
sys.path.insert(0, str(REPO))

FIGURES: list[dict] = []


def report(group: str, name: str, value: float, unit: str, **context) -> None:
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
