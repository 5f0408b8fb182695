"""Attacks on the firmware from outside (``make attacks``).

Each attack runs the real firmware in its simulated world as a ground station would meet it:
``agnav sil fault_yard --tcp tcp:127.0.0.1:0 --out DIR`` in a subprocess, reached over TCP by a
MAVLink client of this module's own (pymavlink's generated codec for the AgNav dialect and a plain
socket; none of the project's link classes). The attacker sends what a careless or hostile ground
station could send; the judge of "moved" is the world simulator's true pose (``truth.csv`` of the
served run), never the robot's own telemetry.

Attacks (every one on the ``fault_yard`` differential robot):

* heartbeats only after a link loss, with a goal stored in the firmware (a ground station connects
  once the host is gone: HEARTBEAT and PARAM_REQUEST_READ, what ``agnav param get`` sends);
* replayed setpoints after a link loss (the host's own frames, captured and sent again);
* a stale setpoint after a failsafe: the last setpoint of the host before a link loss or an e-stop
  (HOST_TIMEOUT_MS 5000, so it is younger than the setpoint timeout when heartbeats, or the host's
  release and arm, come back);
* every motion source beyond MAX_SPEED_MM_S 200: raw PWM full throttle (both directions), RC
  override / MANUAL_CONTROL at full stick and beyond, a physical setpoint of 5 m/s, the firmware's
  own goal seek (GOAL_SPEED_MM_S 400);
* bad-field frames addressed to the robot: each must be counted in SYS_STATUS (errors_comm,
  errors_count1..4);
* unknown AGNAV_CALIB_REQUEST actions: each must get an AGNAV_CALIB_ACK with a refusal.

``python -m agnav_host.faults.attacks [--markdown FILE] [--only NAME]`` prints the table (attack,
tries, refused, moved, crashed, target, met) and exits 1 when a target is missed.
"""

from __future__ import annotations

import argparse
import csv
import math
import os
import re
import select
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any, Callable

__all__ = ["AttackResult", "ATTACKS", "run_attacks", "format_table", "bad_field_frames", "main"]

SCENARIO = "fault_yard"
HOST = (255, 190)  # the host's (and a ground station's) system / component id
ROBOT = (1, 1)
CAP_MM_S = 200  # MAX_SPEED_MM_S of the speed-cap attacks
SPEED_MM_S = 300  # the host's driving setpoint
STILL_M = 0.001  # "did not move": less than 1 mm of true travel
SPEEDUP = 4.0
LAYER_FAILSAFE, LAYER_MANUAL, LAYER_HOST, LAYER_GOAL = 1, 3, 5, 6
CALIB_REFUSALS = {1, 2, 3, 4, 5}  # AGNAV_CALIB_RESULT values that refuse (not ACCEPTED 0, IN_PROGRESS 6)


def _dialect() -> Any:
    from ..protocol import dialect

    return dialect()


# ---- the served firmware ----------------------------------------------------------------------------
class ServedSil:
    """``agnav sil`` in a subprocess on a free loopback port, with the truth written to a temporary folder."""

    def __init__(self, params: dict[str, int] | None = None, speedup: float = SPEEDUP, firmware: str = "native") -> None:
        self._tmp = tempfile.TemporaryDirectory(prefix="agnav-attack-")
        self.out = Path(self._tmp.name)
        cmd = [sys.executable, "-m", "agnav_host.cli", "sil", SCENARIO, "--tcp", "tcp:127.0.0.1:0",
               "--speedup", f"{speedup:g}", "--out", str(self.out), "--firmware", firmware]
        for k, v in (params or {}).items():
            cmd += ["--param", f"{k}={v}"]
        self.speedup = speedup
        self.log: list[str] = []
        self.proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        self._port: int | None = None
        self._ready = threading.Event()
        self._reader = threading.Thread(target=self._read_log, daemon=True)
        self._reader.start()
        if not self._ready.wait(120.0) or self._port is None:
            self.proc.kill()
            raise RuntimeError("agnav sil did not start: " + " | ".join(self.log[-5:]))

    def _read_log(self) -> None:
        assert self.proc.stderr is not None
        for line in self.proc.stderr:
            self.log.append(line.rstrip())
            m = re.search(r"MAVLink on tcp:127\.0\.0\.1:(\d+)", line)
            if m and self._port is None:
                self._port = int(m.group(1))
                self._ready.set()
        self._ready.set()

    @property
    def port(self) -> int:
        assert self._port is not None
        return self._port

    def stop(self) -> tuple[list[tuple[float, float, float, float]], bool]:
        """SIGTERM (the served run ends cleanly and writes its truth); returns the true track
        (t_s, x_m, y_m, speed_m_s) and whether the process crashed instead of stopping."""
        crashed = self.proc.poll() is not None  # it must still be serving when the attack ends
        if not crashed:
            self.proc.send_signal(signal.SIGTERM)
        try:
            rc = self.proc.wait(timeout=60)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            rc = self.proc.wait()
        self._reader.join(timeout=5)
        crashed = crashed or rc != 0
        track: list[tuple[float, float, float, float]] = []
        path = self.out / "truth.csv"
        if path.is_file():
            with path.open(newline="") as f:
                for row in csv.DictReader(f):
                    track.append((float(row["t_s"]), float(row["x_m"]), float(row["y_m"]), float(row["speed_m_s"])))
        self._tmp.cleanup()
        return track, crashed or not track


