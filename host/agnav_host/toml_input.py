"""TOML from files a user hands over (scenarios, host configs): read with bounded nesting.

Python's ``tomllib`` recurses once per level of nested arrays or inline tables, so a file with a few hundred
levels (``a = [[[[...]]]]``) ends in RecursionError. No AgNav file nests deeper than a few levels, so
:func:`loads_bounded` refuses anything deeper than ``max_depth`` before parsing, naming the line."""

from __future__ import annotations

import tomllib
from typing import Any

MAX_DEPTH = 32


class TomlTooDeep(ValueError):
    """Nesting deeper than allowed; ``line`` is 1-based."""

    def __init__(self, line: int, depth: int, max_depth: int) -> None:
        super().__init__(f"line {line}: arrays or inline tables nested {depth} deep; at most {max_depth} levels")
        self.line = line
        self.depth = depth


def nesting_depth(text: str, max_depth: int = MAX_DEPTH) -> tuple[int, int]:
    """(deepest nesting of [ ] and { } in values, the line where it first passes ``max_depth`` or 0). Strings and
    comments are skipped; a table header ``[a.b]`` at a line's start is not nesting."""
    depth = deepest = 0
    line = 1
    over_line = 0
    i, n = 0, len(text)
    at_line_start = True
    while i < n:
        c = text[i]
        if c == "\n":
            line += 1
            at_line_start = True
            i += 1
            continue
        if c in " \t\r":
            i += 1
            continue
        if c == "#":
            while i < n and text[i] != "\n":
                i += 1
            continue
        if c in "\"'":
            q = text[i:i + 3] if text[i:i + 3] in ('"""', "'''") else c
            i += len(q)
            while i < n and not text.startswith(q, i):
                if text[i] == "\n":
                    line += 1
                if q[0] == '"' and text[i] == "\\":
                    i += 1
                i += 1
            i += len(q)
            at_line_start = False
            continue
        if c == "[" and at_line_start and depth == 0:  # a table header: [a] or [[a]]
            while i < n and text[i] not in "\n":
                i += 1
            continue
        at_line_start = False
        if c in "[{":
            depth += 1
            if depth > deepest:
                deepest = depth
                if depth > max_depth and not over_line:
                    over_line = line
        elif c in "]}":
            depth = max(0, depth - 1)
        i += 1
    return deepest, over_line


def loads_bounded(text: str, max_depth: int = MAX_DEPTH) -> dict[str, Any]:
    """``tomllib.loads`` after checking the nesting depth: TomlTooDeep when deeper than ``max_depth``;
    tomllib.TOMLDecodeError as tomllib raises it."""
    deepest, line = nesting_depth(text, max_depth)
    if deepest > max_depth:
        raise TomlTooDeep(line, deepest, max_depth)
    try:
        return tomllib.loads(text)
    except RecursionError:  # a construction the scan does not count: still a clear refusal
        raise TomlTooDeep(line or 1, deepest, max_depth) from None
