"""Findings of the CLI audit of bad and unusual input (2026-11-24): each test is one finding (A1, A2, ...),
the command a user typed and what must happen instead of a traceback, a lost run or silent data loss."""

from __future__ import annotations

from pathlib import Path

import pytest

from agnav_host import cli
from _cli_helpers import _no_user_config, nowhere  # noqa: F401 (the fixture is autouse)

UNWRITABLE_DIR = "/proc"  # exists, takes no new files (even for root)
FAST_CAL = ["--settle-s", "0.1", "--hold-s", "0.25", "--max-step-s", "1"]


# ---- A1: calibrate --plot-dir ---------------------------------------------------------------------------
def test_calibrate_unwritable_plot_dir_refused_before_connecting(capsys):
    bad = f"{UNWRITABLE_DIR}/plots"
    assert cli.main(["calibrate", "steering", "--device", nowhere(), "--no-tlog", "--yes", "--plot-dir", bad]) == 1
    err = capsys.readouterr().err
    assert f"agnav calibrate: --plot-dir {bad}: cannot write there:" in err
    assert "could not open" not in err and "Traceback" not in err and len(err.strip().splitlines()) == 1


def test_calibrate_plot_failure_after_the_sweep_keeps_and_writes_the_table(tmp_path, capsys, monkeypatch):
    from agnav_host.calibration import plot
    from agnav_host.link.fake import FakeRobot

    def fails(fit, path, previous=None, title=None):  # the folder made read-only during the sweep
        raise PermissionError(1, "Operation not permitted", str(Path(path).parent))

    monkeypatch.setattr(plot, "plot_fit", fails)
    cfg = tmp_path / "host.toml"
    cfg.write_text("[calibration]\nsteer_step = 25\npause_s = 0.05\n")
    with FakeRobot(rate_scale=4) as fr:
        rc = cli.main(["calibrate", "steering", "--device", fr.device, "--config", str(cfg), "--no-tlog", "--yes",
                       "--no-save", "--plot-dir", str(tmp_path / "plots")] + FAST_CAL)
        cap = capsys.readouterr()
        assert rc == 0, cap.err
        assert fr.received_of("AGNAV_CALIB_TABLE")  # the fit reached the robot
    assert "warning: fit plot not written" in cap.out and "Operation not permitted" in cap.out
    assert "the fitted table is kept" in cap.out and "written and verified" in cap.out
    assert "Traceback" not in cap.err


# ---- scenario files (A2-A6) ------------------------------------------------------------------------------
SMALL = """[scenario]
name = "t"
duration_s = 5.0

[robot]
model = "diff_drive"
start = { x_m = 0.0, y_m = 0.0, yaw_deg = 0.0 }

[laser]
model = "tim561"

[[goals]]
x_m = 3.0
y_m = 0.0
"""


def sim_refused(capsys, tmp_path: Path, scenario: Path, *extra: str) -> str:
    """Run ``agnav sim scenario`` expecting a clean exit 2 before the run; return the one error line."""
    out = tmp_path / "out"
    rc = cli.main(["sim", str(scenario), "--duration", "1", "--quiet", "--no-plot", "--no-rrd", "--out", str(out), *extra])
    cap = capsys.readouterr()
    assert rc == 2, cap.err
    assert "Traceback" not in cap.err and len(cap.err.strip().splitlines()) == 1, cap.err
    assert not out.exists() or not any(out.iterdir())
    return cap.err.strip()


# A2: a scenario file that is not UTF-8
@pytest.mark.parametrize("body, line, what", [
    (SMALL.replace('"t"', '"caf\u00e9"').encode("latin-1"), 2, "not UTF-8 text (byte 0xe9)"),
    (SMALL.encode("utf-16"), 1, "UTF-16 text"),
    (b"\x00\x17\x80garbage\n", 1, "not UTF-8 text (byte 0x80)"),
    (SMALL.encode() + b"# r\xe9sum\xe9\n", SMALL.count("\n") + 1, "not UTF-8 text (byte 0xe9)"),
])
def test_sim_and_sil_name_a_scenario_file_that_is_not_utf8(tmp_path, capsys, body, line, what):
    f = tmp_path / "bad.toml"
    f.write_bytes(body)
    err = sim_refused(capsys, tmp_path, f)
    assert err == f"agnav sim: {f}:{line}: cannot read scenario file: {what}; save it as UTF-8"
    assert cli.main(["sil", str(f), "--duration", "1", "--tcp", "tcp:127.0.0.1:0"]) == 2
    assert capsys.readouterr().err.strip() == err.replace("agnav sim", "agnav sil")


