"""Lock-step SIL: world simulator, real firmware and host endpoint in one simulated time.

One :meth:`SilSession.step` (``world_dt_s``, default 10 ms):

1. the firmware's actuator outputs at t0 drive the robot model from t0 to t1 (zero-order hold;
   the firmware's control loop runs at 50 Hz, so outputs change at most every 20 ms);
2. the wheel rotation over the step becomes encoder edges queued at their exact microseconds;
3. the firmware runs to t1 in ticks of ``tick_us`` (100 us: a >= 10 kHz main loop); it stops at
   each sonar trigger so the world answers with echo edges timed from the trigger, and at each
   radio delivery so the host's bytes reach the UART at the microsecond they arrive;
4. what the firmware sent goes on the downlink, what the downlink delivered goes to the host
   endpoint, the host logic runs (planner, heartbeats), and its bytes go on the uplink.

Everything random comes from one seed, time is integer microseconds, so the same seed gives
byte-identical telemetry logs.
"""

from __future__ import annotations

import ctypes as C
import json
import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Callable, Protocol

import numpy as np

from ..atomic import write_atomic
from ..link.calib_wire import CALIB_IN_PROGRESS
from ..sim.metrics import RunMetrics
from ..sim.referee import Referee
from ..sim.runner import RunResult, _standin_params, write_outputs
from ..sim.controller import Controller, GoalSeekParams
from ..sim.scenario import Scenario
from ..types import DriveCommand, Goal, LaserScan, Pose2D, SonarFrame
from ..units import milli_to_si
from .binding import Firmware, _COutputs
from .host import HostEndpoint
from .link import LinkChannel, LinkParams, Tlog
from .plant import Plant, PlantConfig

if TYPE_CHECKING:
    from ..hostloop import SensorFrame

__all__ = ["SilConfig", "SilSession", "HostLogic", "PlannerHost", "SilRunResult", "run_sil_scenario",
           "write_sil_outputs", "FIRMWARE_CSV_COLUMNS"]

FIRMWARE_CSV_COLUMNS = ("t_s", "time_boot_ms", "layer", "reason", "failsafe_flags", "steer_cdeg", "speed_mm_s")
_ACTUATOR_BYTES = _COutputs.wdt_kicks.offset  # servo_us[2], duty[2], reverse[2]: what the plant reads


@dataclass(frozen=True)
class SilConfig:
    world_dt_s: float = 0.01
    tick_us: int = 100
    uplink: LinkParams = field(default_factory=LinkParams)
    downlink: LinkParams = field(default_factory=LinkParams)
    plant: PlantConfig = field(default_factory=PlantConfig)
    firmware_params: tuple[tuple[str, int], ...] = ()  # extra EEPROM parameters (after the robot profile)
    record_outputs: bool = False  # keep (t_us, Outputs) after every step
    firmware: str = "native"  # SIL backend: "native" (firmware built for the PC) or "avr" (real ELF under simavr)
    firmware_elf: str | None = None  # avr: another ELF than the PlatformIO build (e.g. a variant under test)


class HostLogic(Protocol):
    def __call__(self, s: "SilSession", t_us: int) -> None: ...