# ---- the attacker's MAVLink client ----------------------------------------------------------------
class Client:
    """A MAVLink client over TCP: pymavlink's codec, a socket, the robot's time from its telemetry."""

    def __init__(self, port: int, speedup: float, sysid: int = HOST[0], compid: int = HOST[1]) -> None:
        self.D = D = _dialect()
        self.speedup = speedup
        self.sock = socket.create_connection(("127.0.0.1", port), timeout=10.0)
        self.sock.setblocking(False)
        self.mav = D.MAVLink(None, srcSystem=sysid, srcComponent=compid)
        self.mav.robust_parsing = True
        self.t_ms: int | None = None  # the newest robot time (time_boot_ms) seen
        self.status: Any = None
        self.statuses: list[Any] = []
        self.sys_status: Any = None
        self.sys_status_n = 0
        self.texts: list[tuple[int, str]] = []
        self.acks: list[Any] = []
        self.calib_acks: list[Any] = []
        self.calib_tables: list[Any] = []
        self.param_values: list[Any] = []
        self.boots = 0  # "boot: ..." texts: a reset of the firmware during the attack
        self.capture: list[tuple[float, bytes]] | None = None  # (wall s, frame) of what this client sent
        self.seq = 0
        self.closed = False

    # sending
    def send(self, msg: Any) -> bytes:
        b = bytes(msg.pack(self.mav))
        self.send_raw(b)
        if self.capture is not None:
            self.capture.append((time.monotonic(), b))
        return b

    def send_raw(self, b: bytes) -> None:
        try:
            self.sock.setblocking(True)
            self.sock.sendall(b)
        finally:
            self.sock.setblocking(False)

    def heartbeat(self) -> None:
        D = self.D
        self.send(D.MAVLink_heartbeat_message(D.MAV_TYPE_GCS, D.MAV_AUTOPILOT_INVALID, 0, 0, D.MAV_STATE_ACTIVE, 3))

    def setpoint(self, steer_cdeg: int, speed_mm_s: int, raw: tuple[int, int] | None = None) -> None:
        D = self.D
        self.seq = (self.seq + 1) & 0xFFFF
        spwm, vpwm = raw or (0, 0)
        mode = D.AGNAV_DRIVE_RAW_PWM if raw is not None else D.AGNAV_DRIVE_PHYSICAL
        self.send(D.MAVLink_agnav_drive_setpoint_message(*ROBOT, steer_cdeg, speed_mm_s, spwm, vpwm, mode, self.seq))

    def command(self, cmd: int, *p: float) -> None:
        q = [float(x) for x in p] + [0.0] * (7 - len(p))
        self.send(self.D.MAVLink_command_long_message(*ROBOT, cmd, 0, *q[:7]))

    def arm(self) -> None:
        D = self.D
        self.command(D.MAV_CMD_AGNAV_ESTOP, 0.0)
        self.command(D.MAV_CMD_COMPONENT_ARM_DISARM, 1.0)

    def goal(self, x_m: float, y_m: float) -> None:
        D = self.D
        self.send(D.MAVLink_set_position_target_local_ned_message(0, *ROBOT, D.MAV_FRAME_LOCAL_NED, 0b0000_1101_1111_1000,
                                                                  x_m, -y_m, 0, 0, 0, 0, 0, 0, 0, 0, 0))

    def param_set(self, name: str, value: float) -> None:
        D = self.D
        self.send(D.MAVLink_param_set_message(*ROBOT, name.encode(), float(value), D.MAV_PARAM_TYPE_INT32))

    def param_read(self, name: str) -> None:
        self.send(self.D.MAVLink_param_request_read_message(*ROBOT, name.encode(), -1))

    # receiving
    def pump(self, timeout_s: float = 0.0) -> None:
        if self.closed:
            return
        r, _, _ = select.select([self.sock], [], [], timeout_s)
        if not r:
            return
        try:
            data = self.sock.recv(65536)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            data = b""
        if not data:
            self.closed = True
            return
        for m in self.mav.parse_buffer(data) or []:
            self._handle(m)

    def _handle(self, m: Any) -> None:
        t = m.get_type()
        tb = getattr(m, "time_boot_ms", None)
        if tb is not None and (self.t_ms is None or tb > self.t_ms):
            self.t_ms = int(tb)
        if t == "AGNAV_BEHAVIOUR_STATUS":
            self.status = m
            self.statuses.append(m)
        elif t == "SYS_STATUS":
            self.sys_status = m
            self.sys_status_n += 1
        elif t == "STATUSTEXT":
            text = m.text if isinstance(m.text, str) else m.text.decode(errors="replace")
            text = text.rstrip("\x00")
            self.texts.append((self.t_ms or 0, text))
            if text.startswith("boot:"):
                self.boots += 1
        elif t == "COMMAND_ACK":
            self.acks.append(m)
        elif t == "AGNAV_CALIB_ACK":
            self.calib_acks.append(m)
        elif t == "AGNAV_CALIB_TABLE":
            self.calib_tables.append(m)
        elif t == "PARAM_VALUE":
            self.param_values.append(m)

    def counted(self) -> int:
        """Every frame SYS_STATUS says the robot dropped: parser drops, refusals, signing drops."""
        s = self.sys_status
        return 0 if s is None else s.errors_comm + s.errors_count1 + s.errors_count2 + s.errors_count3 + s.errors_count4

    # time
    def wait_robot(self, timeout_s: float = 30.0) -> None:
        end = time.monotonic() + timeout_s
        while self.t_ms is None or self.status is None:
            if time.monotonic() > end or self.closed:
                raise RuntimeError("no telemetry from the robot" + (f" ({self.texts[-1][1]})" if self.texts else ""))
            self.pump(0.02)

    @classmethod
    def connect(cls, port: int, speedup: float, tries: int = 50) -> "Client":
        """A client the served run has taken (the previous one's hang-up may not be noticed yet: the
        server refuses a second client), with the robot's telemetry coming in."""
        for _ in range(tries - 1):
            c = cls(port, speedup)
            try:
                c.wait_robot()
                return c
            except RuntimeError:
                c.close()
                if not any(t.startswith("refused") for _, t in c.texts):
                    raise
                time.sleep(0.05)
        c = cls(port, speedup)
        c.wait_robot()
        return c

    def run(self, seconds: float, every: tuple[tuple[float, Callable[[], None]], ...] = (),
            until: Callable[[], bool] | None = None) -> None:
        """Keep the periodic senders going (periods in simulated seconds) for ``seconds`` of robot time
        (its telemetry clock; the wall clock times the speed-up when the telemetry stops)."""
        start_ms = self.t_ms or 0
        wall_end = time.monotonic() + seconds / self.speedup * 3.0 + 2.0
        due = [time.monotonic()] * len(every)
        while True:
            now = time.monotonic()
            for i, (period, fn) in enumerate(every):
                if now >= due[i]:
                    fn()
                    due[i] = now + period / self.speedup
            if until is not None and until():
                return
            if (self.t_ms or 0) - start_ms >= seconds * 1000.0 or now > wall_end or self.closed:
                return
            self.pump(0.002)

    def wait_sys_status(self, n: int = 2) -> None:
        """Until ``n`` new SYS_STATUS frames have arrived (1 Hz), heartbeats going on."""
        want = self.sys_status_n + n
        self.run(n + 2.0, every=((0.2, self.heartbeat),), until=lambda: self.sys_status_n >= want)

    def close(self) -> None:
        try:
            self.sock.close()
        except OSError:
            pass
        self.closed = True


