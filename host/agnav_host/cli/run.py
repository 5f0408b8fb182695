"""``agnav run``: drive a robot (or the SIL over TCP) with any controller of the registry, its lasers, localisation
and timed goals, through the host loop (:mod:`agnav_host.robot`); or with the firmware's own layers.

Exit codes: 0 done (goal reached or duration up), 1 robot, link, laser or output failure, 2 usage or
configuration error, 130 Ctrl-C (the robot is e-stopped).
"""

from __future__ import annotations

import argparse
import math
import re
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

from ..units import cdeg_to_rad, milli_to_si
from .argtypes import finite_float, parse_goal, positive_float
from .link import _LINK_ARGS, _config, _err, _guard, _open, _tlog_path
from .outputs import OutputError, check_output, clear_earlier_outputs, unusable_out_dir
from .registry import subcommand

__all__ = ["laser_feeds_from", "mount_from_url", "robot_spec_from", "field_from"]

_sleep = time.sleep  # the run's pacing (tests replace it to inject Ctrl-C)

#: What `agnav run --out DIR` writes (the files of an earlier run there are removed first).
RUN_OUTPUTS = ("summary.json", "run_info.json", "trajectory.csv", "trajectory.png", "recording.rrd", "laser.alog",
               "link.tlog", "localisation.csv")


class _FirmwareGoal:
    """A goal for the firmware's move-to-goal layer, and when it counts as reached.

    The layer reports GOAL_REACHED (reason 14) until it gets a new goal, and the goal frame is not
    acknowledged: a status from before the goal arrived, or a goal lost on the radio, would read as
    "reached" at once. So GOAL_REACHED counts only when received after the goal was sent and either
    the layer has been seen seeking this goal since, or the odometry pose is within the robot's own
    GOAL_TOL_MM of it (a goal where the robot already stands). Until the layer is seen seeking, the
    goal is sent again every second."""

    RESEND_S = 1.0

    def __init__(self, robot: Any, x_m: float, y_m: float, tol_m: float) -> None:
        self.robot, self.x_m, self.y_m, self.tol_m = robot, x_m, y_m, tol_m
        self.seeking = False
        self._send(time.monotonic())

    def _send(self, now_s: float) -> None:
        self.robot.set_goal(self.x_m, self.y_m)
        self.sent_s = now_s

    def again(self, now_s: float) -> None:
        """The goal once more, as at the start (after a link loss the firmware does not use its stored one)."""
        self.seeking = False
        self._send(now_s)

    def reached(self, st: Any, now_s: float) -> bool:
        b = st.behaviour
        fresh = b is not None and b.rx_time_s > self.sent_s
        if fresh and b.reason != 14:
            self.seeking = True
        if not self.seeking and now_s - self.sent_s >= self.RESEND_S:
            self._send(now_s)
            return False
        if not (fresh and b.reason == 14):
            return False
        p = st.pose
        near = p is not None and math.hypot(p.x_m - self.x_m, p.y_m - self.y_m) <= self.tol_m + 0.05
        return self.seeking or near


class _LinkBack:
    """True once each time the link comes back: the firmware reported a LINK_LOSS failsafe, then a status
    that is no failsafe. The firmware then holds its goal and follow-wall layers until a fresh command
    (docs/safety.md "Failsafe hold"), so the run sends its behaviours and goal again."""

    def __init__(self) -> None:
        self.lost = False
        self.seen_s = -math.inf

    def __call__(self, st: Any) -> bool:
        b = st.behaviour
        if b is None or b.rx_time_s <= self.seen_s:
            return False
        self.seen_s = b.rx_time_s
        if b.layer == 1:  # FAILSAFE
            self.lost = self.lost or b.reason == 2  # LINK_LOSS
            return False
        back, self.lost = self.lost, False
        return back


def _status_line(ep: Any, t: float) -> str:
    st = ep.state
    b = st.behaviour
    p = st.pose
    lay = f"{b.layer_name}/{b.reason_name}" + (f" [{','.join(b.flag_names)}]" if b.flags else "") if b else "?"
    pose = f"x={p.x_m:6.2f} y={p.y_m:6.2f} yaw={math.degrees(p.yaw_rad):6.1f}" if p else "no pose"
    link = "up" if ep.stats.link_up else "DOWN"
    return f"t={t:6.1f} s  {lay:34s} {pose}  link {link} {ep.meter.rate(time.monotonic()):5.0f} B/s"


def _plain(e: BaseException) -> str:
    """A planner's error without the internal field names (``(obs.scan is None)``)."""
    return re.sub(r"\s*\(obs\.\w+ is None\)", "", str(e))


