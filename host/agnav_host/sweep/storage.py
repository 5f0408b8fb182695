"""Where a sweep keeps its runs: one JSON line per finished run, written as the run ends.

``OUT/runs.jsonl``      one row per run (key, task, spec, seed, results, ``wall_s``): the file the tables
                        and plots are built from, and what a resumed sweep reads to skip the finished runs
``OUT/timings.jsonl``   ``{"key": ..., ...}``: the run's measured compute times, when its task measures any
``OUT/arrays/KEY.npz``  the run's arrays (a trajectory for a plot), when its task returns any

A run counts as finished once its line in runs.jsonl is complete: its arrays and timings are written first,
then the row, flushed and synced. A sweep killed while writing leaves at most a torn last line, which the
next open drops. Without a folder (``RunStore(None)``) the rows are kept in memory only.
"""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path
from typing import Any, Iterator

import numpy as np

__all__ = ["RunStore", "RUNS", "TIMINGS", "ARRAYS"]

RUNS = "runs.jsonl"
TIMINGS = "timings.jsonl"
ARRAYS = "arrays"


def _lines(path: Path) -> Iterator[dict[str, Any]]:
    """The complete JSON lines of ``path``; a torn or unreadable last line is cut off the file."""
    if not path.is_file():
        return
    data = path.read_bytes()
    good = 0  # end of the last complete, readable line
    rows = []
    for line in data.splitlines(keepends=True):
        if not line.endswith(b"\n"):
            break
        try:
            rows.append(json.loads(line))
        except ValueError:
            break
        good += len(line)
    if good < len(data):
        with open(path, "r+b") as f:
            f.truncate(good)
    yield from rows


class RunStore:
    """The rows of a sweep in ``out`` (a folder, made when missing), or in memory when ``out`` is None."""

    def __init__(self, out: str | Path | None, fresh: bool = False) -> None:
        self.out = None if out is None else Path(out)
        self._rows: dict[str, dict[str, Any]] = {}
        self._timings: dict[str, dict[str, Any]] = {}
        self._arrays: dict[str, dict[str, np.ndarray]] = {}
        if self.out is None:
            return
        self.out.mkdir(parents=True, exist_ok=True)
        if fresh:
            for name in (RUNS, TIMINGS):
                (self.out / name).unlink(missing_ok=True)
            for p in (self.out / ARRAYS).glob("*.npz"):
                p.unlink()
        for t in _lines(self.out / TIMINGS):
            self._timings[t["key"]] = t
        for r in _lines(self.out / RUNS):
            self._rows[r["key"]] = r

    def __contains__(self, key: str) -> bool:
        return key in self._rows

    def __len__(self) -> int:
        return len(self._rows)

    def row(self, key: str) -> dict[str, Any]:
        return self._rows[key]

    def rows(self) -> list[dict[str, Any]]:
        """Every stored row, in the order they were stored (rows of other sweeps in the same folder too)."""
        return list(self._rows.values())

    def timing(self, key: str) -> dict[str, Any]:
        """The measured times of run ``key`` (empty when its task measures none)."""
        return {k: v for k, v in self._timings.get(key, {}).items() if k != "key"}

    def arrays(self, key: str) -> dict[str, np.ndarray]:
        """The arrays of run ``key`` (empty when its task returns none)."""
        if key in self._arrays:
            return self._arrays[key]
        if self.out is None:
            return {}
        p = self.out / ARRAYS / f"{key}.npz"
        if not p.is_file():
            return {}
        with np.load(p) as z:
            return {k: z[k] for k in z.files}

    def add(self, row: dict[str, Any], timing: dict[str, Any] | None = None,
            arrays: dict[str, np.ndarray] | None = None) -> None:
        """Store one finished run: its arrays and timing first, then its row (the run's commit point)."""
        key = row["key"]
        if self.out is None:
            if arrays:
                self._arrays[key] = dict(arrays)
        elif arrays:
            folder = self.out / ARRAYS
            folder.mkdir(exist_ok=True)
            fd, tmp = tempfile.mkstemp(dir=folder, prefix=f".{key}.", suffix=".npz")
            try:
                with os.fdopen(fd, "wb") as f:
                    np.savez_compressed(f, **arrays)  # type: ignore[arg-type]
                os.replace(tmp, folder / f"{key}.npz")
            finally:
                if os.path.exists(tmp):
                    os.unlink(tmp)
        if timing:
            t = {"key": key, **timing}
            self._timings[key] = t
            if self.out is not None:
                self._append(TIMINGS, t)
        if self.out is not None:
            self._append(RUNS, row)
        self._rows[key] = row

    def _append(self, name: str, record: dict[str, Any]) -> None:
        assert self.out is not None
        line = json.dumps(record, separators=(",", ":"), allow_nan=True) + "\n"
        with open(self.out / name, "a", encoding="utf-8") as f:
            f.write(line)
            f.flush()
            os.fsync(f.fileno())
