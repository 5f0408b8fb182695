"""``agnav sil``: serve the SIL firmware (native build, or the real AVR ELF under simavr with
``--firmware avr``) to a ground station (TCP, SITL style, or a pty)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from .argtypes import nonneg_int, positive_float
from .outputs import OutputError, check_output
from .registry import subcommand


def _scanner(text: str) -> tuple[str, int | None]:
    """``KIND[:PORT]`` -> (kind, port or None for the device's own; 0 = any free port)."""
    from ..sil.emulators import EMULATOR_KINDS

    kind, _, port = text.strip().lower().partition(":")
    if kind not in EMULATOR_KINDS:
        raise argparse.ArgumentTypeError(f"unknown scanner {kind!r}; emulated: {', '.join(EMULATOR_KINDS)}")
    if not port:
        return kind, None
    if EMULATOR_KINDS[kind][0] == "pty":
        raise argparse.ArgumentTypeError(f"{kind} is served on a pseudo-terminal (its path is printed): no port")
    if not port.isdigit() or int(port) > 65535:
        raise argparse.ArgumentTypeError(f"{text!r}: the port must be a number 0-65535 (0: any free one)")
    return kind, int(port)


def _param(text: str) -> tuple[str, int]:
    name, sep, value = text.partition("=")
    if not sep or not name:
        raise argparse.ArgumentTypeError(f"expected NAME=VALUE, got {text!r}")
    try:
        return name.strip().upper(), int(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"parameter value must be an integer: {text!r}") from None


@subcommand(
    "sil",
    help="run the real firmware natively in a simulated world and serve its MAVLink on TCP (SITL style)",
    args=[
        (("scenario",), {"nargs": "?", "default": None, "help": "built-in name or .toml path (default: the default scenario)"}),
        (("--tcp",), {"default": "tcp:127.0.0.1:5760", "metavar": "HOST:PORT",
                      "help": "loopback endpoint to listen on (default tcp:127.0.0.1:5760); 'none' to disable"}),
        (("--pty",), {"action": "store_true", "help": "also serve on a pseudo-terminal (its path is printed)"}),
        (("--speedup",), {"type": positive_float, "default": 1.0,
                          "help": "simulated seconds per wall-clock second, > 0 (default 1)"}),
        (("--duration",), {"type": positive_float, "default": None,
                           "help": "stop after this many simulated seconds, > 0 (default: until Ctrl-C)"}),
        (("--seed",), {"type": nonneg_int, "default": 0, "help": "random seed, a whole number >= 0 (default 0)"}),
        (("--param",), {"type": _param, "action": "append", "default": [], "metavar": "NAME=VALUE",
                        "help": "firmware parameter stored in EEPROM before boot (repeatable), e.g. LINK_TIMEOUT_MS=2000"}),
        (("--tlog",), {"default": None, "help": "write the radio traffic (both ways) to this .tlog"}),
        (("--laser",), {"type": _scanner, "default": None, "metavar": "KIND[:PORT]",
                        "help": "serve the scenario's laser over the device's own protocol: tim5xx (TCP 2112, CoLa-A and "
                                "CoLa-B), lms1xx / lms5xx (CoLa-A 2111, CoLa-B 2112), ust (SCIP 2.0, TCP 10940), urg, "
                                "rplidar (pseudo-terminals); PORT 0 = any free port"}),
        (("--tilted-laser",), {"dest": "tilted_laser", "type": _scanner, "default": None, "metavar": "KIND[:PORT]",
                               "help": "serve the scenario's tilted laser the same way (give it another port than --laser)"}),
        (("--out",), {"default": None, "metavar": "DIR",
                      "help": "write the truth of the run here when it stops: truth.csv, summary.json, run_info.json"}),
        (("--stop-at-end",), {"dest": "stop_at_end", "action": "store_true",
                              "help": "stop serving once the robot arrives, collides or falls into a hole"}),
        (("--movers-wait",), {"dest": "movers_wait", "action": "store_true",
                              "help": "the scenario's walkers start when the host first drives (its first setpoint), "
                                      "not when serving begins: the same encounter as in `agnav sim`"}),
        (("--host-config",), {"dest": "host_config", "default": None, "metavar": "FILE",
                              "help": "write a host config for `agnav run --config FILE`: the scenario's robot, field "
                                      "and the emulated lasers"}),
        (("--firmware",), {"choices": ["native", "avr"], "default": "native",
                           "help": "native: the firmware built for the PC (default); avr: the real ATmega2560 ELF "
                                   "under simavr at 16 MHz"}),
    ],
)
def _cmd_sil(ns: argparse.Namespace) -> int:
    from ..sil.build import SilBuildError
    from ..sil.server import ServeOptions, parse_endpoint, serve
    from ..sil.session import SilConfig
    from ..sim.scenario import ScenarioError, load_scenario

    try:
        sc = load_scenario(ns.scenario)
    except ScenarioError as e:
        print(f"agnav sil: {e}", file=sys.stderr)
        return 2
    try:
        tcp = None if ns.tcp == "none" else parse_endpoint(ns.tcp)
    except ValueError as e:
        print(f"agnav sil: {e}", file=sys.stderr)
        return 2
    if tcp is None and not ns.pty:
        print("agnav sil: nothing to serve on (--tcp none and no --pty)", file=sys.stderr)
        return 2
    if ns.tlog:  # before the firmware loads, as `agnav run --tlog`: named, and its missing folders made
        try:
            check_output("--tlog", ns.tlog)
            Path(ns.tlog).parent.mkdir(parents=True, exist_ok=True)
        except (OutputError, OSError) as e:
            print(f"agnav sil: {e if isinstance(e, OutputError) else f'--tlog {ns.tlog}: {e.strerror or e}'}",
                  file=sys.stderr)
            return 1
    cfg = SilConfig(firmware_params=tuple(ns.param), firmware=ns.firmware)
    lasers = tuple(x for x in (ns.laser, ns.tilted_laser) if x is not None)
    if ns.tilted_laser is not None and ns.laser is None:
        lasers = ((ns.tilted_laser[0], ns.tilted_laser[1]),)
        print("agnav sil: --tilted-laser needs --laser too (the horizontal scanner comes first)", file=sys.stderr)
        return 2
    if ns.speedup != 1.0 and lasers:
        print("agnav sil: warning: scanners' time stamps follow the simulated clock; with --speedup the robot side's "
              "stamps and pacing do not match the wall clock", file=sys.stderr)
    try:
        res = serve(sc, ServeOptions(tcp=tcp, pty=ns.pty, speedup=ns.speedup, duration_s=ns.duration, seed=ns.seed,
                                     tlog_path=ns.tlog, config=cfg, lasers=lasers, out_dir=ns.out,
                                     stop_at_end=ns.stop_at_end, host_config=ns.host_config,
                                     movers_wait=ns.movers_wait))
    except (SilBuildError, ValueError, OSError) as e:
        where = f"{e.filename}: " if isinstance(e, OSError) and e.filename else ""
        print(f"agnav sil: {where}{getattr(e, 'strerror', None) or e}", file=sys.stderr)
        return 1
    print(f"agnav sil: stopped at t = {res.t_s:.1f} s, robot at ({res.pose.x_m:.2f}, {res.pose.y_m:.2f}), "
          f"referee: {res.end_reason}")
    return 0
