"""The documents state what the software does and measures, not how it got there.

Development history (numbered work sessions, "was X before", commit hashes, dates) belongs in the commit
messages. Every figure in BENCHMARKS.md sits in a table row that names its target, whether it is met and
the command that prints it.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

HISTORY_MARKERS = {
    "a numbered work session or round": r"\b(?:sessions?|rounds?)[- ]\d+",
    "a session's start or end": r"\b(?:this|that|last|previous|next) session\b|\bsession(?:'s)? (?:start|end|first)\b",
    "'was ... before'": r"\b(?:was|were)\b(?:(?!\.\s)[^;|])*\bbefore\b",
    "a parenthesised old value": r"\((?:was|were) [^)]*\)",
    "'previously' or 'formerly'": r"\b(?:previously|formerly)\b",
    "a change named as an event": r"\b(?:before|after|since) the (?:change|fix|fixes|rewrite)\b|\bthis change\b",
    "an ISO date": r"\b(?:19|20)\d\d-[01]\d-[0-3]\d\b",
    "an issue number": r"\bissues? #?\d+\b",
    "a commit hash": r"\b(?:commit(?:ted)?(?: in| with)?|HEAD|worktree of) [0-9a-f]{7,40}\b",
}

# (file, text on the flagged line) pairs where a marker's words mean something else.
ALLOWED = [
    ("docs/safety.md", "2015-01-01"),  # MAVLink 2 signing timestamps count from this epoch
    ("docs/lasers_rplidar.md", "2018-03-08"),  # the revision of the vendor's protocol document
    ("bench/results/faults.md", "what was flushed before the disk filled"),  # `agnav faults` writes it
]

BENCH_COLUMNS = ["What", "Figure", "Target", "Met", "Command"]


def _docs() -> list[Path]:
    files = [ROOT / "README.md", ROOT / "BENCHMARKS.md", ROOT / "RELIABILITY.md"]
    files += sorted((ROOT / "docs").rglob("*.md"))
    files += sorted((ROOT / "bench" / "results").glob("*.md"))
    return files


def _history_lines(path: Path) -> list[str]:
    rel = path.relative_to(ROOT).as_posix()
    found = []
    for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
        for what, pattern in HISTORY_MARKERS.items():
            match = re.search(pattern, line, flags=re.IGNORECASE)
            if match is None:
                continue
            if any(rel == f and text in line for f, text in ALLOWED):
                continue
            found.append(f"{rel}:{number}: {what}: ...{match.group(0)}...")
    return found


def _cells(row: str) -> list[str]:
    return [cell.strip() for cell in row.strip().strip("|").split("|")]


def _tables(text: str) -> list[list[str]]:
    tables, current = [], []
    for line in text.splitlines() + [""]:
        if line.lstrip().startswith("|"):
            current.append(line)
        elif current:
            tables.append(current)
            current = []
    return tables


@pytest.mark.parametrize("path", _docs(), ids=lambda p: p.relative_to(ROOT).as_posix())
def test_document_states_the_present_without_history_markers(path):
    found = _history_lines(path)
    assert not found, "history belongs in commit messages; say what holds:\n" + "\n".join(found)


def test_every_allowed_marker_is_still_in_its_file():
    for rel, text in ALLOWED:
        assert text in (ROOT / rel).read_text(encoding="utf-8"), f"{rel} no longer holds {text!r}: drop it from ALLOWED"


def test_history_markers_catch_the_narrating_forms():
    narrating = [
        "Session 8 re-run, after the final-approach law",
        "60 kHz (was 50 kHz)",
        "the tracker was 11.4 ms per scan before its rewrite",
        "it previously stopped short",
        "worst tick 1060 us after the change",
        "working tree of 2024-11-24",
        "the proximity target of issue 7",
        "committed in 39bdfae",
    ]
    for line in narrating:
        assert any(re.search(p, line, flags=re.IGNORECASE) for p in HISTORY_MARKERS.values()), line
    present = [
        "the robot stops 512 ms after the last frame",
        "a track is moving only after travelling its own radius",
        "the scan was taken at the mid-beam stamp",
    ]
    for line in present:
        assert not any(re.search(p, line, flags=re.IGNORECASE) for p in HISTORY_MARKERS.values()), line


def test_every_benchmark_row_names_its_target_whether_it_is_met_and_its_command():
    text = (ROOT / "BENCHMARKS.md").read_text(encoding="utf-8")
    tables = _tables(text)
    assert tables, "BENCHMARKS.md has no table"
    problems = []
    for table in tables:
        header = _cells(table[0])
        if header != BENCH_COLUMNS:
            problems.append(f"header {header}, expected {BENCH_COLUMNS}")
            continue
        for row in table[2:]:
            cells = _cells(row)
            if len(cells) != len(BENCH_COLUMNS):
                problems.append(f"{len(cells)} cells, expected {len(BENCH_COLUMNS)}: {row[:80]}")
                continue
            what, figure, target, met, command = cells
            if not figure or not target:
                problems.append(f"no figure or target: {what}")
            if not re.match(r"^(?:(?:\*\*)?(?:yes|no)\b|-$)", met):
                problems.append(f"met is not yes / no / -: {what}: {met[:40]}")
            if "`" not in command:
                problems.append(f"no command: {what}")
    assert not problems, "\n".join(problems)
