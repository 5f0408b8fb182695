"""The link area's agnav subcommands: help, negative numbers, flash, key, config, param, run, replay."""

from __future__ import annotations

import os
import re
import stat
import time

import pytest

from agnav_host import cli
from agnav_host.cli import link as commands
from agnav_host.cli import run as run_command
from agnav_host.link.config import ConfigError, HostConfig, config_template, load_config, validate_config
from agnav_host.link.fake import FakeRobot

LINK_COMMANDS = ["run", "calibrate", "flash", "replay", "param", "key", "config"]


@pytest.mark.parametrize("name", LINK_COMMANDS)
def test_help_on_every_command(name, capsys):
    with pytest.raises(SystemExit) as e:
        cli.main([name, "--help"])
    assert e.value.code == 0
    assert f"agnav {name}" in capsys.readouterr().out


def test_negative_goal_is_a_value():
    ns = cli.parse_args(["run", "--device", "tcp:127.0.0.1:1", "--goal", "-3,-5,-90"])
    assert ns.goal == [(-3.0, -5.0, -90.0)]  # --goal repeats for waypoints


def test_flash_dry_run_wraps_pio(capsys, monkeypatch):
    monkeypatch.setattr(commands, "_upload_port_problem", lambda port: None)  # no board on the test machine
    assert cli.main(["flash", "--dry-run", "--env", "stm32f405", "--port", "/dev/ttyACM0"]) == 0
    out = capsys.readouterr().out
    assert "pio run -e stm32f405 -t upload --upload-port /dev/ttyACM0" in out
    cmd, env = commands.flash_command("megaatmega2560", None)
    assert env["PLATFORMIO_CORE_DIR"].endswith(".pio-core")
    assert cmd[1:] == ["run", "-e", "megaatmega2560", "-t", "upload"]


def test_key_new_show(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path))
    assert cli.main(["key", "new"]) == 0
    path = tmp_path / "agnav" / "signing.key"
    assert stat.S_IMODE(os.stat(path).st_mode) == 0o600
    assert len(bytes.fromhex(path.read_text().strip())) == 32
    assert cli.main(["key", "new"]) == 2  # refuses to overwrite
    assert cli.main(["key", "show"]) == 0
    out = capsys.readouterr().out
    assert "fingerprint" in out and path.read_text().strip() not in out  # secret only with --reveal
    assert cli.main(["key", "show", "--reveal"]) == 0
    assert path.read_text().strip() in capsys.readouterr().out


def test_config_template_loads_and_typos_fail(tmp_path):
    p = tmp_path / "host.toml"
    p.write_text(config_template())
    cfg = load_config(p)
    assert cfg.link.baud == 57600 and cfg.link.budget_bytes_s == 1500.0 and cfg.source == str(p)
    p.write_text("[link]\nbuad = 9600\n")
    with pytest.raises(ConfigError, match="buad"):
        load_config(p)
    p.write_text("[link]\nbaud = 'fast'\n")
    with pytest.raises(ConfigError, match="integer"):
        load_config(p)
    p.write_text("[run]\ncontrol_hz = 1\n")
    with pytest.raises(ConfigError, match="control_hz"):
        load_config(p)
    with pytest.raises(ConfigError):
        load_config(tmp_path / "missing.toml")


def test_param_commands_against_fake(capsys):
    with FakeRobot() as fr:
        assert cli.main(["param", "list", "--device", fr.device, "--no-tlog"]) == 0
        out = capsys.readouterr().out
        assert "WHEELBASE_MM     174" in out and len(out.strip().splitlines()) == 20
        assert cli.main(["param", "set", "GOAL_TOL_MM", "150", "--device", fr.device, "--no-tlog"]) == 0
        assert fr.params["GOAL_TOL_MM"] == 150
        assert cli.main(["param", "set", "GOAL_TOL_MM", "-5", "--device", fr.device, "--no-tlog"]) == 1
        assert cli.main(["param", "get", "GOAL_TOL_MM", "--device", fr.device, "--no-tlog"]) == 0
        assert "GOAL_TOL_MM 150" in capsys.readouterr().out


def test_run_firmware_layers_then_replay(tmp_path, capsys):
    tlog = tmp_path / "run.tlog"
    with FakeRobot() as fr:
        fr.estop = True  # left engaged by an earlier Ctrl-C: run releases it
        rc = cli.main(["run", "--device", fr.device, "--goal", "2,-1", "--duration", "1.2", "--tlog", str(tlog)])
        assert rc == 0
        assert not fr.estop and fr.goal == pytest.approx((2.0, -1.0))
        assert fr.behaviours & 2  # goal-seek layer enabled
        # heartbeats often enough for the firmware's 500 ms link timeout
        hbs = [m for m in fr.received_of("HEARTBEAT")]
        assert len(hbs) >= 4
        assert fr.received_of("AGNAV_DRIVE_SETPOINT")[-1].speed_mm_s == 0  # stopped at the end
    cap = capsys.readouterr()
    assert "IDLE" in cap.out
    # 1.2 s is shorter than the 5 s budget window: the rate over the run, not a peak of 0
    rate = re.search(r"link: rx \d+ B .* frames, (\d+) B/s over the run \(shorter than the 5 s budget window\)", cap.err)
    assert rate is not None and int(rate.group(1)) > 0, cap.err
    assert cli.main(["replay", str(tlog), "--png", str(tmp_path / "r.png")]) == 0
    out = capsys.readouterr().out
    assert "AGNAV_BEHAVIOUR_STATUS" in out and "SET_POSITION_TARGET_LOCAL_NED" in out
    assert (tmp_path / "r.png").stat().st_size > 1000


def test_run_ctrl_c_engages_estop(monkeypatch, tmp_path):
    real_sleep = time.sleep
    calls = {"n": 0}

    def sleepy(s):
        calls["n"] += 1
        if calls["n"] == 5:
            raise KeyboardInterrupt
        real_sleep(s)

    with FakeRobot() as fr:
        monkeypatch.setattr(run_command, "_sleep", sleepy)
        rc = cli.main(["run", "--device", fr.device, "--planner", "subsumption", "--goal", "3,0", "--no-tlog"])
        assert rc == 130
        assert fr.estop
        sps = fr.received_of("AGNAV_DRIVE_SETPOINT")
        assert sps and sps[-1].speed_mm_s == 0  # zero setpoint before the e-stop


def test_run_usage_errors(capsys):
    assert cli.main(["run", "--device", "tcp:127.0.0.1:9", "--autopilot", "ardupilot"]) == 2
    assert cli.main(["run", "--device", "tcp:127.0.0.1:9", "--planner", "subsumption"]) == 2
    assert cli.main(["run", "--device", "tcp:127.0.0.1:9", "--planner", "nope", "--goal", "1,1"]) == 2
    assert "unknown planner" in capsys.readouterr().err


def test_a_calibration_step_must_outlast_its_settling():
    cfg = HostConfig()
    cfg.calibration.settle_s, cfg.calibration.max_step_s = 2.0, 1.5
    with pytest.raises(ConfigError, match=r"\[calibration\] settle_s: must be < max_step_s"):
        validate_config(cfg)
