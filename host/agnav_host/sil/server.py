"""Serve the SIL firmware's MAVLink byte stream to a ground station, as ArduPilot SITL does.

``serve()`` runs a scenario's world + firmware in real time (times ``speedup``) and bridges the
radio link to a TCP client on a loopback address (default tcp:127.0.0.1:5760; one client at a
time, a new connection replaces the old one) and/or a pseudo-terminal. What the client sends goes
through the uplink model to the firmware's UART; what the firmware sends goes through the
downlink model to the client. MAVProxy: ``mavproxy.py --master tcp:127.0.0.1:5760``.

The firmware's link-loss failsafe needs a host heartbeat (or setpoint / manual control) at least
every LINK_TIMEOUT_MS (500 ms); ground stations send HEARTBEAT at 1 Hz by default, so raise the
station's heartbeat rate (MAVProxy: ``set heartbeat 4``) or store a longer timeout with
``--param LINK_TIMEOUT_MS=2000``.
"""

from __future__ import annotations

import errno
import ipaddress
import os
import select
import signal
import socket
import sys
import threading
import time
import math
from dataclasses import dataclass
from typing import Any, Callable

from ..atomic import write_atomic
from ..sim.scenario import Scenario
from ..types import Pose2D
from .link import Tlog
from .session import SilConfig, SilSession

__all__ = ["ServeOptions", "ServeResult", "serve", "parse_endpoint"]


def parse_endpoint(text: str) -> tuple[str, int]:
    """``[tcp:]HOST:PORT`` -> (host, port); the host must be an IPv4 loopback address (``localhost`` is
    127.0.0.1), the port 0..65535 (0: any free one). ValueError names what is wrong."""
    t = text[4:] if text.startswith("tcp:") else text
    host, _, port = t.rpartition(":")
    host = host.strip("[]") or "127.0.0.1"
    if host == "localhost":
        host = "127.0.0.1"
    try:
        addr = ipaddress.ip_address(host)
    except ValueError:
        raise ValueError(f"--tcp {text!r}: the SIL serves on loopback addresses only (e.g. tcp:127.0.0.1:5760), "
                         f"got {host!r}") from None
    if addr.version != 4:
        raise ValueError(f"--tcp {text!r}: IPv6 is not served; use tcp:127.0.0.1:PORT")
    if not addr.is_loopback:
        raise ValueError(f"--tcp {text!r}: the SIL serves on loopback addresses only, got {host!r}")
    try:
        n = int(port)
    except ValueError:
        n = -1
    if not 0 <= n <= 65535:
        raise ValueError(f"--tcp {text!r}: the port must be a number 0-65535, got {port!r}")
    return host, n


@dataclass(frozen=True)
class ServeResult:
    """Where a served run stopped: simulated time since boot (s), the robot's true pose and the referee's verdict
    (``arrived``, ``collision``, ``fell_in_hole``, ``timeout`` when it was stopped before any of them)."""

    t_s: float
    pose: Pose2D
    end_reason: str = "timeout"


class _EmulatedScanner:
    """One scenario laser served by a device emulator: a scan of the true pose published at the laser's rate."""

    def __init__(self, kind: str, port: int | None, laser: object, rng: object, role: str) -> None:
        from .emulators import geometry_of, make_emulator

        self.kind, self.laser, self.rng, self.role = kind, laser, rng, role
        self.emu = make_emulator(kind, geometry_of(laser.spec), port)  # type: ignore[attr-defined]
        self.period_us = int(round(1e6 / laser.spec.rate_hz))  # type: ignore[attr-defined]
        self.next_us = 0
        self.where = ""

    def start(self) -> str:
        self.where = self.emu.start()
        return self.where

    def url(self) -> str:
        """The ``agnav run --laser`` URL of this emulator, with the scanner's mounting pose."""
        m = self.laser.mount  # type: ignore[attr-defined]
        mount = f"x={m.x_m:g}&y={m.y_m:g}&yaw={math.degrees(m.yaw_rad):g}"
        if self.role == "tilted_laser":
            mount += f"&pitch={math.degrees(self.laser.tilt_rad):g}&height={self.laser.height_m:g}"  # type: ignore[attr-defined]
        if self.kind in ("urg", "rplidar"):
            return f"{self.kind}:{self.where}?{mount}"
        port = self.emu.ports[1] if self.kind in ("tim5xx", "lms1xx", "lms5xx") else self.emu.port
        return f"{self.kind}://127.0.0.1:{port}?{mount}"

    def tick(self, s: SilSession) -> None:
        if s.t_us < self.next_us:
            return
        self.next_us = s.t_us + self.period_us if self.next_us == 0 else self.next_us + self.period_us
        scan = self.laser.scan(s.plant.world, s.pose, s.t_s, self.rng)  # type: ignore[attr-defined]
        self.emu.publish(scan.ranges_m, s.t_s)

    def close(self) -> None:
        self.emu.close()