def test_sim_accepts_a_scenario_with_a_utf8_bom(tmp_path, capsys):
    f = tmp_path / "bom.toml"
    f.write_bytes(b"\xef\xbb\xbf" + SMALL.encode())
    assert cli.main(["sim", str(f), "--duration", "1", "--quiet", "--no-plot", "--no-rrd", "--out", str(tmp_path / "o")]) == 0


# A3, A4, A5: [meta] path / landmarks, [[weeds]] region, bounds: refused when the file is loaded, with file:line
_N = SMALL.count("\n")


@pytest.mark.parametrize("extra, line, field, why", [
    ('[meta]\npath = "abc"\n', _N + 2, "meta.path", "must be a list of at least 2 [x_m, y_m] points"),
    ("[meta]\npath = [[0, 0], [1]]\n", _N + 2, "meta.path[1]", "must be a [x_m, y_m] pair of numbers, got [1]"),
    ("[meta]\npath = [[0, 0], [1, inf]]\n", _N + 2, "meta.path[1]", "must be a [x_m, y_m] pair of numbers"),
    ('[meta]\nlandmarks = "abc"\n', _N + 2, "meta.landmarks", "must be a list of [x_m, y_m, radius_m] rows"),
    ("[meta]\nlandmarks = [[1, 2]]\n", _N + 2, "meta.landmarks[0]", "must be a [x_m, y_m, radius_m] row of finite"),
    ("[meta]\nlandmarks = [[1, 2, 0.1], [1, nan, 0.1]]\n", _N + 2, "meta.landmarks[1]", "row of finite numbers"),
    ("[meta]\nlandmarks = [[1, 2, 0]]\n", _N + 2, "meta.landmarks[0]", "radius_m > 0"),
    ("[[weeds]]\nregion = [0, 0, inf, 1]\n", _N + 2, "weeds[0].region", "finite numbers with min < max"),
])
def test_malformed_scenario_entries_are_refused_at_load_time(tmp_path, capsys, extra, line, field, why):
    f = tmp_path / "s.toml"
    f.write_text(SMALL + extra)
    err = sim_refused(capsys, tmp_path, f)
    assert err.startswith(f"agnav sim: {f}:{line}: {field}: ") and why in err, err


@pytest.mark.parametrize("bounds", ["[-inf, -inf, inf, inf]", "[true, 0, 5, 5]", "[0, 0, 5, nan]"])
def test_scenario_bounds_must_be_finite_numbers(tmp_path, capsys, bounds):
    f = tmp_path / "s.toml"
    f.write_text(SMALL.replace("duration_s = 5.0\n", f"duration_s = 5.0\nbounds = {bounds}\n"))
    err = sim_refused(capsys, tmp_path, f)
    assert err.startswith(f"agnav sim: {f}:4: scenario.bounds: must be [xmin_m, ymin_m, xmax_m, ymax_m], finite"), err


def test_malformed_landmarks_refused_before_a_firmware_in_the_loop_run(tmp_path, capsys):
    f = tmp_path / "s.toml"
    f.write_text(SMALL + '[meta]\nlandmarks = "abc"\n')
    assert "meta.landmarks: must be" in sim_refused(capsys, tmp_path, f, "--firmware", "sil")


def test_well_formed_meta_path_and_landmarks_still_run(tmp_path, capsys):
    f = tmp_path / "s.toml"
    f.write_text(SMALL + "[meta]\npath = [[0, 0], [3, 0]]\nlandmarks = [[1, 2, 0.08]]\n")
    assert cli.main(["sim", str(f), "--planner", "follow-path", "--duration", "1", "--quiet", "--no-plot", "--no-rrd",
                     "--out", str(tmp_path / "o")]) == 0


