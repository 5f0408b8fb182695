"""Output folders and files of the commands: refused before the work when they cannot be written (a plot folder,
a markdown table, a sim output folder, a telemetry log), written when their folders are missing, cleared of an
earlier run's files, and said in one line when writing fails after the work; a closed output pipe ends a
command quietly."""

from __future__ import annotations

from pathlib import Path

import pytest

from agnav_host import cli
from _cli_helpers import _no_user_config, heartbeat_tlog, nowhere  # noqa: F401 (the fixture is autouse)

UNWRITABLE_DIR = "/proc"  # exists, takes no new files (even for root)
FAST_CAL = ["--settle-s", "0.1", "--hold-s", "0.25", "--max-step-s", "1"]


# ---- calibrate --plot-dir ---------------------------------------------------------------------------
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


# ---- faults --markdown checked before the cases run --------------------------------------------------
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


# ---- sim --out reused: the earlier run's files go, link.rrd only from this run's link.tlog ---------------
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


# ---- output piped into a reader that stops early (`| head -1`) ------------------------------------------
@pytest.mark.parametrize("argv", [["scenarios"], ["planners"], ["plan", "--start", "0,0,0", "--goal", "3,5,90",
                                                                 "--samples", "2000"], ["replay", "TLOG"]])
def test_a_closed_output_pipe_ends_the_command_quietly(tmp_path, argv):
    import subprocess
    import sys

    argv = [str(heartbeat_tlog(tmp_path / "r.tlog")) if a == "TLOG" else a for a in argv]
    p = subprocess.Popen([sys.executable, "-m", "agnav_host.cli", *argv], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE)
    p.stdout.close()  # the reader is gone before the command writes a byte: every write meets a closed pipe
    err = p.stderr.read().decode()
    assert p.wait(timeout=120) == 141  # cli.EXIT_BROKEN_PIPE: as if killed by SIGPIPE
    assert err == "", err


# ---- sim --out: an existing folder that takes no new files is refused before the run ------------------
def test_sim_out_folder_that_cannot_be_written_is_refused_before_the_run(capsys, monkeypatch):
    import agnav_host.sim.runner as runner

    ran: list[int] = []
    monkeypatch.setattr(runner, "run_scenario", lambda *a, **k: ran.append(1))
    assert cli.main(["sim", "him_setup1", "--duration", "1", "--quiet", "--out", UNWRITABLE_DIR]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"agnav sim: --out {UNWRITABLE_DIR}: cannot write in the folder:") and not ran


# ---- sil --tlog checked (named, before the firmware loads) and its missing folders made ----------------
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