def _stats_line(ep: Any) -> str:
    s = ep.stats
    if ep.meter.full(time.monotonic()) or s.peak_rx_rate_bytes_s > 0:
        rate = f"peak {s.peak_rx_rate_bytes_s:.0f} B/s"
    else:  # shorter than one budget window: no peak over a whole window yet
        rate = f"{ep.meter.rate(time.monotonic()):.0f} B/s over the run (shorter than the {ep.meter.window_s:g} s budget window)"
    return (f"link: rx {s.rx_bytes} B / {s.rx_msgs} frames, tx {s.tx_bytes} B / {s.tx_msgs} frames, {rate} "
            f"(budget {ep.budget_bytes_s:.0f}), reconnects {s.reconnects}, "
            f"link losses {s.link_losses}, parse errors {s.rx_parse_errors}, lost {s.rx_seq_lost}")


def _parse_start(text: str) -> tuple[float, float, float]:
    x, y, h = parse_goal(text)
    return x, y, 0.0 if h is None else h


def mount_from_url(url: Any, section: Any) -> Any:
    """The scanner's mounting pose: the config section's (``[laser]`` / ``[tilted_laser]``: x_m, y_m, yaw_deg,
    pitch_deg, height_m), each overridden by the URL's query (``?x=0.2&y=0&yaw=0&pitch=20&height=0.5``, m and
    deg). ValueError names a bad value."""
    from ..lasers import LaserMount

    vals = {"x": section.x_m, "y": section.y_m, "yaw": section.yaw_deg, "pitch": section.pitch_deg,
            "height": section.height_m}
    for k in vals:
        v = url.option(k)
        if v is not None:
            try:
                vals[k] = float(v)
            except ValueError:
                raise ValueError(f"--laser {url.text!r}: {k}={v!r} is not a number") from None
            if not math.isfinite(vals[k]):
                raise ValueError(f"--laser {url.text!r}: {k} must be finite")
    try:
        return LaserMount(vals["x"], vals["y"], math.radians(vals["yaw"]), math.radians(vals["pitch"]), vals["height"])
    except ValueError as e:
        raise ValueError(f"--laser {url.text!r}: {e}") from None


def laser_feeds_from(urls: list[str], cfg: Any) -> list[tuple[Any, Any, str]]:
    """(LaserUrl, LaserMount, role) for the run's scanners: ``--laser`` URLs (the first is the horizontal
    scanner, a second the tilted one), else the config's ``[laser]`` / ``[tilted_laser]`` urls. A scanner with a
    pitch is the tilted one. ValueError says what is wrong."""
    from ..lasers import parse_laser_url

    if urls:
        given = [(text, cfg.laser if i == 0 else cfg.tilted_laser) for i, text in enumerate(urls)]
    else:
        given = [(sec.url, sec) for sec in (cfg.laser, cfg.tilted_laser) if sec.url]
    if len(given) > 2:
        raise ValueError(f"at most two --laser: the horizontal scanner and the tilted one, got {len(given)}")
    out = []
    for text, section in given:
        u = parse_laser_url(text)
        m = mount_from_url(u, section)
        out.append((u, m, "tilted_laser" if m.tilted else "laser"))
    roles = [r for _, _, r in out]
    if len(out) == 2 and roles.count("tilted_laser") != 1:
        raise ValueError("two lasers: one horizontal and one tilted (give the tilted one its pitch and height: "
                         "?pitch=DEG&height=M, or [tilted_laser] pitch_deg and height_m)")
    return out


_MOUNT_KEYS = ("x", "y", "yaw", "pitch", "height")


def _without_mount(url: Any) -> Any:
    """The URL a driver gets: the mounting-pose keys are the run's, not the device's."""
    return replace(url, options=tuple((k, v) for k, v in url.options if k not in _MOUNT_KEYS))


def field_from(ns: argparse.Namespace, cfg: Any) -> Any:
    """The field description: the options over the config's ``[field]``."""
    from ..planning.registry import FieldDescription, parse_turn_pattern

    f = cfg.field
    side, lanes = parse_turn_pattern(ns.turns if ns.turns is not None else f.turns)
    return FieldDescription(row_side=ns.row_side or f.row_side,
                            row_offset_m=ns.row_offset if ns.row_offset is not None else f.row_offset_m,
                            row_half_width_m=ns.row_half_width if ns.row_half_width is not None else f.row_half_width_m,
                            row_method=ns.row_method or f.row_method, first_turn=side, lanes_per_turn=lanes,
                            pattern=getattr(ns, "pattern", None) or f.pattern,
                            row_spacing_m=(ns.row_spacing if getattr(ns, "row_spacing", None) is not None
                                           else f.row_spacing_m),
                            reverse=f.reverse and not getattr(ns, "no_reverse", False))