def host_config_text(sc: Scenario, scanners: list[_EmulatedScanner], device: str, landmarks_file: str = "") -> str:
    """A host config (``agnav run --config``) for driving this scenario's robot through the served SIL: the robot
    as its planners see it in ``agnav sim``, the field from ``[meta]``, the emulated lasers with their mounts and,
    when the scenario has surveyed posts, ``landmarks_file`` (written by the caller) to localise on them."""
    from ..link.config import HostConfig, to_toml
    from ..sim.field_controllers import field_from_meta
    from ..sim.runner import robot_spec

    spec = robot_spec(sc)
    cfg = HostConfig()
    cfg.link.device = device
    cfg.link.heartbeat_hz = 2.0
    cfg.run.control_hz = max(5.0, sc.control_hz)
    cfg.run.max_speed_m_s = spec.max_speed_m_s
    cfg.run.start_x_m, cfg.run.start_y_m = sc.start.x_m, sc.start.y_m
    cfg.run.start_yaw_deg = math.degrees(sc.start.yaw_rad)
    cfg.run.goal_tolerance_m = sc.goals[-1].tolerance_m
    cfg.run.landmarks_file = landmarks_file
    r = cfg.robot
    r.radius_m, r.max_steer_deg, r.min_speed_m_s = spec.radius_m, math.degrees(spec.max_steer_rad), spec.min_speed_m_s
    r.max_accel_m_s2, r.max_yaw_rate_rad_s = spec.max_accel_m_s2, spec.max_yaw_rate_rad_s
    r.footprint_offset_m, r.stop_lag_s = spec.footprint_offset_m, spec.stop_lag_s
    f = field_from_meta(sc)
    cfg.field.row_side, cfg.field.row_offset_m, cfg.field.row_half_width_m = f.row_side, f.row_offset_m, f.row_half_width_m
    cfg.field.row_method, cfg.field.turns = f.row_method, f"{f.first_turn},{f.lanes_per_turn}"
    cfg.field.pattern, cfg.field.row_spacing_m, cfg.field.reverse = f.pattern, f.row_spacing_m, f.reverse
    for sc_ in scanners:
        sec = cfg.laser if sc_.role == "laser" else cfg.tilted_laser
        sec.url = sc_.url().split("?")[0]
        m = sc_.laser.mount  # type: ignore[attr-defined]
        sec.x_m, sec.y_m, sec.yaw_deg = m.x_m, m.y_m, math.degrees(m.yaw_rad)
        if sc_.role == "tilted_laser":
            sec.pitch_deg = math.degrees(sc_.laser.tilt_rad)  # type: ignore[attr-defined]
            sec.height_m = sc_.laser.height_m  # type: ignore[attr-defined]
    return to_toml(cfg, f"agnav run against `agnav sil {sc.name}`: the scenario's robot, field and emulated lasers")


def _robot_command(sc: Scenario, scanners: list[_EmulatedScanner], device: str) -> str:
    goals = " ".join(f"--goal {g.x_m:g},{g.y_m:g}" + (f",{math.degrees(g.yaw_rad):g}" if g.yaw_rad is not None else "")
                     for g in sc.goals)
    arrive = f" --arrive-in {sc.goals[-1].arrival_s:g}" if sc.goals[-1].arrival_s is not None else ""
    lasers = " ".join(f"--laser '{x.url()}'" for x in scanners)
    st = sc.start
    return (f"agnav run --device {device} {lasers} --start {st.x_m:g},{st.y_m:g},{math.degrees(st.yaw_rad):g} "
            f"{goals}{arrive} --goal-tolerance {sc.goals[-1].tolerance_m:g} --planner NAME").replace("  ", " ")


