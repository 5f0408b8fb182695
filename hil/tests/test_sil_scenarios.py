"""SIL scenario tests (ArduPilot-autotest style): the real firmware, built natively against the
simulated HAL, drives the world simulator's robot; every assertion is on a measured outcome and
prints the measured value.

The robot is the 0.45 m differential drive of refs 001/002 with the 12-sonar ring; its profile
(DRIVE_KIND=1, two quadrature encoders, track) is stored in the firmware's EEPROM before boot and
its H-bridge tables are sent over MAVLink (AGNAV_CALIB_TABLE) at start, as a set-up tool would.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from _sil_logic import Heartbeats, PurePursuit

from agnav_host.sil import LinkParams, SilConfig, SilSession, run_sil_scenario
from agnav_host.sim import load_scenario

HERE = Path(__file__).resolve().parent
SCEN = HERE / "scenarios"

LAYER_FAILSAFE, LAYER_AVOID, LAYER_FOLLOW_WALL, LAYER_HOST = 1, 2, 4, 5
REASON_LINK_LOSS, REASON_STOP, REASON_BACKOFF, REASON_WAIT, REASON_CANYON = 2, 5, 6, 7, 11


def session(name: str, logic, seed: int = 0, **cfg) -> SilSession:
    sc = load_scenario(str(SCEN / f"{name}.toml")) if (SCEN / f"{name}.toml").exists() else load_scenario(name)
    s = SilSession(sc, seed, SilConfig(**cfg), logic)
    s.provision()
    return s


def test_drive_to_waypoint():
    """Host pure pursuit on the firmware's odometry to (3.0, 1.5): arrives within 0.15 m."""

    s = session("open_field", PurePursuit())
    try:
        g = s.sc.goals[0]
        s.run_for(20.0, until=lambda s: math.hypot(g.x_m - s.pose.x_m, g.y_m - s.pose.y_m) <= g.tolerance_m)
        err = math.hypot(g.x_m - s.pose.x_m, g.y_m - s.pose.y_m)
        assert err <= g.tolerance_m, f"robot ended {err:.3f} m from the waypoint after {s.t_s:.1f} s (pose {s.pose})"
        assert s.t_s < 15.0, f"waypoint (3.35 m away) took {s.t_s:.1f} s"
        bel = s.believed_pose()
        drift = math.hypot(bel.x_m - s.pose.x_m, bel.y_m - s.pose.y_m)
        assert drift < 0.1, f"firmware odometry {bel} is {drift:.3f} m off the true pose {s.pose}"
    finally:
        s.close()


def test_link_loss_stops_within_timeout():
    """Setpoints at 10 Hz, then the uplink is cut: the outputs go neutral within
    LINK_TIMEOUT_MS (500) + one control tick (20 ms) of the last frame the firmware received."""
    s = session("open_field", Heartbeats(0.1, (0, 400)), world_dt_s=0.002, record_outputs=True)
    try:
        s.run_for(2.0)
        assert s.pose.x_m > 0.3, f"robot did not drive before the cut (x = {s.pose.x_m:.3f} m)"
        s.up.down = True
        t_cut = s.t_us
        s.run_for(1.5)
        last_rx = s.up.last_delivery_us
        assert last_rx is not None and last_rx <= t_cut + 20_000
        moving_after = [t for t, o in s.outputs_log if t > last_rx and (o.duty_left or o.duty_right)]
        stop_t = max(moving_after) + s.dt_us if moving_after else last_rx
        reaction_ms = (stop_t - last_rx) / 1000.0
        assert 480.0 <= reaction_ms <= 500.0 + 20.0 + 2.0 + s.dt_us / 1000.0, \
            f"outputs went neutral {reaction_ms:.1f} ms after the last received frame (limit 500 ms + 20 ms tick)"
        fs = [st for st in s.host.status_log if st.t_us > t_cut and st.layer == LAYER_FAILSAFE
              and st.reason == REASON_LINK_LOSS]
        assert fs, "host did not see the LINK_LOSS failsafe on the downlink"
        fs_ms = fs[0].time_boot_ms - last_rx / 1000.0  # firmware tick time of the first LINK_LOSS
        assert 480.0 <= fs_ms <= 500.0 + 20.0 + 2.0, \
            f"LINK_LOSS failsafe raised {fs_ms:.1f} ms after the last received frame (limit 500 ms + 20 ms tick)"
        x_stop = s.pose.x_m
        s.run_for(0.5)
        assert abs(s.pose.x_m - x_stop) < 1e-3, f"robot still moving after the failsafe ({s.pose.x_m - x_stop:.4f} m)"
    finally:
        s.close()