def robot_spec_from(params: dict[str, float], cfg: Any, control_dt_s: float) -> Any:
    """The planners' RobotSpec from the firmware's parameters (DRIVE_KIND, WHEELBASE_MM, TRACK_MM,
    MAX_SPEED_MM_S, MAX_STEER_CDEG) and the host config's ``[robot]`` and ``[run] max_speed_m_s``."""
    from ..planning.base import RobotSpec

    r = cfg.robot
    ack = params["DRIVE_KIND"] < 0.5
    wheelbase = milli_to_si(params["WHEELBASE_MM"])
    max_steer = math.radians(r.max_steer_deg) if r.max_steer_deg > 0 else cdeg_to_rad(params["MAX_STEER_CDEG"])
    offset = r.footprint_offset_m if r.footprint_offset_m >= 0 else (0.5 * wheelbase if ack else 0.0)
    lag = r.stop_lag_s if r.stop_lag_s > 0 else (0.25 if ack else 0.12)
    fw_max = milli_to_si(params["MAX_SPEED_MM_S"])
    return RobotSpec(kinematics="ackermann" if ack else "diff_drive", radius_m=r.radius_m, wheelbase_m=wheelbase,
                     track_m=milli_to_si(params["TRACK_MM"]), max_speed_m_s=min(cfg.run.max_speed_m_s, fw_max or cfg.run.max_speed_m_s),
                     min_speed_m_s=r.min_speed_m_s, max_accel_m_s2=r.max_accel_m_s2,
                     max_yaw_rate_rad_s=r.max_yaw_rate_rad_s, max_steer_rad=max_steer, footprint_offset_m=offset,
                     control_dt_s=control_dt_s, stop_lag_s=lag)


def _goals(ns: argparse.Namespace, cfg: Any) -> list[Any]:
    from ..types import Goal

    tol = ns.goal_tolerance if ns.goal_tolerance is not None else cfg.run.goal_tolerance_m
    goals = [Goal(x, y, None if h is None else math.radians(h), tolerance_m=tol) for x, y, h in (ns.goal or [])]
    if ns.arrive_in is not None and goals:
        goals[-1] = replace(goals[-1], arrival_s=ns.arrive_in)
    return goals


def _load_landmarks(path: str) -> list[list[float]]:
    rows = []
    try:
        text = Path(path).read_text(encoding="utf-8-sig")
    except OSError as e:
        raise ValueError(f"--landmarks {path}: cannot read: {e.strerror or e}") from None
    for i, line in enumerate(text.splitlines(), 1):
        line = line.split("#", 1)[0].strip()
        if not line or line.lower().startswith("x"):
            continue
        try:
            vals = [float(v) for v in line.split(",")]
        except ValueError:
            vals = []
        if len(vals) != 3 or not all(math.isfinite(v) for v in vals) or vals[2] <= 0:
            raise ValueError(f"--landmarks {path}:{i}: expected x_m,y_m,radius_m (radius > 0), got {line!r}")
        rows.append(vals)
    if not rows:
        raise ValueError(f"--landmarks {path}: no posts in the file (one x_m,y_m,radius_m a line)")
    return rows


