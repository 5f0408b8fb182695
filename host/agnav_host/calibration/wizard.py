"""Interactive calibration of the steering and speed tables (``agnav calibrate steering|speed``).

Procedure (ref 003, section 6.5, with the robot measuring itself):

1. Safety briefing and confirmation (open flat area, >= 3 m free around the car, e-stop at hand;
   Ctrl-C engages the firmware e-stop). Nothing moves before the operator answers "y".
2. Read the active table (kept for the plot and to restore on failure), release the e-stop, arm.
3. Sweep: for each PWM step (bounded by ``[calibration]`` limits, at most 40 steps) stream raw
   setpoints (AGNAV_DRIVE_SETPOINT mode=AGNAV_DRIVE_RAW_PWM) at 10 Hz; ignore ``settle_s``; measure
   for ``hold_s``. A step ends early after ``max_step_s`` or ``max_distance_m`` or when a higher
   layer (failsafe, obstacle) takes over (the step is then discarded). The car stops between
   steps.
   Steering: constant low speed, steering PWM swept; phi = atan(L * yaw_rate / v) with the yaw
   rate from two rear wheel encoders ((v_r - v_l) / track). With one encoder, the operator types
   the diameter of the circle driven (ref 003's method).
   Speed: steering at neutral, speed PWM swept; speed = mean wheel-encoder speed.
4. Fit (isotonic, per side, dead band), show the fit (PNG), ask before writing.
5. Write AGNAV_CALIB_TABLE, read back (AGNAV_CALIB_REQUEST READ) and compare, then save
   (AGNAV_CALIB_ACTION_SAVE) if the operator agrees.

Every way out of the sweep stops the car (zero setpoints): Ctrl-C and unexpected errors also engage
the e-stop; a lost link (:class:`LinkLost`: the endpoint reports the link down, or no telemetry for
``link_timeout_s`` or for a whole step) and closed input (:class:`InputClosed`: EOF on stdin, e.g.
``--yes < /dev/null`` where a circle diameter must be typed) abort with a plain message and nothing
written.
"""

from __future__ import annotations

import statistics
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from ..link.calib_wire import TABLE_SPEED, TABLE_STEER, WireTable
from ..link.config import CalibrationConfig
from ..link.robot import AgnavRobot
from ..units import cdeg_to_rad, milli_to_si, rad_to_cdeg, si_to_milli
from .fit import CalibFitError, FitResult, fit_table, steer_from_diameter, steer_from_motion, yaw_rate_from_wheels

__all__ = ["Wizard", "ConsoleIO", "ScriptedIO", "StepResult", "Aborted", "LinkLost", "InputClosed", "sweep_points",
           "MAX_STEPS"]

MAX_STEPS = 40
SETPOINT_HZ = 10.0
MIN_SPEED_FOR_ANGLE_M_S = 0.05


class Aborted(RuntimeError):
    """The operator declined, or the robot could not be driven safely."""


class LinkLost(Aborted):
    """The link to the robot went down (or telemetry stopped) during the sweep."""


class InputClosed(Aborted):
    """The operator's input ended (EOF on stdin) where the wizard needed an answer."""


class ConsoleIO:
    """Prompts on the terminal. ``input_fn`` reads a line (default: the builtin ``input``, which raises
    EOFError when stdin is closed; the wizard turns that into a clean :class:`InputClosed`)."""

    def __init__(self, assume_yes: bool = False, input_fn: Callable[[str], str] | None = None) -> None:
        self.assume_yes = assume_yes
        self.input_fn = input_fn

    def say(self, text: str) -> None:
        print(text, flush=True)

    def _input(self, prompt: str) -> str:
        try:
            return (self.input_fn or input)(prompt)
        except EOFError:
            print(flush=True)  # end the prompt's line before the error message
            raise

    def confirm(self, question: str) -> bool:
        if self.assume_yes:
            print(f"{question} [y/N] y (--yes)")
            return True
        return self._input(f"{question} [y/N] ").strip().lower() in ("y", "yes")

    def ask(self, question: str) -> str:
        return self._input(f"{question} ").strip()