class SilSession:
    """World + firmware + link + host endpoint, advanced together (see the module docstring)."""

    def __init__(self, sc: Scenario, seed: int = 0, config: SilConfig | None = None,
                 host_logic: HostLogic | None = None) -> None:
        self.sc = sc
        self.seed = seed
        self.cfg = cfg = config or SilConfig()
        ss = np.random.SeedSequence(seed)
        # (a sixth stream for the tilted laser leaves the first five as they were)
        rng_robot, self.rng_laser, rng_sonar, rng_up, rng_down, self.rng_tilted = (np.random.default_rng(s) for s in ss.spawn(6))
        self.plant = Plant(sc, rng_robot, rng_sonar, cfg.plant)
        params = dict(self.plant.firmware_params())
        params.update(dict(cfg.firmware_params))
        self.fw = Firmware(params, tick_us=cfg.tick_us, backend=cfg.firmware, elf=cfg.firmware_elf)
        self.tlog = Tlog()
        self.up = LinkChannel(cfg.uplink, rng_up, "up", self.tlog)
        self.down = LinkChannel(cfg.downlink, rng_down, "down", self.tlog)
        self.host = HostEndpoint()
        self.host_logic = host_logic
        self.dt_us = int(round(cfg.world_dt_s * 1e6))
        if self.dt_us < 1:
            raise ValueError("world_dt_s must be >= 1 us")
        self.t_us = self.fw.time_us
        self.outputs_log: list[tuple[int, object]] = []
        self.triggers = 0
        self._uart_pending = b""  # delivered bytes the firmware's receive FIFO had no room for yet
        self.uart_deferred_bytes = 0  # how many bytes had to wait for room (none is ever dropped)
        self.on_downlink: Callable[[int, bytes], None] | None = None  # raw bytes the radio delivered to the host
        # Per-step calls straight into the C API behind self.fw (hil/sil/sil_api.h, every backend):
        # the outputs struct read without building an Outputs object unless an actuator changed,
        # and the UART drained without copying the whole receive buffer.
        lib = getattr(self.fw, "_lib", None)
        self._c_outputs = getattr(lib, "sil_outputs", None)
        self._c_uart_read = getattr(lib, "sil_uart_read", None)
        self._outs = _COutputs()
        self._act: bytes | None = None
        self._rx = C.create_string_buffer(1 << 16)

    @property
    def t_s(self) -> float:
        return self.t_us * 1e-6

    def close(self) -> None:
        self.fw.close()

    # ---- start-up --------------------------------------------------------------------------------------
    def provision(self, timeout_s: float = 6.0, retry_s: float = 0.3) -> None:
        """Send the robot's calibration tables over the link (as a set-up tool would), save them to
        EEPROM, and wait for the firmware to accept them, resending what was not acknowledged every
        ``retry_s`` (the link may lose frames). The save is answered IN_PROGRESS, then ACCEPTED once the
        firmware has written both slots in the background (~1.7 s at 3.3 ms a byte). Raises RuntimeError
        when refused or unanswered."""
        uploads = self.plant.calibration_uploads()
        if not uploads:
            return
        want = {tid for tid, *_ in uploads}
        end = self.t_us + int(timeout_s * 1e6)
        acked: dict[int, int] = {}
        save_asked = saving = saved = False
        while self.t_us < end and not saved:
            if not save_asked:
                for tid, pwm, val, neutral in uploads:
                    if acked.get(tid) != 0:
                        self.host.calib_table(tid, pwm, val, neutral)
            if want <= {t for t, r in acked.items() if r == 0} and not saving:
                self.host.calib_request(0, 1)  # save to EEPROM (clears the CALIB_DEFAULTED health flag)
                save_asked = True
            self.up.send(self.t_us, self.host.take_tx())
            resend = self.t_us + int(retry_s * 1e6)
            while self.t_us < min(resend, end) and not saved:
                self._advance()
                for a in self.host.calib_acks:
                    if save_asked and a.table_id == 0:  # the save's answers (every table was accepted before)
                        if a.result == CALIB_IN_PROGRESS:
                            saving = True
                        elif a.result == 0:
                            saved = True
                        else:
                            raise RuntimeError(f"SIL provisioning: calibration save failed (result {a.result})")
                    elif a.table_id in want and acked.get(a.table_id) != 0:
                        acked[a.table_id] = a.result
                self.host.calib_acks.clear()
                if saving:
                    resend = end  # nothing to resend while the firmware writes
            bad = {t: r for t, r in acked.items() if r != 0}
            if bad:
                raise RuntimeError(f"SIL provisioning: calibration refused {bad}")
        if not saved:
            raise RuntimeError(f"SIL provisioning: no answer from the firmware in {timeout_s} s (acks {acked})")

    # ---- one world step ------------------------------------------------------------------------------------
    def _actuators_changed(self) -> bool:
        """True when the firmware's actuator outputs (servo pulses, duty, direction lines) differ from
        the last step's; the plant takes nothing else from the outputs (the watchdog count in them
        changes every step)."""
        if self._c_outputs is None:
            return True
        o = self._outs
        self._c_outputs(o)
        act = bytes(o)[:_ACTUATOR_BYTES]
        if act == self._act:
            return False
        self._act = act
        return True

    def _uart_read(self) -> bytes:
        rd = self._c_uart_read
        if rd is None:
            return self.fw.uart_read()
        buf, size = self._rx, len(self._rx)
        n = rd(buf, size)
        out = C.string_at(buf, n) if n else b""
        while n == size:
            n = rd(buf, size)
            out += C.string_at(buf, n)
        return out

    def _advance(self, hold_still: bool = False) -> None:
        fw, plant, up = self.fw, self.plant, self.up
        t0 = self.t_us
        t1 = t0 + self.dt_us
        if self._actuators_changed():
            plant.set_outputs(fw.outputs())
        plant.advance(fw, t0, t1)
        step_to, take = fw.step_to, fw.take_triggers
        now = fw.time_us
        while True:
            nxt = up.next_delivery_us()
            new = up.receive(now) if nxt is not None and nxt <= now else b""
            if self._uart_pending or new:
                # the receive FIFO (4 KiB) takes what it has room for; the rest waits for the firmware
                # to read some (an unlimited-baud link, or frames bunched behind a latency spike)
                waiting = len(self._uart_pending)
                buf = self._uart_pending + new
                n = fw.uart_write(buf)
                self._uart_pending = buf[n:]
                self.uart_deferred_bytes += max(0, len(self._uart_pending) - waiting)
            if nxt is not None and nxt <= now:
                now = fw.time_us
                continue
            last = nxt is None or nxt > t1
            target = t1 if last or nxt is None else nxt
            if self._uart_pending:
                target = min(target, now + 1000)  # 1 ms of firmware, then offer the waiting bytes again
                last = last and target == t1
            now = step_to(target)  # returns the time reached (earlier after a sonar trigger)
            trig = take()
            if trig:
                self.triggers += len(trig)
                plant.on_triggers(fw, trig)
            if last and now >= t1:
                break
        self.t_us = t1
        self.down.send(t1, self._uart_read())
        data = self.down.receive(t1)
        if data:
            self.host.feed(t1, data)
            if self.on_downlink is not None:
                self.on_downlink(t1, data)
        if self.cfg.record_outputs:
            self.outputs_log.append((t1, fw.outputs()))

    def step(self) -> None:
        self._advance()
        if self.host_logic is not None:
            self.host_logic(self, self.t_us)
        tx = self.host.take_tx()
        if tx:
            self.up.send(self.t_us, tx)

    def run_for(self, seconds: float, until: Callable[["SilSession"], bool] | None = None) -> None:
        end = self.t_us + int(round(seconds * 1e6))
        while self.t_us < end:
            self.step()
            if until is not None and until(self):
                return

    # ---- truth --------------------------------------------------------------------------------------------------
    @property
    def pose(self) -> Pose2D:
        return self.plant.robot.pose

    def believed_pose(self) -> Pose2D | None:
        """The host's pose: firmware odometry (odometry frame = start pose) in the world frame."""
        o = self.host.odometry
        if o is None:
            return None
        return self.sc.start.compose(Pose2D(o.x_m, o.y_m, o.heading_rad))


