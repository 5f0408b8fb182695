"""The sweep runner: pure tasks, rows stored as each run ends, resuming, the same rows on any number of workers."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

from agnav_host.sweep import LocalBackend, RunStore, SweepFailed, Task, run_sweep
from agnav_host.sweep.storage import RUNS
from agnav_host.sweep.tasks import code_digest, same_results, task_key


def noisy_task(spec, seed):
    """A stand-in run: its result depends on the spec and the seed only (a seeded generator), marks each
    execution in ``spec["marks"]`` (when given) so that a test can count them."""
    if spec.get("marks"):
        Path(spec["marks"], f"{spec['x']}-{seed}-{os.getpid()}-{os.urandom(4).hex()}").touch()
    if spec.get("fail") == spec["x"]:
        raise ValueError("the planner gave up")
    rng = np.random.default_rng(seed)
    return {"value": float(spec["x"] * rng.normal()), "draws": rng.integers(0, 100, 3),
            "timing": {"step_ms": [0.1, 0.2]}, "arrays": {"path": np.arange(4.0) * spec["x"]}}


FN = f"{__name__}:noisy_task"


def _tasks(n=6, **extra):
    return [Task(FN, {"x": x, **extra}, seed) for x in range(n // 2) for seed in (0, 1)]


def test_a_row_holds_its_spec_seed_results_and_only_wall_s_as_a_clock(tmp_path):
    store = RunStore(tmp_path)
    rows = run_sweep(_tasks(2), LocalBackend(1), store)
    assert [(r["x"], r["seed"]) for r in rows] == [(0, 0), (0, 1)]
    r = rows[1]
    assert set(r) == {"key", "task", "x", "seed", "value", "draws", "wall_s"}
    assert r["task"] == "test_sweep.noisy_task" and r["wall_s"] >= 0.0
    rng = np.random.default_rng(1)
    assert r["value"] == 0.0 * rng.normal() and r["draws"] == rng.integers(0, 100, 3).tolist()
    assert store.timing(r["key"]) == {"step_ms": [0.1, 0.2]}  # measured times beside the row, not in it
    assert store.arrays(r["key"])["path"].tolist() == [0.0, 0.0, 0.0, 0.0]
    lines = (tmp_path / RUNS).read_text().splitlines()
    assert [json.loads(line) for line in lines] == rows


def test_the_rows_are_the_same_bit_for_bit_on_one_worker_or_two_in_any_order(tmp_path):
    tasks = _tasks(8)
    one = run_sweep(tasks, LocalBackend(1), RunStore(tmp_path / "one"))
    two = run_sweep(tasks, LocalBackend(2), RunStore(tmp_path / "two"), order=list(reversed(range(len(tasks)))))
    assert len(one) == len(two) == 8
    assert all(same_results(a, b) for a, b in zip(one, two))
    assert len({r["value"] for r in one}) > 4  # the seeds and specs do give different results
    stored = [json.loads(line) for line in (tmp_path / "two" / RUNS).read_text().splitlines()]
    assert sorted(r["key"] for r in stored) == sorted(r["key"] for r in two)


def test_a_killed_sweep_resumes_without_redoing_finished_runs(tmp_path):
    marks = tmp_path / "marks"
    marks.mkdir()
    tasks = _tasks(6, marks=str(marks))
    seen = []

    def stop_after_two(p):
        seen.append(p)
        if p.done == 2:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_sweep(tasks, LocalBackend(1), RunStore(tmp_path / "out"), stop_after_two)
    assert len(list(marks.iterdir())) == 2
    with open(tmp_path / "out" / RUNS, "a") as f:  # killed while writing the third row
        f.write('{"key": "torn')
    store = RunStore(tmp_path / "out")
    assert len(store) == 2 and (tmp_path / "out" / RUNS).read_text().endswith("}\n")
    progress = []
    rows = run_sweep(tasks, LocalBackend(2), store, progress.append)
    assert len(list(marks.iterdir())) == 6  # four more runs, not six
    assert [p.resumed for p in progress] == [2] * 4 and [p.done for p in progress] == [3, 4, 5, 6]
    assert progress[-1].left_s == 0.0 and all(p.rate_per_s > 0 for p in progress)
    fresh = run_sweep(tasks, LocalBackend(1), RunStore(tmp_path / "again"))
    assert all(same_results(a, b) for a, b in zip(rows, fresh))


def test_a_run_stored_by_other_code_is_not_reused(tmp_path):
    t = _tasks(2)[0]
    assert task_key(t) == task_key(t, code_digest()) != task_key(t, "other code")
    assert task_key(t) != task_key(Task(t.fn, t.spec, 7)) != task_key(Task(t.fn, {"x": 1}, t.seed))


def test_fresh_forgets_the_stored_runs(tmp_path):
    run_sweep(_tasks(2), LocalBackend(1), RunStore(tmp_path))
    assert len(RunStore(tmp_path)) == 2
    store = RunStore(tmp_path, fresh=True)
    assert len(store) == 0 and not (tmp_path / RUNS).exists() and not list((tmp_path / "arrays").glob("*.npz"))


@pytest.mark.parametrize("jobs", [1, 2])
def test_a_task_that_raises_stops_the_sweep_naming_it_and_keeps_the_finished_runs(tmp_path, jobs):
    tasks = [Task(FN, {"x": x, "fail": 3}, 0) for x in range(4)]
    with pytest.raises(SweepFailed, match=r"noisy_task \(x=3, fail=3, seed 0\) failed: ValueError: the planner gave up"):
        run_sweep(tasks, LocalBackend(jobs), RunStore(tmp_path))
    assert {r["x"] for r in RunStore(tmp_path).rows()} <= {0, 1, 2} and len(RunStore(tmp_path)) >= 1


def test_a_result_that_json_cannot_hold_or_that_shadows_the_spec_is_refused():
    from agnav_host.sweep.tasks import plain

    with pytest.raises(TypeError, match="plain values"):
        plain({"x": object()})
    assert plain({"a": (np.float64(1.5), np.int64(2), np.bool_(True))}) == {"a": [1.5, 2, True]}


def test_the_same_task_twice_runs_once(tmp_path):
    marks = tmp_path / "marks"
    marks.mkdir()
    t = Task(FN, {"x": 1, "marks": str(marks)}, 0)
    rows = run_sweep([t, t], LocalBackend(2), RunStore(None))
    assert rows[0] == rows[1] and len(list(marks.iterdir())) == 1


def test_local_workers_never_outnumber_the_runs():
    assert LocalBackend(100_000).workers(3) == 3 and LocalBackend(None).workers(1) == 1
    assert LocalBackend(2).describe(5) == "2 local worker processes"


def test_yard_runs_are_pure_tasks_of_their_spec_and_seed():
    """Two yards, one planner: the rows of one worker and of two are the same."""
    from agnav_host.sweep import yards

    tasks = yards.tasks([3, 4], ["apf"])
    assert [t.spec["yard"] for t in tasks] == [3, 4] and {t.spec["robot"] for t in tasks} == {"diff"}
    one = run_sweep(tasks, LocalBackend(1))
    two = run_sweep(tasks, LocalBackend(2))
    assert all(same_results(a, b) for a, b in zip(one, two))
    assert {r["end"] for r in one} <= {"arrived", "timeout", "collision"} and all(r["planner"] == "apf" for r in one)
    lines = yards.report(one, ["apf"], 3, 2, "diff", 0, False, 2.0)
    assert lines[0].startswith("# 2 random cluttered yards 3-4") and lines[4].startswith("| apf | ")


def test_a_yard_run_does_not_depend_on_how_loaded_the_machine_is(monkeypatch):
    """follow-path's A* checks a 50 ms wall-time backstop every 256 expansions: a starved machine (a clock
    that runs 0.1 s per look) cuts its searches short, and yard 2 then times out; the sweep's runs lift the
    backstop (its 60,000-expansion bound ends a search first), so the row is the calm machine's."""
    import time

    import agnav_host.planning._grid as grid
    from agnav_host.sweep import yards

    task = yards.tasks([2], ["follow-path"])[0]
    calm = run_sweep([task], LocalBackend(1))[0]
    real = time.perf_counter

    def starved():
        ticks = iter(range(10**9))
        monkeypatch.setattr(grid.time, "perf_counter", lambda: 0.1 * next(ticks))
        try:
            return run_sweep([task], LocalBackend(1))[0]
        finally:
            monkeypatch.setattr(grid.time, "perf_counter", real)

    assert same_results(calm, starved()) and calm["end"] == "arrived"
    monkeypatch.setattr(yards, "NO_WALL_BACKSTOPS", {})  # with the robot's backstop the starved run differs
    assert starved()["end"] == "timeout"
