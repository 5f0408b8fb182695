"""``agnav`` subcommands of the link area: calibrate, flash, replay, param, key, config (``run``: :mod:`.run`).

Every command reads the host config (``--config``, see docs/user_guide.md) and lets options
override it. Exit codes: 0 ok, 1 robot/link failure or an output file that cannot be written,
2 usage or configuration error, 130 Ctrl-C. Options and output paths are checked before the link
is opened wherever that can be known.
"""

from __future__ import annotations

import argparse
import difflib
import math
import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path
from typing import Any, Callable

from ..link.config import CalibrationConfig, LinkConfig
from ..link.tlog import MAV_TYPE_GCS
from .argtypes import int_in, nonneg_float, positive_float, positive_int, up_to_a_day
from .outputs import OutputError, check_output, unwritable_file
from .progress import ProgressLine
from .registry import subcommand

REPO_ROOT = Path(__file__).resolve().parents[3]
_LINK_DEFAULTS = LinkConfig()
_CAL_DEFAULTS = CalibrationConfig()
PNG_SUFFIXES = (".png", ".pdf", ".svg", ".jpg", ".jpeg")  # what `--png` writes (matplotlib picks by suffix)

_LINK_ARGS: list[tuple[tuple[str, ...], dict[str, Any]]] = [
    (("--device",), {"default": None, "help": "serial:/dev/ttyUSB0:57600, /dev/ttyACM0, tcp:HOST:PORT (SIL: "
                                              "tcp:127.0.0.1:5760), udp:HOST:PORT (default: [link] device)"}),
    (("--baud",), {"type": positive_int, "default": None,
                   "help": f"baud of a serial device given without one, > 0 (default: [link] baud, "
                           f"{_LINK_DEFAULTS.baud})"}),
    (("--config",), {"default": None, "help": "host config TOML (default ~/.config/agnav/host.toml)"}),
    (("--tlog",), {"default": None, "help": "telemetry log path (default: [link] log_dir/<command>-<time>.tlog)"}),
    (("--no-tlog",), {"action": "store_true", "help": "do not write a telemetry log"}),
    (("--sign",), {"action": "store_true", "help": "sign outgoing frames (MAVLink 2 signing)"}),
    (("--key-file",), {"default": None, "help": "signing key file (default ~/.config/agnav/signing.key)"}),
    (("--target-system",), {"type": int_in(1, 255), "default": None, "metavar": "1..255",
                            "help": "robot MAVLink system id, 1..255 (default: [link] target_system; 0 there = "
                                    "the first heartbeat heard)"}),
    (("--wait",), {"type": up_to_a_day, "default": 5.0,
                   "help": "seconds to wait for the connection to open and then for the robot's heartbeat, > 0, "
                           "at most 86400 (default 5)"}),
]


def _err(cmd: str, text: str) -> None:
    print(f"agnav {cmd}: {text}", file=sys.stderr)


def _config(ns: argparse.Namespace) -> Any:
    from ..link.config import load_config

    return load_config(getattr(ns, "config", None))


def _tlog_path(ns: argparse.Namespace, cmd: str, cfg: Any) -> str | None:
    """The telemetry log this session writes (None with --no-tlog), checked writable."""
    if ns.no_tlog:
        return None
    tlog = ns.tlog or str(Path(cfg.link.log_dir) / f"{cmd}-{time.strftime('%Y%m%d-%H%M%S')}.tlog")
    check_output("--tlog" if ns.tlog else "telemetry log", tlog)
    return tlog


def _drop_empty(path: str | None) -> None:
    """Remove a telemetry log nothing was written to (the session never got going)."""
    if path:
        try:
            if os.path.getsize(path) == 0:
                os.unlink(path)
        except OSError:
            pass


_NO_TLOG_YET = object()


