"""``agnav plan``: a timed plan from a start pose to a goal pose, with its feasibility.

    agnav plan --start 0,0,45 --goal 100,100,45 --arrive-in 60 --json

Poses are ``X,Y,HEADING_DEG`` in m and deg (negative numbers work: ``--goal -3,5,90``). Limits default
to the ref-003 RC car (wheelbase 174 mm, steering <= 20 deg commanded and 17 deg planned, speed 0 or
43.5-200 cm/s, 1 m/s^2). Exit code 0 when the plan meets the time, 3 when it does not (the output then
gives the reason and the earliest feasible arrival).
"""

from __future__ import annotations

import argparse
import json
import math

from ..cli import subcommand

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
    return vals[0], vals[1], vals[2]


@subcommand(
    "plan",
    help="timed trajectory from a start pose to a goal pose arriving at a set time (ref 003)",
    args=[
        (("--start",), {"type": _pose, "required": True, "metavar": "X,Y,HDG_DEG", "help": "start pose (m, m, deg)"}),
        (("--goal",), {"type": _pose, "required": True, "metavar": "X,Y,HDG_DEG", "help": "goal pose (m, m, deg)"}),
        (("--arrive-in",), {"type": float, "default": None, "metavar": "SECONDS",
                            "help": "arrival time after the start, s (default: untimed, at the cruise speed)"}),
        (("--start-steer-deg",), {"type": float, "default": 0.0, "help": "steering angle at the start, deg"}),
        (("--goal-steer-deg",), {"type": float, "default": 0.0, "help": "steering angle at the goal, deg"}),
        (("--start-speed",), {"type": float, "default": 0.0, "help": "speed at the start, m/s"}),
        (("--max-speed",), {"type": float, "default": 2.0, "help": "top of the speed band, m/s (default 2.0)"}),
        (("--min-speed",), {"type": float, "default": 0.435, "help": "bottom of the speed band, m/s (default 0.435)"}),
        (("--accel",), {"type": float, "default": 1.0, "help": "acceleration limit, m/s^2 (default 1.0)"}),
        (("--samples",), {"type": int, "default": 0, "help": "also print this many (t, x, y, yaw, speed, steer) samples"}),
        (("--json",), {"action": "store_true", "help": "print JSON"}),
    ],
    negative_ok=["--start", "--goal", "--start-steer-deg", "--goal-steer-deg"],
)
def _cmd_plan(ns: argparse.Namespace) -> int:
    import numpy as np

    from .timed import BoundaryState, TimedLimits, plan_timed

    if ns.arrive_in is not None and not (math.isfinite(ns.arrive_in) and ns.arrive_in > 0):
        print("agnav plan: --arrive-in must be > 0", flush=True)
        return 2
    try:
        lim = TimedLimits(v_min_m_s=ns.min_speed, v_max_m_s=ns.max_speed, accel_m_s2=ns.accel)
    except ValueError as e:
        print(f"agnav plan: {e}")
        return 2
    sx, sy, sh = ns.start
    gx, gy, gh = ns.goal
    start = BoundaryState(sx, sy, math.radians(sh), math.radians(ns.start_steer_deg), ns.start_speed)
    goal = BoundaryState(gx, gy, math.radians(gh), math.radians(ns.goal_steer_deg), 0.0)
    if math.hypot(gx - sx, gy - sy) < 1e-6:
        print("agnav plan: start and goal positions coincide")
        return 2
    plan = plan_timed(start, goal, 0.0, ns.arrive_in, lim)
    out = plan.summary()
    if ns.samples > 0 and plan.path.length_m > 0:
        ts = np.linspace(0.0, plan.duration_s, ns.samples)
        x, y, yaw, k, v, _ = plan.at(ts)
        out["samples"] = [[round(float(a), 4) for a in row] for row in
                          zip(ts, x, y, np.degrees(yaw), v, np.degrees(np.arctan(lim.wheelbase_m * k)))]
    if ns.json:
        print(json.dumps(out, indent=2))
    else:
        verdict = "feasible" if plan.feasible else "NOT feasible"
        print(f"{verdict}: {plan.reason}")
        print(f"  path {out['path_length_m']:.2f} m, duration {out['duration_s']:.2f} s, cruise {out['cruise_speed_mps']:.3f} m/s, "
              f"max speed {out['max_speed_mps']:.3f} m/s, max steering {out['max_steering_deg']:.1f} deg, dwell {out['dwell_s']:.2f} s")
        if out["earliest_arrival_s"] is not None:
            print(f"  earliest feasible arrival: {out['earliest_arrival_s']:.2f} s")
        if out["via_points"]:
            print(f"  via points: {out['via_points']}")
        for row in out.get("samples", []):
            print("  t={:7.2f} x={:8.3f} y={:8.3f} yaw={:7.2f} v={:6.3f} steer={:6.2f}".format(*row))
    return 0 if plan.feasible else 3
