"""Input checks of the link area's commands (run, calibrate, flash, replay, param, key, config):
bad numbers refused by argparse, unwritable outputs named before any work, config values checked
with the file named, `agnav config` output that loads back, parameter names and values checked."""

from __future__ import annotations

import math
import os
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from agnav_host import cli
from agnav_host.cli import run as run_command
from agnav_host.link.config import ConfigError, HostConfig, load_config, to_toml
from agnav_host.link.fake import FakeRobot
from agnav_host.link.tlog import TlogWriter
from agnav_host.protocol import dialect
from _cli_helpers import _no_user_config, free_port, nowhere, usage_error  # noqa: F401 (the fixture is autouse)

UNWRITABLE_DIR = "/proc"  # exists, takes no new files (even for root)


@pytest.fixture
def tlog(tmp_path) -> Path:
    """A small telemetry log: robot heartbeats and odometry over 1 s, one host heartbeat."""
    d = dialect()
    robot, host = d.MAVLink(None, srcSystem=1, srcComponent=1), d.MAVLink(None, srcSystem=255, srcComponent=190)
    p = tmp_path / "link.tlog"
    with TlogWriter(p) as w:
        t0 = 1.7e9
        for i in range(11):
            w.write(robot.heartbeat_encode(d.MAV_TYPE_GROUND_ROVER, 0, 0, 0, 4).pack(robot), t0 + 0.1 * i)
            w.write(robot.agnav_odometry_encode(i * 100, 10 * i, 0, 5 * i, 0, 0).pack(robot), t0 + 0.1 * i)
        w.write(host.heartbeat_encode(d.MAV_TYPE_GCS, 8, 0, 0, 4).pack(host), t0 + 0.5)
    return p


# ---- 1. --duration ------------------------------------------------------------------------------------
@pytest.mark.parametrize("value, why", [("nan", "finite"), ("-2", "> 0"), ("0", "> 0"), ("inf", "finite")])
def test_run_duration_must_be_finite_and_positive(capsys, value, why):
    err = usage_error(capsys, ["run", "--device", nowhere(), "--duration", value])
    assert "argument --duration: must be" in err and why in err


# ---- 2. output paths ----------------------------------------------------------------------------------
def test_run_unwritable_rrd_refused_before_connecting(capsys, tmp_path):
    bad = f"{UNWRITABLE_DIR}/x.rrd"
    assert cli.main(["run", "--device", nowhere(), "--rrd", bad, "--no-tlog"]) == 1
    err = capsys.readouterr().err
    assert f"agnav run: --rrd {bad}: cannot write there:" in err
    assert "could not open" not in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1


def test_run_rrd_needs_the_rrd_suffix(capsys, tmp_path):
    assert cli.main(["run", "--device", nowhere(), "--rrd", str(tmp_path / "r.txt"), "--no-tlog"]) == 2
    err = capsys.readouterr().err
    assert "--rrd" in err and "must end in .rrd" in err and "could not open" not in err


def test_run_unwritable_tlog_refused_before_connecting(capsys, tmp_path):
    bad = f"{UNWRITABLE_DIR}/x.tlog"
    assert cli.main(["run", "--device", nowhere(), "--tlog", bad]) == 1
    err = capsys.readouterr().err
    assert f"agnav run: --tlog {bad}: cannot write there:" in err and "could not open" not in err
    # a file where a folder should be
    (tmp_path / "afile").write_text("x")
    assert cli.main(["run", "--device", nowhere(), "--tlog", str(tmp_path / "afile" / "r.tlog")]) == 1
    assert "afile is not a directory" in capsys.readouterr().err


def test_replay_png_and_rrd_paths(capsys, tlog, tmp_path):
    # a bad suffix is a usage error, checked before the log is read (nothing printed on stdout)
    assert cli.main(["replay", str(tlog), "--png", str(tmp_path / "r.txt")]) == 2
    cap = capsys.readouterr()
    assert "--png" in cap.err and "must end in .png" in cap.err and cap.out == ""
    assert cli.main(["replay", str(tlog), "--rrd", str(tmp_path / "r.png")]) == 2
    assert "must end in .rrd" in capsys.readouterr().err
    for opt, name in (("--png", "x.png"), ("--rrd", "x.rrd")):
        bad = f"{UNWRITABLE_DIR}/{name}"
        assert cli.main(["replay", str(tlog), opt, bad]) == 1
        cap = capsys.readouterr()
        assert f"agnav replay: {opt} {bad}: cannot write there:" in cap.err and "Traceback" not in cap.err
        assert cap.out == ""  # checked before the summary
    # the good path still works
    assert cli.main(["replay", str(tlog)]) == 0
    assert "AGNAV_ODOMETRY" in capsys.readouterr().out


