"""Fault cases and the table they make: each case injects one fault, measures what the system
did, and compares it with what it should do."""

from __future__ import annotations

import time
import traceback
from dataclasses import dataclass, field
from typing import Callable, Iterable

__all__ = ["FaultOutcome", "FaultCase", "FaultRow", "run_cases", "format_table"]


@dataclass(frozen=True)
class FaultOutcome:
    measured: str  # what happened, in words and figures
    passed: bool
    figures: dict[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class FaultCase:
    name: str
    area: str  # link, sensor, controller, command, signing, host
    expected: str
    run: Callable[[], FaultOutcome]


@dataclass(frozen=True)
class FaultRow:
    case: FaultCase
    outcome: FaultOutcome
    wall_s: float


def run_cases(cases: Iterable[FaultCase], progress: Callable[[int, int, str], None] | None = None) -> list[FaultRow]:
    """Run every case; a case that raises is a failure whose measured reaction names the error
    (the suite always completes)."""
    todo = list(cases)
    rows: list[FaultRow] = []
    for i, c in enumerate(todo):
        if progress is not None:
            progress(i, len(todo), c.name)
        t0 = time.perf_counter()
        try:
            out = c.run()
        except Exception as e:  # the table must show it, not die on it
            tb = traceback.extract_tb(e.__traceback__)
            where = f" at {tb[-1].filename.rsplit('/', 1)[-1]}:{tb[-1].lineno}" if tb else ""
            out = FaultOutcome(f"ERROR {type(e).__name__}: {e}{where}", False)
        rows.append(FaultRow(c, out, time.perf_counter() - t0))
    if progress is not None:
        progress(len(todo), len(todo), "")
    return rows


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def format_table(rows: list[FaultRow], markdown: bool = True) -> str:
    head = ("area", "fault", "expected reaction", "measured reaction", "result")
    body = [(r.case.area, r.case.name, r.case.expected, r.outcome.measured, "pass" if r.outcome.passed else "FAIL")
            for r in rows]
    if markdown:
        lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        lines += ["| " + " | ".join(_cell(c) for c in row) + " |" for row in body]
    else:
        lines = []
        for row in body:
            lines.append(f"[{row[4]:>4}] {row[0]}: {row[1]}")
            lines.append(f"       expected: {row[2]}")
            lines.append(f"       measured: {row[3]}")
    n_ok = sum(1 for r in rows if r.outcome.passed)
    lines.append("")
    lines.append(f"{n_ok} of {len(rows)} fault cases pass")
    return "\n".join(lines)
