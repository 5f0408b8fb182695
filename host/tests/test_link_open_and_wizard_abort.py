"""Opening a device that is not there fails fast with the OS error; the calibration wizard aborts
cleanly (car stopped, nothing written, non-zero exit) when the link is lost or stdin is closed."""

from __future__ import annotations

import errno
import io
import socket
import sys
import threading
import time

import re

import pytest
import serial
from pymavlink import mavutil

from agnav_host import cli
from agnav_host.calibration.wizard import Aborted, ConsoleIO, ScriptedIO, Wizard, sweep_points
from agnav_host.link import AgnavRobot, Endpoint, parse_device
from agnav_host.link.config import CalibrationConfig
from agnav_host.link.fake import FakeRobot
from _cli_helpers import free_port

FAST = dict(settle_s=0.1, hold_s=0.25, max_step_s=1.0, pause_s=0.05)
FAST_ARGS = ["--settle-s", "0.1", "--hold-s", "0.25", "--max-step-s", "1"]


def failing_open(monkeypatch, *errors: BaseException) -> list[str]:
    """mavutil.mavlink_connection raises ``errors`` in turn (the last one for ever); returns the calls."""
    calls: list[str] = []

    def fake(device, *a, **k):
        calls.append(device)
        raise errors[min(len(calls), len(errors)) - 1]

    monkeypatch.setattr(mavutil, "mavlink_connection", fake)
    return calls


def open_error(device: str, **start) -> tuple[str, float]:
    ep = Endpoint(device, reconnect_delay_s=0.1, heartbeat_hz=0)
    t0 = time.monotonic()
    with pytest.raises(ConnectionError) as e:
        ep.start(**start)
    return str(e.value), time.monotonic() - t0


# ---- Defect A: device strings ----------------------------------------------------------------------
def test_parse_device_refuses_out_of_range_ports_and_bad_bauds(tmp_path):
    for bad in ("tcp:127.0.0.1:99999", "tcp:127.0.0.1:0", "udp:0.0.0.0:70000"):
        with pytest.raises(ValueError, match=r"port must be 1\.\.65535"):
            parse_device(bad)
    with pytest.raises(ValueError, match=r"baud 'abc' is not a whole number"):
        parse_device("serial:/dev/ttyNOPE:abc")
    for bad in ("serial:/dev/ttyUSB0:0", "serial:/dev/ttyUSB0:-5"):
        with pytest.raises(ValueError, match=r"must be > 0"):
            parse_device(bad)
    for b in (0, -9600):
        with pytest.raises(ValueError, match=r"must be > 0"):
            parse_device("/dev/ttyUSB0", b)
        with pytest.raises(ValueError, match=r"must be > 0"):
            parse_device("serial:/dev/ttyUSB0", b)
    with pytest.raises(ValueError, match="no host"):
        parse_device("tcp::5760")
    with pytest.raises(ValueError, match="no serial device path"):
        parse_device("serial::57600")
    # a by-path name holds ':'; with the baud at the end it parses
    p = parse_device("serial:/dev/serial/by-path/pci-0000:00:14.0-usb-0:2:1.0-port0:115200")
    assert (p.address, p.baud) == ("/dev/serial/by-path/pci-0000:00:14.0-usb-0:2:1.0-port0", 115200)
    colon = tmp_path / "usb-0:1.0"
    colon.touch()
    assert parse_device(f"serial:{colon}", 9600).address == str(colon)  # an existing path is taken whole
    # the good forms are unchanged
    assert parse_device("serial:/dev/ttyUSB0:57600").baud == 57600
    assert parse_device("tcp:127.0.0.1:65535").kind == "tcp"


# ---- Defect A: opening -------------------------------------------------------------------------------
def test_missing_serial_device_fails_fast_with_the_os_error(tmp_path):
    dev = tmp_path / "ttyNOPE"
    msg, dt = open_error(f"serial:{dev}:57600", open_timeout_s=10.0)
    assert msg == f"could not open serial:{dev}:57600: [Errno 2] No such file or directory"
    assert dt < 3.0  # a short grace for a board re-enumerating, not the 10 s open timeout


