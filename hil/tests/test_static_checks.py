"""The static checks suite (tools/static_checks.py) and its place in the closing line of every suite
(tools/sum_test_reports.py): a check that finds something is a failed case, and so is a check whose
report is missing."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

import pytest

TOOLS = Path(__file__).resolve().parents[2] / "tools"


def _tool(name: str) -> ModuleType:
    spec = importlib.util.spec_from_file_location(name, TOOLS / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def checks() -> ModuleType:
    return _tool("static_checks")


@pytest.fixture(scope="module")
def sums() -> ModuleType:
    return _tool("sum_test_reports")


def _fake_tool(code: int, text: str) -> list[str]:
    return [sys.executable, "-c", f"import sys; print({text!r}); sys.exit({code})"]


def test_check_with_findings_writes_a_failed_case_carrying_the_findings(checks, sums, tmp_path):
    found = "host/agnav_host/x.py:3: error: Name \"y\" is not defined  [name-defined]\nFound 1 error in 1 file"
    assert checks.run_check("mypy", _fake_tool(1, found), tmp_path) is False
    report = tmp_path / "check-mypy.xml"
    assert sums.count_junit(report) == (0, 1)
    text = report.read_text(encoding="utf-8")
    assert 'message="Found 1 error in 1 file"' in text and "name-defined" in text


def test_clean_check_writes_one_passed_case(checks, sums, tmp_path):
    assert checks.run_check("ruff", _fake_tool(0, "All checks passed!"), tmp_path) is True
    assert sums.count_junit(tmp_path / "check-ruff.xml") == (1, 0)


def test_check_whose_tool_cannot_start_fails(checks, sums, tmp_path):
    assert checks.run_check("ruff", [str(tmp_path / "no-such-tool")], tmp_path) is False
    assert sums.count_junit(tmp_path / "check-ruff.xml") == (0, 1)


def test_closing_line_counts_the_checks_and_a_missing_check_report_as_a_failure(checks, sums, tmp_path, capsys):
    (tmp_path / "pytest.xml").write_text('<testsuite tests="5" failures="0" errors="0" skipped="1"/>', encoding="utf-8")
    checks.run_check("ruff", _fake_tool(0, ""), tmp_path)
    assert sums.main(["sum", str(tmp_path)]) == 1  # no mypy report
    assert capsys.readouterr().out.splitlines()[-1] == "5 passed, 1 failed"
    checks.run_check("mypy", _fake_tool(0, ""), tmp_path)
    assert sums.main(["sum", str(tmp_path)]) == 0
    assert capsys.readouterr().out.splitlines()[-1] == "6 passed, 0 failed"


def test_every_check_has_a_report_the_closing_line_requires(checks, sums):
    assert {f"check-{name}" for name in checks.CHECKS} <= set(sums.JUNIT_REPORTS)