@dataclass
class ServeOptions:
    tcp: tuple[str, int] | None = ("127.0.0.1", 5760)
    pty: bool = False
    speedup: float = 1.0
    duration_s: float | None = None  # None: until interrupted
    seed: int = 0
    tlog_path: str | None = None
    config: SilConfig | None = None
    lasers: tuple[tuple[str, int | None], ...] = ()  # (kind, port) of the horizontal scanner, then the tilted one
    out_dir: str | None = None  # the truth of the run: truth.csv, summary.json, run_info.json
    stop_at_end: bool = False  # stop serving once the referee ends the run (arrived, collision, fell in a hole)
    end_grace_s: float = 5.0  # with stop_at_end: keep serving this long (sim s) for a TCP client to see the end itself
    host_config: str | None = None  # write the robot side's host config (robot, field, lasers) here
    movers_wait: bool = False  # the scenario's walkers wait at their first waypoint until the host drives



def _refuse_second_client(conn: socket.socket, owner: tuple[str, int], addr: tuple[str, int], fw: object) -> None:
    """Tell a second TCP client why it is refused (a STATUSTEXT from the robot's system id), then close it."""
    from ..protocol import dialect

    D = dialect()
    text = f"refused: {owner[0]}:{owner[1]} owns the link"[:50]
    try:
        sysid = int(fw.param_get("SYSID_THISMAV"))  # type: ignore[attr-defined]
    except Exception:  # noqa: BLE001 -- the refusal must go out whatever the firmware says
        sysid = 1
    frame = D.MAVLink_statustext_message(D.MAV_SEVERITY_WARNING, text.encode()).pack(D.MAVLink(None, sysid, 1))
    try:
        conn.settimeout(0.5)
        conn.sendall(frame)
    except OSError:
        pass
    finally:
        conn.close()

