"""Input checks and honest output of ``agnav plan``, ``agnav rows`` and ``agnav bench planners``.

Each test pins one audit finding: a bad value refused with the option's name, an impossible plan
reported as such, a scan in the wrong unit or with nothing in it refused or reported, an unwritable
output folder named without a traceback.
"""

import json
import math
from pathlib import Path

import numpy as np
import pytest

from agnav_host.cli import build_parser, main
from agnav_host.scanio import ScanFileError, load_scan_csv

from _scan_files import four_rows_scan_csv

PLAN = ["plan", "--start", "0,0,0", "--goal", "5,0,0"]


def _exit_code(argv: list[str]) -> int:
    """main()'s return value, or the code argparse exits with."""
    try:
        return main(argv)
    except SystemExit as e:
        return int(e.code or 0)


# ---- agnav plan ------------------------------------------------------------------------------------


@pytest.mark.parametrize("opt, val", [
    ("--start-speed", "-1"), ("--start-speed", "nan"), ("--accel", "inf"), ("--accel", "0"),
    ("--samples", "-3"), ("--samples", "0"), ("--samples", "1"), ("--start-steer-deg", "nan"),
    ("--goal-steer-deg", "inf"), ("--arrive-in", "nan"), ("--max-speed", "-2"),
])
def test_plan_refuses_bad_numbers_naming_the_option(opt, val, capsys):
    assert _exit_code(PLAN + [opt, val]) == 2
    err = capsys.readouterr().err
    assert opt in err and val in err


@pytest.mark.parametrize("opt, val, limit", [
    ("--start-steer-deg", "1000", "20"), ("--start-steer-deg", "-25", "20"), ("--goal-steer-deg", "18", "17"),
])
def test_plan_steering_beyond_the_limit_names_option_and_limit(opt, val, limit, capsys):
    assert main(PLAN + [opt, val]) == 2
    err = capsys.readouterr().err
    assert opt in err and f"+-{limit} deg" in err
    assert "the path needs" not in err


def test_plan_start_speed_above_max_speed_refused(capsys):
    assert main(PLAN + ["--start-speed", "3", "--max-speed", "2"]) == 2
    assert "--start-speed 3 m/s is above --max-speed 2 m/s" in capsys.readouterr().err