def test_a_regular_file_or_directory_as_serial_device_fails_at_once(tmp_path):
    f = tmp_path / "notatty"
    f.write_bytes(b"")
    for dev in (f, tmp_path):
        msg, dt = open_error(f"serial:{dev}:57600", open_timeout_s=10.0)
        assert msg.startswith(f"could not open serial:{dev}:57600:") and "not a serial port" in msg, msg
        assert dt < 1.0


def test_refused_loopback_connection_fails_fast():
    port = free_port()
    msg, dt = open_error(f"tcp:127.0.0.1:{port}", open_timeout_s=10.0)
    assert msg.startswith(f"could not open tcp:127.0.0.1:{port}: [Errno {errno.ECONNREFUSED}] Connection refused")
    assert dt < 3.0


def test_unknown_host_fails_at_once(monkeypatch):
    calls = failing_open(monkeypatch, socket.gaierror(socket.EAI_NONAME, "Name or service not known"))
    msg, dt = open_error("tcp:nohost.invalid:5760", open_timeout_s=10.0)
    assert "could not open tcp:nohost.invalid:5760: cannot resolve host 'nohost.invalid'" in msg
    assert "Name or service not known" in msg
    assert len(calls) == 1 and dt < 1.0


def test_permission_denied_fails_at_once_with_the_dialout_hint(monkeypatch):
    e = serial.SerialException(errno.EACCES, "could not open port /dev/ttyUSB0: [Errno 13] Permission denied: "
                                             "'/dev/ttyUSB0'")
    calls = failing_open(monkeypatch, e)
    msg, dt = open_error("serial:/dev/ttyUSB0:57600", open_timeout_s=10.0)
    assert msg.startswith("could not open serial:/dev/ttyUSB0:57600: [Errno 13] Permission denied")
    assert "dialout" in msg
    assert len(calls) == 1 and dt < 1.0


def test_transient_errors_retried_until_the_timeout_then_the_last_one_named(monkeypatch):
    calls = failing_open(monkeypatch, OSError(errno.ETIMEDOUT, "Connection timed out"),
                         OSError(errno.EHOSTUNREACH, "No route to host"))
    msg, dt = open_error("tcp:192.0.2.7:5760", open_timeout_s=0.8)
    assert msg == "could not open tcp:192.0.2.7:5760 within 0.8 s: [Errno 113] No route to host"
    assert len(calls) >= 3 and 0.7 < dt < 2.0


def test_wait_heartbeat_bounds_the_open_wait(monkeypatch):
    failing_open(monkeypatch, OSError(errno.EHOSTUNREACH, "No route to host"))
    msg, dt = open_error("tcp:192.0.2.7:5760", wait_heartbeat_s=1.0)  # `--wait 1`
    assert "within 1 s: [Errno 113] No route to host" in msg
    assert dt < 2.0


def test_a_peer_that_starts_listening_within_the_grace_is_opened():
    """`agnav sil ... &` then `agnav run` at once: the refused first attempts are retried briefly."""
    fr = FakeRobot()
    fr.port = free_port()
    t = threading.Timer(0.3, fr.start)
    t.start()
    try:
        ep = Endpoint(fr.device, reconnect_delay_s=0.1)
        ep.start(wait_heartbeat_s=3.0)
        assert ep.target_system == 1
        ep.close()
    finally:
        t.join()
        fr.close()


@pytest.mark.parametrize("cmd", [["run"], ["param", "get", "WHEELBASE_MM"], ["calibrate", "steering", "--yes"]])
def test_cli_names_the_real_cause_quickly(cmd, tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path))
    dev = tmp_path / "ttyNOPE"
    t0 = time.monotonic()
    assert cli.main(cmd + ["--device", str(dev), "--no-tlog"]) == 1
    assert time.monotonic() - t0 < 3.0
    err = capsys.readouterr().err
    assert f"could not open serial:{dev}:57600: [Errno 2] No such file or directory" in err
    port = free_port()
    assert cli.main(cmd + ["--device", f"tcp:127.0.0.1:{port}", "--no-tlog"]) == 1
    assert "Connection refused" in capsys.readouterr().err
    assert cli.main(cmd + ["--device", "tcp:127.0.0.1:99999", "--no-tlog"]) == 2
    assert "1..65535" in capsys.readouterr().err