def test_key_new_unwritable_key_file(capsys, tmp_path):
    assert cli.main(["key", "new", "--key-file", f"{UNWRITABLE_DIR}/k"]) == 1
    err = capsys.readouterr().err
    assert f"agnav key: cannot write signing key {UNWRITABLE_DIR}/k:" in err
    assert cli.main(["key", "new", "--key-file", str(tmp_path)]) == 1
    assert "is a directory" in capsys.readouterr().err
    assert cli.main(["key", "show", "--key-file", str(tmp_path)]) == 2
    assert "is a directory" in capsys.readouterr().err


# ---- 3. target system ---------------------------------------------------------------------------------
@pytest.mark.parametrize("value", ["-1", "0", "256"])
def test_target_system_range_checked_by_argparse(capsys, value):
    err = usage_error(capsys, ["run", "--device", nowhere(), "--target-system", value])
    assert "argument --target-system: must be 1..255" in err


def test_target_system_not_heard_names_the_systems_heard(capsys):
    with FakeRobot(sysid=1) as fr:
        t0 = time.monotonic()
        rc = cli.main(["param", "get", "LINK_TIMEOUT_MS", "--device", fr.device, "--no-tlog",
                       "--target-system", "200", "--wait", "1.5"])
        assert rc == 1 and time.monotonic() - t0 < 5.0
        err = capsys.readouterr().err
        assert "no heartbeat from system 200 within 1.5 s" in err
        assert "heard system(s) 1" in err and "--target-system 1" in err
        assert "LINK_TIMEOUT_MS" not in err  # no request was sent to a system that is not there
        assert not fr.received_of("PARAM_REQUEST_READ")


# ---- 4 + 5. config validation -------------------------------------------------------------------------
@pytest.mark.parametrize("body, expect", [
    ("[run]\nmax_speed_m_s = nan", "[run] max_speed_m_s: must be a finite number > 0"),
    ("[run]\nmax_speed_m_s = inf", "[run] max_speed_m_s: must be a finite number > 0"),
    ("[run]\nmax_speed_m_s = -1", "[run] max_speed_m_s: must be > 0"),
    ("[link]\nbaud = -9600", "[link] baud: must be > 0"),
    ("[link]\nsysid = 999", "[link] sysid: must be 1..255"),
    ("[link]\nheartbeat_hz = 0", "[link] heartbeat_hz: must be > 0"),
    ("[link]\nlink_timeout_s = nan", "[link] link_timeout_s: must be a finite number > 0"),
    ("[calibration]\nsteer_pwm_min = 200\nsteer_pwm_max = 100", "[calibration] steer_pwm_min: must be < steer_pwm_max"),
    ('[ardupilot]\nmode = "warp"', "[ardupilot] mode: must be one of 'velocity', 'rc', got 'warp'"),
    ('[run]\nplanner = "nosuch"', "[run] planner: unknown planner 'nosuch'; known: flb"),
    ("[run]\ngoal_tolerance_m = -3", "[run] goal_tolerance_m: must be > 0"),
    ("[run]\nstatus_hz = 0", "[run] status_hz: must be > 0"),
    ("[run]\ncontrol_hz = nan", "[run] control_hz: must be >= 5"),
    ("[link]\nbaud = 'fast'", "[link] baud: must be an integer"),
    ("[link]\nbuad = 9600", "[link] unknown key 'buad'"),
    ("link = 3", "[link] must be a table"),
])
def test_config_values_checked_with_the_file_named(capsys, tmp_path, body, expect):
    p = tmp_path / "host.toml"
    p.write_text(body + "\n")
    assert cli.main(["config", "--config", str(p)]) == 2
    # the file, the line of the key the message names, then the message
    rest = expect.split("] ", 1)[1]
    key = rest.split("'")[1] if rest.startswith("unknown key") else expect[1:].split("]")[0] if rest.startswith("must be a table") \
        else rest.split(":")[0]
    line = next(i for i, t in enumerate(body.splitlines(), 1) if t.split("=")[0].strip() == key)
    assert f"agnav config: {p}:{line}: {expect}" in capsys.readouterr().err
    with pytest.raises(ConfigError, match=str(p)):
        load_config(p)