def serve(sc: Scenario, opt: ServeOptions, log: Callable[[str], None] = lambda m: print(m, file=sys.stderr),
          ready: Callable[[tuple[str, int] | None, str | None], None] | None = None) -> ServeResult:
    """Run until ``duration_s`` of simulated time, Ctrl-C or SIGTERM (the tlog is then complete up to
    the stop); returns where it stopped. The listening socket and the pty are made before the firmware
    is loaded, and everything is released on every way out."""
    if not opt.speedup > 0:
        raise ValueError("speedup must be > 0")
    lsock = None
    bound = None
    if opt.tcp is not None:
        lsock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        lsock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            lsock.bind(opt.tcp)
        except (OSError, OverflowError) as e:
            lsock.close()
            en = getattr(e, "errno", None)
            raise OSError(en, f"cannot listen on tcp:{opt.tcp[0]}:{opt.tcp[1]}: {getattr(e, 'strerror', None) or e}"
                          + (" (another agnav sil or ground station is using it; pick another --tcp port)"
                             if en == errno.EADDRINUSE else "")) from None
        lsock.listen(1)
        lsock.setblocking(False)
        bound = lsock.getsockname()
    master = slave = None
    slave_name = None
    if opt.pty:
        import tty

        master, slave = os.openpty()
        tty.setraw(slave)
        os.set_blocking(master, False)
        slave_name = os.ttyname(slave)
    main = threading.current_thread() is threading.main_thread()
    old_term = signal.signal(signal.SIGTERM, _raise_interrupt) if main else None
    s = None
    tlog = None
    client: socket.socket | None = None
    client_addr: tuple[str, int] = ("", 0)
    scanners: list[_EmulatedScanner] = []
    truth: list[tuple[float, ...]] = []
    referee = None
    wall0 = time.monotonic()
    t0 = 0
    try:
        s = SilSession(sc, opt.seed, opt.config)
        tlog = Tlog(opt.tlog_path, on_error=lambda m: log(f"agnav sil: {m}")) if opt.tlog_path else None
        if tlog is not None:
            s.up._tlog = s.down._tlog = tlog
        s.provision()
        if bound is not None:
            log(f"agnav sil: {sc.name}: MAVLink on tcp:{bound[0]}:{bound[1]} (speedup {opt.speedup:g})")
        if slave_name is not None:
            log(f"agnav sil: MAVLink on pty {slave_name}")
        lasers = [(sc.laser, s.rng_laser, "laser"), (sc.tilted_laser, s.rng_tilted, "tilted_laser")]
        for (kind, port), (laser, rng, role) in zip(opt.lasers, lasers):
            if laser is None:
                raise ValueError(f"--{role.replace('_', '-')} {kind}: scenario {sc.name!r} has no "
                                 f"[{role}] to serve")
            x = _EmulatedScanner(kind, port, laser, rng, role)
            scanners.append(x)
            where = x.start()
            log(f"agnav sil: {role.replace('_', ' ')} {laser.spec.name} as {kind} on {where}")
        device = f"tcp:{bound[0]}:{bound[1]}" if bound is not None else (slave_name or "")
        if scanners:
            log(f"agnav sil: robot side: {_robot_command(sc, scanners, device)}")
        if opt.host_config:
            from pathlib import Path

            hc = Path(opt.host_config)
            posts = ""
            if sc.meta.get("landmarks") and scanners:
                lm = hc.with_name(hc.stem + "_landmarks.csv")
                lm.write_text("x_m,y_m,radius_m\n" + "".join(f"{x:g},{y:g},{r:g}\n" for x, y, r in sc.meta["landmarks"]),
                              encoding="utf-8")
                posts = str(lm.resolve())
            tmp = hc.with_name(hc.name + ".part")  # whole or not at all: the robot side waits for this file
            tmp.write_text(host_config_text(sc, scanners, device, posts), encoding="utf-8")
            tmp.replace(hc)
            log(f"agnav sil: host config for the robot side: {opt.host_config}")
        from ..sim.referee import Referee

        referee = Referee(sc)
        if ready is not None:
            ready(bound, slave_name)

        def drop_client(why: str) -> None:
            nonlocal client
            if client is not None:
                client.close()
                client = None
                log(f"agnav sil: client {why}")
            s.up.reset_framer()  # a frame the client left half-sent must not swallow the next one's start

        def to_clients(t_us: int, data: bytes) -> None:
            if client is not None:
                try:
                    client.sendall(data)
                except OSError:
                    drop_client("gone (send failed)")
            if master is not None:
                try:
                    os.write(master, data)
                except (BlockingIOError, OSError):
                    pass  # nobody reading the pty: the bytes are lost, like on a radio

        s.on_downlink = to_clients
        referee_said = [False]
        ended_at_s: float | None = None
        client_after_end = False
        held = list(sc.world.movers) if opt.movers_wait else []
        if held:  # the walkers' scripts start when the host does, as in a scenario run (not when serving began)
            from dataclasses import replace as _replace

            sc.world.movers[:] = [_replace(m, start_s=math.inf) for m in held]
            log(f"agnav sil: {len(held)} walkers wait until the host's first setpoint")
        wall0 = time.monotonic()
        t0 = s.t_us
        end_us = None if opt.duration_s is None else t0 + int(opt.duration_s * 1e6)
        try:
            while end_us is None or s.t_us < end_us:
                if lsock is not None:
                    try:
                        conn, addr = lsock.accept()
                        if client is not None:  # one owner at a time: the robot has one radio
                            _refuse_second_client(conn, client_addr, addr, s.fw)
                            log(f"agnav sil: refused {addr[0]}:{addr[1]}: {client_addr[0]}:{client_addr[1]} "
                                "is connected (one client at a time)")
                        else:
                            conn.setblocking(False)
                            conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
                            s.up.reset_framer()
                            client, client_addr = conn, addr
                            log(f"agnav sil: client {addr[0]}:{addr[1]} connected")
                    except BlockingIOError:
                        pass
                rd = [x for x in (client, master) if x is not None]
                if rd:
                    ready_r, _, _ = select.select(rd, [], [], 0)
                    for src in ready_r:
                        try:
                            data = src.recv(4096) if isinstance(src, socket.socket) else os.read(src, 4096)
                        except (BlockingIOError, InterruptedError):
                            continue
                        except OSError as e:
                            if src is client:
                                drop_client(f"disconnected ({e.strerror or e})")
                            continue
                        if src is client and data == b"":
                            drop_client("disconnected")
                        elif data:
                            s.up.send(s.t_us, data)
                s.step()
                if held:
                    st = s.host.status
                    if st is not None and st.layer == 5 and st.reason == 12:  # HOST_COMMAND on a host setpoint
                        sc.world.movers[:] = [_replace(m, start_s=m.start_s + s.t_s) for m in held]
                        log(f"agnav sil: the host drives from t = {s.t_s:.2f} s: the walkers start")
                        held = []
                for x in scanners:
                    x.tick(s)
                r = s.plant.robot
                cl = s.plant.clearance(s.t_s)
                if opt.out_dir:
                    truth.append((s.t_s, r.pose.x_m, r.pose.y_m, r.pose.yaw_rad, r.speed_m_s, r.yaw_rate_rad_s, cl,
                                  referee.goal_index))
                if referee.judge(s.t_s, r, cl) is not None and not referee_said[0]:
                    referee_said[0] = True
                    ended_at_s = s.t_s
                    log(f"agnav sil: referee: {referee.reason} at t = {s.t_s:.2f} s")
                if opt.stop_at_end and ended_at_s is not None:
                    client_after_end = client_after_end or client is not None
                    if (client_after_end and client is None) or s.t_s - ended_at_s >= opt.end_grace_s:
                        break  # the robot side has seen the end and hung up, or had its grace period
                lag = (s.t_us - t0) * 1e-6 / opt.speedup - (time.monotonic() - wall0)
                if lag > 0:
                    time.sleep(lag)
        except KeyboardInterrupt:
            pass
        return ServeResult(s.t_s, s.pose, referee.reason if referee is not None else "timeout")
    finally:
        for x in scanners:
            x.close()
        if opt.out_dir and s is not None and referee is not None and truth:
            _write_truth(opt, sc, truth, referee, wall0, t0 * 1e-6, log)
        if main:  # a second Ctrl-C (or SIGTERM) while cleaning up must not cut the cleanup short
            old_int = signal.signal(signal.SIGINT, signal.SIG_IGN)
            signal.signal(signal.SIGTERM, signal.SIG_IGN)
        if client is not None:
            client.close()
        if lsock is not None:
            lsock.close()
        for fd in (master, slave):
            if fd is not None:
                os.close(fd)
        if tlog is not None:
            tlog.close()
        if s is not None:
            s.close()
        if main:
            signal.signal(signal.SIGINT, old_int)
            signal.signal(signal.SIGTERM, old_term)


