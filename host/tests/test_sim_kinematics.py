import math

import numpy as np
import pytest

from agnav_host.calib import default_speed_table, default_steering_table
from agnav_host.sim.robots import Ackermann, AckermannParams, DiffDrive, DiffDriveParams
from agnav_host.types import DriveCommand, Pose2D, PwmCommand

# ref 002 test arc: x = 2 cos(phi), y = 2 sin(phi), phi = 0.03 t -> v = 0.06 m/s, w = 0.03 rad/s
R, W = 2.0, 0.03


def _run(robot, cmd, seconds, dt=0.05):
    for _ in range(int(round(seconds / dt))):
        robot.step(cmd, dt)


def test_diff_drive_straight_line_matches_closed_form():
    r = DiffDrive(DiffDriveParams.ideal())
    r.reset(Pose2D(1.0, 2.0, math.radians(30)))
    _run(r, DriveCommand(0.4, 0.0), 10.0)
    assert r.pose.x_m == pytest.approx(1.0 + 4.0 * math.cos(math.radians(30)), abs=1e-9)
    assert r.pose.y_m == pytest.approx(2.0 + 4.0 * math.sin(math.radians(30)), abs=1e-9)


@pytest.mark.parametrize("kind", ["diff_drive", "ackermann"])
def test_ref002_arc_matches_closed_form(kind):
    if kind == "diff_drive":
        r = DiffDrive(DiffDriveParams.ideal())
        cmd = DriveCommand(R * W, W)
    else:
        r = Ackermann(AckermannParams.ideal())
        cmd = DriveCommand(R * W, 0.0, math.atan(r.params.wheelbase_m / R))
    r.reset(Pose2D(R, 0.0, math.pi / 2))
    elapsed = 0.0
    for t_end in (10.0, 50.0, 100.0):
        _run(r, cmd, t_end - elapsed)
        elapsed = t_end
        phi = W * t_end
        assert r.pose.x_m == pytest.approx(R * math.cos(phi), abs=1e-6), t_end
        assert r.pose.y_m == pytest.approx(R * math.sin(phi), abs=1e-6), t_end


def test_diff_drive_first_order_lag_step_response():
    p = DiffDriveParams(tau_s=0.2, max_accel_m_s2=1e6, deadband_m_s=0.0, slip_std=0.0)
    r = DiffDrive(p)
    _run(r, DriveCommand(0.5, 0.0), 0.2, dt=0.01)
    assert r.speed_m_s == pytest.approx(0.5 * (1 - math.exp(-1.0)), rel=1e-6)


def test_diff_drive_acceleration_limit_and_dead_band():
    r = DiffDrive(DiffDriveParams(tau_s=0.0, max_accel_m_s2=0.5, slip_std=0.0))
    _run(r, DriveCommand(1.0, 0.0), 1.0, dt=0.01)
    assert r.speed_m_s == pytest.approx(0.5, abs=1e-9)
    r2 = DiffDrive(DiffDriveParams(deadband_m_s=0.05, slip_std=0.0))
    _run(r2, DriveCommand(0.03, 0.0), 2.0)
    assert r2.pose.x_m == 0.0


def test_slip_noise_moves_pose_but_not_wheel_angles():
    p = DiffDriveParams(slip_std=0.05)
    a, b = DiffDrive(p), DiffDrive(p)
    rng = np.random.default_rng(3)
    for _ in range(200):
        a.step(DriveCommand(0.5, 0.0), 0.02, rng)
        b.step(DriveCommand(0.5, 0.0), 0.02, None)
    assert np.allclose(a.wheel_angles_rad, b.wheel_angles_rad)
    assert a.pose.x_m != b.pose.x_m


def _calibrated(true_steer_scale=1.0, true_offset=0.0):
    s, v = default_steering_table(), default_speed_table()
    return Ackermann(AckermannParams.ideal(true_steer=s.miscalibrated(true_steer_scale, true_offset), ctrl_steer=s,
                                           true_speed=v, ctrl_speed=v))


def test_ackermann_calibrated_physical_command_reaches_setpoint():
    r = _calibrated()
    steer, speed = r.physical_targets(DriveCommand(1.0, 0.0, math.radians(10)))
    assert math.degrees(steer) == pytest.approx(10.0, abs=0.7)  # 1-count PWM quantisation
    assert speed == pytest.approx(1.0, abs=0.025)


def test_ackermann_speed_dead_band_and_saturation():
    r = _calibrated()
    # slower than the car's minimum speed: the controller (like the firmware's calib_table_pwm) stops
    assert r.physical_targets(DriveCommand(0.2, 0.0, 0.0))[1] == 0.0
    assert r.physical_targets(DriveCommand(0.44, 0.0, 0.0))[1] == pytest.approx(0.44, abs=0.02)  # in the band
    assert r.physical_targets(DriveCommand(5.0, 0.0, 0.0))[1] == pytest.approx(2.0, abs=0.01)
    assert r.pwm_targets(PwmCommand(133, 20))[1] == 0.0  # below the speed dead band
    assert r.physical_targets(DriveCommand(1.0, 0.0, math.radians(60)))[0] == pytest.approx(math.radians(24.6))


def test_miscalibrated_ackermann_turns_less_than_believed():
    good, bad = _calibrated(), _calibrated(0.8)
    cmd = DriveCommand(1.0, 0.0, math.radians(15))
    for r in (good, bad):
        _run(r, cmd, 1.0, dt=0.01)
    assert abs(bad.pose.yaw_rad) < abs(good.pose.yaw_rad)
    assert math.degrees(bad.steer_rad) == pytest.approx(0.8 * math.degrees(good.steer_rad), rel=0.05)


def test_ackermann_positive_steer_turns_left():
    r = _calibrated()
    _run(r, DriveCommand(1.0, 0.0, math.radians(10)), 1.0, dt=0.01)
    assert r.pose.y_m > 0 and r.pose.yaw_rad > 0