@dataclass
class ScriptedIO:
    """Answers from a list (tests); records what was said."""

    answers: list[str] = field(default_factory=list)
    said: list[str] = field(default_factory=list)
    default_yes: bool = True

    def say(self, text: str) -> None:
        self.said.append(text)

    def confirm(self, question: str) -> bool:
        self.said.append(question)
        a = self.answers.pop(0) if self.answers else ("y" if self.default_yes else "n")
        return a.lower().startswith("y")

    def ask(self, question: str) -> str:
        self.said.append(question)
        return self.answers.pop(0) if self.answers else ""


@dataclass
class StepResult:
    pwm: int
    values: list[float]        # per-sample measurements, cdeg or mm/s
    duration_s: float
    distance_m: float
    ok: bool
    note: str = ""

    @property
    def median(self) -> float:
        return statistics.median(self.values) if self.values else float("nan")


def sweep_points(lo: int, hi: int, step: int, neutral: int | None = None) -> list[int]:
    """PWM steps from lo to hi (inclusive, clamped to 0..3000), including neutral, at most MAX_STEPS."""
    lo, hi = max(0, int(lo)), min(3000, int(hi))
    if hi < lo or step <= 0:
        raise ValueError(f"bad sweep {lo}..{hi} step {step}")
    pts = set(range(lo, hi + 1, step)) | {hi}
    if neutral is not None and lo <= neutral <= hi:
        pts.add(int(neutral))
    out = sorted(pts)
    if len(out) > MAX_STEPS:
        raise ValueError(f"sweep has {len(out)} steps (max {MAX_STEPS}): raise the step")
    return out


