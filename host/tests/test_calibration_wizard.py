"""Calibration wizard protocol steps against the fake robot (raw sweeps, write, read-back, save)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from agnav_host.calib import default_speed_table, default_steering_table
from agnav_host.calibration.wizard import Aborted, ScriptedIO, Wizard, sweep_points
from agnav_host.link import AgnavRobot, Endpoint
from agnav_host.link.calib_wire import TABLE_SPEED, TABLE_STEER
from agnav_host.link.config import CalibrationConfig
from agnav_host.link.fake import FakeRobot

FAST = dict(settle_s=0.1, hold_s=0.25, max_step_s=1.0, pause_s=0.05)
CDEG = 18000.0 / math.pi


def test_sweep_points_bounded():
    assert sweep_points(96, 171, 25, 133) == [96, 121, 133, 146, 171]
    with pytest.raises(ValueError):
        sweep_points(0, 3000, 10)  # too many steps
    assert sweep_points(-50, 5000, 1000)[0] == 0 and sweep_points(-50, 5000, 1000)[-1] == 3000


@pytest.fixture
def rig():
    true_s = default_steering_table().miscalibrated(0.85, 4)
    true_v = default_speed_table().miscalibrated(0.8, 5)
    with FakeRobot(true_steer=true_s, true_speed=true_v, rate_scale=4, speed_noise_m_s=0.005, seed=4) as fr:
        with Endpoint(fr.device, budget_bytes_s=1e6) as ep:
            ep.wait_heartbeat(3.0)
            yield fr, AgnavRobot(ep), true_s, true_v


def test_steering_wizard_writes_verifies_saves(rig, tmp_path):
    fr, robot, true_s, _ = rig
    io = ScriptedIO()
    cfg = CalibrationConfig(steer_step=10, **FAST)
    fit = Wizard(robot, cfg, io, plot_dir=tmp_path).run_steering(save=True)
    raw = [m for m in fr.received_of("AGNAV_DRIVE_SETPOINT") if m.mode == 1]
    assert {m.steer_pwm for m in raw} == set(sweep_points(96, 171, 10, 133))
    assert all(m.speed_pwm == cfg.steer_speed_pwm for m in raw)
    assert fr.tables[TABLE_STEER] == fit.table  # written
    assert any(m.get_type() == "AGNAV_CALIB_REQUEST" and m.action == 0 for m in fr.received)  # read back
    assert fr.saved_tables is not None and fr.saved_tables[TABLE_STEER] == fit.table  # saved
    assert abs(fit.neutral_pwm - 137) <= 1
    grid = np.arange(100, 168)
    err = np.array([fit.table.value(int(g)) for g in grid]) - true_s.value_from_pwm(grid) * CDEG
    assert np.sqrt(np.mean(err ** 2)) < 120  # within ~1 deg RMS of the car's true steering
    assert (tmp_path / "calib_steer.png").stat().st_size > 5000
    assert fr.received_of("AGNAV_DRIVE_SETPOINT")[-1].mode == 0  # ends with a physical stop


def test_speed_wizard(rig):
    fr, robot, _, true_v = rig
    cfg = CalibrationConfig(speed_step=16, **FAST)
    fit = Wizard(robot, cfg, ScriptedIO()).run_speed(save=False)
    assert fr.tables[TABLE_SPEED] == fit.table and fr.saved_tables is None
    assert fit.table.neg == ()
    for p in (60, 90):
        assert fit.table.value(p) == pytest.approx(true_v.value_from_pwm(p) * 1000, abs=60)


def test_declined_start_moves_nothing(rig):
    fr, robot, _, _ = rig
    with pytest.raises(Aborted, match="declined"):
        Wizard(robot, CalibrationConfig(**FAST), ScriptedIO(["n"])).run_steering()
    assert not fr.received_of("AGNAV_DRIVE_SETPOINT")
    assert not fr.received_of("AGNAV_CALIB_TABLE")


def test_declined_write_keeps_the_old_table(rig):
    fr, robot, _, _ = rig
    before = fr.tables[TABLE_SPEED]
    with pytest.raises(Aborted, match="not written"):
        Wizard(robot, CalibrationConfig(speed_step=24, **FAST), ScriptedIO(["y", "n"])).run_speed()
    assert fr.tables[TABLE_SPEED] == before


def test_ctrl_c_engages_estop(rig, monkeypatch):
    fr, robot, _, _ = rig
    w = Wizard(robot, CalibrationConfig(**FAST), ScriptedIO())
    calls = {"n": 0}
    real = w.measure_step

    def boom(*a, **k):
        calls["n"] += 1
        if calls["n"] == 2:
            raise KeyboardInterrupt
        return real(*a, **k)

    monkeypatch.setattr(w, "measure_step", boom)
    with pytest.raises(Aborted, match="interrupted"):
        w.run_steering()
    assert fr.estop
    assert not fr.received_of("AGNAV_CALIB_TABLE")


def test_step_discarded_when_a_higher_layer_takes_over(rig):
    fr, robot, _, _ = rig
    w = Wizard(robot, CalibrationConfig(settle_s=0.1, hold_s=1.5, max_step_s=2.0), ScriptedIO())
    robot.release()
    fr.estop = True  # e.g. someone pressed the e-stop
    r = w.measure_step(133, 40, "speed", "encoders")
    assert not r.ok and "took over" in r.note and r.duration_s < 1.5