def test_plan_steering_within_the_limit_still_plans(capsys):
    assert main(PLAN + ["--start-steer-deg", "-19", "--goal-steer-deg", "17", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["feasible"] is True


def test_plan_help_gives_units_defaults_and_exit_codes(capsys):
    with pytest.raises(SystemExit) as e:
        main(["plan", "--help"])
    assert e.value.code == 0
    text = " ".join(capsys.readouterr().out.split())  # argparse wraps lines
    assert "3 = not feasible" in text and "0 = feasible" in text
    assert "cruise speed 0.8 m/s" in text
    parser = build_parser()
    sub = next(a for a in parser._actions if a.choices and "plan" in a.choices).choices["plan"]
    numeric = [a for a in sub._actions if a.type is not None and a.dest not in ("start", "goal")]
    assert len(numeric) == 9
    for a in numeric:
        assert "default" in a.help, a.dest
        assert any(u in a.help for u in (", s,", ", deg,", ", m/s", "N >= 2")), a.dest


def test_plan_goal_behind_with_same_heading_is_a_forward_loop(capsys):
    rc = main(["plan", "--start", "0,0,0", "--goal", "-5,0,0", "--samples", "6", "--json"])
    out = json.loads(capsys.readouterr().out)
    assert rc == 0 and out["feasible"] is True
    assert out["reverse_m"] == 0.0 and out["path_type"].split()[0] in ("dubins", "clothoid")
    assert out["path_length_m"] > 5.0  # it drives round, forward only


def test_plan_start_equal_to_goal_text_output_gives_the_reason(capsys):
    assert main(["plan", "--start", "0,0,0", "--goal", "0,0,0"]) == 2
    err = capsys.readouterr().err
    assert "agnav plan" in err and "Traceback" not in err


@pytest.mark.parametrize("goal", ["5,0,180", "-1,0,0"])
def test_plan_turning_round_is_a_drivable_loop_not_an_in_place_turn(goal, capsys):
    rc = main(["plan", "--start", "0,0,0", "--goal", goal, "--samples", "400", "--json"])
    out = json.loads(capsys.readouterr().out)
    assert rc == 0 and out["feasible"] is True
    assert out["path_type"].split()[0] in ("dubins", "clothoid")  # a loop of the car's own path family
    assert 0.0 < out["max_steering_deg"] <= out["steering_limit_deg"]
    s = np.array(out["samples"])
    yaw = np.unwrap(np.radians(s[:, 3]))
    step = np.hypot(np.diff(s[:, 1]), np.diff(s[:, 2]))
    # the heading turns continuously at no more than the steering limit's curvature (+ sampling slack)
    kappa_max = math.tan(math.radians(out["steering_limit_deg"])) / 0.174
    assert np.all(np.abs(np.diff(yaw)) <= kappa_max * step + math.radians(2.0))
    assert abs(yaw[-1] - yaw[0]) > math.radians(170)  # it did turn round, by driving


def test_plan_samples_end_at_rest_on_the_goal(capsys):
    assert main(PLAN + ["--samples", "6", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    t, x, y, yaw, v, steer = out["samples"][-1]
    assert (x, y) == (pytest.approx(5.0, abs=1e-3), pytest.approx(0.0, abs=1e-3))
    assert v == 0.0 and yaw == 0.0
    assert t == pytest.approx(out["rest_s"]) and out["rest_s"] > out["duration_s"]
    assert out["samples"][0][:5] == [0.0, 0.0, 0.0, 0.0, 0.0]


def test_plan_samples_text_says_arrival_and_rest(capsys):
    assert main(PLAN + ["--samples", "3"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert any("at rest on the goal at" in ln for ln in lines)
    assert "x=   5.000" in lines[-1] and "v= 0.000" in lines[-1]


# ---- agnav rows / scanio ---------------------------------------------------------------------------


@pytest.fixture(scope="module")
def rows_scan(tmp_path_factory) -> Path:
    return four_rows_scan_csv(tmp_path_factory.mktemp("scan"))


def _write(path: Path, angles, ranges, meta: str = "") -> Path:
    lines = ["# agnav-scan v1"] + ([f"# {meta}"] if meta else []) + ["angle_rad,range_m"]
    lines += [f"{float(a)!r},{float(r)!r}" for a, r in zip(angles, ranges)]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def test_rows_refuses_angles_in_degrees_naming_the_line(tmp_path, capsys):
    f = _write(tmp_path / "sc_deg.csv", np.linspace(-135.0, 135.0, 271), np.full(271, 1.0))
    assert main(["rows", "--scan", str(f), "--json"]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert f"{f}:3:" in captured.err and "degrees" in captured.err


def test_scanio_refuses_an_angle_span_wider_than_a_turn(tmp_path):
    f = _write(tmp_path / "wide.csv", np.linspace(-4.0, 4.0, 81), np.full(81, 1.0))
    with pytest.raises(ScanFileError, match=r"wide.csv:83: the angles span 8 rad.*degrees"):
        load_scan_csv(f)


@pytest.mark.parametrize("meta, match", [
    ("range_max_m=-3", r":2: metadata range_max_m must be > 0, got -3"),
    ("range_max_m=0", r":2: metadata range_max_m must be > 0"),
    ("range_max_m=nan", r":2: metadata range_max_m must be > 0"),
    ("range_min_m=2,range_max_m=1", r"range_max_m must be > range_min_m \(2\), got 1"),
])
def test_scanio_refuses_bad_range_limits(tmp_path, meta, match):
    f = _write(tmp_path / "r.csv", [0.0, 0.1, 0.2], [1.0, 1.0, 1.0], meta)
    with pytest.raises(ScanFileError, match=match):
        load_scan_csv(f)


def test_rows_refuses_negative_range_max(tmp_path, capsys):
    f = _write(tmp_path / "neg.csv", [0.0, 0.1, 0.2], [1.0, 1.0, 1.0], "range_max_m=-3")
    assert main(["rows", "--scan", str(f)]) == 2
    assert "range_max_m must be > 0" in capsys.readouterr().err


@pytest.mark.parametrize("val, msg", [("75", "row spacing is in metres"), ("0", "must be > 0"),
                                      ("-1", "must be > 0"), ("nan", "finite")])
def test_rows_spacing_checked(rows_scan, val, msg, capsys):
    assert _exit_code(["rows", "--scan", str(rows_scan), "--spacing", val]) == 2
    err = capsys.readouterr().err
    assert "--spacing" in err and msg in err


def test_rows_plausible_spacing_still_accepted(rows_scan, capsys):
    assert main(["rows", "--scan", str(rows_scan), "--spacing", "0.8", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["confidence"] > 0.0


def test_rows_accepts_a_scan_with_a_utf8_bom(rows_scan, tmp_path, capsys):
    bom = tmp_path / "excel.csv"
    bom.write_bytes(b"\xef\xbb\xbf" + rows_scan.read_bytes())
    assert main(["rows", "--scan", str(rows_scan), "--json"]) == 0
    plain = json.loads(capsys.readouterr().out)
    assert main(["rows", "--scan", str(bom), "--json"]) == 0
    assert json.loads(capsys.readouterr().out) == plain
    assert load_scan_csv(bom).range_max_m == load_scan_csv(rows_scan).range_max_m


def test_rows_all_nan_scan_says_nothing_was_measured(tmp_path, capsys):
    f = _write(tmp_path / "nan.csv", np.linspace(-2.0, 2.0, 100), [math.nan] * 100)
    assert main(["rows", "--scan", str(f), "--json"]) == 3
    captured = capsys.readouterr()
    out = json.loads(captured.out)
    assert out == {"lateral_offset_m": None, "heading_rad": None, "row_spacing_m": None, "confidence": 0.0,
                   "end_of_row": None}
    assert "no usable return" in captured.err
    assert main(["rows", "--scan", str(f)]) == 3
    captured = capsys.readouterr()
    assert captured.out == "" and "nothing measured" in captured.err


def test_rows_no_rows_found_is_not_printed_as_a_measurement(tmp_path, capsys):
    # returns, but no rows: one wall far to the left
    a = np.linspace(-2.0, 2.0, 201)
    r = np.where(a > 1.0, 3.0 / np.sin(np.clip(a, 1.0, None)), math.nan)
    f = _write(tmp_path / "wall.csv", a, r)
    assert main(["rows", "--scan", str(f)]) == 0
    out = capsys.readouterr().out
    assert "no rows found" in out and "offset" not in out


def test_rows_help_documents_the_exit_codes(capsys):
    with pytest.raises(SystemExit):
        main(["rows", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "3 = no usable return in the scan" in text and "2 = a bad option or scan file" in text


# ---- agnav bench planners --------------------------------------------------------------------------


@pytest.fixture
def no_run(monkeypatch):
    """Replace the (minutes-long) suite run by an empty one; records the calls."""
    import agnav_host.planning.bench as bench

    calls: list[object] = []
    monkeypatch.setattr(bench, "run_suite", lambda suite, *a, **k: calls.append(suite) or [])
    return calls


def test_bench_unwritable_out_is_one_line_exit_1(tmp_path, no_run, capsys):
    blocker = tmp_path / "a_file"
    blocker.write_text("x")
    out = blocker / "results"
    rc = main(["bench", "planners", "--out", str(out), "--scenarios", "canyon", "--planners", "flb", "--seeds", "1",
               "--quiet", "--no-plot"])
    assert rc == 1
    err = capsys.readouterr().err
    assert str(out) in err and "Traceback" not in err
    assert no_run == []  # refused before the run


@pytest.mark.skipif(not Path("/proc/self").exists(), reason="needs /proc")
def test_bench_out_under_proc(no_run, capsys):
    assert main(["bench", "planners", "--out", "/proc/x", "--scenarios", "canyon", "--planners", "flb", "--seeds", "1",
                 "--quiet", "--no-plot"]) == 1
    assert "/proc/x" in capsys.readouterr().err


@pytest.mark.parametrize("val", ["0", "-1"])
def test_bench_seeds_must_be_positive(val, no_run, capsys):
    assert _exit_code(["bench", "planners", "--seeds", val, "--quiet"]) == 2
    assert "--seeds" in capsys.readouterr().err
    assert no_run == []


def test_bench_seeds_keeps_the_first_n(tmp_path, no_run, capsys):
    assert main(["bench", "planners", "--out", str(tmp_path / "o"), "--scenarios", "canyon", "--planners", "flb",
                 "--seeds", "2", "--quiet", "--no-plot"]) == 0
    (suite,) = no_run
    assert [(c.scenario, c.planners, c.seeds) for c in suite] == [("canyon", ("flb",), (0, 1))]


def test_bench_unknown_planner_is_named_with_the_known_ones(no_run, capsys):
    assert main(["bench", "planners", "--planners", "nosuch,flb", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "unknown planner entry nosuch" in err and "flb@0.3" in err and "him" in err
    assert "nothing to run" not in err and no_run == []


# A10 (CLI audit): empty filters are an error; a subset run never replaces the default folder's full tables
# (an empty value, "--planners ''", is refused by argparse as every empty text option is: test_cli_typed_values.py)
@pytest.mark.parametrize("opt, val", [("--scenarios", ","), ("--planners", " "), ("--planners", ",,")])
def test_bench_empty_filter_is_an_error(opt, val, tmp_path, no_run, capsys):
    assert main(["bench", "planners", "--out", str(tmp_path / "o"), opt, val, "--quiet", "--no-plot"]) == 2
    err = capsys.readouterr().err.strip()
    assert err == f"agnav bench: {opt} {val!r} names nothing; leave the option out to run the whole suite"
    assert no_run == []


@pytest.mark.parametrize("subset", [["--scenarios", "canyon"], ["--planners", "him"], ["--seeds", "1"]])
def test_bench_subset_needs_its_own_out(subset, tmp_path, no_run, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["bench", "planners", *subset, "--quiet", "--no-plot"]) == 2
    err = capsys.readouterr().err.strip()
    assert "a subset run (--scenarios, --planners or --seeds) needs --out" in err and "bench/results/planners" in err
    assert no_run == [] and not (tmp_path / "bench").exists()


def test_bench_explicit_out_replaces_an_earlier_runs_tables_and_plots(tmp_path, no_run, capsys):
    out = tmp_path / "copy"
    out.mkdir()
    for name in ("runs.csv", "summary.csv", "planners.md", "paths_canyon.png", "speed_him_wall.png",
                 "curvature_flb_setup1.png"):
        (out / name).write_text("full run")
    (out / "notes.md").write_text("mine")
    assert main(["bench", "planners", "--out", str(out), "--scenarios", "canyon", "--planners", "him", "--seeds", "1",
                 "--no-plot"]) == 0
    assert "removed the earlier run's runs.csv, summary.csv, planners.md" in capsys.readouterr().err
    assert sorted(p.name for p in out.iterdir()) == ["notes.md", "planners.md", "runs.csv", "summary.csv"]
    assert "full run" not in (out / "runs.csv").read_text()


# B1 (CLI audit): --samples has an upper bound, refused by argparse before any planning
@pytest.mark.parametrize("val", ["100001", "10000000", "1000000000"])
def test_plan_samples_has_an_upper_bound(val, capsys):
    assert _exit_code(["plan", "--start", "0,0,0", "--goal", "3,5,90", "--samples", val]) == 2
    assert f"argument --samples: must be 2..100000, got '{val}'" in capsys.readouterr().err


def test_bench_says_at_once_what_is_under_way(tmp_path, no_run, capsys):
    """The progress bar moves only when a run ends (a minute or more on a slow planner): a line first."""
    out = tmp_path / "o"
    assert main(["bench", "planners", "--out", str(out), "--scenarios", "canyon", "--planners", "him,flb", "--seeds", "2",
                 "--jobs", "1", "--no-plot"]) == 0
    assert f"agnav bench: 4 runs on 1 worker(s), results to {out}" in capsys.readouterr().err
    assert main(["bench", "planners", "--out", str(out), "--scenarios", "canyon", "--planners", "him", "--seeds", "1",
                 "--quiet", "--no-plot"]) == 0
    assert "runs on" not in capsys.readouterr().err


def test_bench_never_starts_more_workers_than_runs(monkeypatch, tmp_path, capsys):
    """``--jobs 100000`` starts two processes for a two-run subset, not that many."""
    import concurrent.futures as cf

    import agnav_host.planning.bench as bench

    pools: list[int] = []

    class Recording(cf.ProcessPoolExecutor):  # records how many workers were asked for
        def __init__(self, n, **kw):
            pools.append(n)
            super().__init__(n, **kw)

    def fake_run(job, *params):  # the forked workers run this stand-in for the (minutes-long) simulation
        scenario, planner, seed = job
        return {"scenario": scenario, "planner": planner, "seed": seed, "end": "arrived", "step_median_ms": 0.0,
                "step_p95_ms": 0.0, "wall_s": 0.0, "traj": np.zeros((2, 4)), "kappa": np.zeros(1)}

    monkeypatch.setattr(cf, "ProcessPoolExecutor", Recording)
    monkeypatch.setattr(bench, "run_case", fake_run)
    out = bench.run_suite([bench.BenchCase("canyon", ("flb",), (0, 1), "test")], processes=100_000)
    assert pools == [2] and [(r["scenario"], r["planner"], r["seed"]) for r in out] == [("canyon", "flb", 0), ("canyon", "flb", 1)]
    monkeypatch.setattr(bench, "run_suite", lambda *a, **k: [])
    main(["bench", "planners", "--out", str(tmp_path / "o"), "--scenarios", "canyon", "--planners", "flb",
          "--seeds", "2", "--jobs", "100000", "--no-plot"])
    assert "2 runs on 2 worker(s)" in capsys.readouterr().err


@pytest.mark.parametrize("args, opt", [(["--arrive-in", "1e300"], "--arrive-in"), (["--arrive-in", "86401"], "--arrive-in"),
                                       (["--goal", "3e300,2,0"], "--goal"), (["--start", "0,-1e6,0"], "--start")])
def test_plan_refuses_times_and_places_beyond_a_field_robot(args, opt, capsys):
    """Refused naming the option, not printed as 300-digit durations and distances."""
    base = {"--start": "0,0,0", "--goal": "3,2,0"}
    for k, v in zip(args[::2], args[1::2]):
        base[k] = v
    argv = ["plan"] + [x for kv in base.items() for x in kv] + ([] if "--arrive-in" in base else ["--arrive-in", "20"])
    assert _exit_code(argv) == 2
    err = capsys.readouterr().err
    assert f"argument {opt}:" in err and len(err) < 450


def test_plan_takes_a_day_and_100_km():
    assert main(["plan", "--start", "0,0,0", "--goal", "-100000,5,90", "--arrive-in", "86400"]) in (0, 3)
