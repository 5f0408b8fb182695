#!/usr/bin/env python3
"""Add up the test reports in a folder and print one line: "N passed, N failed".

Reads PlatformIO's `pio test --json-output-path` files (pio-*.json), pytest's
--junitxml file (pytest.xml) and the static checks' JUnit files (check-*.xml, written by
tools/static_checks.py: one case per check). A suite that errored before running (a build
failure) counts as one failure, and so does a missing pytest or check report, so neither can
be mistaken for a pass. Exit code 1 when anything failed or nothing ran.
"""
import json
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

#: JUnit reports that must be there: pytest's and one per static check (tools/static_checks.py CHECKS)
JUNIT_REPORTS = ("pytest", "check-ruff", "check-mypy")


def count_pio(path: Path) -> tuple[int, int]:
    data = json.loads(path.read_text(encoding="utf-8"))
    passed = failed = 0
    for suite in data.get("test_suites", []):
        suite_failed = 0
        for case in suite.get("test_cases", []):
            status = str(case.get("status", "")).upper()
            if status.endswith("PASSED"):
                passed += 1
            elif not status.endswith("SKIPPED"):
                suite_failed += 1
        if suite_failed == 0 and str(suite.get("status", "")).upper().endswith(("ERRORED", "FAILED")):
            suite_failed = 1  # e.g. the build failed: no case ran, still a failure
        failed += suite_failed
    return passed, failed


def count_junit(path: Path) -> tuple[int, int]:
    root = ET.parse(path).getroot()
    suites = [root] if root.tag == "testsuite" else list(root)
    passed = failed = 0
    for s in suites:
        tests = int(s.get("tests", 0))
        bad = int(s.get("failures", 0)) + int(s.get("errors", 0))
        skipped = int(s.get("skipped", 0))
        passed += tests - bad - skipped
        failed += bad
    return passed, failed


def main(argv: list[str]) -> int:
    folder = Path(argv[1] if len(argv) > 1 else "build/test-reports")
    passed = failed = 0
    for path in sorted(folder.glob("pio-*.json")):
        p, f = count_pio(path)
        print(f"  {path.stem}: {p} passed, {f} failed")
        passed, failed = passed + p, failed + f
    for name in JUNIT_REPORTS:
        junit = folder / f"{name}.xml"
        if junit.is_file():
            p, f = count_junit(junit)
            print(f"  {name}: {p} passed, {f} failed")
            passed, failed = passed + p, failed + f
        else:
            print(f"  {name}: no report (did not run)")
            failed += 1
    print(f"{passed} passed, {failed} failed")
    return 0 if failed == 0 and passed > 0 else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv))