def _open(ns: argparse.Namespace, cmd: str, cfg: Any, tlog: Any = _NO_TLOG_YET) -> Any:
    """Endpoint from options + config, started, heartbeat seen (from ``--target-system`` when set).
    On failure the endpoint is closed and an empty telemetry log removed."""
    from ..link.endpoint import Endpoint, LinkTimeout
    from ..link.keys import load_key

    lc = cfg.link
    device = ns.device or lc.device
    key = None
    if ns.sign or lc.signing or ns.key_file:
        key = load_key(ns.key_file or lc.key_file or None)
    if lc.require_signed and key is None:
        # without a key pymavlink checks no signature at all: every unsigned frame would still be taken
        raise ValueError("[link] require_signed = true needs a signing key to check frames with: also set "
                         "[link] signing = true, or give --sign / --key-file")
    if tlog is _NO_TLOG_YET:
        tlog = _tlog_path(ns, cmd, cfg)
    target = ns.target_system if ns.target_system is not None else lc.target_system

    def on_event(text: str) -> None:
        print(f"[link] {text}", file=sys.stderr, flush=True)

    heard: dict[int, int] = {}  # system id -> component id of every robot heartbeat

    def listen(m: Any) -> None:
        if m.get_type() == "HEARTBEAT" and m.type != MAV_TYPE_GCS:
            heard.setdefault(m.get_srcSystem(), m.get_srcComponent())

    ep = Endpoint(device, ns.baud or lc.baud, source_system=lc.sysid, source_component=lc.compid,
                  target_system=target, tlog=tlog, key=key, require_signed=lc.require_signed,
                  heartbeat_hz=lc.heartbeat_hz, link_timeout_s=lc.link_timeout_s,
                  reconnect_delay_s=lc.reconnect_delay_s, budget_bytes_s=lc.budget_bytes_s,
                  budget_window_s=lc.budget_window_s, on_event=on_event)
    ep.add_listener(listen)
    try:
        ep.start(wait_heartbeat_s=None if target else ns.wait, open_timeout_s=max(1.0, ns.wait))
        if target:
            deadline = time.monotonic() + ns.wait
            while target not in heard and time.monotonic() < deadline:
                time.sleep(0.02)
            if target not in heard:
                others = sorted(heard)
                if others:
                    raise LinkTimeout(
                        f"no heartbeat from system {target} within {ns.wait:.1f} s on {ep.spec}; heard system(s) "
                        f"{', '.join(map(str, others))}: use --target-system {others[0]} (or [link] target_system), "
                        "or leave it at 0 to take the first heartbeat")
                raise LinkTimeout(f"no heartbeat from system {target} (nor any other) within {ns.wait:.1f} s "
                                  f"on {ep.spec}")
    except BaseException:
        ep.close()
        _drop_empty(tlog)
        raise
    if tlog:
        print(f"logging to {tlog}", file=sys.stderr)
    return ep


def _guard(cmd: str, fn: Any, ns: argparse.Namespace) -> int:
    from ..link.config import ConfigError
    from ..link.endpoint import LinkTimeout
    from ..link.keys import KeyError_, KeyWriteError
    from ..link.robot import CommandFailed

    try:
        return int(fn(ns))
    except (OutputError, KeyWriteError) as e:
        _err(cmd, str(e))
        return 1
    except (ConfigError, KeyError_, ValueError) as e:
        _err(cmd, str(e))
        return 2
    except BrokenPipeError:
        raise  # stdout closed by the reader (`| head`): cli.main exits quietly
    except (LinkTimeout, CommandFailed, ConnectionError) as e:
        _err(cmd, str(e))
        return 1
    except OSError as e:  # a file that could not be read or written late in a command: one line, not a traceback
        where = f"{e.filename}: " if getattr(e, "filename", None) else ""
        _err(cmd, f"{where}{e.strerror or e}")
        return 1