def test_obstacle_stop_and_backoff():
    """Host insists on 0.4 m/s straight at a wall: passive safety stops short of it, backs off
    AVOID_BACKOFF_MM (50 mm) and never touches it."""
    s = session("wall_ahead", Heartbeats(0.1, (0, 400)), world_dt_s=0.005)
    try:
        wall_x = 3.0
        gaps: list[tuple[float, float, int]] = []  # (t, gap robot edge -> wall, reason)
        min_gap = math.inf
        while s.t_s < 12.0:
            s.step()
            gap = wall_x - s.pose.x_m - s.plant.robot.radius_m
            min_gap = min(min_gap, gap)
            st = s.host.status
            gaps.append((s.t_s, gap, st.reason if st and st.layer == LAYER_AVOID else 0))
        stops = [g for g in gaps if g[2] == REASON_STOP]
        assert stops, "passive safety never stopped the robot"
        first_stop_gap = stops[0][1]
        assert min_gap >= 0.10, f"robot came within {min_gap * 1000:.0f} mm of the wall (first STOP at {first_stop_gap * 1000:.0f} mm)"
        backoff = [g for g in gaps if g[2] == REASON_BACKOFF]
        assert backoff, "no back-off after the stop"
        i0 = gaps.index(backoff[0])
        after = [g for g in gaps[i0:] if g[2] in (REASON_BACKOFF, REASON_WAIT)]
        waits = [g for g in after if g[2] == REASON_WAIT]
        assert waits, "back-off never ended in WAIT"
        gap_at_wait = waits[0][1]
        gap_before = min(g[1] for g in gaps[:i0 + 1])
        backed = gap_at_wait - gap_before
        assert 0.035 <= backed <= 0.09, f"backed off {backed * 1000:.0f} mm (AVOID_BACKOFF_MM 50)"
        assert s.plant.clearance(s.t_s) > 0.0
    finally:
        s.close()


def test_follow_wall_down_corridor():
    """Follow-wall (MAV_CMD_AGNAV_SET_BEHAVIOURS 45901) drives down a 2 m corridor: >= 4 m in
    25 s, stays off both walls, and the follow-wall layer is in charge."""
    s = session("wall_corridor", Heartbeats(0.2, None, follow_wall=True))
    try:
        min_cl = math.inf
        while s.t_s < 25.0:
            s.step()
            min_cl = min(min_cl, s.plant.clearance(s.t_s))
        ack = [a for a in s.host.acks if a.command == 45901]
        assert ack and ack[0].result == 0, f"SET_BEHAVIOURS not accepted: {ack}"
        dist = s.pose.x_m - s.sc.start.x_m
        assert dist >= 4.0, f"follow-wall covered only {dist:.2f} m in 25 s"
        assert min_cl >= 0.2, f"came within {min_cl:.3f} m of a wall"
        wall = sum(1 for st in s.host.status_log if st.layer == LAYER_FOLLOW_WALL)
        frac = wall / max(1, len(s.host.status_log))
        assert frac > 0.9, f"follow-wall layer active only {frac:.0%} of the ticks"
        assert abs(s.pose.y_m - 1.0) < 0.4, f"ended {s.pose.y_m - 1.0:+.2f} m off the corridor centre"
    finally:
        s.close()


def _canyon_run(seconds: float):
    s = session("canyon", Heartbeats(0.2, (0, 300), follow_wall=True))
    steer_signs: list[int] = []
    inside_t = None
    out_t = None
    try:
        while s.t_s < seconds:
            s.step()
            p = s.pose
            inside = 2.5 < p.x_m < 4.5 and abs(p.y_m) < 1.2
            if inside and inside_t is None:
                inside_t = s.t_s
            if inside_t is not None and not inside and out_t is None:
                out_t = s.t_s
            st = s.host.status
            if inside and st is not None and st.layer == LAYER_FOLLOW_WALL and abs(st.steer_cdeg) >= 500:
                sg = 1 if st.steer_cdeg > 0 else -1
                if not steer_signs or steer_signs[-1] != sg:
                    steer_signs.append(sg)
        return s, inside_t, out_t, steer_signs
    finally:
        s.close()


