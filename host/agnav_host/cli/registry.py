"""The registry of ``agnav`` subcommands: :func:`subcommand` adds one, :data:`SUBCOMMANDS` holds them in the
order they were added (the order of ``agnav --help``)."""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from typing import Any, Callable, Sequence

__all__ = ["Handler", "ArgSpec", "Subcommand", "SUBCOMMANDS", "subcommand"]

Handler = Callable[[argparse.Namespace], int]
#: One argument of a subcommand: the flags or name, and the keywords of ``ArgumentParser.add_argument``
ArgSpec = tuple[tuple[str, ...], dict[str, Any]]


@dataclass(frozen=True)
class Subcommand:
    name: str
    help: str
    handler: Handler
    args: tuple[ArgSpec, ...]
    epilog: str = ""


SUBCOMMANDS: dict[str, Subcommand] = {}


def subcommand(name: str, help: str, args: Sequence[ArgSpec] = (), epilog: str = "") -> Callable[[Handler], Handler]:
    """Register ``fn`` as ``agnav <name>``; ``epilog`` ends ``agnav <name> --help`` (exit codes, units)."""

    def deco(fn: Handler) -> Handler:
        if name in SUBCOMMANDS:
            raise ValueError(f"subcommand {name!r} registered twice")
        SUBCOMMANDS[name] = Subcommand(name, help, fn, tuple(args), epilog)
        return fn

    return deco