# ---- calibrate -----------------------------------------------------------------------------------
def _cmd_calibrate(ns: argparse.Namespace) -> int:
    from ..calibration.wizard import Aborted, ConsoleIO, Wizard
    from ..link.robot import AgnavRobot

    cfg = _config(ns)
    c = cfg.calibration
    for k in ("settle_s", "hold_s", "max_step_s", "max_distance_m"):
        v = getattr(ns, k)
        if v is not None:
            setattr(c, k, v)
    if c.settle_s >= c.max_step_s:  # as the config file's check ([calibration] settle_s < max_step_s), with the options

        def name(k: str) -> str:
            return f"--{k.replace('_', '-')}" if getattr(ns, k) is not None else f"[calibration] {k}"

        _err("calibrate", f"{name('settle_s')} ({c.settle_s:g} s) must be < {name('max_step_s')} ({c.max_step_s:g} s): "
                          "a sweep step settles first, then measures")
        return 2
    if ns.plot_dir:  # before the link opens: a sweep's plot must not fail on a folder known to be unusable
        png = Path(ns.plot_dir) / f"calib_{'steer' if ns.table == 'steering' else 'speed'}.png"
        why = unwritable_file(png)
        if why:
            raise OutputError(f"--plot-dir {ns.plot_dir}: cannot write there: {why}")
    ep = _open(ns, "calibrate", cfg)
    try:
        w = Wizard(AgnavRobot(ep), c, ConsoleIO(assume_yes=ns.yes), plot_dir=ns.plot_dir)
        save = False if ns.no_save else (True if ns.yes else None)
        try:
            fit = w.run_steering(save) if ns.table == "steering" else w.run_speed(save)
        except Aborted as e:
            _err("calibrate", str(e))
            return 130 if "interrupted" in str(e) else 1
        print(f"done: {fit.table.describe()}")
        return 0
    finally:
        ep.close()


subcommand("calibrate", help="calibration wizard: sweep raw PWM, fit, write, verify, save (ref 003 procedure)",
           args=_LINK_ARGS + [
               (("table",), {"choices": ["steering", "speed"], "help": "which table"}),
               (("--plot-dir",), {"default": "logs", "help": "where the fit PNG goes (default logs/)"}),
               (("--yes",), {"action": "store_true", "help": "answer yes to every yes/no question (also saves); measured "
                                                          "circle diameters (robots with fewer than two wheel "
                                                          "encoders) must still be typed"}),
               (("--no-save",), {"action": "store_true", "help": "write and verify, but do not save to EEPROM"}),
               (("--settle-s",), {"dest": "settle_s", "type": nonneg_float, "default": None, "metavar": "S",
                                  "help": "seconds ignored at the start of every sweep step, >= 0 (default: "
                                          f"[calibration] settle_s, {_CAL_DEFAULTS.settle_s:g} s)"}),
               (("--hold-s",), {"dest": "hold_s", "type": positive_float, "default": None, "metavar": "S",
                                "help": "seconds measured in every sweep step after the settling, > 0 (default: "
                                        f"[calibration] hold_s, {_CAL_DEFAULTS.hold_s:g} s)"}),
               (("--max-step-s",), {"dest": "max_step_s", "type": positive_float, "default": None, "metavar": "S",
                                    "help": "hard limit on one sweep step, seconds, > 0 (default: [calibration] "
                                            f"max_step_s, {_CAL_DEFAULTS.max_step_s:g} s)"}),
               (("--max-distance-m",), {"dest": "max_distance_m", "type": positive_float, "default": None,
                                        "metavar": "M",
                                        "help": "a sweep step ends early after this distance, metres, > 0 (default: "
                                                f"[calibration] max_distance_m, {_CAL_DEFAULTS.max_distance_m:g} m)"}),
           ])(lambda ns: _guard("calibrate", _cmd_calibrate, ns))


# ---- flash ---------------------------------------------------------------------------------------
def flash_command(env: str, port: str | None, repo: Path = REPO_ROOT) -> tuple[list[str], dict[str, str]]:
    """The pio command line and environment `agnav flash` runs."""
    pio = repo / ".venv" / "bin" / "pio"
    cmd = [str(pio if pio.exists() else (shutil.which("pio") or pio)), "run", "-e", env, "-t", "upload"]
    if port:
        cmd += ["--upload-port", port]
    envv = dict(os.environ)
    envv["PLATFORMIO_CORE_DIR"] = str(repo / ".pio-core")
    return cmd, envv


def pio_envs(repo: Path = REPO_ROOT) -> list[str] | None:
    """The ``[env:NAME]`` sections of ``platformio.ini`` (None when the file is not there)."""
    try:
        text = (repo / "platformio.ini").read_text()
    except OSError:
        return None
    return re.findall(r"^\[env:([^\]]+)\]", text, re.MULTILINE)


