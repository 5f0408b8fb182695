"""``agnav plan``: a timed plan from a start pose to a goal pose, with its feasibility.

    agnav plan --start 0,0,45 --goal 100,100,45 --arrive-in 60 --json

Poses are ``X,Y,HEADING_DEG`` in m and deg (negative numbers work: ``--goal -3,5,90``). Limits default
to the ref-003 RC car (wheelbase 174 mm, steering <= 20 deg commanded and 17 deg planned, speed 0 or
43.5-200 cm/s, 1 m/s^2, servo steering rate 200 deg/s, no reverse). The path is the ref-003 polynomial
where it fits, else a continuous-curvature (clothoid), Dubins or, with ``--reverse-speed``, Reeds-Shepp
path (``path_type``; ``reverse_m`` is the length driven backwards). Exit code 0 when the plan meets the time,
3 when it does not (the output then gives the reason and the earliest feasible arrival), 2 for a bad
option value or a goal no path reaches (the reason is printed).

``--samples N`` prints N states evenly spaced in time from the start to the moment the car is at rest on
the goal; the plan's *arrival* (``duration_s``) is a fraction of a second earlier, when the final stop
brings the car within 5 cm of the goal (see :class:`~agnav_host.planning.timed.TimedLimits`).
"""

from __future__ import annotations

import argparse
import json
import math
import sys

from ..planning.timed import TimedLimits
from .argtypes import finite_float, int_in, nonneg_float, positive_float, up_to_a_day
from .registry import subcommand

__all__: list[str] = []


def _pose(text: str) -> tuple[float, float, float]:
    parts = [p.strip() for p in text.split(",")]
    if len(parts) != 3:
        raise argparse.ArgumentTypeError(f"pose must be X,Y,HEADING_DEG, got {text!r}")
    try:
        vals = [float(p) for p in parts]
    except ValueError:
        raise argparse.ArgumentTypeError(f"pose must contain numbers, got {text!r}") from None
    if not all(math.isfinite(v) for v in vals):
        raise argparse.ArgumentTypeError(f"pose values must be finite, got {text!r}")
    if max(abs(vals[0]), abs(vals[1])) > MAX_COORD_M:
        raise argparse.ArgumentTypeError(f"pose x and y must be within +-{MAX_COORD_M:g} m (100 km), got {text!r}")
    return vals[0], vals[1], vals[2]


#: Largest |x|, |y| of a pose `plan` takes, m: a field robot's task lies well within it (1e300 printed
#: 300-digit figures); its arrival time is at most a day (argtypes.up_to_a_day)
MAX_COORD_M = 1e5


_DEF = TimedLimits()
#: Most states --samples prints: 100 000 lines are about 6 MB of text and take a few seconds; more would only
#: cost memory and time (10 million took more than 3 GB).
MAX_SAMPLES = 100_000
_MAX_STEER_DEG = math.degrees(_DEF.max_steer_rad)
_PLAN_STEER_DEG = math.degrees(_DEF.plan_steer_rad)