class PlannerHost:
    """The host companion on the SIL's link: heartbeats, and at ``control_hz`` one step of the host loop
    (:class:`~agnav_host.hostloop.HostLoop`) on the firmware's odometry, its sonar ring and the scenario's lasers,
    sent as AGNAV_DRIVE_SETPOINT. The lasers hang off the host (they are cast from the true pose) but the loop
    places their scans with the believed pose, as on a robot."""

    def __init__(self, sc: Scenario, planner: str = "goal_seek", heartbeat_hz: float = 2.0,
                 control_hz: float | None = None, behaviours: tuple[bool, bool, bool] | None = None,
                 controller: Controller | None = None, localise: str | None = None,
                 map_yaml: str | None = None) -> None:
        from ..hostloop import HostLoop
        from ..perception._health import LaserWatchdog
        from ..sim.field_controllers import make_scenario_controller
        from ..sim.runner import robot_spec

        self.sc = sc
        if controller is not None:  # built by the caller (e.g. a perception follower); planner is its label
            self.ctrl = controller
        else:  # the registry's controller, as the ideal runner builds it (the stand-in with a wider margin)
            self.ctrl = make_scenario_controller(sc, planner, self.planner_params(sc) if planner == "goal_seek" else None)
        self.spec = robot_spec(sc)
        self.hb_us = int(1e6 / heartbeat_hz)
        self.ctrl_us = int(1e6 / (control_hz or sc.control_hz))
        self.next_hb = 0
        self.next_ctrl = 0
        self.goal_index = 0
        self.behaviours = behaviours
        self.commands: list[tuple[int, DriveCommand]] = []
        self.max_steer_rad = math.radians(45.0 if sc.robot_kind != "ackermann" else 30.0)  # MAX_STEER_CDEG
        # how the host localises (``localise``, else the scenario's meta.localise): ``scan`` (scan matching
        # against ``map_yaml`` or a map built online), ``posts`` (the surveyed marker posts, meta.landmarks),
        # ``odometry``; by default the posts when the scenario lists them and has a laser, else odometry
        self.localiser = None
        localise = localise or sc.meta.get("localise")
        if localise is not None:
            from ..sim.runner import make_localiser

            self.localiser = make_localiser(sc, str(localise), map_yaml or sc.meta.get("map"))
        elif sc.laser is not None and sc.meta.get("landmarks"):
            from ..localisation import localiser_for

            self.localiser = localiser_for(sc.meta, sc.start, sc.laser.mount)
        self.last_pose: tuple[Pose2D, Pose2D] | None = None  # (planned, true) at the last control step
        self._odo_stamp_ms = -1
        # The laser is checked before anything plans on it (perception._health); a fault holds the
        # robot with zero setpoints until the laser is healthy again. laser_fault (tests and the
        # fault suite) turns each true scan into what a broken laser would deliver.
        self.laser_health = LaserWatchdog()
        self.laser_fault: Callable[[LaserScan, float], LaserScan] | None = None
        self.events: list[tuple[int, str]] = []  # (t_us, text): what the host decided and why
        # optional: more Observation.extras for the planner at each control step (e.g. a stand-in for a
        # tracker's moving-obstacle tracks in a benchmark); called with the session
        self.observation_extras: Callable[[SilSession], dict[str, object]] | None = None
        self.loop = HostLoop(self.ctrl, list(sc.goals), laser_mount=sc.laser.mount if sc.laser is not None else None,
                             tilted_mount=sc.tilted_laser.mount if sc.tilted_laser is not None else None,
                             localiser=self.localiser, watchdog=self.laser_health)
        self.uses_sonar = "sonar" in self.loop.needs
        self.uses_tilted = sc.tilted_laser is not None and "tilted_laser" in self.loop.needs

    @staticmethod
    def planner_params(sc: Scenario) -> GoalSeekParams:
        if sc.robot_kind == "ackermann":
            return _standin_params(sc)
        p = sc.robot_params
        # Wider margin than the ideal runner's: the firmware's passive safety stops the robot when
        # the front cone of the sonar ring sees an obstacle nearer than AVOID_STOP_MM (300 mm).
        return GoalSeekParams(kinematics="diff_drive", radius_m=p.radius_m, max_speed_m_s=sc.max_speed_m_s,
                              margin_m=0.2)

    def to_setpoint(self, cmd: DriveCommand) -> tuple[float, float]:
        """(steer_rad, speed_m_s) for the firmware (:func:`agnav_host.hostloop.firmware_setpoint`)."""
        from ..hostloop import firmware_setpoint

        sp = self.spec
        return firmware_setpoint(cmd, sp.kinematics, sp.track_m, sp.wheelbase_m, self.max_steer_rad)

    @staticmethod
    def sonar_frame(s: SilSession) -> SonarFrame | None:
        """The firmware's latest AGNAV_SONAR_RING as a SonarFrame (NaN = no echo / fault / stale)."""
        f = s.host.sonar
        if f is None:
            return None
        st = np.array(f.status[:12])
        r = np.where(st == 0, milli_to_si(np.array(f.ranges_mm[:12], dtype=float)), np.nan)
        return SonarFrame(f.t_us * 1e-6, st != 3, r * 2.0 / 343.0 * 1e6, r)

    def _read_laser(self, s: SilSession) -> LaserScan:
        assert self.sc.laser is not None
        scan = self.sc.laser.scan(s.plant.world, s.pose, s.t_s, s.rng_laser)
        return scan if self.laser_fault is None else self.laser_fault(scan, s.t_s)

    def frame(self, s: SilSession) -> "SensorFrame":
        """The SIL's sources for one control step: the firmware's odometry (a report only when new) and sonar
        ring, the scenario's lasers cast from the true pose, the referee's goal index."""
        from ..hostloop import OdometryReport, SensorFrame

        o = s.host.odometry
        if o is None:  # no odometry yet: no pose, and no laser read
            return SensorFrame(s.t_s, None, sonar=self.sonar_frame(s) if self.uses_sonar else None,
                               goal_index=self.goal_index)
        report = None
        if o.time_boot_ms != self._odo_stamp_ms:
            self._odo_stamp_ms = o.time_boot_ms
            report = OdometryReport(o.x_m, o.y_m, o.heading_rad, milli_to_si(o.time_boot_ms), o.speed_m_s, o.yaw_rate_rad_s)
        tl = self.sc.tilted_laser
        return SensorFrame(
            s.t_s, s.believed_pose(), o.speed_m_s, o.yaw_rate_rad_s, odometry=report,
            scan=self._read_laser(s) if self.sc.laser is not None else None,
            tilted_scan=tl.scan(s.plant.world, s.pose, s.t_s, s.rng_tilted) if self.uses_tilted and tl is not None else None,
            sonar=self.sonar_frame(s) if self.uses_sonar else None, goal_index=self.goal_index,
            extras=self.observation_extras(s) if self.observation_extras is not None else None)

    def __call__(self, s: SilSession, t_us: int) -> None:
        h = s.host
        if self.behaviours is not None:
            h.set_behaviours(*self.behaviours)
            self.behaviours = None
        if t_us >= self.next_hb:
            h.heartbeat()
            self.next_hb += self.hb_us
        if t_us < self.next_ctrl:
            return
        self.next_ctrl += self.ctrl_us
        d = self.loop.step(self.frame(s))
        if d.pose is not None:
            self.last_pose = (d.pose, s.pose)
        if d.event:
            self.events.append((t_us, d.event))
        if d.command is None:
            return
        if d.hold:
            h.setpoint(0, 0)
            return
        h.setpoint_si(*self.to_setpoint(d.command))
        self.commands.append((t_us, d.command))