def _serial_ports() -> list[str]:
    """The USB serial devices present (where an Arduino Mega or an STM32 board shows up on Linux and macOS)."""
    import glob

    return sorted(p for pat in ("/dev/ttyACM*", "/dev/ttyUSB*", "/dev/cu.usb*") for p in glob.glob(pat))


def _upload_port_problem(port: str) -> str | None:
    """Why ``flash --port`` cannot be uploaded to: a device path (``/dev/...``, or a pattern such as
    ``/dev/ttyUSB*`` as PlatformIO takes) that names no device. Other ports (``COM3``, a network address) are
    left to PlatformIO; None when there is nothing to say."""
    import glob

    if not port.startswith("/"):
        return None
    if any(c in port for c in "*?["):
        if glob.glob(port):
            return None
        problem = "matches no device"
    elif not os.path.exists(port):
        problem = "no such device"
    elif os.path.isdir(port) or os.path.isfile(port):
        return f"{'a folder' if os.path.isdir(port) else 'a file'}, not a serial device"
    else:
        return None
    here = _serial_ports()
    return (f"{problem} (is the board plugged in? serial devices here: {', '.join(here)})" if here else
            f"{problem} (is the board plugged in? no USB serial device here)")


def _cmd_flash(ns: argparse.Namespace) -> int:
    if ns.port is not None:  # before the command is shown: a dry run says the same as the upload would
        bad = _upload_port_problem(ns.port)
        if bad:
            _err("flash", f"--port {ns.port}: {bad}")
            return 1
    envs = pio_envs()
    if envs is not None:
        boards = [e for e in envs if e != "native"]
        if ns.env == "native":
            _err("flash", "env native is the PC build (it runs as the SIL: `agnav sil`), there is no board to flash; "
                          f"boards: {', '.join(boards)}")
            return 2
        if ns.env not in envs:
            _err("flash", f"unknown PlatformIO env {ns.env!r}; known in {REPO_ROOT / 'platformio.ini'}: "
                          f"{', '.join(boards)}")
            return 2
    cmd, envv = flash_command(ns.env, ns.port)
    print("$ PLATFORMIO_CORE_DIR=" + envv["PLATFORMIO_CORE_DIR"] + " " + " ".join(cmd), flush=True)
    if ns.dry_run:
        return 0
    if not Path(cmd[0]).exists():
        _err("flash", f"{cmd[0]} not found: run `make setup` first")
        return 2
    return subprocess.call(cmd, env=envv, cwd=REPO_ROOT)


subcommand("flash", help="build and upload the firmware (pio run -e ENV -t upload, offline core in .pio-core)",
           args=[(("--env",), {"default": "megaatmega2560",
                               "help": "PlatformIO env to build and upload: default megaatmega2560 (Arduino Mega); "
                                       "also stm32f405 (the [env:...] sections of platformio.ini)"}),
                 (("--port",), {"default": None, "help": "upload port, e.g. /dev/ttyACM0, checked to exist (default: pio "
                                                         "autodetect)"}),
                 (("--dry-run",), {"action": "store_true", "help": "print the command only"})])(_cmd_flash)


# ---- replay --------------------------------------------------------------------------------------
#: replay refuses a log (exit 2, after its summary) when more than this share of it is not MAVLink frames
MAX_UNDECODED = 0.5

#: a log at least this large gets a progress line on stderr while it is read (about 1 s of reading)
REPLAY_PROGRESS_BYTES = 1_000_000


def _replay_progress(path: str) -> Callable[[int, int], None] | None:
    """A progress line on stderr for a log of REPLAY_PROGRESS_BYTES or more (None: a small log, or not a file)."""
    try:
        size = Path(path).stat().st_size
    except OSError:
        return None
    if size < REPLAY_PROGRESS_BYTES:
        return None

    line = ProgressLine()

    def show(done: int, total: int) -> None:
        text = f"reading {path}: {done / 1e6:.1f} of {total / 1e6:.1f} MB ({100.0 * done / max(total, 1):3.0f} %)"
        if done >= total:
            line.end(text)
        else:
            line.show(text)

    return show


