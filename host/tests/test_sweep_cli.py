"""``agnav bench yards|planners|timed|perception``: the options, their errors, stored rows and resuming."""

from __future__ import annotations

import json
import sys

import pytest

from agnav_host.cli import main


def test_yards_stores_each_run_and_a_second_sweep_runs_only_the_new_yards(tmp_path, capsys):
    out = tmp_path / "yards"
    assert main(["bench", "yards", "--yards", "2", "--planners", "apf", "--jobs", "1", "--out", str(out)]) == 0
    first = capsys.readouterr()
    assert "agnav bench: 2 runs on 1 worker(s), rows to" in first.err
    assert "| apf | " in first.out and "# 2 random cluttered yards 0-1" in first.out
    rows = [json.loads(line) for line in (out / "runs.jsonl").read_text().splitlines()]
    assert sorted((r["yard"], r["planner"], r["robot"], r["seed"]) for r in rows) == [(0, "apf", "diff", 0), (1, "apf", "diff", 0)]
    assert main(["bench", "yards", "--yards", "3", "--planners", "apf", "--jobs", "1", "--out", str(out)]) == 0
    again = capsys.readouterr()
    assert "3 runs on 1 worker(s) (2 stored by an earlier run: resuming)" in again.err
    assert len((out / "runs.jsonl").read_text().splitlines()) == 3
    assert main(["bench", "yards", "--yards", "2", "--planners", "apf", "--jobs", "1", "--out", str(out), "--quiet"]) == 0
    table = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("| apf")]
    assert table == [ln for ln in first.out.splitlines() if ln.startswith("| apf")]  # built from the stored rows
    assert main(["bench", "yards", "--yards", "2", "--planners", "apf", "--jobs", "1", "--out", str(out), "--fresh"]) == 0
    assert "resuming" not in capsys.readouterr().err and len((out / "runs.jsonl").read_text().splitlines()) == 2


def test_an_unknown_planner_is_exit_2_listing_the_known_ones(capsys):
    assert main(["bench", "yards", "--planners", "flb,nosuch"]) == 2
    err = capsys.readouterr().err
    assert "unknown planner(s) nosuch; known: " in err and "vfh" in err and "Traceback" not in err


def test_ray_asked_for_without_ray_installed_says_how_to_install_it(monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray raises ImportError
    assert main(["bench", "yards", "--yards", "1", "--planners", "flb", "--ray", "local"]) == 2
    err = capsys.readouterr().err.strip()
    assert err == "agnav bench yards: --ray needs Ray, an optional extra of agnav: pip install agnav[ray]"


@pytest.mark.parametrize("argv, what", [
    (["bench", "planners", "--walkers", "2"], "--walkers is an option of yards, not of planners"),
    (["bench", "yards", "--scenarios", "canyon"], "--scenarios is an option of planners, not of yards"),
    (["bench", "timed", "--robot", "ackermann"], "--robot is an option of yards, not of timed"),
    (["bench", "yards", "--fresh"], "--fresh needs --out"),
    (["bench", "timed", "--multi"], "--multi goes with --sil"),
    (["bench", "perception", "--only", "rows,nosuch"], "--only: unknown part(s) nosuch; known: rows, proximity"),
    (["bench", "perception", "--methods", "nosuch"], "--methods: unknown method(s) nosuch; known: "),
])
def test_an_option_of_another_suite_or_a_bad_value_is_exit_2(argv, what, capsys):
    assert main(argv) == 2
    assert what in capsys.readouterr().err


@pytest.mark.parametrize("argv", [["--yards", "0"], ["--first", "-1"], ["--walkers", "-2"], ["--mover-horizon", "11"],
                                  ["--jobs", "0"], ["--robot", "tank"], ["--seeds", "0"]])
def test_yard_options_out_of_range_are_refused_by_the_parser(argv, capsys):
    with pytest.raises(SystemExit) as e:
        main(["bench", "yards", *argv])
    assert e.value.code == 2 and argv[0] in capsys.readouterr().err


def test_an_out_folder_that_is_a_file_is_exit_1_before_any_run(tmp_path, capsys):
    f = tmp_path / "file"
    f.write_text("x")
    assert main(["bench", "yards", "--yards", "1", "--planners", "flb", "--out", str(f)]) == 1
    assert "is a file, not a folder" in capsys.readouterr().err


def test_perception_runs_through_the_sweep_and_prints_the_scripts_table(tmp_path, capsys):
    """One hole-detection seed... the script's own table, each seed a stored run."""
    out = tmp_path / "p"
    from agnav_host.sweep.scripts import script

    mod = script("bench_perception")
    original = mod.bench_holes
    assert main(["bench", "perception", "--only", "holes", "--no-plot", "--out", str(out), "--quiet", "--jobs", "2"]) == 0
    text = capsys.readouterr().out
    assert "## Holes of ref 000 table 5-I" in text and "| all | | " in text
    rows = [json.loads(line) for line in (out / "runs.jsonl").read_text().splitlines()]
    assert sorted(r["seed"] for r in rows) == [0, 1, 2] and {r["call"] for r in rows} == {"bench_holes"}
    assert mod.bench_holes is original  # the script's own function again afterwards
