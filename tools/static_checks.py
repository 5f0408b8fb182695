#!/usr/bin/env python3
"""The static checks as one test suite: `ruff check` (host/, hil/, bench/, tools/) and `mypy` (agnav_host,
strict), both configured in pyproject.toml.

Each check prints what its tool printed and writes a JUnit report ``check-<name>.xml`` to the given folder with
one test case, failed when the tool exited non-zero (its findings are the failure text), so that
tools/sum_test_reports.py counts it into the closing "N passed, N failed" line. Exit code 1 when a check failed.

    .venv/bin/python tools/static_checks.py [REPORT_DIR]    (default build/test-reports)
"""
from __future__ import annotations

import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent

#: name -> command; each tool reads its settings from pyproject.toml
CHECKS: dict[str, list[str]] = {
    "ruff": [sys.executable, "-m", "ruff", "check", "--no-cache", "--output-format", "concise"],
    "mypy": [sys.executable, "-m", "mypy"],
}


def write_report(path: Path, name: str, passed: bool, output: str) -> None:
    """A JUnit file with the one case ``name``; a failed case carries the tool's output."""
    suite = ET.Element("testsuite", name=f"check-{name}", tests="1", failures="0" if passed else "1",
                       errors="0", skipped="0")
    case = ET.SubElement(suite, "testcase", classname="static_checks", name=name)
    if not passed:
        lines = output.strip().splitlines()
        summary = next((ln for ln in reversed(lines) if ln.startswith("Found ")), lines[-1] if lines else "")
        failure = ET.SubElement(case, "failure", message=summary or f"{name} failed")
        failure.text = output
    ET.ElementTree(suite).write(path, encoding="utf-8", xml_declaration=True)


def run_check(name: str, argv: list[str], report_dir: Path, cwd: Path = REPO) -> bool:
    """Run one check, print its output, write ``check-<name>.xml``; True when it passed."""
    try:
        proc = subprocess.run(argv, cwd=cwd, capture_output=True, text=True)
        output, passed = proc.stdout + proc.stderr, proc.returncode == 0
    except OSError as e:  # the tool itself cannot be started
        output, passed = f"{name}: cannot run {argv[0]}: {e}\n", False
    sys.stdout.write(output)
    write_report(report_dir / f"check-{name}.xml", name, passed, output)
    return passed


def main(argv: list[str]) -> int:
    report_dir = Path(argv[1] if len(argv) > 1 else REPO / "build" / "test-reports")
    report_dir.mkdir(parents=True, exist_ok=True)
    ok = True
    for name, cmd in CHECKS.items():
        print(f"--- {name} ---", flush=True)
        ok = run_check(name, cmd, report_dir) and ok
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv))