# ---- Defect B: the wizard on a lost link -----------------------------------------------------------
@pytest.fixture
def rig():
    with FakeRobot(rate_scale=4, seed=4) as fr:
        with Endpoint(fr.device, budget_bytes_s=1e6, link_timeout_s=0.6) as ep:
            ep.wait_heartbeat(3.0)
            yield fr, AgnavRobot(ep)


def _stopped_after(fr: FakeRobot, n_before: int) -> bool:
    sps = fr.received_of("AGNAV_DRIVE_SETPOINT")[n_before:]
    return bool(sps) and sps[-1].mode == 0 and sps[-1].speed_mm_s == 0 and sps[-1].steer_cdeg == 0


def test_link_silent_between_steps_aborts_at_that_pwm(rig):
    fr, robot = rig
    cfg = CalibrationConfig(steer_step=10, **FAST)
    pwms = sweep_points(cfg.steer_pwm_min, cfg.steer_pwm_max, cfg.steer_step, cfg.steer_neutral_pwm)
    io_ = ScriptedIO()
    w = Wizard(robot, cfg, io_)
    real = w.measure_step
    calls = {"n": 0, "muted_at": 0.0, "sps": 0}

    def step(*a, **k):
        calls["n"] += 1
        if calls["n"] == 3:  # the robot goes silent (SIL killed, radio out of range)
            fr.mute = True
            calls["muted_at"] = time.monotonic()
            calls["sps"] = len(fr.received_of("AGNAV_DRIVE_SETPOINT"))
            # frames already on their way (socket buffer, a loaded machine) land before this step listens: the
            # step is then silent from its start, as the test means (else it sees them, and only the next
            # step can tell the 0.6 s silence from its own 0.35 s)
            time.sleep(0.1)
        return real(*a, **k)

    w.measure_step = step
    with pytest.raises(Aborted, match=rf"^link lost during the sweep at pwm {pwms[2]}; nothing was written"):
        w.run_steering(save=False)
    assert time.monotonic() - calls["muted_at"] < 0.6 + 0.5  # within the link timeout, not the whole sweep
    assert calls["n"] == 3 and len(w.steps) == 2  # no further steps, no "n/a" lines
    assert not any("n/a" in s or "is the car moving" in s for s in io_.said)
    time.sleep(0.1)
    assert _stopped_after(fr, calls["sps"])  # zero setpoint sent after the silence began
    assert not fr.received_of("AGNAV_CALIB_TABLE") and not fr.estop


def test_link_silent_mid_step_aborts_within_the_link_timeout(rig):
    fr, robot = rig
    cfg = CalibrationConfig(steer_step=40, settle_s=0.1, hold_s=2.5, max_step_s=5.0, pause_s=0.05)
    w = Wizard(robot, cfg, ScriptedIO())
    real = w.measure_step
    calls = {"n": 0}
    muted = {}

    def mute():
        muted["t"] = time.monotonic()
        fr.mute = True

    def step(*a, **k):
        calls["n"] += 1
        if calls["n"] == 1:
            threading.Timer(0.5, mute).start()
        return real(*a, **k)

    w.measure_step = step
    with pytest.raises(Aborted, match=r"^link lost during the sweep at pwm 96; nothing was written"):
        w.run_steering(save=False)
    assert time.monotonic() - muted["t"] < 0.6 + 0.6  # the 2.6 s step was cut short
    assert calls["n"] == 1
    time.sleep(0.1)
    assert fr.received_of("AGNAV_DRIVE_SETPOINT")[-1].mode == 0
    assert not fr.received_of("AGNAV_CALIB_TABLE")


def test_motion_hint_only_when_telemetry_arrives(rig):
    fr, robot = rig
    w = Wizard(robot, CalibrationConfig(**FAST), ScriptedIO())
    robot.release()
    r = w.measure_step(133, 0, "steer", "encoders")  # speed PWM 0: the car stands, encoders report 0
    assert not r.ok and "is the car moving? encoders connected?" in r.note
    fr.mute = True
    with pytest.raises(Aborted, match=r"^link lost during the sweep at pwm 133") as e:
        w.measure_step(133, 40, "steer", "encoders")
    assert "is the car moving" not in str(e.value)