def _cmd_replay(ns: argparse.Namespace) -> int:
    from ..link.replay import TlogError, summarize_tlog

    # usage first (wrong suffixes), then whether the outputs can be written, then the work
    for opt, path, suffixes in (("--png", ns.png, PNG_SUFFIXES), ("--rrd", ns.rrd, (".rrd",))):
        if path and Path(path).suffix.lower() not in suffixes:
            raise ValueError(f"{opt} {path}: the file name must end in {' or '.join(suffixes)}")
    try:
        s = summarize_tlog(ns.log, progress=_replay_progress(ns.log))
    except TlogError as e:
        _err("replay", str(e))
        return 2
    for opt, path in (("--png", ns.png), ("--rrd", ns.rrd)):
        if path:
            check_output(opt, path)
    if not s.rx_msgs and not s.tx_msgs:
        size = Path(ns.log).stat().st_size
        _err("replay", f"{ns.log}: no MAVLink frames in {size} B (empty, or not a .tlog telemetry log)")
        return 2
    print(s.text(ns.budget))
    if s.undecoded_fraction > MAX_UNDECODED:  # after the summary: what could be read is still shown
        _err("replay", f"{ns.log}: {100 * s.undecoded_fraction:.1f} % of the file ({s.undecoded_bytes} of "
                       f"{s.file_bytes} B) is not MAVLink frames: not a .tlog telemetry log, or badly corrupt")
        return 2
    if ns.png:
        from ..viz.plots import plot_run

        try:
            print(f"plot: {plot_run(s, ns.png)}")
        except (OSError, ValueError) as e:
            raise OutputError(f"--png {ns.png}: cannot write there: {getattr(e, 'strerror', None) or e}") from None
        except RuntimeError as e:  # matplotlib missing
            _err("replay", str(e))
            return 2
    if ns.rrd:
        from ..viz import VizUnavailable, record_tlog

        try:
            print(f"recording: {record_tlog(ns.log, ns.rrd)} (open with `rerun {ns.rrd}`)")
        except VizUnavailable as e:
            _err("replay", str(e))
            return 2
        except (OSError, RuntimeError) as e:
            raise OutputError(f"--rrd {ns.rrd}: cannot write there: {getattr(e, 'strerror', None) or e}") from None
    return 0


subcommand("replay", help="summarise a .tlog (rates, layers, status texts); optional PNG and rerun .rrd; exit 2 "
                          "when more than half of the file is not MAVLink frames",
           args=[(("log",), {"help": "telemetry log (.tlog, mavutil format)"}),
                 (("--rrd",), {"default": None,
                               "help": "write a rerun recording of the log, FILE.rrd (default: none)"}),
                 (("--png",), {"default": None, "help": "write a matplotlib plot (path, layer over time), FILE.png "
                                                        "(.pdf, .svg, .jpg also work; default: none)"}),
                 (("--budget",), {"type": positive_float, "default": 1500.0,
                                  "help": "telemetry budget to compare with, B/s, > 0 (default 1500)"})])(
    lambda ns: _guard("replay", _cmd_replay, ns))


# ---- param ---------------------------------------------------------------------------------------
#: MAV_PARAM_TYPE values of whole-number parameters (UINT8 .. INT64)
INT_PARAM_TYPES = frozenset(range(1, 9))


class UnknownParameter(ValueError):
    """The robot has no parameter of that name (or did not answer for it)."""


def known_param_names() -> list[str]:
    """Parameter names the host knows offline: the fake robot's mirror of part of the firmware's PARAMS table
    (20 of its rows). Used for hints and the whole-number check before connecting; a name outside it is
    checked with the robot itself (:func:`_param_read`)."""
    try:
        from ..link.fake import FIRMWARE_PARAMS
    except ImportError:
        return []
    return list(FIRMWARE_PARAMS)


def _unknown_param_text(name: str, why: str) -> str:
    known = known_param_names()
    hint = ""
    if name != name.upper() and name.upper() in known:
        hint = f"; parameter names are case-sensitive: did you mean {name.upper()}?"
    else:
        close = difflib.get_close_matches(name.upper(), known, n=3, cutoff=0.6)
        if close:
            hint = f"; did you mean {' or '.join(close)}?"
    return f"no parameter named {name} on the robot ({why}){hint} (`agnav param list` lists them)"


