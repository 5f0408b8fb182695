"""Laser faults: the host's planner (HIM) drives the SIL robot down ``corridor_obstacles`` on the
laser and the firmware's odometry; at 3 s the laser breaks for 3 s - every return vanishes (NaN),
it returns garbage, or its driver freezes and re-sends one scan. The host's laser watchdog
(``perception._health``) must notice, hold the robot with zero setpoints and say why; when the laser
is back the run goes on."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from ._core import FaultCase, FaultOutcome

if TYPE_CHECKING:
    from ..types import LaserScan

__all__ = ["LASER_CASES"]

T_FAULT_S, FAULT_LEN_S = 3.0, 3.0


class _BrokenLaser:
    """The host's laser_fault: each scan as the laser delivers it, broken (``mode``) from T_FAULT_S for
    FAULT_LEN_S after ``t0_s`` (the end of provisioning, set by the case)."""

    def __init__(self, mode: str) -> None:
        self.mode = mode
        self.t0_s = 0.0
        self._rng = np.random.default_rng(1)
        self._frozen: list[LaserScan] = []

    def __call__(self, scan: LaserScan, t_s: float) -> LaserScan:
        from ..types import LaserScan

        if not T_FAULT_S <= t_s - self.t0_s < T_FAULT_S + FAULT_LEN_S:
            return scan
        if self.mode == "nan":
            r = np.full(len(scan.ranges_m), np.nan)
        elif self.mode == "garbage":
            r = self._rng.uniform(-5.0, 60.0, len(scan.ranges_m))
        else:  # frozen: the last good buffer again, same time stamp
            if not self._frozen:
                self._frozen.append(scan)
            return self._frozen[0]
        return LaserScan(scan.angle_min_rad, scan.angle_increment_rad, r, scan.range_max_m, scan.stamp_s, scan.pose)


def _laser_case(mode: str) -> FaultOutcome:
    from ..sil import SilConfig, SilSession
    from ..sil.session import PlannerHost
    from ..sim import load_scenario

    sc = load_scenario("corridor_obstacles")
    host = PlannerHost(sc, "him")
    fault = _BrokenLaser(mode)
    host.laser_fault = fault
    s = SilSession(sc, 0, SilConfig(world_dt_s=0.01), host)
    try:
        s.provision()
        fault.t0_s = s.t_s
        t0 = s.t_us
        moving: list[tuple[float, bool, float]] = []
        g = sc.goals[-1]
        arrived = None
        while s.t_us - t0 < 40_000_000:
            s.step()
            t = (s.t_us - t0) * 1e-6
            o = s.fw.outputs()
            moving.append((t, bool(o.duty_left or o.duty_right), s.plant.robot.speed_m_s))
            if math.hypot(g.x_m - s.pose.x_m, g.y_m - s.pose.y_m) <= g.tolerance_m:
                arrived = t
                break
            if s.plant.clearance(s.t_s) < 0:
                break
        ev = [(t_us - t0) * 1e-6 for t_us, _ in host.events]
        text = host.events[0][1] if host.events else "NO EVENT"
    finally:
        s.close()
    t_end = T_FAULT_S + FAULT_LEN_S
    detect = ev[0] - T_FAULT_S if ev else math.inf
    during = [m for t, m, _ in moving if T_FAULT_S + detect + 0.3 <= t < t_end]
    still = next((t for t, _, v in moving if t > T_FAULT_S and abs(v) < 1e-3), math.inf) - T_FAULT_S
    held = bool(during) and not any(during)
    ok = detect <= 0.3 and held and arrived is not None
    return FaultOutcome(f"host: \"{text}\" {detect * 1000:.0f} ms after the fault; robot still after "
                        f"{still * 1000:.0f} ms and {'held' if held else 'NOT HELD'} until the laser was back; "
                        + (f"arrived at {arrived:.1f} s" if arrived else "DID NOT ARRIVE"), ok,
                        {"detect_ms": detect * 1000, "still_ms": still * 1000})


LASER_CASES = (
    FaultCase("laser: every return vanishes (NaN) for 3 s", "sensor",
              "host laser watchdog holds the robot within 0.3 s, says why, resumes when returns come back",
              lambda: _laser_case("nan")),
    FaultCase("laser: garbage ranges (-5..60 m) for 3 s", "sensor",
              "held within 0.3 s (2 bad scans), resumes after 5 good scans", lambda: _laser_case("garbage")),
    FaultCase("laser: driver frozen, re-sends one scan for 3 s", "sensor",
              "held within 0.3 s (time stamp not increasing), resumes after", lambda: _laser_case("frozen")),
)
