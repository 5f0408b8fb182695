"""The fault-injection suite (``make faults``) as tests: each case injects its fault into the SIL
firmware, the radio model, or the host's I/O, and passes only when the measured reaction matches
the expected one. The measured reaction is the assertion message."""

from __future__ import annotations

import pytest

from agnav_host.faults import all_cases, run_cases

CASES = all_cases()


@pytest.mark.parametrize("case", CASES, ids=[f"{c.area}:{c.name}" for c in CASES])
def test_fault_case(case):
    (row,) = run_cases([case])
    assert row.outcome.passed, f"{case.name}: expected {case.expected}; measured {row.outcome.measured}"