def _param_number(name: str, text: str) -> float:
    """VALUE of ``param set``: a finite number, and a whole one for the firmware's integer parameters."""
    try:
        v = float(text)
    except ValueError:
        raise ValueError(f"param set {name}: value {text!r} is not a number") from None
    if not math.isfinite(v):
        raise ValueError(f"param set {name}: value must be a finite number, got {text!r}")
    if name in known_param_names() and v != int(v):
        raise ValueError(f"param set {name}: {name} is a whole-number parameter, got {text!r}")
    return v


def _param_read(ep: Any, robot: Any, name: str) -> Any:
    """PARAM_VALUE of ``name``; :class:`UnknownParameter` when the robot refuses the name (its
    STATUSTEXT "unknown parameter") or never answers for a name the firmware does not know."""
    from ..link.endpoint import LinkTimeout
    from ..link.robot import _pid

    def match(m: Any) -> bool:
        if m.get_type() == "PARAM_VALUE":
            return _pid(m) == name
        text = m.text if isinstance(m.text, str) else bytes(m.text).decode("ascii", "replace")
        return "unknown parameter" in text

    try:
        m = ep.request(lambda: robot.mav.param_request_read_encode(*robot._tgt(), name.encode(), -1),
                       ["PARAM_VALUE", "STATUSTEXT"], match, robot.timeout_s, robot.retries, f"param get {name}")
    except LinkTimeout as e:
        if name in known_param_names():
            raise
        raise UnknownParameter(_unknown_param_text(name, f"or no answer: {e}")) from None
    if m.get_type() == "STATUSTEXT":
        raise UnknownParameter(_unknown_param_text(name, "the robot refused the name"))
    return m


def _cmd_param(ns: argparse.Namespace) -> int:
    from ..link.robot import AgnavRobot

    if ns.action in ("save", "load"):
        return _param_file(ns)
    if ns.action in ("get", "set") and not ns.name:
        _err("param", f"param {ns.action} needs NAME")
        return 2
    if ns.action == "set" and ns.value is None:
        _err("param", "param set needs NAME VALUE")
        return 2
    if ns.action == "store" and ns.name is not None:
        _err("param", f"param store takes no NAME (got {ns.name!r}): it stores every parameter")
        return 2
    if ns.action == "list" and ns.name is not None:
        _err("param", f"param list takes no NAME (got {ns.name!r}); use `agnav param get {ns.name}`")
        return 2
    if ns.action == "get" and ns.value is not None:
        _err("param", f"param get takes one NAME (got also {ns.value!r}); to change it: `agnav param set NAME VALUE`")
        return 2
    value = _param_number(ns.name, ns.value) if ns.action == "set" else None
    cfg = _config(ns)
    ep = _open(ns, "param", cfg)
    try:
        r = AgnavRobot(ep, timeout_s=ns.timeout)
        if ns.action == "list":
            params = r.param_list(timeout_s=max(10.0, ns.timeout * 10))
            for k, v in params.items():
                print(f"{k:16s} {v:g}")
            print(f"{len(params)} parameters", file=sys.stderr)
        elif ns.action == "store":
            r.params_store()
            print("parameters stored in the robot's EEPROM")
        elif ns.action == "get":
            print(f"{ns.name} {float(_param_read(ep, r, ns.name).param_value):g}")
        else:
            assert value is not None
            cur = _param_read(ep, r, ns.name)  # the name exists, and its type, before anything is sent
            if cur.param_type in INT_PARAM_TYPES and value != int(value):
                _err("param", f"param set {ns.name}: {ns.name} is a whole-number parameter (now {cur.param_value:g}), "
                              f"got {ns.value!r}; nothing sent")
                return 2
            print(f"{ns.name} {r.param_set(ns.name, value):g}")
        return 0
    finally:
        ep.close()


