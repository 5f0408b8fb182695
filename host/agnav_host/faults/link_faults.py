"""Radio faults in the SIL: the real firmware (native build) drives the ``fault_yard`` robot
straight ahead at 0.4 m/s on host setpoints sent at 10 Hz, while the uplink loses frames at random,
in bursts, is delayed, or dies. The firmware must stop within LINK_TIMEOUT_MS (500 ms) + one control
tick (20 ms) of the last frame it received, and move again only when a fresh setpoint arrives.

Every figure comes from the run: frame delivery times from the link model, the actuator outputs
after every 2 ms world step, the true robot pose from the world simulator.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Callable, Iterable, Protocol

from ._core import FaultCase, FaultOutcome

if TYPE_CHECKING:
    from ..sil import LinkFaults, SilSession

__all__ = ["LINK_CASES", "DriveTrace", "drive_with_link_faults"]

SPEED_MM_S = 400
TIMEOUT_MS = 500.0  # LINK_TIMEOUT_MS default (behaviour.c)
TICK_MS = 20.0  # 50 Hz control tick
DT_S = 0.002  # world step: the resolution of every time figure below


class HostDriver(Protocol):
    """The host side of a fault run: called after every world step; ``t0_us`` is set to the end of provisioning."""

    t0_us: int

    def __call__(self, s: SilSession, t_us: int) -> None: ...


class _Driver:
    """Host logic: heartbeat + AGNAV_DRIVE_SETPOINT every 100 ms; setpoints paused inside
    ``quiet`` windows (heartbeats go on), nothing at all inside ``silent`` windows (seconds after
    ``t0_us``, the end of provisioning)."""

    def __init__(self, quiet: tuple[tuple[float, float], ...] = (), silent: tuple[tuple[float, float], ...] = ()) -> None:
        self.next_us = 0
        self.quiet = quiet
        self.silent = silent
        self.setpoints_sent_us: list[int] = []
        self.t0_us = 0

    def __call__(self, s: SilSession, t_us: int) -> None:
        if t_us < self.next_us:
            return
        self.next_us = t_us + 100_000
        t = (t_us - self.t0_us) * 1e-6
        if any(a <= t < b for a, b in self.silent):
            return
        s.host.heartbeat()
        if not any(a <= t < b for a, b in self.quiet):
            s.host.setpoint(0, SPEED_MM_S)
            self.setpoints_sent_us.append(t_us)


@dataclass
class DriveTrace:
    t_us: list[int] = field(default_factory=list)  # after every world step
    moving: list[bool] = field(default_factory=list)  # any H-bridge duty non-zero
    x_m: list[float] = field(default_factory=list)
    speed_m_s: list[float] = field(default_factory=list)
    deliveries_us: list[int] = field(default_factory=list)  # uplink frames reaching the firmware's UART
    statuses: list[tuple[int, int, int, int]] = field(default_factory=list)  # (t_us, layer, reason, failsafe flags) the host saw
    texts: list[tuple[int, str]] = field(default_factory=list)  # STATUSTEXT the host saw
    acks: list[Any] = field(default_factory=list)  # COMMAND_ACK the host saw
    # SYS_STATUS errors_count1..4 at the end: refusals, unsigned, wrong key, replayed frames dropped
    sys_status_counters: tuple[int, ...] = ()
    t0_us: int = 0
    link: dict[str, int] = field(default_factory=dict)

    def stops(self) -> list[int]:
        """Times (us) the outputs went from driving to neutral."""
        return [self.t_us[i] for i in range(1, len(self.t_us)) if self.moving[i - 1] and not self.moving[i]]

    def starts(self) -> list[int]:
        return [self.t_us[i] for i in range(1, len(self.t_us)) if not self.moving[i - 1] and self.moving[i]]

    def first_stop_after(self, t_us: int) -> int | None:
        """When the outputs first went neutral at or after t_us (us), None if they never did."""
        return next((t for t in self.stops() if t >= t_us), None)

    def texts_after(self, t_us: int) -> list[str]:
        return [txt for t, txt in self.texts if t >= t_us]

    def statuses_after(self, t_us: int) -> list[tuple[int, int, int, int]]:
        return [st for st in self.statuses if st[0] >= t_us]

    def speeds_after(self, t_us: int) -> list[float]:
        return self.speed_m_s[self.index_at(t_us):]

    def last_delivery_before(self, t_us: int) -> int | None:
        prev = [d for d in self.deliveries_us if d <= t_us]
        return prev[-1] if prev else None

    def first_delivery_after(self, t_us: int) -> int | None:
        nxt = [d for d in self.deliveries_us if d > t_us]
        return nxt[0] if nxt else None

    def long_gaps(self, limit_ms: float) -> list[tuple[int, int]]:
        """(last frame before, first frame after) for every silence longer than limit_ms."""
        d = self.deliveries_us
        return [(a, b) for a, b in zip(d, d[1:]) if (b - a) / 1000.0 > limit_ms]

    def index_at(self, t_us: int) -> int:
        for i, t in enumerate(self.t_us):
            if t >= t_us:
                return i
        return len(self.t_us) - 1


def drive_with_link_faults(duration_s: float, seed: int = 0, loss: float = 0.0, up_faults: LinkFaults | None = None,
                           down_faults: LinkFaults | None = None, driver: HostDriver | None = None,
                           cut_at_s: float | None = None, restore_at_s: float | None = None,
                           events: Iterable[tuple[float, Callable[[SilSession], object]]] = (),
                           firmware_params: Iterable[tuple[str, int]] = ()) -> DriveTrace:
    """Run the SIL with the given uplink faults and return the trace (see :class:`DriveTrace`).
    ``events``: (t_s, fn(session)) called once when the session clock passes t_s after provisioning
    (fault injection into the firmware's hardware)."""
    from ..sil import LinkParams, SilConfig, SilSession
    from ..sim import load_scenario

    sc = load_scenario("fault_yard")
    cfg = SilConfig(world_dt_s=DT_S, record_outputs=False, uplink=LinkParams(loss=loss),
                    firmware_params=tuple(firmware_params))
    pending = sorted(events, key=lambda e: e[0])
    drv: HostDriver = driver or _Driver()
    s = SilSession(sc, seed, cfg, drv)
    tr = DriveTrace()
    try:
        s.provision()
        tr.t0_us = drv.t0_us = s.t_us
        s.up.faults = up_faults
        s.down.faults = down_faults
        orig_receive = s.up.receive

        def receive(t_us: int) -> bytes:
            data = orig_receive(t_us)
            if data:
                tr.deliveries_us.append(s.up.last_delivery_us or t_us)
            return data

        s.up.receive = receive  # type: ignore[method-assign]
        end = s.t_us + int(duration_s * 1e6)
        n_status = len(s.host.status_log)
        n_text = len(s.host.statustexts)
        while s.t_us < end:
            t_rel = (s.t_us - tr.t0_us) * 1e-6
            while pending and t_rel >= pending[0][0]:
                pending.pop(0)[1](s)
            if cut_at_s is not None and t_rel >= cut_at_s and not s.up.down and (restore_at_s is None or t_rel < restore_at_s):
                s.up.down = s.down.down = True
            if restore_at_s is not None and t_rel >= restore_at_s and s.up.down:
                s.up.down = s.down.down = False
            s.step()
            o = s.fw.outputs()
            tr.t_us.append(s.t_us)
            tr.moving.append(bool(o.duty_left or o.duty_right))
            tr.x_m.append(s.pose.x_m)
            tr.speed_m_s.append(s.plant.robot.speed_m_s)
            for st in s.host.status_log[n_status:]:
                tr.statuses.append((st.t_us, st.layer, st.reason, st.failsafe_flags))
            n_status = len(s.host.status_log)
            tr.texts += s.host.statustexts[n_text:]
            n_text = len(s.host.statustexts)
        tr.link = {"up_sent": s.up.frames_sent, "up_lost": s.up.frames_lost}
        tr.acks = list(s.host.acks)
        ss = s.host.sys_status
        if ss is not None:
            tr.sys_status_counters = tuple(int(getattr(ss, f"errors_count{i}")) for i in range(1, 5))
    finally:
        s.close()
    return tr


def _check_stops(tr: DriveTrace, from_us: int) -> tuple[bool, str, dict[str, float]]:
    """Every silence > TIMEOUT_MS on the uplink must give exactly one stop, TIMEOUT_MS..TIMEOUT_MS +
    one tick + one step after the last frame, and driving again within a tick + step of the next
    frame; no stop anywhere else."""
    gaps = [g for g in tr.long_gaps(TIMEOUT_MS) if g[0] >= from_us]
    stops = [t for t in tr.stops() if t >= from_us]
    worst_react = 0.0
    worst_resume = 0.0
    bad: list[str] = []
    used: set[int] = set()
    for a, b in gaps:
        inside = [t for t in stops if a < t <= b + TICK_MS * 1000 + DT_S * 1e6]
        if not inside:
            bad.append(f"no stop in a {(b - a) / 1000:.0f} ms silence")
            continue
        t_stop = inside[0]
        used.add(t_stop)
        react = (t_stop - a) / 1000.0
        worst_react = max(worst_react, react)
        if not TIMEOUT_MS - TICK_MS <= react <= TIMEOUT_MS + TICK_MS + DT_S * 1000:
            bad.append(f"stopped {react:.0f} ms after the last frame")
        restart = [t for t in tr.starts() if t > t_stop]
        if restart:
            resume = (restart[0] - b) / 1000.0
            worst_resume = max(worst_resume, resume)
            if resume < 0:
                bad.append(f"moved again {-resume:.0f} ms before any fresh frame")
            elif resume > TICK_MS + DT_S * 1000 + 1:
                bad.append(f"resumed {resume:.0f} ms after the fresh frame")
    spurious = [t for t in stops if t not in used]
    if spurious:
        bad.append(f"{len(spurious)} stop(s) with the link alive")
    figs = {"silences_over_timeout": float(len(gaps)), "stops": float(len(stops)),
            "worst_stop_after_last_frame_ms": worst_react, "worst_resume_after_fresh_frame_ms": worst_resume}
    return not bad, "; ".join(bad), figs


def _gap_summary(tr: DriveTrace) -> float:
    d = tr.deliveries_us
    return max(((b - a) / 1000.0 for a, b in zip(d, d[1:])), default=math.inf)


def _case_random_loss() -> FaultOutcome:
    tr = drive_with_link_faults(20.0, seed=3, loss=0.2)
    ok, bad, figs = _check_stops(tr, tr.t0_us + 1_000_000)
    dist = tr.x_m[-1] - tr.x_m[0]
    lost = tr.link["up_lost"] / max(1, tr.link["up_sent"])
    msg = (f"{lost * 100:.0f} % of {tr.link['up_sent']} uplink frames lost, longest silence {_gap_summary(tr):.0f} ms; "
           f"{int(figs['stops'])} stop(s) for {int(figs['silences_over_timeout'])} silence(s) > 500 ms; drove {dist:.2f} m in 20 s")
    return FaultOutcome(msg + (f"; {bad}" if bad else ""), ok and dist > 0.8 * 20 * SPEED_MM_S / 1000 * 0.9, figs)


def _case_bursts() -> FaultOutcome:
    from ..sil import LinkFaults, random_bursts

    bursts = random_bursts(seed=11, duration_s=40.0, rate_hz=0.25, mean_length_s=0.5, start_s=2.0)
    tr = drive_with_link_faults(44.0, seed=1, up_faults=LinkFaults(outages=bursts))
    ok, bad, figs = _check_stops(tr, tr.t0_us + 1_000_000)
    long_b = sum(1 for a, b in bursts if b - a > 0.4)
    msg = (f"{len(bursts)} bursts ({min(b - a for a, b in bursts):.2f}-{max(b - a for a, b in bursts):.2f} s, {long_b} over 0.4 s): "
           f"{int(figs['silences_over_timeout'])} silences > 500 ms -> {int(figs['stops'])} stops, each "
           f"<= {figs['worst_stop_after_last_frame_ms']:.0f} ms after the last frame; resumed <= "
           f"{figs['worst_resume_after_fresh_frame_ms']:.0f} ms after the next frame")
    return FaultOutcome(msg + (f"; {bad}" if bad else ""), ok and figs["silences_over_timeout"] >= 1, figs)


def _case_latency(extra_s: float) -> FaultOutcome:
    from ..sil import LinkFaults

    spike = (4.0, 6.0, extra_s)
    tr = drive_with_link_faults(12.0, seed=2, up_faults=LinkFaults(latency_spikes=(spike,)))
    ok, bad, figs = _check_stops(tr, tr.t0_us + 1_000_000)
    msg = (f"longest silence {_gap_summary(tr):.0f} ms: {int(figs['stops'])} stop(s)"
           + (f", {figs['worst_stop_after_last_frame_ms']:.0f} ms after the last frame, moving again "
              f"{figs['worst_resume_after_fresh_frame_ms']:.0f} ms after the delayed frames arrived" if figs["stops"] else ""))
    want_stop = extra_s * 1000.0 + 100.0 > TIMEOUT_MS
    return FaultOutcome(msg + (f"; {bad}" if bad else ""), ok and (figs["stops"] >= 1) == want_stop, figs)


def _case_dead_radio() -> FaultOutcome:
    """Radio dead both ways at 5 s; back at 9 s with heartbeats only (the host paused its
    setpoints: 'quiet' until 12 s); setpoints again from 12 s."""
    drv = _Driver(quiet=((9.0, 12.0),))
    tr = drive_with_link_faults(14.0, seed=4, driver=drv, cut_at_s=5.0, restore_at_s=9.0)
    cut_us = tr.t0_us + 5_000_000
    last = tr.last_delivery_before(cut_us + 100_000)
    t_stop = tr.first_stop_after(cut_us - 200_000 + 1)
    if last is None or t_stop is None:
        return FaultOutcome("robot never stopped after the radio died", False)
    i_last, i_stop = tr.index_at(last), tr.index_at(t_stop)
    i_still = next((i for i in range(i_stop, len(tr.t_us)) if abs(tr.speed_m_s[i]) < 1e-3), None)
    react_ms = (t_stop - last) / 1000.0
    still_ms = (tr.t_us[i_still] - last) / 1000.0 if i_still is not None else math.inf
    dist_m = (tr.x_m[i_still] if i_still is not None else tr.x_m[-1]) - tr.x_m[i_last]
    # heartbeats only between 9 s and 12 s: must stay still
    i9, i12 = tr.index_at(tr.t0_us + 9_000_000), tr.index_at(tr.t0_us + 12_000_000)
    crept = tr.x_m[i12] - tr.x_m[i9]
    moved_on_hb = any(tr.moving[i9:i12])
    restart = [t for t in tr.starts() if t > tr.t0_us + 12_000_000 - 1]
    fresh = tr.first_delivery_after(tr.t0_us + 12_000_000 - 1)
    resume_ms = (restart[0] - fresh) / 1000.0 if restart and fresh else math.inf
    ok = (TIMEOUT_MS - TICK_MS <= react_ms <= TIMEOUT_MS + TICK_MS + DT_S * 1000 and not moved_on_hb
          and abs(crept) < 1e-3 and 0 <= resume_ms <= TICK_MS + DT_S * 1000 + 1)
    msg = (f"outputs neutral {react_ms:.0f} ms and robot still {still_ms:.0f} ms after the last frame, "
           f"{dist_m:.3f} m travelled; radio back with heartbeats only: "
           f"{'moved' if moved_on_hb else 'stayed stopped'} ({crept * 1000:.1f} mm in 3 s); "
           f"first fresh setpoint -> moving after {resume_ms:.0f} ms")
    return FaultOutcome(msg, ok, {"stop_ms": react_ms, "still_ms": still_ms, "stop_distance_m": dist_m,
                                  "resume_ms": resume_ms})


LINK_CASES = (
    FaultCase("20 % random uplink frame loss", "link",
              "keeps driving; a stop only for a silence > LINK_TIMEOUT_MS (500 ms)", _case_random_loss),
    FaultCase("loss bursts (Poisson 0.25 Hz, mean 0.5 s) for 40 s", "link",
              "stop 500-520 ms after the last frame of every silence > 500 ms, none otherwise; "
              "move again within one tick of the next setpoint", _case_bursts),
    FaultCase("latency spike +0.3 s for 2 s", "link", "no stop (silences stay < 500 ms)",
              lambda: _case_latency(0.3)),
    FaultCase("latency spike +1.0 s for 2 s", "link",
              "stop 500-520 ms after the last frame; move again when the delayed setpoints arrive",
              lambda: _case_latency(1.0)),
    FaultCase("dead radio at 0.4 m/s, back 4 s later", "link",
              "stop 500-520 ms after the last frame; heartbeats alone do not restart it; "
              "moves within one tick of a fresh setpoint", _case_dead_radio),
)
