"""Add up the JUnit XML files of several pytest runs into one closing line.

Prints a line per run and then 'total: N passed, N failed, N skipped'. Exits non-zero when a run
failed, had errors, or ran no test at all (an empty run is not a pass).
"""

from __future__ import annotations

import sys
import xml.etree.ElementTree as ET
from pathlib import Path


def counts(path: Path) -> dict[str, int]:
    suites = ET.parse(path).getroot()
    suites = suites.findall("testsuite") if suites.tag == "testsuites" else [suites]
    total = {"tests": 0, "failures": 0, "errors": 0, "skipped": 0}
    for suite in suites:
        for key in total:
            total[key] += int(suite.get(key, 0))
    return total


def main(paths: list[str]) -> int:
    if not paths:
        print("no test results found")
        return 1
    grand = {"passed": 0, "failed": 0, "skipped": 0}
    ok = True
    for name in paths:
        c = counts(Path(name))
        failed = c["failures"] + c["errors"]
        passed = c["tests"] - failed - c["skipped"]
        ok = ok and failed == 0 and c["tests"] > 0
        print(f"{Path(name).stem:12s} {passed} passed, {failed} failed, {c['skipped']} skipped")
        grand["passed"] += passed
        grand["failed"] += failed
        grand["skipped"] += c["skipped"]
    print(f"total: {grand['passed']} passed, {grand['failed']} failed, {grand['skipped']} skipped")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
