"""The command line as people type it, put in the order argparse reads without guessing.

People type negative numbers after a space (``--goal -3,5,90``, ``--x -1.5``, ``param set NAME -1e3``) and
options between positionals (``param get --device X NAME``). argparse takes a word that starts with ``-``
for an option unless it is a plain ``-3`` or ``-0.5``, so :func:`arrange` rewrites the words of one
subcommand, with nothing but what the parser declared (:class:`Options`), before argparse sees them:

* an option that takes a value is joined with the word after it (``--goal -3,5,90`` -> ``--goal=-3,5,90``;
  an abbreviation as argparse resolves it: ``--start-steer -1e-3``), when that word is not itself an option:
  it does not start with ``-``, or it starts like a negative number (:data:`NEGATIVE`; no option of agnav
  starts with ``-`` and a digit, ``.``, ``inf`` or ``nan``). A malformed list (``--goal -3,abc,90``) is
  joined too, and the option's type gives its own message;
* the positionals go last, after ``--``, in the order typed, so that a negative one is a value and options
  may stand between them.

Anything else (an unknown option, an option without its value, a typo in the command's name) is left where
it was, for argparse to refuse with its usual message.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Iterable, Sequence

__all__ = ["NEGATIVE", "Options", "arrange"]

#: A word that starts like a negative number: "-3,5,90", "-1e-3", "-.5", "-inf", a malformed "-3,abc,90"
NEGATIVE = re.compile(r"^-(\d|\.\d|inf|nan)", re.IGNORECASE)


@dataclass(frozen=True)
class Options:
    """The option strings of one parser: those that take a value and the flags."""

    takes_value: frozenset[str]
    flags: frozenset[str]

    @classmethod
    def of(cls, actions: Iterable[tuple[Sequence[str], bool]]) -> "Options":
        """From (option strings, takes a value) of each option (positionals have no option strings)."""
        value: set[str] = set()
        flag: set[str] = set()
        for strings, takes_value in actions:
            (value if takes_value else flag).update(strings)
        return cls(frozenset(value), frozenset(flag))

    def resolve(self, word: str) -> str | None:
        """The option ``word`` names (before any ``=``): itself, or the one long option it abbreviates (as
        argparse resolves a prefix); None when it names none or several."""
        head = word.split("=", 1)[0]
        if head in self.takes_value or head in self.flags:
            return head
        if not head.startswith("--"):
            return None
        hits = [o for o in self.takes_value | self.flags if o.startswith("--") and o.startswith(head)]
        return hits[0] if len(hits) == 1 else None


def _is_option(word: str) -> bool:
    return word.startswith("-") and len(word) > 1 and not NEGATIVE.match(word)


def _is_value(word: str) -> bool:
    return not word.startswith("-") or word == "-" or bool(NEGATIVE.match(word))


def arrange(argv: Sequence[str], top: Options, commands: dict[str, Options]) -> list[str]:
    """``argv`` (without the program's name) as argparse must read it: the top-level options as typed, the
    command's name, its options with their values joined (``--opt=value``), then ``--`` and its positionals.
    ``top``: the options of the top-level parser; ``commands``: each subcommand's options."""
    words = list(argv)
    out: list[str] = []
    i = 0
    while i < len(words) and _is_option(words[i]) and words[i] != "--":  # agnav's own options
        w = words[i]
        out.append(w)
        i += 1
        if "=" not in w and top.resolve(w) in top.takes_value and i < len(words):
            out.append(words[i])
            i += 1
    if i >= len(words) or words[i] not in commands:
        return out + words[i:]
    options = commands[words[i]]
    out.append(words[i])
    rest = words[i + 1:]
    opts: list[str] = []
    positionals: list[str] = []
    j = 0
    while j < len(rest):
        w = rest[j]
        j += 1
        if w == "--":  # the user's own end of options
            positionals += rest[j:]
            break
        if not _is_option(w):
            positionals.append(w)
            continue
        if "=" not in w and options.resolve(w) in options.takes_value and j < len(rest) and _is_value(rest[j]):
            opts.append(f"{w}={rest[j]}")
            j += 1
            continue
        opts.append(w)
    return out + opts + (["--", *positionals] if positionals else [])