@subcommand(
    "plan",
    help="timed trajectory from a start pose to a goal pose arriving at a set time (ref 003)",
    epilog="exit codes: 0 = feasible, 3 = not feasible (the reason is printed), 2 = a bad option value",
    args=[
        (("--start",), {"type": _pose, "required": True, "metavar": "X,Y,HDG_DEG", "help": "start pose (m, m, deg)"}),
        (("--goal",), {"type": _pose, "required": True, "metavar": "X,Y,HDG_DEG", "help": "goal pose (m, m, deg)"}),
        (("--arrive-in",), {"type": up_to_a_day, "default": None, "metavar": "SECONDS",
                            "help": "arrival time after the start, s, > 0 and <= 86400 (default: untimed, at the cruise speed "
                                    f"{_DEF.cruise_m_s:g} m/s, capped at --max-speed)"}),
        (("--start-steer-deg",), {"type": finite_float, "default": 0.0, "metavar": "DEG",
                                  "help": f"steering angle at the start, deg, + = left, |value| <= {_MAX_STEER_DEG:g} "
                                          f"(the plan starts from at most {_PLAN_STEER_DEG:g}) (default 0)"}),
        (("--goal-steer-deg",), {"type": finite_float, "default": 0.0, "metavar": "DEG",
                                 "help": f"steering angle at the goal, deg, + = left, |value| <= {_PLAN_STEER_DEG:g} "
                                         "(default 0)"}),
        (("--start-speed",), {"type": nonneg_float, "default": 0.0, "metavar": "M_S",
                              "help": "speed at the start, m/s, >= 0 and <= --max-speed (default 0)"}),
        (("--max-speed",), {"type": positive_float, "default": _DEF.v_max_m_s, "metavar": "M_S",
                            "help": f"top of the speed band, m/s (default {_DEF.v_max_m_s:g})"}),
        (("--min-speed",), {"type": nonneg_float, "default": _DEF.v_min_m_s, "metavar": "M_S",
                            "help": f"bottom of the speed band, m/s (default {_DEF.v_min_m_s:g})"}),
        (("--accel",), {"type": positive_float, "default": _DEF.accel_m_s2, "metavar": "M_S2",
                        "help": f"acceleration limit, m/s^2, > 0 (default {_DEF.accel_m_s2:g})"}),
        (("--reverse-speed",), {"type": nonneg_float, "default": 0.0, "metavar": "M_S",
                                "help": "top reverse speed, m/s: the reverse side of the speed calibration; above "
                                        "--min-speed allows Reeds-Shepp paths (default 0: no reverse, as the ref-003 car)"}),
        (("--samples",), {"type": int_in(2, MAX_SAMPLES), "default": None, "metavar": "N",
                          "help": f"also print N >= 2 states, at most {MAX_SAMPLES} (t s, x m, y m, yaw deg, speed m/s, "
                                  "steering deg) evenly spaced from the start to the car at rest on the goal (default: "
                                  "none)"}),
        (("--json",), {"action": "store_true", "help": "print JSON"}),
    ],
)
def _cmd_plan(ns: argparse.Namespace) -> int:
    import numpy as np

    from ..planning.timed import BoundaryState, plan_timed

    for opt, val, lim_deg in (("--start-steer-deg", ns.start_steer_deg, _MAX_STEER_DEG),
                              ("--goal-steer-deg", ns.goal_steer_deg, _PLAN_STEER_DEG)):
        if abs(val) > lim_deg + 1e-9:
            print(f"agnav plan: {opt} {val:g} is beyond the steering limit of +-{lim_deg:g} deg", file=sys.stderr)
            return 2
    if ns.start_speed > ns.max_speed:
        print(f"agnav plan: --start-speed {ns.start_speed:g} m/s is above --max-speed {ns.max_speed:g} m/s", file=sys.stderr)
        return 2
    try:
        lim = TimedLimits(v_min_m_s=ns.min_speed, v_max_m_s=ns.max_speed, accel_m_s2=ns.accel,
                          reverse_v_max_m_s=ns.reverse_speed)
    except ValueError as e:
        print(f"agnav plan: {e}", file=sys.stderr)
        return 2
    sx, sy, sh = ns.start
    gx, gy, gh = ns.goal
    start = BoundaryState(sx, sy, math.radians(sh), math.radians(ns.start_steer_deg), ns.start_speed)
    goal = BoundaryState(gx, gy, math.radians(gh), math.radians(ns.goal_steer_deg), 0.0)
    plan = plan_timed(start, goal, 0.0, ns.arrive_in, lim)
    if plan.path.length_m <= 0.0:
        print(f"agnav plan: the goal cannot be reached: {plan.reason.removeprefix('no path: ')}", file=sys.stderr)
        return 2
    out = plan.summary()
    out["rest_s"] = round(plan.profile.duration_s, 3)  # at rest on the goal (arrival = within 5 cm, earlier)
    if ns.samples is not None and plan.path.length_m > 0:
        ts = np.linspace(0.0, plan.profile.duration_s, ns.samples)  # the last one: at rest on the goal
        x, y, yaw, k, v, _ = plan.at(ts)
        yaw_deg = (np.degrees(yaw) + 180.0) % 360.0 - 180.0  # the path's yaw is unwrapped (loops reach +-360)
        out["samples"] = [[round(float(a), 4) + 0.0 for a in row] for row in  # + 0.0: no -0.0
                          zip(ts, x, y, yaw_deg, v, np.degrees(np.arctan(lim.wheelbase_m * k)))]
    if ns.json:
        print(json.dumps(out, indent=2))
    else:
        verdict = "feasible" if plan.feasible else "NOT feasible"
        print(f"{verdict}: {plan.reason}")
        print(f"  path type {out['path_type']}, reverse {out['reverse_m']:.2f} m")
        if plan.path.length_m > 0:
            print(f"  path {out['path_length_m']:.2f} m, duration {out['duration_s']:.2f} s, cruise {out['cruise_speed_mps']:.3f} m/s, "
                  f"max speed {out['max_speed_mps']:.3f} m/s, max steering {out['max_steering_deg']:.1f} deg, "
                  f"dwell {out['dwell_s']:.2f} s")
        if out["earliest_arrival_s"] is not None:
            print(f"  earliest feasible arrival: {out['earliest_arrival_s']:.2f} s")
        if out["via_points"]:
            print(f"  via points: {out['via_points']}")
        if "samples" in out:
            print(f"  arrival (within {lim.arrive_tol_m * 100:g} cm of the goal) at {out['duration_s']:.2f} s, "
                  f"at rest on the goal at {out['rest_s']:.2f} s")
        for row in out.get("samples", []):
            print("  t={:7.2f} x={:8.3f} y={:8.3f} yaw={:7.2f} v={:6.3f} steer={:6.2f}".format(*row))
    return 0 if plan.feasible else 3