def test_cli_calibrate_link_lost_exits_non_zero(tmp_path, capsys, monkeypatch):
    cfgf = tmp_path / "host.toml"
    cfgf.write_text("[link]\nlink_timeout_s = 0.6\n[calibration]\npause_s = 0.05\n")
    real = Wizard.measure_step
    calls = {"n": 0}
    with FakeRobot(rate_scale=4) as fr:
        def step(self, *a, **k):
            calls["n"] += 1
            if calls["n"] == 2:
                fr.mute = True
            return real(self, *a, **k)

        monkeypatch.setattr(Wizard, "measure_step", step)
        rc = cli.main(["calibrate", "speed", "--device", fr.device, "--config", str(cfgf), "--yes", "--no-save",
                       "--no-tlog", "--plot-dir", str(tmp_path)] + FAST_ARGS)
        assert rc == 1
        assert fr.received_of("AGNAV_DRIVE_SETPOINT")[-1].speed_mm_s == 0
        assert not fr.received_of("AGNAV_CALIB_TABLE")
    err = capsys.readouterr().err
    # the radio goes quiet from the second step (pwm 24) on; the loss is noticed link_timeout_s later,
    # in that step or, when the machine is slow and the step short, in the next (pwm 32) - never before
    m = re.search(r"agnav calibrate: link lost during the sweep at pwm (\d+); nothing was written", err)
    assert m is not None, err
    assert int(m.group(1)) in (24, 32)


# ---- Defect B: closed stdin ----------------------------------------------------------------------
class EOFAtAsk(ScriptedIO):
    """An input source that ends where a measurement must be typed."""

    def ask(self, question: str) -> str:
        self.said.append(question)
        raise EOFError("EOF when reading a line")


@pytest.mark.parametrize("source", ["io", "stdin"])
def test_eof_at_the_diameter_prompt_stops_the_car_cleanly(rig, source, monkeypatch):
    fr, robot = rig
    if source == "stdin":  # the console on a closed stdin (`--yes < /dev/null`)
        monkeypatch.setattr(sys, "stdin", io.StringIO(""))
        io_ = ConsoleIO(assume_yes=True)
    else:
        io_ = EOFAtAsk()
    w = Wizard(robot, CalibrationConfig(**FAST), io_)
    w._method = lambda kind: "diameter"  # a robot with fewer than two wheel encoders
    with pytest.raises(Aborted) as e:
        w.run_steering(save=False)
    msg = str(e.value)
    assert "pwm 96" in msg and "diameter" in msg and "stdin was closed" in msg and "nothing was written" in msg
    time.sleep(0.1)
    sps = fr.received_of("AGNAV_DRIVE_SETPOINT")
    assert sps[-1].mode == 0 and sps[-1].speed_mm_s == 0  # stopped (neutral), not left on a raw setpoint
    assert not fr.received_of("AGNAV_CALIB_TABLE") and not fr.estop


def test_eof_at_a_yes_no_question_is_a_clean_abort(rig, monkeypatch):
    fr, robot = rig
    monkeypatch.setattr(sys, "stdin", io.StringIO(""))
    with pytest.raises(Aborted, match="EOF on stdin"):
        Wizard(robot, CalibrationConfig(**FAST), ConsoleIO()).run_steering()
    assert not fr.received_of("AGNAV_DRIVE_SETPOINT")  # nothing moved


def test_cli_calibrate_yes_with_stdin_closed(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path))
    monkeypatch.setattr(Wizard, "_method", lambda self, kind: "diameter")
    monkeypatch.setattr(sys, "stdin", io.StringIO(""))  # `< /dev/null`
    with FakeRobot(rate_scale=4) as fr:
        rc = cli.main(["calibrate", "steering", "--device", fr.device, "--yes", "--no-save", "--no-tlog",
                       "--plot-dir", str(tmp_path)] + FAST_ARGS)
        assert rc == 1
        time.sleep(0.1)
        sps = fr.received_of("AGNAV_DRIVE_SETPOINT")
        assert sps[-1].mode == 0 and sps[-1].speed_mm_s == 0
        assert not fr.received_of("AGNAV_CALIB_TABLE")
    out = capsys.readouterr()
    assert "agnav calibrate: input closed (EOF on stdin) at pwm 96" in out.err
    assert "stdin was closed" in out.err and "Traceback" not in out.err + out.out