def _param_file(ns: argparse.Namespace) -> int:
    """``param save FILE``: every parameter into a .parm file (MAVProxy's form). ``param load FILE``: set the
    file's parameters on the robot (all names checked first, nothing sent if one is unknown), then store them
    in its EEPROM unless ``--no-store``."""
    from ..link.parm import ParmError, read_parm, write_parm
    from ..link.robot import AgnavRobot, CommandFailed

    if not ns.name or ns.value is not None:
        _err("param", f"param {ns.action} takes one FILE (e.g. `agnav param {ns.action} robot.parm`)")
        return 2
    wanted: dict[str, float] = {}
    if ns.action == "load":
        try:
            wanted = read_parm(ns.name)
        except ParmError as e:
            _err("param", str(e))
            return 2
        if not wanted:
            _err("param", f"{ns.name}: no parameters in the file")
            return 2
    cfg = _config(ns)
    ep = _open(ns, "param", cfg)
    try:
        r = AgnavRobot(ep, timeout_s=ns.timeout)
        have = r.param_list(timeout_s=max(10.0, ns.timeout * 10))
        if ns.action == "save":
            try:
                write_parm(have, ns.name, header=f"AgNav robot parameters, {len(have)} of them (agnav param save)")
            except OSError as e:
                _err("param", f"{ns.name}: cannot write: {e.strerror or e}")
                return 1
            print(f"{len(have)} parameters saved to {ns.name}")
            return 0
        unknown = sorted(set(wanted) - set(have))
        if unknown:
            _err("param", f"{ns.name}: the robot has no parameter {', '.join(unknown)}; nothing sent "
                          "(`agnav param list` lists them)")
            return 2
        kept: list[str] = []
        changed = 0
        for name, v in wanted.items():
            if have[name] == v:
                continue
            try:
                r.param_set(name, v)
                changed += 1
            except CommandFailed as e:
                kept.append(str(e))
        for why in kept:
            _err("param", why)
        print(f"{changed} of {len(wanted)} parameters changed ({len(wanted) - changed - len(kept)} already so)")
        if not ns.no_store:
            r.params_store()
            print("parameters stored in the robot's EEPROM")
        return 1 if kept else 0
    finally:
        ep.close()


subcommand("param", help="robot parameters: list, get NAME, set NAME VALUE, store (to EEPROM), save FILE / load FILE "
                         "(.parm, MAVProxy's and Mission Planner's format)",
           args=_LINK_ARGS + [(("action",), {"choices": ["list", "get", "set", "store", "save", "load"]}),
                              (("name",), {"nargs": "?", "default": None,
                                           "help": "parameter name, case-sensitive (e.g. LINK_TIMEOUT_MS); "
                                                   "save / load: the .parm file"}),
                              (("--no-store",), {"dest": "no_store", "action": "store_true",
                                                 "help": "load: set the values on the robot but do not store them in "
                                                         "its EEPROM"}),
                              (("value",), {"nargs": "?", "default": None,
                                            "help": "set: a finite number (negative allowed; whole for the "
                                                    "firmware's integer parameters)"}),
                              (("--timeout",), {"type": up_to_a_day, "default": 1.0,
                                                "help": "seconds to wait for each answer, > 0, at most 86400, 3 "
                                                        "tries (default 1; "
                                                        "list: 10 x this, at least 10 s)"})])(
    lambda ns: _guard("param", _cmd_param, ns))


# ---- key -----------------------------------------------------------------------------------------
def _cmd_key(ns: argparse.Namespace) -> int:
    from ..link.keys import default_key_path, fingerprint, load_key, new_key

    if ns.action == "new":
        p, key = new_key(ns.key_file, force=ns.force)
        print(f"new signing key in {p} (mode 0600), fingerprint {fingerprint(key)}")
        print("use it with `agnav run --sign` or [link] signing = true; give the same key to every peer that verifies")
        return 0
    if ns.action == "push":
        return _key_push(ns)
    p = Path(ns.key_file) if ns.key_file else default_key_path()
    key = load_key(p)
    print(f"key file    {p}")
    print(f"fingerprint {fingerprint(key)}")
    if ns.reveal:
        print(f"secret      {key.hex()}")
    return 0


