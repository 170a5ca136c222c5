"""The animator's path in a real Blender window: Debian's Blender 4.3 under Xvfb (tests/gui/session.py).

One session walks the whole path (install the zip with Blender's own operator, import, add and aim
impacts, Esc a bake, bake, Ctrl+Z / Ctrl+Shift+Z, preview, discard, accept, move and duplicate a
marker, save and reload, the overlay's arrow on screen); each step is a test here, plus one that
fails on any Python exception Blender printed (an add-on's register() failing is printed, not raised).

It needs the Debian 13 root of tools/setup_gui_root.sh (root and Debian's package mirror). Where it
cannot be made the tests skip and say why; in CI (CI=true) they fail instead.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
OUT = REPO / "out" / "gui"
INSIDE = Path("/repo")  # where tests/gui/run.sh binds this checkout in the root
SESSION_TIMEOUT_S = 1800
STEPS = (
    "install",
    "import_bvh",
    "add_impacts",
    "escape_cancels_a_long_bake",
    "bake",
    "undo_redo",
    "preview_discard_accept",
    "drag_and_duplicate_a_marker",
    "save_and_reload",
    "overlay_arrow_is_drawn",
)
# What Blender prints when Python code of an add-on or the session failed.
PYTHON_ERRORS = re.compile(r"Traceback \(most recent call last\)|Exception in module|Error: Python|^\w+Error: ", re.M)


def _unavailable(reason: str) -> None:
    if os.environ.get("CI") == "true":
        pytest.fail(f"the real Blender window cannot be tested: {reason}")
    pytest.skip(f"no real Blender window here: {reason}")


def _run(command: list[str], what: str, timeout: float = 1800) -> str:
    """The last line a setup command printed (the path it made); unavailable if it failed."""
    completed = subprocess.run(command, cwd=REPO, capture_output=True, text=True, timeout=timeout)
    if completed.returncode != 0:
        _unavailable(f"{what} failed: {(completed.stdout + completed.stderr).strip()[-2000:]}")
    return completed.stdout.strip().splitlines()[-1]


@pytest.fixture(scope="session")
def session() -> dict:
    """Build (or reuse) the Debian root and the linux zip, run the session once, read what it saw."""
    if sys.platform != "linux" or shutil.which("unshare") is None:
        _unavailable("needs Linux with unshare and chroot")
    if os.geteuid() != 0:
        _unavailable("needs root (debootstrap, chroot, mounts)")
    root = _run(["bash", "tools/setup_gui_root.sh"], "setting up the Debian 13 root")
    python = _run(["bash", "tools/setup_env.sh", "bpy-5.2"], "setting up the bpy 5.2 environment")
    _run([python, "tools/build_extension.py", "--platform", "linux-x64"], "building the linux zip", timeout=900)
    zip_file = next((REPO / "dist").glob("reactive_anim-*-linux_x64.zip"))
    shutil.rmtree(OUT, ignore_errors=True)
    paths = (OUT, REPO / "tests/gui/session.py", zip_file, REPO / "sample_clips/walk.bvh")
    command = ["bash", "tests/gui/run.sh", root, *(str(INSIDE / p.relative_to(REPO)) for p in paths)]
    completed = subprocess.run(command, cwd=REPO, capture_output=True, text=True, timeout=SESSION_TIMEOUT_S)
    log = (OUT / "blender.log").read_text(errors="replace") if (OUT / "blender.log").is_file() else ""
    report = OUT / "steps.json"
    if not report.is_file():
        pytest.fail(
            f"no report from the session (exit {completed.returncode}): {completed.stderr[-2000:]}\n{log[-4000:]}"
        )
    found = json.loads(report.read_text())
    found["log"] = log
    return found


@pytest.mark.parametrize("step", STEPS)
def test_step(session: dict, step: str) -> None:
    by_name = {record["step"]: record for record in session["steps"]}
    assert step in by_name, f"not reached: an earlier step failed ({[r['step'] for r in session['steps']]})"
    assert by_name[step]["ok"], by_name[step]["error"]


def test_blender_printed_no_python_exception(session: dict) -> None:
    lines = [line for line in session["log"].splitlines() if PYTHON_ERRORS.search(line)]
    assert lines == [], "\n".join(lines[:20])


def test_the_screenshots_are_there(session: dict) -> None:
    for name in ("impacts", "baked", "preview", "overlay_at_impact", "overlay_away"):
        path = OUT / f"{name}.png"
        assert path.is_file() and path.stat().st_size > 20_000, path