def _cmd_run(ns: argparse.Namespace) -> int:
    cfg = _config(ns)
    planner_name = ns.planner if ns.planner is not None else cfg.run.planner
    if ns.autopilot == "ardupilot" and not planner_name:
        _err("run", "--autopilot ardupilot needs --planner (a stock autopilot has no AgNav behaviour layers)")
        return 2
    goals = _goals(ns, cfg)
    if planner_name and not goals:
        _err("run", "a host planner needs --goal X,Y[,DEG] (repeat --goal for waypoints)")
        return 2
    if ns.arrive_in is not None and not planner_name:
        _err("run", "--arrive-in is for a host planner (e.g. --planner timed); the firmware's layers keep no time")
        return 2
    try:
        lasers = laser_feeds_from(ns.laser or [], cfg)
    except ValueError as e:
        _err("run", str(e))
        return 2
    if ns.rrd:
        check_output("--rrd", ns.rrd, (".rrd",))
        from ..viz import VizUnavailable
        from ..viz.recorder import require_rerun

        try:
            require_rerun()
        except VizUnavailable as e:
            _err("run", str(e))
            return 2
    if not planner_name:
        if lasers:
            _err("run", "--laser is read by a host planner (--planner NAME); the firmware's layers use the sonar ring")
            return 2
        return _firmware_layers(ns, cfg, goals)
    from ..planning.registry import CONTROLLERS, sensors_needed, split_controller_name

    base, _ = split_controller_name(planner_name)  # UnknownPlanner (a ValueError) before touching the robot
    roles = {r for _, _, r in lasers}
    need = sensors_needed(planner_name)
    if "laser" in need and "laser" not in roles:
        what = "planner" if CONTROLLERS[base].kind != "field" else "field controller"
        _err("run", f"{what} {planner_name} needs a laser; this run has none: give one with --laser URL "
                    "(tim5xx://HOST, lms1xx://HOST, lms5xx://HOST, ust://HOST, urg:/dev/ttyACM0, rplidar:/dev/ttyUSB0, "
                    "replay:FILE) or [laser] url in the host config")
        return 2
    if "tilted_laser" in need and "tilted_laser" not in roles:
        _err("run", f"{planner_name} needs a tilted laser: a second --laser URL?pitch=DEG&height=M (or [tilted_laser])")
        return 2
    field = field_from(ns, cfg)
    why = field.problem()
    if why:
        _err("run", f"field: {why}")
        return 2
    landmarks = _load_landmarks(ns.landmarks or cfg.run.landmarks_file) if (ns.landmarks or cfg.run.landmarks_file) else None
    if landmarks is not None and "laser" not in roles:
        _err("run", "--landmarks: localising on posts needs the horizontal laser (--laser URL)")
        return 2
    localise = getattr(ns, "localise", None)
    if localise in ("scan", "poles", "posts") and "laser" not in roles:
        _err("run", f"--localise {localise}: localising needs the horizontal laser (--laser URL)")
        return 2
    if localise == "posts" and landmarks is None:
        _err("run", "--localise posts needs the surveyed posts (--landmarks FILE)")
        return 2
    if getattr(ns, "map", None) is not None:
        if localise != "scan":
            _err("run", "--map is for --localise scan")
            return 2
        from ..localisation.occupancy import load_map

        try:  # an unreadable map fails before the link is opened
            load_map(ns.map)
        except (ValueError, OSError) as e:
            _err("run", f"--map {ns.map}: {getattr(e, 'strerror', None) or e}")
            return 2
    out_dir = None
    if ns.out:
        bad = unusable_out_dir(ns.out) or clear_earlier_outputs("run", ns.out, RUN_OUTPUTS, False)
        if bad:
            raise OutputError(f"--out {ns.out}: {bad}")
        out_dir = Path(ns.out)
        if not ns.tlog and not ns.no_tlog:
            ns.tlog = str(out_dir / "link.tlog")
    if out_dir is not None:
        from ..viz import VizUnavailable
        from ..viz.recorder import require_rerun

        try:
            require_rerun()
        except VizUnavailable as e:
            _err("run", str(e))
            return 2
    # the scanners first: a wrong address or device is said before the robot is armed
    from ..lasers import LaserError, open_laser
    from ..robot import LaserFeed

    feeds: list[LaserFeed] = []
    try:
        for url, mount, role in lasers:
            src = open_laser(_without_mount(url), mount)
            try:
                info = src.start(timeout_s=max(1.0, ns.wait))
            except LaserError as e:
                src.close()
                _err("run", f"laser {url.text}: {e}")
                return 1
            feeds.append(LaserFeed(src, mount, info, role))
            print(f"laser {url.text}: {info.model or info.kind} ({role.replace('_', ' ')}, stamps: {info.stamps}"
                  f"{', latency %.1f ms' % (info.latency_s * 1e3) if info.stamps == 'arrival' else ''})", file=sys.stderr)
        return _host_controlled(ns, cfg, planner_name, goals, feeds, field, landmarks, out_dir)
    finally:
        for f in feeds:
            f.source.close()