@dataclass
class SilRunResult:
    run: RunResult
    tlog: bytes
    firmware_status: list[tuple[float, int, int, int, int, int, int]]
    link_stats: dict[str, int]
    wall_s: float = 0.0
    backend: str = "native"


def run_sil_scenario(sc: Scenario, planner: str = "goal_seek", seed: int = 0, duration_s: float | None = None,
                     goal: Goal | None = None, config: SilConfig | None = None,
                     progress: Callable[[float, float], None] | None = None,
                     controller: Controller | None = None, localise: str | None = None,
                     map_yaml: str | None = None) -> SilRunResult:
    """The ideal runner's scenario loop with the real firmware in the loop (same metrics and
    end reasons: arrived, collision, fell_in_hole, timeout). ``controller``: a controller built by the
    caller instead of the named ``planner`` (which then only labels the run). ``localise`` / ``map_yaml``: how
    the host localises (:class:`PlannerHost`)."""
    import time

    if goal is not None:
        sc = replace(sc, goals=[goal])
    duration = sc.duration_s if duration_s is None else duration_s
    host = PlannerHost(sc, planner, controller=controller, localise=localise, map_yaml=map_yaml)
    s = SilSession(sc, seed, config, host)
    wall0 = time.perf_counter()
    try:
        s.provision()
        t_start = s.t_us
        rec_every = max(1, int(round(sc.dt_s / s.cfg.world_dt_s)))
        n_steps = int(round(duration / s.cfg.world_dt_s))
        rows = [(0.0, s.pose.x_m, s.pose.y_m, s.pose.yaw_rad, 0.0, 0.0, s.plant.clearance(0.0), 0)]
        referee = Referee(sc)
        gi = 0
        prog_every = max(1, int(round(1.0 / s.cfg.world_dt_s)))
        for k in range(1, n_steps + 1):
            s.step()
            t = (s.t_us - t_start) * 1e-6
            r = s.plant.robot
            p = r.pose
            cl = s.plant.clearance(s.t_s)
            if k % rec_every == 0 or cl < 0:
                rows.append((t, p.x_m, p.y_m, p.yaw_rad, r.speed_m_s, r.yaw_rate_rad_s, cl, gi))
            if progress is not None and k % prog_every == 0:
                progress(t, duration)
            if referee.judge(t, r, cl) is not None:
                if referee.reason == "arrived" and rows[-1][0] != t:
                    rows.append((t, p.x_m, p.y_m, p.yaw_rad, r.speed_m_s, r.yaw_rate_rad_s, cl, gi))
                break
            gi = host.goal_index = referee.goal_index
        arr = np.array(rows, dtype=float)
        last = sc.goals[-1]
        metrics = RunMetrics.compute(arr[:, 0], arr[:, 1:3], arr[:, 3], arr[:, 4], arr[:, 5], arr[:, 6],
                                     (last.x_m, last.y_m), last.yaw_rad, last.arrival_s, referee.reason == "arrived",
                                     referee.arrival_s, field=referee.field_score())
        run = RunResult(sc.name, planner, seed, metrics, arr, referee.reason, scene=sc,
                        believed=host.last_pose if host.localiser is not None else None,
                        events=[(t_us * 1e-6, e) for t_us, e in host.events])
        status = [(st.t_us * 1e-6, st.time_boot_ms, st.layer, st.reason, st.failsafe_flags, st.steer_cdeg, st.speed_mm_s)
                  for st in s.host.status_log]
        stats = {"up_frames": s.up.frames_sent, "up_lost": s.up.frames_lost, "up_dropped": s.up.frames_dropped,
                 "down_frames": s.down.frames_sent, "down_lost": s.down.frames_lost,
                 "down_dropped": s.down.frames_dropped, "encoder_edges": s.plant.edges_queued,
                 "sonar_echoes": s.plant.echoes, "firmware_loop_passes": s.fw.loop_passes,
                 "late_events": s.fw.late_events}
        return SilRunResult(run, s.tlog.getvalue(), status, stats, time.perf_counter() - wall0, s.cfg.firmware)
    finally:
        s.close()


def write_sil_outputs(res: SilRunResult, out_dir: str | Path, plot: bool = True) -> list[Path]:
    """The ideal runner's files (summary.json, run_info.json, trajectory.csv[, .png]) plus
    ``link.tlog`` (both directions, see :class:`~agnav_host.sil.link.Tlog`) and ``firmware.csv``
    (AGNAV_BEHAVIOUR_STATUS as the host received it)."""
    out = Path(out_dir)
    paths = write_outputs(res.run, out, plot=plot)
    info = out / "run_info.json"
    d = json.loads(info.read_text(encoding="utf-8"))
    d.update(firmware="sil" if res.backend == "native" else f"sil-{res.backend}", link=res.link_stats)
    write_atomic(info, json.dumps(d, indent=2) + "\n")
    tl = out / "link.tlog"
    write_atomic(tl, res.tlog)
    fc = out / "firmware.csv"
    lines = [",".join(FIRMWARE_CSV_COLUMNS)] + [f"{r[0]:.6f}," + ",".join(str(int(v)) for v in r[1:]) for r in res.firmware_status]
    write_atomic(fc, "\n".join(lines) + "\n")
    return [*paths, tl, fc]
