"""``agnav`` command line: every subcommand and every argument type of the host, each command a thin wrapper
around library calls. The library packages (link, planning, perception, sil, sim, faults, ...) never import
this package.

Add a subcommand with the :func:`subcommand` decorator in one of the command modules (:data:`COMMAND_MODULES`)::

    @subcommand("name", help="one line", args=[(("--flag",), {"type": int})])
    def _cmd_name(ns: argparse.Namespace) -> int: ...

Any option that takes a value may be given a negative number after a space (``--goal -3,5,90``,
``--start-speed -1e-3``), a positional may be a negative number (``param set NAME -1e3``), and options may
stand between a subcommand's positionals (``param get --device X NAME``): :func:`parse_args` puts the words
in argparse's order first (:mod:`.argv`), from the options each parser declares, so a subcommand declares
nothing for this.

``agnav --version`` prints the installed version; ``-v`` (info) / ``-vv`` (debug) or ``--log-level LEVEL``
show the library's log records on stderr (default: warnings and errors).
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import logging
import sys
from dataclasses import dataclass
from typing import Iterator, Sequence

from .argtypes import (
    DAY_S,
    finite_float,
    int_in,
    nonempty_text,
    nonneg_float,
    nonneg_int,
    parse_goal,
    positive_float,
    positive_float_at_most,
    positive_int,
    text_refusing_empty,
    up_to_a_day,
)
from .argv import Options, arrange
from .outputs import clear_earlier_outputs, unusable_out_dir, unwritable_file
from .registry import SUBCOMMANDS, Handler, subcommand

__all__ = ["main", "parse_args", "build_parser", "subcommand", "SUBCOMMANDS", "COMMAND_MODULES", "version",
           "parse_goal", "finite_float", "positive_float", "positive_float_at_most", "DAY_S", "up_to_a_day",
           "nonneg_float", "positive_int", "nonneg_int", "int_in", "nonempty_text", "unusable_out_dir",
           "unwritable_file", "clear_earlier_outputs", "EXIT_BROKEN_PIPE", "LOG_LEVELS"]

log = logging.getLogger(__name__)

#: The modules that register the subcommands, in the order of ``agnav --help``
COMMAND_MODULES: tuple[str, ...] = (
    "agnav_host.cli.sim",
    "agnav_host.cli.field",
    "agnav_host.cli.perception",
    "agnav_host.cli.planners",
    "agnav_host.cli.bench",
    "agnav_host.cli.plan",
    "agnav_host.cli.link",
    "agnav_host.cli.run",
    "agnav_host.cli.sil",
    "agnav_host.cli.faults",
    "agnav_host.cli.slam",
)

#: The levels of ``--log-level``
LOG_LEVELS = ("debug", "info", "warning", "error", "critical")
#: The logger whose records ``-v`` / ``--log-level`` show: every library module logs under it (``__name__``)
LIBRARY_LOGGER = "agnav_host"


def version() -> str:
    """The installed agnav-host version (the package's own ``__version__`` when it is not installed)."""
    from importlib.metadata import PackageNotFoundError
    from importlib.metadata import version as installed

    try:
        return installed("agnav-host")
    except PackageNotFoundError:
        from .. import __version__

        return __version__


def _log_level(text: str) -> str:
    name = text.strip().lower()
    if name not in LOG_LEVELS:
        raise argparse.ArgumentTypeError(f"must be one of {', '.join(LOG_LEVELS)}, got {text!r}")
    return name


@dataclass(frozen=True)
class _Cli:
    parser: argparse.ArgumentParser
    commands: dict[str, argparse.ArgumentParser]
    top: Options
    options: dict[str, Options]


_HELP = (("-h", "--help"), False)  # the help flag argparse adds to every parser


def _options(adds: list[argparse.Action]) -> Options:
    return Options.of([_HELP, *((a.option_strings, a.nargs != 0) for a in adds if a.option_strings)])


def _build() -> _Cli:
    for name in COMMAND_MODULES:
        importlib.import_module(name)
    parser = argparse.ArgumentParser(prog="agnav", description="AgNav host companion")
    top = [parser.add_argument("--version", action="version", version=f"agnav {version()}"),
           parser.add_argument("-v", "--verbose", action="count", default=0,
                               help="show the library's log records on stderr: -v info, -vv debug (default: warnings "
                                    "and errors only)"),
           parser.add_argument("--log-level", type=_log_level, default=None, metavar="LEVEL",
                               help=f"the least severe log records shown on stderr: {', '.join(LOG_LEVELS)} "
                                    "(default: warning, or as -v says)")]
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    commands: dict[str, argparse.ArgumentParser] = {}
    options: dict[str, Options] = {}
    for s in SUBCOMMANDS.values():
        sp = sub.add_parser(s.name, help=s.help, description=s.help, epilog=s.epilog or None)
        adds = [sp.add_argument(*flags, **text_refusing_empty(kw)) for flags, kw in s.args]
        sp.set_defaults(_handler=s.handler)
        commands[s.name] = sp
        options[s.name] = _options(adds)
    return _Cli(parser, commands, _options(top), options)


def build_parser() -> argparse.ArgumentParser:
    """The ``agnav`` parser with every subcommand. It reads a command line in argparse's own order; what people
    type goes through :func:`parse_args`."""
    return _build().parser


def _parse(cli: _Cli, argv: Sequence[str]) -> argparse.Namespace:
    ns, extras = cli.parser.parse_known_args(arrange(argv, cli.top, cli.options))
    if extras:  # with the subcommand's usage, not agnav's
        cli.commands[ns.command].error(f"unrecognized arguments: {' '.join(extras)}")
    return ns


def parse_args(argv: Sequence[str]) -> argparse.Namespace:
    """``agnav argv`` parsed as :func:`main` parses it (negative values after a space, options between
    positionals: :mod:`.argv`); argparse's exit (2) with its message on a bad command line."""
    return _parse(_build(), argv)


class _StderrHandler(logging.Handler):
    """Writes to whatever ``sys.stderr`` is at the time of the record (a test's capture, a redirected stream)."""

    def emit(self, record: logging.LogRecord) -> None:
        try:
            sys.stderr.write(self.format(record) + "\n")
        except Exception:  # noqa: BLE001  (logging's own rule: a record that cannot be written is reported, not raised)
            self.handleError(record)


@contextlib.contextmanager
def _logging_to_stderr(level: int) -> Iterator[None]:
    """The library's log records of ``level`` and above on stderr while a command runs, one line each; the
    logging set-up as it was afterwards (``main`` may run more than once in a process)."""
    lib = logging.getLogger(LIBRARY_LOGGER)
    handler = _StderrHandler()
    handler.setFormatter(logging.Formatter("%(levelname)s %(name)s: %(message)s"))
    old_level = lib.level
    lib.addHandler(handler)
    lib.setLevel(level)
    try:
        yield
    finally:
        lib.removeHandler(handler)
        lib.setLevel(old_level)


def _level(ns: argparse.Namespace) -> int:
    if ns.log_level is not None:
        return int(getattr(logging, ns.log_level.upper()))
    return {0: logging.WARNING, 1: logging.INFO}.get(ns.verbose, logging.DEBUG)


#: Exit code when the reader of our output went away (``agnav planners | head -1``): what a process killed by
#: SIGPIPE reports to the shell, 128 + 13.
EXIT_BROKEN_PIPE = 141


def _quiet_broken_pipe() -> int:
    """The reader of stdout (or stderr) is gone: point both at /dev/null so that nothing more, not even
    Python's flush at exit, fails on them, and exit quietly as standard tools do."""
    import os

    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        for stream in (sys.stdout, sys.stderr):
            os.dup2(devnull, stream.fileno())
    except (OSError, ValueError, AttributeError):  # a stream without a file descriptor (a test's capture)
        pass
    return EXIT_BROKEN_PIPE


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``agnav`` console script; returns the exit code."""
    ns = parse_args(list(sys.argv[1:] if argv is None else argv))
    handler: Handler = ns._handler
    with _logging_to_stderr(_level(ns)):
        log.debug("agnav %s: %s", ns.command,
                  ", ".join(f"{k}={v!r}" for k, v in sorted(vars(ns).items()) if not k.startswith("_")))
        try:
            rc = handler(ns)
            sys.stdout.flush()  # here, not at exit, so that a closed pipe is caught below
        except BrokenPipeError:
            return _quiet_broken_pipe()
    return rc