@pytest.fixture(scope="module")
def canyon_run():
    return _canyon_run(40.0)


def test_canyon_no_oscillation(canyon_run):
    """In the dead-end canyon the canyon timer holds one turn direction: at most one steering
    sign change (|steer| >= 5 deg) while inside."""
    s, inside_t, _, signs = canyon_run
    assert inside_t is not None, "robot never entered the canyon"
    changes = max(0, len(signs) - 1)
    assert changes <= 1, f"{changes} steering sign changes inside the canyon (sequence {signs})"
    assert any(st.reason == REASON_CANYON for st in s.host.status_log), "canyon timer never engaged"


def test_canyon_escape(canyon_run):
    """The robot leaves the canyon within 40 s of simulated time."""
    s, inside_t, out_t, _ = canyon_run
    assert out_t is not None, f"still in the canyon after {s.t_s:.0f} s (pose {s.pose})"


def test_corridor_obstacles_s_to_g():
    """Ref 002 experiment I: the 8 m corridor with four obstacles, host goal_seek planner on the
    laser + firmware odometry, firmware passive safety underneath: reaches G."""
    sc = load_scenario("corridor_obstacles")
    res = run_sil_scenario(sc, "goal_seek", seed=0, duration_s=60.0)
    m = res.run.metrics
    assert res.run.end_reason == "arrived", (f"ended {res.run.end_reason} after {m.time_s:.1f} s, "
                                             f"{m.final_position_error_m:.2f} m from G")
    assert m.time_s < 55.0, f"S to G took {m.time_s:.1f} s"
    assert m.min_clearance_m > 0.1, f"min clearance {m.min_clearance_m:.3f} m"


def test_determinism_byte_identical_tlog():
    """Two runs with the same seed (5 % frame loss each way) give byte-identical telemetry logs;
    another seed gives a different one."""
    sc = load_scenario("corridor_obstacles")
    lossy = LinkParams(loss=0.05)
    cfg = SilConfig(uplink=lossy, downlink=lossy)
    a = run_sil_scenario(sc, seed=7, duration_s=8.0, config=cfg)
    b = run_sil_scenario(sc, seed=7, duration_s=8.0, config=cfg)
    c = run_sil_scenario(sc, seed=8, duration_s=8.0, config=cfg)
    assert len(a.tlog) > 10_000, f"tlog only {len(a.tlog)} bytes"
    assert a.link_stats["down_lost"] > 0 and a.link_stats["up_lost"] > 0, a.link_stats
    assert a.tlog == b.tlog, f"same seed, different tlogs ({len(a.tlog)} vs {len(b.tlog)} bytes)"
    assert (a.run.trajectory == b.run.trajectory).all()
    assert a.tlog != c.tlog, "different seeds gave identical tlogs"


def test_storage_upkeep_only_at_rest():
    """The firmware tells the HAL once a second that the robot is at rest (hal_eeprom_idle: the STM32
    moves its flash EEPROM then, so an erase never stalls a moving robot): never while it drives to
    the waypoint, about once a second after it has stopped there."""
    s = session("open_field", PurePursuit())
    try:
        g = s.sc.goals[0]
        standing = s.fw.eeprom_idle_calls()  # the set-up (calibration upload and its save) ran at rest
        s.run_for(1.5)
        moving = s.fw.eeprom_idle_calls() - standing
        assert s.pose.x_m > 0.3, f"robot did not drive (x = {s.pose.x_m:.3f} m)"
        s.run_for(20.0, until=lambda s: math.hypot(g.x_m - s.pose.x_m, g.y_m - s.pose.y_m) <= g.tolerance_m)
        s.host_logic = None  # the host goes quiet: no more setpoints, the robot stops and stays
        s.run_for(1.5)
        before = s.fw.eeprom_idle_calls()
        s.run_for(4.0)
        at_rest = s.fw.eeprom_idle_calls() - before
        print(f"idle calls: {moving} in the first 1.5 s of driving, {at_rest} in 4 s at rest")
        assert moving == 0, f"{moving} idle calls while driving"
        assert 3 <= at_rest <= 5, f"{at_rest} idle calls in 4 s at rest"
    finally:
        s.close()