# A6: huge durations, tiny steps, dense plants, many weeds: refused before anything is allocated
def test_sim_duration_beyond_the_step_limit_is_refused_before_the_run(tmp_path, capsys):
    out = tmp_path / "out"
    assert cli.main(["sim", "canyon", "--duration", "1e7", "--no-plot", "--no-rrd", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("agnav sim: --duration 1e+07: ") and "5e+08 physics steps (29.8 GiB of trajectory)" in err
    assert "at most 2000000 steps: --duration <= 40000 s" in err and not out.exists()


@pytest.mark.parametrize("edit, line, field, why", [
    (("duration_s = 5.0\n", "duration_s = 5.0\ndt_s = 1e-9\ncontrol_hz = 1\n"), 4, "scenario.dt_s", "5e+09 physics steps"),
    (("duration_s = 5.0\n", "duration_s = 1e9\n"), 3, "scenario.duration_s", "at most 2000000 steps"),
    (("", "[[rows]]\npoints = [[0, 2], [5, 2]]\nplant_spacing_m = 1e-9\n"), _N + 3, "rows[0].plant_spacing_m",
     "1.5e+10 obstacle circles"),
    (("", "[[weeds]]\nregion = [0, 0, 1, 1]\ncount = 1000000000\n"), _N + 3, "weeds[0].count",
     "this many weeds would make 1e+09 obstacle circles; at most 1000000"),
])
def test_scenario_sizes_beyond_the_limits_are_refused_at_load_time(tmp_path, capsys, edit, line, field, why):
    f = tmp_path / "s.toml"
    old, new = edit
    f.write_text(SMALL.replace(old, new, 1) if old else SMALL + new)
    err = sim_refused(capsys, tmp_path, f)
    assert err.startswith(f"agnav sim: {f}:{line}: {field}: ") and why in err, err


def test_run_scenario_refuses_a_run_beyond_the_step_limit():
    from agnav_host.sim.runner import run_scenario
    from agnav_host.sim.scenario import load_scenario

    with pytest.raises(ValueError, match="at most 2000000 steps"):
        run_scenario(load_scenario("canyon"), duration_s=1e9)


# ---- A7: faults --markdown checked before the cases run --------------------------------------------------
@pytest.fixture
def no_fault_run(monkeypatch):
    """agnav faults without running any case: records the calls, returns no rows."""
    import agnav_host.faults as faults

    calls: list[int] = []
    monkeypatch.setattr(faults, "run_cases", lambda cases, progress=None: calls.append(1) or [])
    return calls


def test_faults_markdown_that_cannot_be_written_is_refused_before_the_cases(tmp_path, capsys, no_fault_run):
    (tmp_path / "afile").write_text("x")
    for bad, why in ((f"{UNWRITABLE_DIR}/faults.md", "does not take new files"), (str(tmp_path), "it is a directory"),
                     (str(tmp_path / "afile" / "x.md"), "is not a directory")):
        assert cli.main(["faults", "--only", "corrupt scenario", "--quiet", "--markdown", bad]) == 2
        cap = capsys.readouterr()
        assert cap.err.strip().startswith(f"agnav faults: --markdown {bad}: cannot write there:") and why in cap.err
        assert len(cap.err.strip().splitlines()) == 1 and cap.out == ""
    assert not no_fault_run
    ok = tmp_path / "new" / "faults.md"
    assert cli.main(["faults", "--only", "corrupt scenario", "--quiet", "--markdown", str(ok)]) == 0
    assert no_fault_run and ok.is_file()


def test_faults_markdown_failing_after_the_run_is_one_line(tmp_path, capsys, monkeypatch, no_fault_run):
    def full(self, *a, **k):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(Path, "write_text", full)
    assert cli.main(["faults", "--only", "corrupt scenario", "--quiet", "--markdown", str(tmp_path / "f.md")]) == 1
    err = capsys.readouterr().err.strip()
    assert err == f"agnav faults: --markdown {tmp_path / 'f.md'}: could not write the table (printed above): " \
                  "No space left on device"


def test_fault_suite_sends_a_scenario_that_is_really_not_utf8():
    from agnav_host.faults.host_faults import _case_corrupt_scenarios

    out = _case_corrupt_scenarios()
    assert out.passed, out.measured
    assert "not UTF-8 (Latin-1): exit 2" in out.measured and "cannot read scenario file: not UTF-8" in out.measured


# ---- A8: sim --out reused: the earlier run's files go, link.rrd only from this run's link.tlog ---------------
def test_sim_out_reused_removes_the_earlier_runs_files(tmp_path, capsys):
    out = tmp_path / "mix"
    out.mkdir()
    for name in ("summary.json", "run_info.json", "trajectory.csv", "trajectory.png", "recording.rrd", "link.tlog",
                 "firmware.csv", "link.rrd"):  # as a firmware-in-the-loop run of another scenario left them
        (out / name).write_text("stale")
    (out / "notes.txt").write_text("mine")
    assert cli.main(["sim", "canyon", "--duration", "1", "--no-plot", "--out", str(out)]) == 0
    cap = capsys.readouterr()
    for name in ("link.tlog", "firmware.csv", "link.rrd", "trajectory.png"):  # not written by an ideal --no-plot run
        assert not (out / name).exists(), name
    assert (out / "notes.txt").read_text() == "mine"  # not a file sim writes: left alone
    assert "canyon" in (out / "run_info.json").read_text()
    assert "link.rrd" not in cap.out
    assert f"agnav sim: --out {out}: removed the earlier run's summary.json" in cap.err


def test_sim_firmware_in_the_loop_still_records_its_own_link_tlog(tmp_path, capsys):
    pytest.importorskip("rerun")
    out = tmp_path / "sil"
    assert cli.main(["sim", "--firmware", "sil", "--duration", "1", "--quiet", "--no-plot", "--out", str(out)]) == 0
    assert f"wrote {out / 'link.rrd'}" in capsys.readouterr().out
    assert (out / "link.tlog").stat().st_size > 0 and (out / "link.rrd").stat().st_size > 0


# ---- A9: rows: a misspelt key on a scan's metadata line ---------------------------------------------------
def _scan(path: Path, meta: str) -> Path:
    n = 271
    lines = ["# agnav-scan v1", meta, "angle_rad,range_m"]
    lines += [f"{-2.35 + 4.7 * i / (n - 1)!r},1.5" for i in range(n)]
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.parametrize("meta, why", [
    ("# stamp_s=1.0,range_mx_m=1.0", "unknown metadata key 'range_mx_m'; did you mean range_max_m? known: pose_x_m,"),
    ("# stamp_s=1.0,operator=Anna", "unknown metadata key 'operator'; known: pose_x_m, pose_y_m, pose_yaw_rad, "
                                    "range_max_m, range_min_m, stamp_s"),
    ("# range_max=1.0", "unknown metadata key 'range_max'; did you mean range_max_m?"),
    ("# range_max_m: 1.0", "metadata is written key=value (range_max_m=...), got 'range_max_m: 1.0'"),
])
def test_rows_refuses_an_unknown_or_misspelt_metadata_key_naming_the_line(tmp_path, capsys, meta, why):
    f = _scan(tmp_path / "s.csv", meta)
    assert cli.main(["rows", "--scan", str(f)]) == 2
    err = capsys.readouterr().err.strip()
    assert err == f"agnav rows: {f}:2: {why}" or err.startswith(f"agnav rows: {f}:2: {why}"), err


def test_rows_free_text_comments_and_good_metadata_still_read(tmp_path, capsys):
    from agnav_host.scanio import load_scan_csv

    assert load_scan_csv(_scan(tmp_path / "a.csv", "# operator=Anna, left row")).range_max_m == float("inf")
    assert load_scan_csv(_scan(tmp_path / "b.csv", "# stamp_s=1.0,range_max_m=1.0")).range_max_m == 1.0
    assert cli.main(["rows", "--scan", str(tmp_path / "b.csv")]) == 3  # nothing within the 1 m limit
    assert "in 0.05..1 m" in capsys.readouterr().err


# ---- A11: output piped into a reader that stops early (`| head -1`) -------------------------------------
def _tlog(path: Path) -> Path:
    from agnav_host.link.tlog import TlogWriter
    from agnav_host.protocol import dialect

    d = dialect()
    robot = d.MAVLink(None, srcSystem=1, srcComponent=1)
    with TlogWriter(path) as w:
        for i in range(11):
            w.write(robot.heartbeat_encode(d.MAV_TYPE_GROUND_ROVER, 0, 0, 0, 4).pack(robot), 1.7e9 + 0.1 * i)
    return path


@pytest.mark.parametrize("argv", [["scenarios"], ["planners"], ["plan", "--start", "0,0,0", "--goal", "3,5,90",
                                                                 "--samples", "2000"], ["replay", "TLOG"]])
def test_a_closed_output_pipe_ends_the_command_quietly(tmp_path, argv):
    import subprocess
    import sys

    argv = [str(_tlog(tmp_path / "r.tlog")) if a == "TLOG" else a for a in argv]
    p = subprocess.Popen([sys.executable, "-m", "agnav_host.cli", *argv], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE)
    p.stdout.close()  # the reader is gone before the command writes a byte: every write meets a closed pipe
    err = p.stderr.read().decode()
    assert p.wait(timeout=120) == 141  # cli.EXIT_BROKEN_PIPE: as if killed by SIGPIPE
    assert err == "", err


# ---- B3, B4: options between positionals, negative values after abbreviated options and as positionals ----
def _parse(argv: list[str]):
    parser = cli.build_parser()
    return parser.parse_args(cli._join_negative_values(argv, cli._value_options(parser)))


def test_param_takes_options_between_its_positionals_against_the_fake_robot(capsys):
    from agnav_host.link.fake import FakeRobot

    with FakeRobot() as fr:
        assert cli.main(["param", "set", "GOAL_TOL_MM", "--device", fr.device, "--no-tlog", "150"]) == 0
        assert fr.params["GOAL_TOL_MM"] == 150
        assert cli.main(["param", "get", "--device", fr.device, "--wait", "2", "--no-tlog", "GOAL_TOL_MM"]) == 0
    assert "GOAL_TOL_MM 150" in capsys.readouterr().out


@pytest.mark.parametrize("argv, dest, value", [
    (["param", "set", "AVOID_WAIT_MS", "-1e3", "--device", "tcp:h:1"], "value", "-1e3"),
    (["param", "set", "AVOID_WAIT_MS", "--device", "tcp:h:1", "-1e3"], "value", "-1e3"),
    (["param", "set", "AVOID_WAIT_MS", "-inf"], "value", "-inf"),
    (["plan", "--start", "0,0,0", "--goal", "3,5,90", "--start-steer", "-1e-3"], "start_steer_deg", -1e-3),
    (["rows", "--scan", "s.csv", "--mou", "-0.2,0.1,-5"], "mount", None),
    (["sim", "--out", "o", "--go", "-3,1"], "goal", (-3.0, 1.0, None)),
])
def test_negative_values_after_abbreviated_options_and_as_positionals(argv, dest, value):
    got = getattr(_parse(argv), dest)
    assert got is not None and (value is None or got == value), got


@pytest.mark.parametrize("goal, why", [("-3,abc,90", "pose must contain numbers, got '-3,abc,90'"),
                                       ("-3,5,90,", "pose must be X,Y,HEADING_DEG, got '-3,5,90,'"),
                                       ("-3,,90", "pose must contain numbers, got '-3,,90'")])
def test_a_malformed_negative_list_gets_the_options_own_message(capsys, goal, why):
    with pytest.raises(SystemExit) as e:
        cli.main(["plan", "--start", "0,0,0", "--goal", goal])
    assert e.value.code == 2
    assert f"agnav plan: error: argument --goal: {why}" in capsys.readouterr().err


def test_stray_arguments_are_named_with_the_subcommands_usage(capsys):
    with pytest.raises(SystemExit) as e:
        cli.main(["param", "set", "A", "1", "2", "--device", nowhere()])
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert "usage: agnav param" in err and "agnav param: error: unrecognized arguments: 2" in err


# ---- B7: replay counts the bytes it could not decode, and refuses a file that is mostly not MAVLink -------
def test_replay_says_how_much_of_the_file_was_skipped(tmp_path, capsys):
    import numpy as np

    good = _tlog(tmp_path / "good.tlog")
    assert cli.main(["replay", str(good)]) == 0
    assert "could not be decoded" not in capsys.readouterr().out
    damaged = tmp_path / "damaged.tlog"
    raw = good.read_bytes()
    damaged.write_bytes(raw + bytes(40))  # a tail of zeros, as a log cut short by a crash can end
    assert cli.main(["replay", str(damaged)]) == 0
    assert f"40 B of {len(raw) + 40} (" in capsys.readouterr().out
    noise = tmp_path / "random.tlog"
    noise.write_bytes(np.random.default_rng(3).bytes(100_000))
    rc = cli.main(["replay", str(noise)])
    cap = capsys.readouterr()
    assert rc == 2 and "Traceback" not in cap.err
    assert "could not be decoded as MAVLink frames and were skipped" in cap.out
    assert cap.err.strip().startswith(f"agnav replay: {noise}: ") and "is not MAVLink frames: not a .tlog" in cap.err


# ---- B2: calibrate --settle-s must be below the step's time limit, as in the config file -----------------
@pytest.mark.parametrize("opts, why", [
    (["--settle-s", "2", "--max-step-s", "0.5"], "--settle-s (2 s) must be < --max-step-s (0.5 s)"),
    (["--settle-s", "10"], "--settle-s (10 s) must be < [calibration] max_step_s (6 s)"),
    (["--max-step-s", "0.2"], "[calibration] settle_s (1 s) must be < --max-step-s (0.2 s)"),
])
def test_calibrate_settle_time_not_below_the_step_limit_is_refused_before_connecting(capsys, opts, why):
    assert cli.main(["calibrate", "steering", "--device", nowhere(), "--no-tlog", "--yes", *opts]) == 2
    err = capsys.readouterr().err.strip()
    assert err == f"agnav calibrate: {why}: a sweep step settles first, then measures"


# ---- B5: sim --out: an existing folder that takes no new files is refused before the run ------------------
def test_sim_out_folder_that_cannot_be_written_is_refused_before_the_run(capsys, monkeypatch):
    import agnav_host.sim.runner as runner

    ran: list[int] = []
    monkeypatch.setattr(runner, "run_scenario", lambda *a, **k: ran.append(1))
    assert cli.main(["sim", "him_setup1", "--duration", "1", "--quiet", "--out", UNWRITABLE_DIR]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"agnav sim: --out {UNWRITABLE_DIR}: cannot write in the folder:") and not ran


# ---- B6: sil --tlog checked (named, before the firmware loads) and its missing folders made ----------------
@pytest.fixture
def no_serve(monkeypatch):
    """agnav sil without the firmware: records the tlog path serve() was given."""
    from types import SimpleNamespace

    import agnav_host.sil.server as server

    calls: list[str | None] = []

    def serve(sc, opt):
        calls.append(opt.tlog_path)
        return SimpleNamespace(t_s=0.0, pose=SimpleNamespace(x_m=0.0, y_m=0.0), end_reason="timeout")

    monkeypatch.setattr(server, "serve", serve)
    return calls


def test_sil_unwritable_tlog_is_named_before_the_firmware_loads(capsys, no_serve):
    bad = f"{UNWRITABLE_DIR}/x.tlog"
    assert cli.main(["sil", "--tlog", bad, "--duration", "1", "--tcp", "tcp:127.0.0.1:0"]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"agnav sil: --tlog {bad}: cannot write there:") and no_serve == []


def test_sil_tlog_missing_folders_are_made(tmp_path, capsys, no_serve):
    t = tmp_path / "new" / "sub" / "x.tlog"
    assert cli.main(["sil", "--tlog", str(t), "--duration", "1", "--tcp", "tcp:127.0.0.1:0"]) == 0
    assert no_serve == [str(t)] and t.parent.is_dir()


@pytest.mark.parametrize("text, line, what", [
    ('# host config\n[link]\ndevice = "tcp:127.0.0.1:5760"\n\nheartbeat_hz = nan\n', 5, "[link] heartbeat_hz: must be a finite"),
    ('[link]\ndevice = "tcp:x:1"\n[run]\nmax_speed_m_s = 0.5\nbogus = 3\n', 5, "[run] unknown key 'bogus'"),
    ('[link]\n[weird]\na = 1\n', 2, "unknown section [weird]"),
    ('[run]\nmax_speed_m_s = "fast"\n', 2, "[run] max_speed_m_s: must be a number"),
])
def test_b9_config_value_errors_name_the_line(tmp_path, capsys, text, line, what):
    cfg = tmp_path / "agnav.toml"
    cfg.write_text(text)
    assert cli.main(["config", "--config", str(cfg)]) == 2
    err = capsys.readouterr().err
    assert f"{cfg}:{line}: {what}" in err and "Traceback" not in err