def _key_push(ns: argparse.Namespace) -> int:
    """Load the key into the robot (SETUP_SIGNING), then prove the robot takes frames signed with it."""
    from ..link.endpoint import LinkTimeout
    from ..link.keys import CLEAR_KEY, fingerprint, load_key, setup_signing_message
    from ..link.robot import AgnavRobot
    from ..link.state import _text

    new = CLEAR_KEY if ns.clear else load_key(ns.key_file)
    old = load_key(ns.old_key_file) if ns.old_key_file else None
    cfg = _config(ns)
    ns.sign, ns.key_file = False, None  # the session signs with the OLD key (or not at all)
    cfg.link.require_signed = False  # and takes the robot's frames however they come while its key changes
    ep = _open(ns, "key", cfg)
    try:
        ep.set_signing_key(old)
        if old is None:
            print("sending unsigned: the robot accepts this only within 10 s of a power-on or reset "
                  "(opening the USB serial port of a Mega resets it)", file=sys.stderr)
        with ep.subscribe("STATUSTEXT") as sub:
            ep.send(setup_signing_message(ep.d, new, ep.target_system))
            time.sleep(0.3)
            texts = [_text(m.text) for m in sub.drain()]
        r = AgnavRobot(ep, timeout_s=ns.timeout)
        refused = next((t for t in texts if t.startswith("refused SETUP_SIGNING")), None)
        if not ns.clear:
            # A robot without a key answers frames signed with any key, so a signed answer alone proves
            # nothing: with the key taken, an unsigned request must go unanswered.
            ep.set_signing_key(None)
            try:
                r.param_get("SYSID_THISMAV")
            except LinkTimeout:
                pass
            else:
                why = f"it said: {refused}" if refused else "no 'signing: key set' from it"
                _err("key", f"robot {ep.target_system} did not take the key ({why}); it still answers unsigned "
                            "requests. An unsigned key is taken only within 10 s of a power-on or reset; a robot that "
                            "holds a key needs --old-key-file")
                return 1
        ep.set_signing_key(None if ns.clear else new)
        r.param_get("SYSID_THISMAV")  # answered only if the robot accepts the new signing state
        what = "signing cleared" if ns.clear else f"key {fingerprint(new)} set"
        print(f"robot {ep.target_system}: {what}; it refuses unsigned requests and answered one signed accordingly"
              if not ns.clear else f"robot {ep.target_system}: {what}; it answered an unsigned request")
        return 0
    finally:
        ep.close()


subcommand("key", help="MAVLink 2 signing key: new (create, 0600), show (fingerprint; --reveal prints the "
                       "secret), push (load it into the robot with SETUP_SIGNING)",
           args=[a for a in _LINK_ARGS if a[0][0] not in ("--sign", "--key-file")] + [
               (("action",), {"choices": ["new", "show", "push"]}),
               (("--key-file",), {"default": None, "help": "key file (default ~/.config/agnav/signing.key)"}),
               (("--old-key-file",), {"default": None, "help": "push: the key the robot holds now (sign with it); "
                                                                "without it the frame goes unsigned"}),
               (("--clear",), {"action": "store_true", "help": "push: switch signing off on the robot"}),
               (("--timeout",), {"type": up_to_a_day, "default": 1.0,
                                 "help": "push: seconds to wait for each answer, > 0, at most 86400, 3 tries "
                                         "(default 1)"}),
               (("--force",), {"action": "store_true", "help": "new: replace an existing key"}),
               (("--reveal",), {"action": "store_true", "help": "show: also print the secret key (hex)"})])(
    lambda ns: _guard("key", _cmd_key, ns))


# ---- config --------------------------------------------------------------------------------------
def _cmd_config(ns: argparse.Namespace) -> int:
    from ..link.config import config_template, default_config_path, to_toml

    if ns.template:
        if ns.config:
            _err("config", "--template prints the built-in defaults and reads no file; for the configuration "
                           f"{ns.config} gives, run `agnav config --config {ns.config}`")
            return 2
        print(config_template(), end="")
        return 0
    cfg = _config(ns)
    src = cfg.source or f"defaults; file {default_config_path()} absent"
    print(to_toml(cfg, f"effective host configuration ({src})"), end="")
    return 0


subcommand("config", help="show the effective host configuration, or --template for a file with every default",
           args=[(("--config",), {"default": None, "help": "host config TOML (default ~/.config/agnav/host.toml)"}),
                 (("--template",), {"action": "store_true",
                                    "help": "print a complete config file with the built-in defaults "
                                            "(not with --config)"})])(
    lambda ns: _guard("config", _cmd_config, ns))