def _write_truth(opt: ServeOptions, sc: Scenario, truth: list[tuple[float, ...]], referee: object, wall0: float,
                 t0_s: float, log: Callable[[str], None]) -> None:
    """The served run as the referee saw it: ``truth.csv`` (the true pose every world step, simulated seconds since
    the firmware booted), ``summary.json`` (the metric keys of ``agnav sim``, times since serving began) and
    ``run_info.json`` with ``monotonic_at_sim_zero_s``: a robot-side time on ``time.monotonic()`` is simulated time
    ``(m - monotonic_at_sim_zero_s) * speedup``."""
    import json
    from pathlib import Path

    import numpy as np

    from ..sim.metrics import RunMetrics
    from ..sim.runner import TRAJECTORY_COLUMNS

    out = Path(opt.out_dir or ".")
    out.mkdir(parents=True, exist_ok=True)
    arr = np.array(truth, dtype=float)
    lines = [",".join(TRAJECTORY_COLUMNS)] + [f"{r[0]:.4f},{r[1]:.6f},{r[2]:.6f},{r[3]:.6f},{r[4]:.6f},{r[5]:.6f},{r[6]:.6f},"
                                              f"{int(r[7])}" for r in arr]
    write_atomic(out / "truth.csv", "\n".join(lines) + "\n")
    last = sc.goals[-1]
    ref: Any = referee
    arr[:, 0] -= t0_s
    m = RunMetrics.compute(arr[:, 0], arr[:, 1:3], arr[:, 3], arr[:, 4], arr[:, 5], arr[:, 6], (last.x_m, last.y_m),
                           last.yaw_rad, None, ref.reason == "arrived",
                           None if ref.arrival_s is None else ref.arrival_s - t0_s, field=ref.field_score(t0_s))
    write_atomic(out / "summary.json", json.dumps(m.to_dict(), indent=2) + "\n")
    info = {"scenario": sc.name, "seed": opt.seed, "end_reason": ref.reason,
            "arrival_sim_s": ref.arrival_s, "serve_start_sim_s": t0_s, "speedup": opt.speedup,
            "monotonic_at_sim_zero_s": wall0 - t0_s / opt.speedup}
    write_atomic(out / "run_info.json", json.dumps(info, indent=2) + "\n")
    log(f"agnav sil: wrote {out / 'truth.csv'}, {out / 'summary.json'}, {out / 'run_info.json'}")


def _raise_interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt  # SIGTERM (systemd, docker stop, kill) ends a served run like Ctrl-C