def _firmware_layers(ns: argparse.Namespace, cfg: Any, goals: list[Any]) -> int:
    """No host controller: the firmware's move-to-goal / follow-wall layers drive; the host watches and records."""
    goal = goals[-1] if goals else None
    if goal is not None and goal.yaw_rad is not None:
        _err("run", f"warning: heading {math.degrees(goal.yaw_rad):g} deg ignored: the firmware's move-to-goal layer "
                    "drives to the position only (the host planners, --planner, use the heading)")
    rec = _recorder(ns)
    tlog = _tlog_path(ns, "run", cfg)
    ep = _open(ns, "run", cfg, tlog)
    from ..link.robot import AgnavRobot

    robot = AgnavRobot(ep)
    t0 = time.monotonic()
    try:
        timeout_ms = robot.param_get("LINK_TIMEOUT_MS")
        ep.heartbeat_hz = max(ep.heartbeat_hz, 2.5 / max(milli_to_si(timeout_ms), 0.1))
        robot.release()
        robot.arm()
        robot.set_behaviours(follow_wall=ns.follow_wall, goal_seek=goal is not None, avoid=not ns.no_avoid)
        fw_goal = _FirmwareGoal(robot, goal.x_m, goal.y_m, milli_to_si(robot.param_get("GOAL_TOL_MM"))) if goal else None
        if rec is not None and goal is not None:
            rec.log_goal(goal.x_m, goal.y_m)
        print(f"running: firmware layers{f', goal ({goal.x_m:g}, {goal.y_m:g})' if goal else ''}; Ctrl-C stops the robot",
              flush=True)
        period = 1.0 / cfg.run.control_hz
        next_status = 0.0
        last_layer = None
        link_back = _LinkBack()
        while True:
            loop_t = time.monotonic()
            t = loop_t - t0
            if ns.duration is not None and t >= ns.duration:
                print("duration reached")
                break
            st = ep.state
            if link_back(st):
                print(f"link back at t={t:.1f} s: behaviours{' and goal' if fw_goal else ''} sent again", flush=True)
                try:
                    robot.set_behaviours(follow_wall=ns.follow_wall, goal_seek=goal is not None, avoid=not ns.no_avoid)
                except Exception as e:  # noqa: BLE001 -- the next link loss and recovery tries again
                    _err("run", f"behaviours not confirmed after the link came back ({e})")
                if fw_goal is not None:
                    fw_goal.again(time.monotonic())
            if fw_goal is not None and fw_goal.reached(st, time.monotonic()):
                print(f"goal reached (firmware) at t={t:.1f} s")
                break
            if rec is not None:
                rec.set_time(t)
                if st.pose is not None:
                    rec.log_pose(st.pose)
                if st.sonar is not None:
                    rec.log_sonar(st.sonar, st.pose)
                if st.behaviour is not None:
                    rec.log_behaviour(st.behaviour)
                    if (st.behaviour.layer, st.behaviour.reason) != last_layer:
                        last_layer = (st.behaviour.layer, st.behaviour.reason)
                        rec.log_layer_change(st.behaviour)
            if t >= next_status:
                next_status = t + 1.0 / cfg.run.status_hz
                print(_status_line(ep, t), flush=True)
            _sleep(max(0.0, period - (time.monotonic() - loop_t)))
        _stop_three_times(robot)
        return 0
    except KeyboardInterrupt:
        return _interrupted(robot)
    finally:
        print(_stats_line(ep), file=sys.stderr)
        ep.close()
        _close_recorder(rec, ns.rrd)


def _recorder(ns: argparse.Namespace) -> Any:
    if not ns.rrd:
        return None
    from ..viz import Recorder

    try:
        return Recorder.streaming_to(ns.rrd)
    except (OSError, RuntimeError) as e:
        raise OutputError(f"--rrd {ns.rrd}: cannot write there: {getattr(e, 'strerror', None) or e}") from None


def _close_recorder(rec: Any, path: str | None) -> None:
    if rec is None:
        return
    try:
        rec.close()
    except OSError as e:
        print(f"agnav run: recording {path} not written: {e.strerror or e}", file=sys.stderr)
        return
    _say_recording(rec.result, path)


def _say_recording(result: Any, path: str | None) -> None:
    """Where the streamed recording is: ``partial (N B)`` when a write error stopped it (said when it
    happened), nothing when not one message reached the disk."""
    if result is not None and not result.kept:
        print(f"agnav run: recording {path} not written: {result.error or 'nothing recorded'}", file=sys.stderr)
    elif result is not None and result.partial:
        print(f"recording: {path} partial ({result.size_bytes} B) (open with `rerun {path}`)", file=sys.stderr)
    else:
        print(f"recording: {path} (open with `rerun {path}`)", file=sys.stderr)


def _stop_three_times(robot: Any) -> None:
    for _ in range(3):
        robot.stop()
        _sleep(0.05)


def _interrupted(robot: Any) -> int:
    print("\nCtrl-C: stopping the robot", file=sys.stderr)
    try:
        robot.stop()
        robot.estop(True)
        print("e-stop engaged (the next `agnav run` releases it)", file=sys.stderr)
    except Exception as e:
        print(f"e-stop not confirmed ({e}); the firmware stops by itself on link loss", file=sys.stderr)
    return 130