# ---- measuring on the truth ------------------------------------------------------------------------
def travelled_m(track: list[tuple[float, float, float, float]], t0_ms: float, t1_ms: float) -> float:
    """True path length (m) between robot times t0 and t1 (ms)."""
    pts = [(x, y) for t, x, y, _ in track if t0_ms <= t * 1000.0 <= t1_ms]
    return sum(math.hypot(b[0] - a[0], b[1] - a[1]) for a, b in zip(pts, pts[1:]))


def top_speed_m_s(track: list[tuple[float, float, float, float]], t0_ms: float, t1_ms: float) -> float:
    return max((abs(v) for t, _, _, v in track if t0_ms <= t * 1000.0 <= t1_ms), default=0.0)


@dataclass(frozen=True)
class AttackResult:
    name: str
    tries: int
    refused: int  # tries refused (no motion, clamped to the cap, counted, answered: see the attack)
    moved: str  # what the true robot did, in words and figures
    crashed: int  # firmware resets or a served run that died
    target: str
    met: bool
    figures: dict[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class Attack:
    name: str
    target: str
    run: Callable[[float, str], AttackResult]


# ---- motion attacks ----------------------------------------------------------------------------------
def _drive(c: Client, seconds: float, speed: int = SPEED_MM_S) -> None:
    c.run(seconds, every=((0.1, c.heartbeat), (0.1, lambda: c.setpoint(0, speed))))


def _attack_heartbeat_after_link_loss(speedup: float, firmware: str, tries: int = 3) -> AttackResult:
    sil = ServedSil(speedup=speedup, firmware=firmware)
    windows: list[tuple[int, int]] = []
    seeking = 0
    boots = 0
    try:
        for _ in range(tries):
            host = Client.connect(sil.port, speedup)
            host.run(0.6, every=((0.2, host.heartbeat),))  # past the end of the last window
            host.arm()
            D = host.D
            host.command(D.MAV_CMD_AGNAV_SET_BEHAVIOURS, 0.0, 1.0, 1.0)  # goal seek, avoid
            host.goal(8.0, 0.0)
            host.run(2.0, every=((0.2, host.heartbeat), (1.0, partial(host.goal, 8.0, 0.0))))
            seeking += any(s.active_layer == LAYER_GOAL for s in host.statuses)
            boots += host.boots
            host.close()  # the host is killed while the robot seeks its goal
            time.sleep(2.5 / speedup)  # link loss (0.5 s), then the robot coasts to a standstill
            gcs = Client.connect(sil.port, speedup)  # a ground station: heartbeats and a parameter read
            t0 = gcs.t_ms or 0
            gcs.run(3.0, every=((0.2, gcs.heartbeat), (1.0, partial(gcs.param_read, "MAX_SPEED_MM_S"))))
            windows.append((t0, (gcs.t_ms or 0) + 300))
            boots += gcs.boots
            gcs.close()
    finally:
        track, crashed = sil.stop()
    moved = [travelled_m(track, a, b) for a, b in windows]
    refused = sum(m < STILL_M for m in moved)
    ok = seeking == tries and refused == tries and not crashed and boots == 0
    return AttackResult("heartbeats only after a link loss, goal stored", tries, refused,
                        f"{sum(moved) * 1000:.1f} mm in {3 * tries} s of heartbeats (goal seek seen in {seeking} of "
                        f"{tries} drives before the loss)", boots + crashed, "0 m", ok, {"moved_m": sum(moved)})


def _attack_replayed_setpoints(speedup: float, firmware: str, tries: int = 3) -> AttackResult:
    sil = ServedSil(speedup=speedup, firmware=firmware)
    windows: list[tuple[int, int]] = []
    replayed = 0
    boots = 0
    try:
        for k in range(tries):
            host = Client.connect(sil.port, speedup)
            host.seq = 1000 * k  # the host's own setpoints, newer each session
            if k == 0:
                host.arm()
            host.capture = []
            _drive(host, 2.0)
            captured = host.capture
            boots += host.boots
            host.close()  # link loss: the host is gone
            time.sleep(2.5 / speedup)
            thief = Client.connect(sil.port, speedup)
            t0 = thief.t_ms or 0
            base = captured[0][0]
            start = time.monotonic()
            for t, frame in captured:  # the captured frames again, at their own pace
                while time.monotonic() - start < t - base:
                    thief.pump(0.002)
                thief.send_raw(frame)
                replayed += 1
            thief.run(0.5)
            windows.append((t0, (thief.t_ms or 0) + 300))
            boots += thief.boots
            thief.close()
            time.sleep(1.0 / speedup)
    finally:
        track, crashed = sil.stop()
    moved = [travelled_m(track, a, b) for a, b in windows]
    refused = sum(m < STILL_M for m in moved)
    ok = refused == tries and not crashed and boots == 0
    return AttackResult("replayed setpoints after a link loss", tries, refused,
                        f"{sum(moved) * 1000:.1f} mm while {replayed} captured frames were replayed",
                        boots + crashed, "0 m", ok, {"moved_m": sum(moved)})


def _attack_stale_setpoint(speedup: float, firmware: str, tries: int = 2) -> AttackResult:
    """HOST_TIMEOUT_MS 5000: the host's last setpoint stays younger than the setpoint timeout through
    a link loss or an e-stop; when heartbeats (or the host's release and arm) come back, it is stale."""
    sil = ServedSil({"HOST_TIMEOUT_MS": 5000}, speedup=speedup, firmware=firmware)
    windows: list[tuple[int, int]] = []
    boots = 0
    try:
        c = Client.connect(sil.port, speedup)
        D = c.D
        for _ in range(tries):
            c.arm()
            _drive(c, 1.5)
            c.run(2.2)  # silent: link loss, standstill
            t0 = c.t_ms or 0
            c.run(2.0, every=((0.2, c.heartbeat),))  # heartbeats again
            windows.append((t0, (c.t_ms or 0) + 300))
            c.run(0.6, every=((0.2, c.heartbeat),))  # past the end of the window before the host drives again
            c.arm()
            _drive(c, 1.5)
            c.command(D.MAV_CMD_AGNAV_ESTOP, 1.0)
            c.run(2.2, every=((0.2, c.heartbeat),))  # e-stop: standstill, heartbeats on
            t0 = c.t_ms or 0
            c.arm()  # the host releases the e-stop and arms, no new setpoint
            c.run(2.0, every=((0.2, c.heartbeat),))
            windows.append((t0, (c.t_ms or 0) + 300))
            c.run(0.6, every=((0.2, c.heartbeat),))
        boots += c.boots
        c.close()
    finally:
        track, crashed = sil.stop()
    moved = [travelled_m(track, a, b) for a, b in windows]
    refused = sum(m < STILL_M for m in moved)
    ok = refused == len(windows) and not crashed and boots == 0
    return AttackResult("stale setpoint after a link loss / an e-stop (HOST_TIMEOUT_MS 5000)", len(windows), refused,
                        f"{sum(moved) * 1000:.1f} mm after {tries} link losses and {tries} e-stop releases",
                        boots + crashed, "0 m", ok, {"moved_m": sum(moved)})


def _cap_run(speedup: float, firmware: str, phases: list[tuple[str, Callable[[Client], None], float]],
             extra: dict[str, int] | None = None) -> tuple[list[tuple[str, float, float, int]], bool, int]:
    """Each phase drives with its sender for its seconds, then 2 s of standstill; returns (name, true top
    speed m/s, distance m, reported top |speed| mm/s) per phase."""
    sil = ServedSil({"MAX_SPEED_MM_S": CAP_MM_S, **(extra or {})}, speedup=speedup, firmware=firmware)
    out: list[tuple[str, float, float, int]] = []
    windows: list[tuple[str, int, int, int]] = []
    boots = 0
    try:
        c = Client.connect(sil.port, speedup)
        c.arm()
        for name, sender, seconds in phases:
            n0 = len(c.statuses)
            t0 = c.t_ms or 0
            c.run(seconds, every=((0.1, c.heartbeat), (0.1, partial(sender, c))))
            reported = max((abs(s.speed_mm_s) for s in c.statuses[n0:]), default=0)
            windows.append((name, t0, (c.t_ms or 0) + 300, reported))
            c.run(2.0, every=((0.1, c.heartbeat), (0.1, lambda: c.setpoint(0, 0))))
        boots = c.boots
        c.close()
    finally:
        track, crashed = sil.stop()
    for name, a, b, rep in windows:
        out.append((name, top_speed_m_s(track, a, b), travelled_m(track, a, b), rep))
    return out, crashed, boots


def _cap_result(name: str, rows: list[tuple[str, float, float, int]], crashed: bool, boots: int) -> AttackResult:
    lim = CAP_MM_S / 1000.0 * 1.1
    held = sum(v <= lim for _, v, _, _ in rows)
    moved = "; ".join(f"{n}: top {v:.3f} m/s over {d:.2f} m, reported {r} mm/s" for n, v, d, r in rows)
    ok = held == len(rows) and not crashed and boots == 0 and all(d > 0.05 for _, _, d, _ in rows)
    return AttackResult(name, len(rows), held, moved, boots + crashed, f"<= {lim:.2f} m/s (cap + 10 %)", ok,
                        {"top_m_s": max(v for _, v, _, _ in rows)})


def _attack_raw_pwm(speedup: float, firmware: str) -> AttackResult:
    rows, crashed, boots = _cap_run(speedup, firmware, [
        ("forward", lambda c: c.setpoint(0, 0, raw=(0, 255)), 3.0),
        ("reverse", lambda c: c.setpoint(0, -1, raw=(0, 255)), 3.0),
    ])
    return _cap_result(f"raw PWM full throttle, MAX_SPEED_MM_S {CAP_MM_S}", rows, crashed, boots)


def _rc(c: Client, throttle_us: int) -> None:
    c.send(c.D.MAVLink_rc_channels_override_message(*ROBOT, 1500, 0, throttle_us, 0, 0, 0, 0, 0))


def _manual(c: Client, x: int) -> None:
    c.send(c.D.MAVLink_manual_control_message(ROBOT[0], x, 0, 0, 0, 0))


def _attack_manual(speedup: float, firmware: str) -> AttackResult:
    rows, crashed, boots = _cap_run(speedup, firmware, [
        ("RC 2200 us", lambda c: _rc(c, 2200), 3.0),
        ("RC 2000 us", lambda c: _rc(c, 2000), 3.0),
        ("MANUAL_CONTROL x 1000", lambda c: _manual(c, 1000), 3.0),
    ])
    return _cap_result(f"manual override beyond the cap, MAX_SPEED_MM_S {CAP_MM_S}", rows, crashed, boots)


def _attack_physical(speedup: float, firmware: str) -> AttackResult:
    rows, crashed, boots = _cap_run(speedup, firmware, [
        ("5 m/s", lambda c: c.setpoint(0, 5000), 3.0),
        ("-5 m/s", lambda c: c.setpoint(0, -5000), 3.0),
    ])
    return _cap_result(f"host setpoint of 5 m/s, MAX_SPEED_MM_S {CAP_MM_S}", rows, crashed, boots)


def _attack_goal_seek(speedup: float, firmware: str) -> AttackResult:
    sent: list[bool] = []

    def seek(c: Client) -> None:  # the goal once, then heartbeats only: the firmware drives
        if not sent:
            c.command(c.D.MAV_CMD_AGNAV_SET_BEHAVIOURS, 0.0, 1.0, 1.0)
            c.goal(8.0, 0.0)
            sent.append(True)

    rows, crashed, boots = _cap_run(speedup, firmware, [("goal 8 m ahead", seek, 4.0)])
    return _cap_result(f"firmware goal seek (GOAL_SPEED_MM_S 400), MAX_SPEED_MM_S {CAP_MM_S}", rows, crashed, boots)


# ---- bad-field frames and calibration requests ------------------------------------------------------------
def bad_field_frames() -> list[tuple[str, list[Any]]]:
    """Frames addressed to the robot (system 1) with a field out of its range, by message: every one
    is refused by the firmware's checks (docs/safety.md "Bad commands")."""
    D = _dialect()
    nan, inf = float("nan"), float("inf")
    out: list[tuple[str, list[Any]]] = []

    def sp(tc: int = 1, steer: int = 0, speed: int = 100, spwm: int = 0, vpwm: int = 0, mode: int = 0, ts: int = 1) -> Any:
        return D.MAVLink_agnav_drive_setpoint_message(ts, tc, steer, speed, spwm, vpwm, mode, 1)

    out.append(("AGNAV_DRIVE_SETPOINT", [
        *[sp(mode=m) for m in (2, 3, 7, 100, 255)],
        *[sp(steer=s) for s in (18001, -18001, 32767, -32768)],
        *[sp(speed=v) for v in (10001, -10001, 32767, -32768)],
        *[sp(mode=1, vpwm=p) for p in (3001, 40000, 65535)],
        *[sp(mode=1, spwm=p) for p in (3001, 65535)],
        *[sp(mode=0, vpwm=p) for p in (3001, 65535)],
        *[sp(mode=0, spwm=p) for p in (3001, 65535)],
        sp(ts=0, tc=0), sp(ts=0, tc=1),
        *[sp(tc=c) for c in (2, 42, 190, 255)],
    ]))

    def rc(ch1: int = 1500, ch3: int = 1500, ts: int = 1, tc: int = 1) -> Any:
        return D.MAVLink_rc_channels_override_message(ts, tc, ch1, 0, ch3, 0, 0, 0, 0, 0)

    out.append(("RC_CHANNELS_OVERRIDE", [
        *[rc(ch3=p) for p in (1, 500, 799, 2201, 3000, 65534)],
        *[rc(ch1=p) for p in (1, 799, 2201, 65534)],
        rc(ts=0, tc=0), *[rc(tc=c) for c in (2, 42, 255)],
    ]))

    def mc(x: int = 0, r: int = 0, target: int = 1) -> Any:
        return D.MAVLink_manual_control_message(target, x, 0, 0, r, 0)

    out.append(("MANUAL_CONTROL", [*[mc(x=v) for v in (1001, -1001, 20000, -32768)],
                                   *[mc(r=v) for v in (1001, -1001, 32766)], mc(target=0, x=500)]))

    mask = 0b0000_1101_1111_1000

    def goal(x: float = 2.0, y: float = 0.0, frame: int = D.MAV_FRAME_LOCAL_NED, m: int = mask, ts: int = 1,
             tc: int = 1) -> Any:
        return D.MAVLink_set_position_target_local_ned_message(0, ts, tc, frame, m, x, y, 0, 0, 0, 0, 0, 0, 0, 0, 0)

    out.append(("SET_POSITION_TARGET_LOCAL_NED", [
        goal(x=nan), goal(y=nan), goal(x=inf), goal(y=-inf), goal(x=10000.5), goal(y=-2e9),
        *[goal(frame=f) for f in (D.MAV_FRAME_GLOBAL, D.MAV_FRAME_BODY_NED, D.MAV_FRAME_LOCAL_ENU, 200)],
        goal(m=mask | 1), goal(m=mask | 2), goal(m=0xFFFF),
        goal(ts=0, tc=0), *[goal(tc=c) for c in (2, 42)],
    ]))

    def cmd(c: int, p1: float = 0.0, p2: float = 0.0, p3: float = 0.0, ts: int = 1, tc: int = 1) -> Any:
        return D.MAVLink_command_long_message(ts, tc, c, 0, p1, p2, p3, 0, 0, 0, 0)

    estop, arm, beh, store = D.MAV_CMD_AGNAV_ESTOP, D.MAV_CMD_COMPONENT_ARM_DISARM, D.MAV_CMD_AGNAV_SET_BEHAVIOURS, \
        D.MAV_CMD_PREFLIGHT_STORAGE
    out.append(("COMMAND_LONG", [
        cmd(estop, nan), cmd(estop, inf), cmd(estop, 0.5), cmd(estop, 2.0), cmd(estop, -1.0),
        cmd(arm, nan), cmd(arm, 0.7), cmd(arm, 3.0),
        cmd(beh, 2.0), cmd(beh, 0.0, nan), cmd(beh, 0.0, 0.0, 0.5),
        cmd(store, 2.0), cmd(store, nan), cmd(store, -1.0),
        cmd(31999, 1.0), cmd(0, 0.0), cmd(65535, 0.0),
        cmd(arm, 1.0, ts=0, tc=0), cmd(beh, 1.0, ts=0, tc=0),
        *[cmd(arm, 1.0, tc=c) for c in (2, 42, 255)],
    ]))

    def pset(name: bytes, v: float, ts: int = 1, tc: int = 1) -> Any:
        return D.MAVLink_param_set_message(ts, tc, name, v, D.MAV_PARAM_TYPE_INT32)

    out.append(("PARAM_SET", [
        pset(b"NO_SUCH_PARAM", 1.0), pset(b"", 1.0), pset(b"\xff\xfe", 1.0),
        pset(b"MAX_SPEED_MM_S", nan), pset(b"MAX_SPEED_MM_S", inf), pset(b"MAX_SPEED_MM_S", 3e9),
        pset(b"MAX_SPEED_MM_S", 3001.0), pset(b"MAX_SPEED_MM_S", -1.0), pset(b"LINK_TIMEOUT_MS", 99.0),
        pset(b"LINK_TIMEOUT_MS", 5001.0), pset(b"BHV_MODES", 8.0),
        pset(b"MAX_SPEED_MM_S", 100.0, ts=0, tc=0), *[pset(b"MAX_SPEED_MM_S", 100.0, tc=c) for c in (2, 42)],
    ]))

    def pread(name: bytes, idx: int, tc: int = 1) -> Any:
        return D.MAVLink_param_request_read_message(1, tc, name, idx)

    out.append(("PARAM_REQUEST_READ", [pread(b"", 500), pread(b"", 32767), pread(b"NO_SUCH", -1), pread(b"", -1),
                                       *[pread(b"MAX_SPEED_MM_S", -1, tc=c) for c in (2, 42)]]))
    out.append(("PARAM_REQUEST_LIST", [D.MAVLink_param_request_list_message(1, c) for c in (2, 42, 255)]))

    def table(tid: int = 1, n: int = 2, pwm: list[int] | None = None, val: list[int] | None = None,
              neutral: int = 0, ts: int = 1, tc: int = 1) -> Any:
        p = (pwm or [10, 255]) + [0] * 16
        v = (val or [20, 1000]) + [0] * 16
        return D.MAVLink_agnav_calib_table_message(ts, tc, tid, n, p[:16], v[:16], neutral, neutral, neutral)

    out.append(("AGNAV_CALIB_TABLE", [
        table(tid=3), table(tid=200), table(pwm=[255, 10]), table(val=[1000, 20]),
        table(pwm=[10, 3001]), table(pwm=[10, 600]), table(val=[20, 12000]), table(n=1),
        table(n=17, pwm=list(range(1, 17)), val=list(range(10, 170, 10))), table(neutral=5),
        table(tid=0, pwm=[140, 255], val=[100, 9000], neutral=133),
        table(ts=0, tc=0), *[table(tc=c) for c in (2, 42)],
    ]))

    def creq(tid: int, action: int, ts: int = 1, tc: int = 1) -> Any:
        return D.MAVLink_agnav_calib_request_message(ts, tc, tid, action)

    out.append(("AGNAV_CALIB_REQUEST", [creq(3, 0), creq(200, 2), creq(1, 3), creq(0, 255),
                                        creq(1, 0, ts=0, tc=0), *[creq(1, 0, tc=c) for c in (2, 42)]]))

    def sign(ts: int = 1, tc: int = 1) -> Any:
        return D.MAVLink_setup_signing_message(ts, tc, [0x42] * 32, 1)

    out.append(("SETUP_SIGNING", [sign(), sign(ts=0, tc=0), *[sign(tc=c) for c in (2, 42)]]))
    return out


def _truncated_setpoint(c: Client) -> bytes:
    """A setpoint cut to 4 payload bytes with a valid CRC (MAVLink 2 zero-fills it: target 0)."""
    D = c.D
    mav = D.MAVLink(None, srcSystem=HOST[0], srcComponent=HOST[1])
    msg = D.MAVLink_agnav_drive_setpoint_message(*ROBOT, 0, 300, 0, 0, 0, 1)
    buf = bytearray(msg.pack(mav))
    payload = bytes(buf[10:14])
    hdr = bytearray(buf[:10])
    hdr[1] = 4
    from pymavlink.generator.mavcrc import x25crc

    crc = x25crc(bytes(hdr[1:]) + payload)
    crc.accumulate(bytes([D.MAVLink_agnav_drive_setpoint_message.crc_extra]))
    return bytes(hdr) + payload + int(crc.crc).to_bytes(2, "little")


def _attack_bad_fields(speedup: float, firmware: str) -> AttackResult:
    sil = ServedSil(speedup=speedup, firmware=firmware)
    per: list[tuple[str, int, int]] = []
    boots = 0
    try:
        c = Client.connect(sil.port, speedup)
        c.wait_sys_status(1)
        groups = bad_field_frames()
        groups.append(("truncated or corrupted frames", []))
        for name, frames in groups:
            if name == "SETUP_SIGNING":  # only after the 10 s key window of the power-on (an unsigned key would be set)
                c.run(max(0.0, 11.0 - (c.t_ms or 0) / 1000.0), every=((0.2, c.heartbeat),))
            c.wait_sys_status(1)
            before = c.counted()
            n = 0
            if frames:
                for m in frames:
                    c.send(m)
                    n += 1
                    c.run(0.03)
            else:
                good = c.D.MAVLink_heartbeat_message(6, 8, 0, 0, 0, 3).pack(c.mav)
                for k in range(6):
                    bad = bytearray(good)
                    bad[-1 - k] ^= 0x5A  # a CRC byte or the last payload byte flipped
                    c.send_raw(bytes(bad))
                    n += 1
                    c.run(0.03)
                unknown = bytearray(good)  # a message id this dialect has no entry for
                unknown[7:10] = (0xFFFFFE).to_bytes(3, "little")
                c.send_raw(bytes(unknown))
                c.send_raw(_truncated_setpoint(c))
                n += 2
                c.run(0.03)
            c.wait_sys_status(2)
            per.append((name, n, c.counted() - before))
        boots = c.boots
        c.close()
    finally:
        track, crashed = sil.stop()
    tries = sum(n for _, n, _ in per)
    counted = sum(min(n, k) for _, n, k in per)
    moved = travelled_m(track, 0, 1e12)
    missing = [f"{name} {n - k} of {n}" for name, n, k in per if k < n]
    ok = counted == tries and moved < STILL_M and not crashed and boots == 0
    return AttackResult("bad-field frames addressed to the robot (counted in SYS_STATUS)", tries, counted,
                        f"{moved * 1000:.1f} mm; uncounted: {', '.join(missing) if missing else 'none'}",
                        boots + crashed, "every frame counted, 0 m", ok,
                        {"uncounted": float(tries - counted), **{f"uncounted {n}": float(c_ - k) for n, c_, k in per}})


def _more(items: list[Any], n: int) -> bool:
    return len(items) > n


def _attack_calib_request(speedup: float, firmware: str) -> AttackResult:
    sil = ServedSil(speedup=speedup, firmware=firmware)
    asked: list[tuple[int, int]] = [(t, a) for t in (0, 1, 2) for a in (3, 4, 100, 255)]
    answered = 0
    tables = 0
    boots = 0
    try:
        c = Client.connect(sil.port, speedup)
        D = c.D
        before = c.counted()
        for tid, action in asked:
            n_ack, n_tab = len(c.calib_acks), len(c.calib_tables)
            c.send(D.MAVLink_agnav_calib_request_message(*ROBOT, tid, action))
            c.run(0.5, every=((0.2, c.heartbeat),), until=partial(_more, c.calib_acks, n_ack))
            acks = c.calib_acks[n_ack:]
            tables += len(c.calib_tables) - n_tab
            answered += any(a.table_id == tid and a.result in CALIB_REFUSALS for a in acks)
        c.wait_sys_status(2)
        counted = c.counted() - before
        boots = c.boots
        c.close()
    finally:
        track, crashed = sil.stop()
    ok = answered == len(asked) and tables == 0 and counted >= len(asked) and not crashed and boots == 0
    return AttackResult("unknown AGNAV_CALIB_REQUEST actions (answered)", len(asked), answered,
                        f"{travelled_m(track, 0, 1e12) * 1000:.1f} mm; {answered} refusal acks, {tables} tables sent "
                        f"instead, {counted} counted", boots + crashed, "every request answered with a refusal", ok)


ATTACKS: tuple[Attack, ...] = (
    Attack("heartbeat", "0 m", _attack_heartbeat_after_link_loss),
    Attack("replay", "0 m", _attack_replayed_setpoints),
    Attack("stale", "0 m", _attack_stale_setpoint),
    Attack("raw", "cap + 10 %", _attack_raw_pwm),
    Attack("manual", "cap + 10 %", _attack_manual),
    Attack("physical", "cap + 10 %", _attack_physical),
    Attack("goal", "cap + 10 %", _attack_goal_seek),
    Attack("fields", "all counted", _attack_bad_fields),
    Attack("calib", "all answered", _attack_calib_request),
)


def run_attacks(only: list[str] | None = None, speedup: float = SPEEDUP, firmware: str = "native",
                progress: Callable[[str], None] | None = None) -> list[AttackResult]:
    out = []
    for a in ATTACKS:
        if only and not any(k in a.name for k in only):
            continue
        if progress is not None:
            progress(a.name)
        try:
            out.append(a.run(speedup, firmware))
        except Exception as e:  # the table must show it, not die on it
            out.append(AttackResult(a.name, 0, 0, f"ERROR {type(e).__name__}: {e}", 1, a.target, False))
    return out


def _cell(s: object) -> str:
    return str(s).replace("|", "\\|").replace("\n", " ")


def format_table(rows: list[AttackResult], markdown: bool = True) -> str:
    head = ("attack", "tries", "refused", "moved", "crashed", "target", "met")
    lines = []
    if markdown:
        lines.append("| " + " | ".join(head) + " |")
        lines.append("|" + "---|" * len(head))
    for r in rows:
        cells = (r.name, r.tries, r.refused, r.moved, r.crashed, r.target, "yes" if r.met else "NO")
        lines.append("| " + " | ".join(_cell(c) for c in cells) + " |" if markdown else "  ".join(str(c) for c in cells))
    n_ok = sum(r.met for r in rows)
    lines.append("")
    lines.append(f"{n_ok} of {len(rows)} attacks met their target")
    return "\n".join(lines)


def _unwritable(path: Path) -> str:
    """Why ``path`` cannot be written ('' when it can): a folder, or no write access to it or to the
    nearest folder that exists."""
    if path.is_dir():
        return "it is a folder"
    if path.exists():
        return "" if os.access(path, os.W_OK) else "no write access"
    parent = path.parent.resolve()
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir():
        return f"{parent} is not a folder"
    return "" if os.access(parent, os.W_OK | os.X_OK) else f"no write access to {parent}"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m agnav_host.faults.attacks", description=__doc__.split("\n\n")[0])
    ap.add_argument("--markdown", metavar="FILE", help="also write the table as markdown")
    ap.add_argument("--only", action="append", default=[], metavar="NAME",
                    help="run the attacks whose name contains NAME: " + ", ".join(a.name for a in ATTACKS))
    ap.add_argument("--speedup", type=float, default=SPEEDUP, help=f"simulated seconds per wall second (default {SPEEDUP:g})")
    ap.add_argument("--firmware", choices=("native", "avr"), default="native")
    ns = ap.parse_args(argv)
    if not ns.speedup > 0 or not math.isfinite(ns.speedup):
        print("attacks: --speedup must be a number > 0", file=sys.stderr)
        return 2
    if ns.only and not any(k in a.name for a in ATTACKS for k in ns.only):
        print(f"attacks: no attack matches {', '.join(ns.only)}", file=sys.stderr)
        return 2
    if ns.markdown:  # before the attacks run (a minute or more), not after
        why = _unwritable(Path(ns.markdown))
        if why:
            print(f"attacks: --markdown {ns.markdown}: cannot write there: {why}", file=sys.stderr)
            return 2
    rows = run_attacks(ns.only, ns.speedup, ns.firmware, progress=lambda n: print(f"attack: {n}", file=sys.stderr))
    table = format_table(rows, markdown=True)
    print(table)
    if ns.markdown:
        try:
            Path(ns.markdown).parent.mkdir(parents=True, exist_ok=True)
            Path(ns.markdown).write_text(table + "\n", encoding="utf-8")
        except OSError as e:
            print(f"attacks: --markdown {ns.markdown}: {e.strerror or e}", file=sys.stderr)
            return 1
    return 0 if all(r.met for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