def test_run_with_bad_run_config_fails_before_connecting(capsys, tmp_path):
    p = tmp_path / "gt.toml"
    p.write_text("[run]\ngoal_tolerance_m = -3\nstatus_hz = 0\n")
    assert cli.main(["run", "--device", nowhere(), "--goal", "1,1", "--config", str(p), "--no-tlog"]) == 2
    err = capsys.readouterr().err
    assert f"{p}:3: [run] status_hz" in err and "could not open" not in err and "ZeroDivision" not in err


def test_config_path_that_is_a_directory(capsys, tmp_path):
    assert cli.main(["config", "--config", str(tmp_path)]) == 2
    assert f"config file {tmp_path} is a directory" in capsys.readouterr().err
    assert cli.main(["replay", str(tmp_path)]) == 2
    assert f"{tmp_path}: is a directory" in capsys.readouterr().err


# ---- 6. `agnav config` prints TOML that loads back ----------------------------------------------------
def test_config_output_round_trips(capsys, tmp_path):
    src = tmp_path / "in.toml"
    src.write_text('[link]\ndevice = "tcp:127.0.0.1:5798"\nsigning = true\nkey_file = "a \\"q\\" b"\n'
                   '[run]\nplanner = "subsumption"\nmax_speed_m_s = 0.25\n[viz]\nrerun = true\n')
    for argv in (["config"], ["config", "--config", str(src)]):
        assert cli.main(argv) == 0
        out = capsys.readouterr().out
        assert "False" not in out and "True" not in out
        back = tmp_path / "back.toml"
        back.write_text(out)
        got = load_config(back)
        want = load_config(src) if len(argv) > 1 else HostConfig()
        got.source = want.source = ""
        assert got == want
    assert to_toml(HostConfig()).count("[") >= 5


def test_config_template_with_config_is_refused(capsys):
    assert cli.main(["config", "--template", "--config", "nosuch.toml"]) == 2
    cap = capsys.readouterr()
    assert "--template prints the built-in defaults and reads no file" in cap.err and cap.out == ""


# ---- 7 + 8. param values and names --------------------------------------------------------------------
@pytest.mark.parametrize("name, value, expect", [
    ("LINK_TIMEOUT_MS", "nan", "value must be a finite number, got 'nan'"),
    ("LINK_TIMEOUT_MS", "inf", "value must be a finite number"),
    ("X", "abc", "value 'abc' is not a number"),
    ("LINK_TIMEOUT_MS", "2000.7", "LINK_TIMEOUT_MS is a whole-number parameter, got '2000.7'"),
])
def test_param_set_value_checked_before_connecting(capsys, name, value, expect):
    assert cli.main(["param", "set", name, value, "--device", nowhere(), "--no-tlog"]) == 2
    err = capsys.readouterr().err
    assert expect in err and "could not open" not in err


def test_param_stray_arguments_and_bad_timeouts(capsys):
    assert cli.main(["param", "list", "extra", "--device", nowhere(), "--no-tlog"]) == 2
    assert "param list takes no NAME (got 'extra')" in capsys.readouterr().err
    assert cli.main(["param", "get", "A", "B", "--device", nowhere(), "--no-tlog"]) == 2
    assert "param get takes one NAME" in capsys.readouterr().err
    for bad in ("-1", "nan", "0"):
        assert "argument --timeout: must be" in usage_error(capsys, ["param", "list", "--timeout", bad])


def test_param_unknown_names_against_the_fake_robot(capsys):
    """The fake robot, like a lossy link, does not answer an unknown name: the message says so."""
    with FakeRobot() as fr:
        base = ["--device", fr.device, "--no-tlog", "--timeout", "0.2"]
        assert cli.main(["param", "get", "NOSUCH", *base]) == 2
        assert "no parameter named NOSUCH on the robot (or no answer" in capsys.readouterr().err
        assert cli.main(["param", "set", "link_timeout_ms", "600", *base]) == 2
        err = capsys.readouterr().err
        assert "no parameter named link_timeout_ms" in err and "case-sensitive" in err and "LINK_TIMEOUT_MS?" in err
        assert cli.main(["param", "get", "LINK_TIMEOUT_M", *base]) == 2
        assert "did you mean LINK_TIMEOUT_MS?" in capsys.readouterr().err
        assert not fr.received_of("PARAM_SET")  # nothing was set
        assert fr.params["LINK_TIMEOUT_MS"] == 500