def _host_controlled(ns: argparse.Namespace, cfg: Any, planner_name: str, goals: list[Any], feeds: list[Any],
                     field: Any, landmarks: list[list[float]] | None, out_dir: Path | None) -> int:
    from ..hostloop import HostLoop
    from ..planning.base import PlanningError
    from ..planning.registry import ControllerContext, make_controller
    from ..robot import RobotRun, RunOutputs, RunSettings, latency_summary
    from ..types import Pose2D

    sx, sy, sh = ns.start if ns.start is not None else (cfg.run.start_x_m, cfg.run.start_y_m, cfg.run.start_yaw_deg)
    start = Pose2D(sx, sy, math.radians(sh))
    laser = next((f for f in feeds if f.role == "laser"), None)
    tilted = next((f for f in feeds if f.role == "tilted_laser"), None)
    rate = laser.info.scan_hz if laser is not None and laser.info.scan_hz > 0 else cfg.run.control_hz
    tlog = _tlog_path(ns, "run", cfg)
    ep = _open(ns, "run", cfg, tlog)
    outputs = None
    try:
        if ns.autopilot == "ardupilot":
            from ..planning.base import RobotSpec
            from ..link.ardupilot import ArduRover, ArduRoverConfig

            a = cfg.ardupilot
            robot: Any = ArduRover(ep, ArduRoverConfig(a.mode, a.steer_channel, a.throttle_channel, a.trim_us,
                                                       a.half_range_us, a.reverse_steer, math.radians(a.max_steer_deg),
                                                       a.max_speed_m_s, a.wheelbase_m))
            spec = RobotSpec(kinematics="ackermann", wheelbase_m=a.wheelbase_m, max_speed_m_s=a.max_speed_m_s,
                             max_steer_rad=math.radians(a.max_steer_deg), stop_lag_s=0.25, control_dt_s=1.0 / rate)
            fw_steer = math.radians(a.max_steer_deg)
            robot.start()
        else:
            from ..link.robot import AgnavRobot

            robot = AgnavRobot(ep)
            params = {n: robot.param_get(n) for n in ("DRIVE_KIND", "WHEELBASE_MM", "TRACK_MM", "MAX_SPEED_MM_S",
                                                       "MAX_STEER_CDEG", "LINK_TIMEOUT_MS")}
            # The firmware declares link loss after LINK_TIMEOUT_MS without a heartbeat or setpoint.
            ep.heartbeat_hz = max(ep.heartbeat_hz, 2.5 / max(milli_to_si(params["LINK_TIMEOUT_MS"]), 0.1))
            spec = robot_spec_from(params, cfg, 1.0 / rate)
            fw_steer = cdeg_to_rad(params["MAX_STEER_CDEG"])
        ctx = ControllerContext(spec=spec, field=field, laser_mount=laser.mount.pose if laser is not None else None,
                                tilted=_tilted_mount(tilted), where="this run")
        try:
            ctrl = make_controller(planner_name, ctx)
        except ValueError as e:
            _err("run", str(e))
            return 2
        localiser: Any = None
        if getattr(ns, "localise", None) == "scan" and laser is not None:  # scan matching, no posts needed
            from ..localisation.scan_localiser import scan_localiser_for

            localiser = scan_localiser_for(start, laser.mount.pose, ns.map)
        elif getattr(ns, "localise", None) == "poles" and laser is not None:  # poles learnt as it drives
            from ..localisation.pole_slam import PoleSlam

            localiser = PoleSlam(start, laser.mount.pose)
        elif landmarks is not None and laser is not None and getattr(ns, "localise", None) != "odometry":
            from ..localisation import localiser_for

            localiser = localiser_for({"landmarks": landmarks}, start, laser.mount.pose)
        loop = HostLoop(ctrl, goals, laser_mount=laser.mount.pose if laser is not None else None,
                        tilted_mount=tilted.mount.pose if tilted is not None else None, localiser=localiser)
        if out_dir is not None or ns.rrd:
            try:
                outputs = RunOutputs(out_dir, Path(ns.rrd) if ns.rrd else (out_dir / "recording.rrd" if out_dir else None))
            except (OSError, RuntimeError) as e:
                raise OutputError(f"--out {out_dir}: cannot write there: {getattr(e, 'strerror', None) or e}") from None
        if ns.autopilot != "ardupilot":
            robot.release()
            robot.arm()
            robot.set_behaviours(follow_wall=ns.follow_wall, goal_seek=False, avoid=not ns.no_avoid)
        settings = RunSettings(tuple(goals), spec, start, cfg.run.control_hz, ns.duration, fw_steer, cfg.run.status_hz)
        g = goals[-1]
        hdg = f", {math.degrees(g.yaw_rad):g} deg" if g.yaw_rad is not None else ""
        when = f", arriving at t={g.arrival_s:g} s" if g.arrival_s is not None else ""
        print(f"running: {planner_name}, goal ({g.x_m:g}, {g.y_m:g}{hdg}){when}"
              f"{f' after {len(goals) - 1} waypoints' if len(goals) > 1 else ''}; Ctrl-C stops the robot", flush=True)

        def say(text: str) -> None:
            print(f"agnav run: {text}", file=sys.stderr, flush=True)

        run = RobotRun(robot, loop, settings, feeds, outputs, ardupilot=ns.autopilot == "ardupilot", say=say,
                       status=lambda t: print(_status_line(ep, t), flush=True), sleep=lambda s: _sleep(s))
        import signal
        import threading

        main_thread = threading.current_thread() is threading.main_thread()
        old_term = signal.signal(signal.SIGTERM, _raise_interrupt) if main_thread else None
        try:
            outcome = run.run()
        finally:
            if main_thread:
                signal.signal(signal.SIGTERM, old_term)
        rc = _interrupted(robot) if outcome.reason == "interrupted" else 0
        lat = latency_summary(outcome.latency_s)
        if outcome.reason == "arrived":
            print(outcome.message)
        elif outcome.reason == "duration":
            print("duration reached")
        if laser is not None and lat["scans"]:
            print(f"laser to command: median {lat['median_ms']:.1f} ms, 99th percentile {lat['p99_ms']:.1f} ms "
                  f"over {lat['scans']} scans")
        if outputs is not None:
            info: dict[str, Any] = {"planner": planner_name, "end_reason": outcome.reason, "t0_monotonic_s": run.t0,
                    "duration_s": round(outcome.t_s, 3), "steps": outcome.steps, "holds": outcome.holds,
                    "start": [sx, sy, sh], "goals": [[gg.x_m, gg.y_m, None if gg.yaw_rad is None else math.degrees(gg.yaw_rad),
                                                      gg.arrival_s, gg.tolerance_m] for gg in goals],
                    "lasers": [{"url": f.source.url, "role": f.role, "kind": f.info.kind, "model": f.info.model,
                                "stamps": f.info.stamps, "scans": f.source.stats.scans,
                                "malformed": f.source.stats.malformed, "reconnects": f.source.stats.reconnects}
                               for f in feeds],
                    "laser_to_command": lat, "scan_to_loop": latency_summary(outcome.wait_s),
                    "controller_step": latency_summary(outcome.step_s),
                    "controller_events": [[round(float(t), 3), str(e)] for t, e in getattr(ctrl, "events", [])][-500:],
                    "latency_s": [round(v, 6) for v in outcome.latency_s]}
            try:
                for f in outputs.finish(settings, outcome, info, plot=not ns.no_plot):
                    print(f"  wrote {f.listing()}")
                if ns.rrd:
                    _say_recording(outputs.rec.result if outputs.rec is not None else None, ns.rrd)
            except OSError as e:
                outputs = None
                raise OutputError(f"--out {out_dir}: {e.strerror or e}") from None
            unwritten, outputs = outputs.unwritten, None
            if unwritten:
                raise OutputError(f"--out {out_dir}: not written: {'; '.join(unwritten)}")
        if outcome.reason == "planning_error":
            _err("run", f"planner {planner_name}: {_plain(PlanningError(outcome.message))}; stopped")
            return 1
        return rc
    finally:
        if outputs is not None:
            outputs.abandon()
        print(_stats_line(ep), file=sys.stderr)
        ep.close()


