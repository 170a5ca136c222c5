"""`bake --workers 2`: a local Dask cluster bakes the inputs and one corrupt file, each file in a
Blender process of its own; the outputs are those of a one-process bake, the corrupt file is
reported and fails the run, and a rerun bakes nothing that was complete."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

from tests.farm.support import ENVIRONMENT, REPO, command, partial_files, reacted_keys, report


@pytest.fixture(scope="module")
def farm_run(inputs: list[Path], tmp_path_factory: pytest.TempPathFactory) -> dict:
    """The inputs and a corrupt .blend baked by 2 local workers, then the same command again."""
    folder = tmp_path_factory.mktemp("farm")
    corrupt = folder / "corrupt.blend"
    corrupt.write_bytes(b"BLENDER-v405" + bytes(range(256)) * 8)
    out = folder / "out"
    files = [*map(str, inputs[:3]), str(corrupt), *map(str, inputs[3:])]

    def run(name: str) -> subprocess.CompletedProcess:
        args = [*files, "--out-dir", str(out), "--workers", "2", "--report", str(folder / name)]
        return subprocess.run(command(*args), cwd=REPO, env=ENVIRONMENT, capture_output=True, text=True, timeout=300)

    first = run("first.jsonl")
    written = {p.name: (p.stat().st_mtime_ns, p.stat().st_ino) for p in out.iterdir()}
    again = run("again.jsonl")
    return {"first": first, "again": again, "folder": folder, "out": out, "written": written}


def test_two_workers_bake_what_one_process_bakes(farm_run: dict, reference: dict) -> None:
    first, out = farm_run["first"], farm_run["out"]
    assert sorted(p.name for p in out.iterdir()) == sorted(reference)  # nothing else: no partial file
    for name, keys in reference.items():
        assert reacted_keys(out / name) == keys, name
    rows = report(farm_run["folder"] / "first.jsonl")
    baked = [row for name, row in rows.items() if name != "corrupt.blend"]
    assert [row["status"] for row in baked] == ["baked"] * len(reference)
    assert len({row["worker"] for row in baked}) == 2  # both workers took files
    assert all(row["worker"].startswith("tcp://127.0.0.1:") for row in baked)
    assert all(row["impacts"] == 2 and row["classes"] == ["step_forward", "sway_balance"] for row in baked)
    assert all(len(row["inputs"]) == 64 and row["attempts"] == 1 and row["clips"] for row in baked)
    assert "started shot_0.blend on tcp://127.0.0.1:" in first.stderr
    assert "failed, 0 running" in first.stderr.splitlines()[-1]  # the progress line after the last file


def test_a_corrupt_input_is_reported_and_fails_the_run(farm_run: dict) -> None:
    first = farm_run["first"]
    assert first.returncode == 1, first.stderr
    row = report(farm_run["folder"] / "first.jsonl")["corrupt.blend"]
    assert row["status"] == "failed" and row["attempts"] == 1  # reported once, not retried
    assert row["error"].startswith("cannot open corrupt.blend: ")
    assert not (farm_run["out"] / "corrupt.reacted.blend").exists()
    table = first.stdout[first.stdout.index("file ") :].splitlines()
    assert [line.split()[0] for line in table[1:8]] == [*(f"shot_{k}.blend" for k in range(3)), "corrupt.blend",
                                                       *(f"shot_{k}.blend" for k in range(3, 6))]  # fmt: skip
    assert "FAILED: cannot open corrupt.blend" in table[4]
    assert table[8] == "6 of 7 files baked, 1 failed"


def test_a_rerun_bakes_nothing_that_was_complete(farm_run: dict) -> None:
    again, out = farm_run["again"], farm_run["out"]
    assert again.returncode == 1, again.stderr  # the corrupt file fails again
    rows = report(farm_run["folder"] / "again.jsonl")
    assert {name: row["status"] for name, row in rows.items()} == {
        **{f"shot_{k}.blend": "skipped" for k in range(6)},
        "corrupt.blend": "failed",
    }
    assert all(row["impacts"] == 2 and row["clips"] for name, row in rows.items() if name != "corrupt.blend")
    assert {p.name: (p.stat().st_mtime_ns, p.stat().st_ino) for p in out.iterdir()} == farm_run["written"]
    assert "6 of 7 files baked (6 complete already: skipped), 1 failed" in again.stdout
    assert partial_files(farm_run["folder"]) == []