def test_param_set_non_integer_refused_after_fetching_the_type(capsys):
    """A name the package does not know: the robot's PARAM_VALUE type (INT32) decides, nothing is sent."""
    with FakeRobot() as fr:
        fr.params["NEW_INT_P"] = 7
        fr.param_names.append("NEW_INT_P")
        assert cli.main(["param", "set", "NEW_INT_P", "2.5", "--device", fr.device, "--no-tlog"]) == 2
        assert "NEW_INT_P is a whole-number parameter (now 7), got '2.5'; nothing sent" in capsys.readouterr().err
        assert not fr.received_of("PARAM_SET") and fr.params["NEW_INT_P"] == 7


@pytest.fixture(scope="module")
def sil_device():
    """The real firmware (native SIL) on a free loopback port, as a subprocess."""
    port = free_port()
    proc = subprocess.Popen([sys.executable, "-m", "agnav_host.cli", "sil", "him_setup1", "--tcp",
                             f"tcp:127.0.0.1:{port}"], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 20.0
        while time.monotonic() < deadline:
            with socket.socket() as s:
                if s.connect_ex(("127.0.0.1", port)) == 0:
                    break
            if proc.poll() is not None:
                pytest.skip(f"SIL did not start: {proc.stderr.read() if proc.stderr else ''}")
            time.sleep(0.1)
        else:
            pytest.skip("SIL did not start listening within 20 s")
        yield f"tcp:127.0.0.1:{port}"
    finally:
        proc.terminate()
        try:
            proc.wait(5)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def test_param_unknown_name_refused_by_the_firmware_at_once(capsys, sil_device):
    """The firmware answers an unknown name with STATUSTEXT "unknown parameter": no 3 x 1 s wait."""
    t0 = time.monotonic()
    assert cli.main(["param", "get", "NOSUCH", "--device", sil_device, "--no-tlog"]) == 2
    err = capsys.readouterr().err
    assert "no parameter named NOSUCH on the robot (the robot refused the name)" in err
    assert time.monotonic() - t0 < 2.5
    assert cli.main(["param", "set", "link_timeout_ms", "600", "--device", sil_device, "--no-tlog"]) == 2
    assert "parameter names are case-sensitive: did you mean LINK_TIMEOUT_MS?" in capsys.readouterr().err
    assert cli.main(["param", "get", "LINK_TIMEOUT_MS", "--device", sil_device, "--no-tlog"]) == 0
    assert capsys.readouterr().out.strip() == "LINK_TIMEOUT_MS 500"  # unchanged


def test_target_system_not_heard_on_the_sil(capsys, sil_device):
    assert cli.main(["run", "--device", sil_device, "--no-tlog", "--target-system", "200", "--wait", "1.5"]) == 1
    err = capsys.readouterr().err
    assert "no heartbeat from system 200" in err and "heard system(s) 1" in err
    assert "param get LINK_TIMEOUT_MS" not in err


# ---- 9. --baud ----------------------------------------------------------------------------------------
@pytest.mark.parametrize("value", ["-5", "0", "fast"])
def test_baud_must_be_a_positive_whole_number(capsys, value):
    assert "argument --baud:" in usage_error(capsys, ["run", "--device", nowhere(), "--baud", value])


# ---- 10. goal heading with the firmware layers --------------------------------------------------------
def test_goal_heading_without_planner_is_warned_about(capsys):
    with FakeRobot() as fr:
        assert cli.main(["run", "--device", fr.device, "--goal", "-1,2,90", "--duration", "0.3", "--no-tlog"]) == 0
        assert fr.goal == pytest.approx((-1.0, 2.0))
    err = capsys.readouterr().err
    assert "heading 90 deg ignored: the firmware's move-to-goal layer drives to the position only" in err


# ---- 11. planners that need a laser --------------------------------------------------------------------
def test_laser_planner_refused_before_connecting(capsys):
    assert cli.main(["run", "--device", nowhere(), "--planner", "him", "--goal", "1,1", "--no-tlog"]) == 2
    err = capsys.readouterr().err
    assert "planner him needs a laser; this run has none: give one with --laser URL" in err
    assert "obs.scan" not in err and "could not open" not in err


def test_planner_errors_lose_internal_names():
    from agnav_host.planning.base import InvalidObservation

    e = InvalidObservation("the subsumption planner needs a sonar frame (obs.sonar is None)")
    assert run_command._plain(e) == "the subsumption planner needs a sonar frame"


# ---- 12. replay --budget ------------------------------------------------------------------------------
@pytest.mark.parametrize("value", ["-5", "nan", "0"])
def test_replay_budget_must_be_positive(capsys, tlog, value):
    assert "argument --budget: must be" in usage_error(capsys, ["replay", str(tlog), "--budget", value])


# ---- 13. flash --env ----------------------------------------------------------------------------------
def test_flash_env_checked_against_platformio_ini(capsys):
    assert cli.main(["flash", "--dry-run", "--env", "nosuch"]) == 2
    cap = capsys.readouterr()
    assert "unknown PlatformIO env 'nosuch'" in cap.err and "megaatmega2560" in cap.err and "stm32f405" in cap.err
    assert "pio run" not in cap.out
    assert cli.main(["flash", "--dry-run", "--env", "native"]) == 2
    assert "no board to flash" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        cli.main(["flash", "--help"])
    assert "default megaatmega2560" in capsys.readouterr().out.replace("\n", " ").replace("  ", " ")


# ---- 14. no empty telemetry log after a failed connection ----------------------------------------------
def test_failed_connection_leaves_no_empty_tlog(capsys, tmp_path):
    t = tmp_path / "logs" / "run.tlog"
    assert cli.main(["run", "--device", nowhere(), "--tlog", str(t), "--wait", "1"]) == 1
    assert "could not open" in capsys.readouterr().err
    assert not t.exists()
    # the default log (<log_dir>/param-<time>.tlog) likewise
    auto = tmp_path / "auto"
    auto.mkdir()
    cfg = tmp_path / "h.toml"
    cfg.write_text(f'[link]\nlog_dir = "{auto}"\n')
    assert cli.main(["param", "list", "--device", nowhere(), "--config", str(cfg), "--wait", "1"]) == 1
    assert list(auto.iterdir()) == []


# ---- 15. help text and number types -------------------------------------------------------------------
def _link_parsers() -> dict:
    p = cli.build_parser()
    sub = next(a for a in p._actions if a.__class__.__name__ == "_SubParsersAction")
    return {n: sp for n, sp in sub.choices.items() if n in ("run", "calibrate", "flash", "replay", "param", "key")}


def test_every_numeric_option_is_checked_and_documented():
    for name, sp in _link_parsers().items():
        for a in sp._actions:
            if not a.option_strings or a.nargs == 0 or a.type in (None, cli.nonempty_text):  # text: no number
                continue
            assert a.type not in (int, float), f"agnav {name} {a.option_strings[0]}: unchecked {a.type.__name__}"
            assert "default" in (a.help or ""), f"agnav {name} {a.option_strings[0]}: help names no default"


def test_calibrate_overrides_give_units_and_defaults(capsys):
    with pytest.raises(SystemExit):
        cli.main(["calibrate", "--help"])
    out = " ".join(capsys.readouterr().out.split())
    assert "[calibration] settle_s, 1 s" in out and "[calibration] hold_s, 3 s" in out
    assert "[calibration] max_step_s, 6 s" in out and "[calibration] max_distance_m, 4 m" in out
    assert "override" not in out
    for opt, bad in (("--settle-s", "-1"), ("--hold-s", "0"), ("--max-step-s", "nan"), ("--max-distance-m", "-2")):
        assert f"argument {opt}: must be" in usage_error(capsys, ["calibrate", "steering", opt, bad])


def test_finite_config_values_still_load(tmp_path):
    """The checks refuse nonsense only: edge values that make sense load."""
    p = tmp_path / "ok.toml"
    p.write_text("[link]\ntarget_system = 0\nsysid = 1\n[run]\ncontrol_hz = 5\n[calibration]\nsettle_s = 0\n"
                 "[ardupilot]\nmode = \"rc\"\n")
    cfg = load_config(p)
    assert cfg.run.control_hz == 5.0 and cfg.ardupilot.mode == "rc" and math.isfinite(cfg.link.heartbeat_hz)
    assert os.path.samefile(cfg.source, p)


def test_run_asks_a_field_controller_for_the_lasers_it_needs(capsys):
    for name, what in (("proximity", "needs a laser"), ("row-follower", "needs a laser"),
                       ("goal_seek+ground-guard", "needs a laser"), ("rut-follower", "needs a tilted laser")):
        assert cli.main(["run", "--device", nowhere(), "--planner", name, "--goal", "1,0", "--no-tlog"]) == 2
        err = capsys.readouterr().err
        assert f"{name} {what}" in err and "--laser" in err and "could not open" not in err, err