def _raise_interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt  # SIGTERM ends a run like Ctrl-C: the robot stopped and e-stopped, the outputs written


def _tilted_mount(feed: Any) -> Any:
    if feed is None:
        return None
    from ..perception import TiltedMount

    return TiltedMount(feed.mount.height_m, feed.mount.pitch_rad, feed.mount.pose)


subcommand("run", help="drive a robot (or a SIL over tcp:) with any controller, its lasers and timed goals, or with "
                       "the firmware layers; Ctrl-C e-stops",
           args=_LINK_ARGS + [
               (("--planner",), {"default": None, "help": "controller by name (see `agnav planners`: planners, field "
                                                          "controllers, +ground-guard / +mover-guard); default: [run] "
                                                          "planner, else the firmware move-to-goal layer"}),
               (("--goal",), {"type": parse_goal, "action": "append", "default": None, "metavar": "X,Y[,DEG]",
                              "help": "goal in the field frame (the frame --start is in), m, m, deg; repeat for "
                                      "waypoints in order; negatives allowed (default: none)"}),
               (("--arrive-in",), {"dest": "arrive_in", "type": positive_float, "default": None, "metavar": "S",
                                   "help": "arrive at the last goal this many seconds after the run starts (timed "
                                           "planner; default: no set time)"}),
               (("--goal-tolerance",), {"dest": "goal_tolerance", "type": positive_float, "default": None, "metavar": "M",
                                        "help": "a goal counts as reached within this distance, m (default: [run] "
                                                "goal_tolerance_m, 0.3)"}),
               (("--start",), {"type": _parse_start, "default": None, "metavar": "X,Y[,DEG]",
                               "help": "the robot's pose at the start in the field frame, m, m, deg (default: [run] "
                                       "start_*, the odometry origin)"}),
               (("--laser",), {"action": "append", "default": None, "metavar": "URL",
                               "help": "a laser scanner, repeatable (the horizontal one, then a tilted one): "
                                       "tim5xx://HOST[:PORT], lms1xx://..., lms5xx://..., ust://HOST[:PORT], "
                                       "urg:/dev/ttyACM0, rplidar:/dev/ttyUSB0, replay:FILE; mounting pose from "
                                       "[laser] / [tilted_laser] or ?x=M&y=M&yaw=DEG&pitch=DEG&height=M"}),
               (("--row-side",), {"dest": "row_side", "choices": ["left", "right"], "default": None,
                                  "help": "field: the robot's side of the row it follows (default: [field] row_side)"}),
               (("--row-offset",), {"dest": "row_offset", "type": positive_float, "default": None, "metavar": "M",
                                    "help": "field: distance kept from the row, m (default: [field] row_offset_m)"}),
               (("--row-half-width",), {"dest": "row_half_width", "type": finite_float, "default": None, "metavar": "M",
                                        "help": "field: row centre line to the face the laser sees, m (default: [field] "
                                                "row_half_width_m)"}),
               (("--row-method",), {"dest": "row_method", "choices": ["offset", "lsq", "triangle", "ransac", "hough"],
                                    "default": None, "help": "field: crop-row detection (default: [field] row_method)"}),
               (("--turns",), {"default": None, "metavar": "SIDE[,N]",
                               "help": "field: headland turn pattern, first turn side and lanes per turn (default: "
                                       "[field] turns, left,1)"}),
               (("--pattern",), {"default": None, "metavar": "S-1L-2R-F",
                                 "help": "field: the row navigator's turn pattern in the Field Robot Event's notation "
                                         "(S start, nL / nR the n-th lane to the left / right, F finish: stop), "
                                         "instead of --turns (default: [field] pattern)"}),
               (("--row-spacing",), {"dest": "row_spacing", "type": positive_float, "default": None, "metavar": "M",
                                     "help": "field: the rows' spacing the row navigator turns by, m, 0.2-10 (default: "
                                             "[field] row_spacing_m, 0.75)"}),
               (("--no-reverse",), {"dest": "no_reverse", "action": "store_true",
                                    "help": "field: the row navigator never backs up on the headland (default: "
                                            "[field] reverse)"}),
               (("--landmarks",), {"default": None, "metavar": "FILE",
                                   "help": "surveyed marker posts to localise on, CSV x_m,y_m,radius_m (default: [run] "
                                           "landmarks_file; none = odometry)"}),
               (("--localise",), {"choices": ["scan", "poles", "posts", "odometry"], "default": None,
                                  "help": "how the host localises: scan (laser scan matching against --map or a map "
                                          "built online), poles (poles and trunks learnt online), posts "
                                          "(--landmarks), odometry (none); default: posts when "
                                          "--landmarks is given, else odometry"}),
               (("--map",), {"default": None, "metavar": "FILE.yaml",
                             "help": "a saved map (map_server YAML + PGM, e.g. from agnav slam) for --localise scan"}),
               (("--autopilot",), {"choices": ["agnav", "ardupilot"], "default": "agnav",
                                   "help": "agnav firmware (default) or a stock ArduPilot Rover"}),
               (("--duration",), {"type": positive_float, "default": None,
                                  "help": "stop after this many seconds, > 0 (default: until the goal or Ctrl-C)"}),
               (("--follow-wall",), {"action": "store_true", "help": "enable the firmware follow-wall layer"}),
               (("--no-avoid",), {"action": "store_true", "help": "disable passive obstacle avoidance (careful)"}),
               (("--out",), {"default": None, "metavar": "DIR",
                             "help": "write summary.json (the keys of agnav sim), run_info.json, trajectory.csv/.png, "
                                     "link.tlog, recording.rrd (streamed) and laser.alog (every scan) here"}),
               (("--no-plot",), {"action": "store_true", "help": "with --out: no trajectory.png"}),
               (("--rrd",), {"default": None, "help": "save a rerun recording here, FILE.rrd, streamed as the run goes "
                                                      "(open with `rerun FILE`; default: none)"}),
           ])(lambda ns: _guard("run", _cmd_run, ns))