class Wizard:
    """See the module docstring. ``io`` has say/confirm/ask; ``plot_dir`` gets the PNGs."""

    def __init__(self, robot: AgnavRobot, cfg: CalibrationConfig | None = None, io: Any = None,
                 plot_dir: str | Path | None = None, sleep: Callable[[float], None] = time.sleep) -> None:
        self.robot = robot
        self.cfg = cfg or CalibrationConfig()
        self.io = io or ConsoleIO()
        self.plot_dir = Path(plot_dir) if plot_dir else None
        self.sleep = sleep
        self.steps: list[StepResult] = []
        self.plots: list[Path] = []

    # ---- operator input -------------------------------------------------------------------------
    def _confirm(self, question: str, moved: bool = False, state: str = "") -> bool:
        """The operator's yes/no; EOF on stdin is :class:`InputClosed`, saying what has happened so far
        (``state``, default: nothing written, and the car stopped if ``moved``)."""
        try:
            return bool(self.io.confirm(question))
        except EOFError:
            state = state or f"{'the car is stopped; ' if moved else ''}nothing was written"
            raise InputClosed(f"input closed (EOF on stdin) at the question {question!r}; {state}") from None

    # ---- safety ---------------------------------------------------------------------------------
    def _brief(self, what: str) -> None:
        c = self.cfg
        self.io.say(f"Calibrating {what}. The car will drive by itself in raw PWM mode: each step lasts at "
                    f"most {c.max_step_s:g} s and {c.max_distance_m:g} m; the firmware's failsafe and obstacle "
                    f"layers stay active. Use an open, flat area with >= {c.max_distance_m:g} m free all around. "
                    "Ctrl-C stops the car with the firmware e-stop.")
        if not self._confirm("Area clear, wheels on the ground, e-stop at hand: start?"):
            raise Aborted("operator declined")

    def _prepare(self) -> None:
        st = self.robot.state
        if self.robot.ep.stats.link_up is False and st.heartbeat is None:
            raise Aborted("no link to the robot")
        self.robot.param_get("ENC_NM_PER_CNT")  # distance per encoder count, for the distance limit
        self.robot.release()
        self.robot.arm()

    def _stop(self, estop: bool = False) -> None:
        for _ in range(3):
            try:
                self.robot.stop()
            except Exception:
                pass
        if estop:
            try:
                self.robot.estop(True)
            except Exception as e:  # the firmware link-loss failsafe still stops it
                self.io.say(f"e-stop not acknowledged ({e}); the firmware stops on link loss")

    # ---- one step -------------------------------------------------------------------------------
    def measure_step(self, steer_pwm: int, speed_pwm: int, kind: str, method: str) -> StepResult:
        """Drive one raw step and measure (see module docstring). ``kind``: steer | speed."""
        c = self.cfg
        ep = self.robot.ep
        values: list[float] = []
        dist = 0.0
        t0 = time.monotonic()
        period = 1.0 / SETPOINT_HZ
        note = ""
        ok = True
        pwm = steer_pwm if kind == "steer" else speed_pwm
        start_counts: tuple[int, ...] | None = None
        link_timeout = float(getattr(ep, "link_timeout_s", 3.0))
        last_rx = t0          # last telemetry of this step (any of the subscribed types)
        n_rx = 0              # telemetry frames received during the step
        n_motion = 0          # ... of them, the ones the measurement method reads
        with ep.subscribe(["AGNAV_ENCODER_STATUS", "AGNAV_ODOMETRY", "AGNAV_BEHAVIOUR_STATUS"]) as sub:
            next_send = 0.0
            bad_since: float | None = None
            while True:
                now = time.monotonic()
                el = now - t0
                if ep.stats.link_up is False:
                    raise self._link_lost(pwm, "the link is down")
                if getattr(ep.stats, "transport_open", True) is False:
                    raise self._link_lost(pwm, "the connection to the robot closed")
                if now - last_rx > link_timeout:
                    raise self._link_lost(pwm, f"no telemetry for {now - last_rx:.1f} s")
                if el >= min(c.settle_s + c.hold_s, c.max_step_s):
                    break
                if now >= next_send:
                    self.robot.drive_raw(steer_pwm, speed_pwm)
                    next_send = now + period
                m = sub.get(max(0.0, min(next_send - time.monotonic(), 0.05)))
                if m is None:
                    continue
                last_rx = time.monotonic()
                n_rx += 1
                t = m.get_type()
                if t == "AGNAV_BEHAVIOUR_STATUS":
                    if m.active_layer != 5 and el > 0.3:  # not HOST_COMMAND: something overrides us
                        bad_since = bad_since if bad_since is not None else now
                        if now - bad_since > 0.5:
                            ok, note = False, f"layer {m.active_layer} reason {m.reason} took over"
                            break
                    else:
                        bad_since = None
                elif t == "AGNAV_ENCODER_STATUS" and m.count_wheels >= 1:
                    n_motion += 1 if method == "encoders" else 0
                    k = m.count_wheels
                    nm = float(self.robot.state.params.get("ENC_NM_PER_CNT", 13550000.0))
                    if start_counts is None:
                        start_counts = tuple(m.count[:k])
                    dist = abs(statistics.mean((m.count[i] - start_counts[i]) for i in range(k))) * nm * 1e-9
                    if dist > c.max_distance_m:
                        note = f"stopped early after {dist:.1f} m"
                        break
                    if el < c.settle_s:
                        continue
                    speeds = [milli_to_si(s) for s in m.speed_mm_s[:k]]
                    v = statistics.mean(speeds)
                    if kind == "speed" and method == "encoders":
                        values.append(si_to_milli(v))
                    elif kind == "steer" and method == "encoders" and k >= 2 and abs(v) >= MIN_SPEED_FOR_ANGLE_M_S:
                        w = yaw_rate_from_wheels(speeds[0], speeds[1], c.track_m)
                        values.append(rad_to_cdeg(steer_from_motion(v, w, c.wheelbase_m)))
                elif t == "AGNAV_ODOMETRY" and el >= c.settle_s and method == "odometry":
                    n_motion += 1
                    v = milli_to_si(m.speed_mm_s)
                    if kind == "speed":
                        values.append(float(m.speed_mm_s))
                    elif abs(v) >= MIN_SPEED_FOR_ANGLE_M_S:
                        w = cdeg_to_rad(m.yaw_rate_cdeg_s)
                        values.append(rad_to_cdeg(steer_from_motion(v, w, c.wheelbase_m)))
        dur = time.monotonic() - t0
        if n_rx == 0 and dur >= 0.3:  # a whole step without one frame of 10-50 Hz telemetry: link gone
            raise self._link_lost(pwm, f"no telemetry during the {dur:.1f} s step")
        if ok and not values and method != "diameter":
            if n_motion:  # telemetry arrives but shows no usable motion
                ok, note = False, note or "no usable samples (is the car moving? encoders connected?)"
            else:
                ok, note = False, note or f"no {'encoder' if method == 'encoders' else 'odometry'} telemetry during the step"
        return StepResult(pwm, values, dur, dist, ok, note)

    def _link_lost(self, pwm: int, why: str) -> LinkLost:
        return LinkLost(f"link lost during the sweep at pwm {pwm}; nothing was written ({why}; stop setpoints "
                        "sent, and the firmware's link-loss failsafe stops the car)")

    def _pause_between_steps(self) -> None:
        end = time.monotonic() + self.cfg.pause_s
        while time.monotonic() < end:
            self.robot.stop()
            self.sleep(0.1)

    # ---- sweeps ---------------------------------------------------------------------------------
    def _method(self, kind: str) -> str:
        enc = self.robot.state.encoders
        wheels = enc.wheels if enc else 0
        if kind == "speed":
            return "encoders" if wheels >= 1 else "odometry"
        return "encoders" if wheels >= 2 else "diameter"

    def _sweep(self, kind: str) -> tuple[np.ndarray, np.ndarray]:
        c = self.cfg
        method = self._method(kind)
        if kind == "steer":
            pwms = sweep_points(c.steer_pwm_min, c.steer_pwm_max, c.steer_step, c.steer_neutral_pwm)
        else:
            pwms = sweep_points(c.speed_pwm_min, c.speed_pwm_max, c.speed_step)
        self.io.say(f"{kind}: {len(pwms)} steps {pwms[0]}..{pwms[-1]}, measuring with {method}")
        if method == "diameter":
            self.io.say("fewer than two wheel encoders: after each step, measure the circle the car drove and type "
                        "its diameter (--yes answers only the yes/no questions)")
        xs: list[float] = []
        ys: list[float] = []
        for p in pwms:
            steer_pwm, speed_pwm = (p, c.steer_speed_pwm) if kind == "steer" else (self._steer_neutral, p)
            r = self.measure_step(steer_pwm, speed_pwm, kind, method)
            self._pause_between_steps()
            if method == "diameter" and kind == "steer":
                r = self._ask_diameter(r)
            self.steps.append(r)
            self.io.say(f"  pwm {p:5d}: {'%8.0f' % r.median if r.values else '     n/a'} "
                        f"({len(r.values)} samples, {r.distance_m:.2f} m){' ' + r.note if r.note else ''}")
            if r.ok:
                xs += [p] * len(r.values)
                ys += r.values
        return np.array(xs, dtype=float), np.array(ys, dtype=float)

    def _ask_diameter(self, r: StepResult) -> StepResult:
        try:
            a = self.io.ask(f"pwm {r.pwm}: diameter of the circle driven in m, then L or R (e.g. '1.9 L'; 'inf' if "
                            "straight):")
        except EOFError:
            raise InputClosed(f"input closed (EOF on stdin) at pwm {r.pwm}: the steering sweep of a robot with fewer "
                              "than two wheel encoders needs the measured circle diameter typed in after each step, "
                              "and stdin was closed (--yes answers only the yes/no questions; run it in a terminal). "
                              "The car is stopped; nothing was written") from None
        parts = a.split()
        try:
            dia = float(parts[0])
        except (ValueError, IndexError):
            return StepResult(r.pwm, [], r.duration_s, r.distance_m, False, "no diameter given")
        left = len(parts) > 1 and parts[1].upper().startswith("L")
        phi = steer_from_diameter(dia, self.cfg.wheelbase_m, left)
        return StepResult(r.pwm, [rad_to_cdeg(phi)], r.duration_s, r.distance_m, True, "diameter")

    def _plot(self, fit: FitResult, path: Path, previous: WireTable) -> None:
        """The fit's PNG at ``path``, if it can be made: the plot only illustrates the fit, so no failure of it
        (matplotlib missing, folder read-only or removed during the sweep, disk full) loses the fitted table;
        the reason is said and the wizard goes on to the write."""
        try:
            from .plot import plot_fit

            png = plot_fit(fit, path, previous)
        except RuntimeError as e:  # matplotlib missing
            self.io.say(str(e))
            return
        except Exception as e:  # noqa: BLE001 - any other failure of the plot: report it, keep the table
            why = getattr(e, "strerror", None) or str(e) or type(e).__name__
            self.io.say(f"warning: fit plot not written ({path}: {why}); the fitted table is kept")
            return
        self.plots.append(png)
        self.io.say(f"fit plot: {png}")

    def _fit_write(self, kind: str, table_id: int, xs: np.ndarray, ys: np.ndarray, previous: WireTable,
                   save: bool | None) -> FitResult:
        c = self.cfg
        try:
            if kind == "steer":
                fit = fit_table(xs, ys, table_id, dead_band=c.dead_band_cdeg)
            else:
                fit = fit_table(xs, ys, table_id, dead_band=c.dead_band_mm_s, neutral_pwm=previous.neutral_pwm,
                                require_both_sides=False)
        except CalibFitError as e:
            raise Aborted(f"fit failed: {e}") from None
        self.io.say(fit.summary())
        if self.plot_dir is not None:
            self._plot(fit, self.plot_dir / f"calib_{kind}.png", previous)
        if not self._confirm("Write this table to the robot (active at once, verified by read-back)?", moved=True):
            raise Aborted("table not written")
        self.robot.calib_write_verified(fit.table, save=False)
        self.io.say("written and verified by read-back")
        do_save = save if save is not None else self._confirm(
            "Save all tables to EEPROM?", state="the table is written and active but not saved (lost at the next reset)")
        if do_save:
            self.robot.calib_save(table_id)
            self.io.say("saved to EEPROM")
        return fit

    def _run(self, kind: str, table_id: int, save: bool | None) -> FitResult:
        self._brief("the steering" if kind == "steer" else "the speed")
        previous = self.robot.calib_read(table_id)
        steer_tab = previous if table_id == TABLE_STEER else self.robot.calib_read(TABLE_STEER)
        self._steer_neutral = steer_tab.neutral_pwm
        self.io.say(f"active table: {previous.describe()}")
        estop = False
        try:  # the car is stopped on every way out of the sweep (finally)
            self._prepare()
            xs, ys = self._sweep(kind)
        except KeyboardInterrupt:
            estop = True
            raise Aborted("interrupted: e-stop engaged (release with `agnav run` or the wizard)") from None
        except EOFError:  # an io object other than ConsoleIO/ScriptedIO ran out of input
            raise InputClosed("input closed (EOF on stdin) during the sweep; the car is stopped; nothing was "
                              "written") from None
        except Aborted:  # link lost, input closed: zero setpoints; an e-stop request would wait in vain
            raise
        except BaseException:
            estop = True
            raise
        finally:
            self._stop(estop=estop)
        return self._fit_write(kind, table_id, xs, ys, previous, save)

    def run_steering(self, save: bool | None = None) -> FitResult:
        return self._run("steer", TABLE_STEER, save)

    def run_speed(self, save: bool | None = None) -> FitResult:
        return self._run("speed", TABLE_SPEED, save)
