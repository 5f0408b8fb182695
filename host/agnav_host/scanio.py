"""Save and load laser scans as CSV.

Format::

    # agnav-scan v1
    # pose_x_m=1.0,pose_y_m=2.0,pose_yaw_rad=0.5,stamp_s=12.25,beams=181,range_max_m=10.0
    angle_rad,range_m
    -2.356194,1.234000
    ...

Angles are in the sensor frame (0 = forward, CCW positive), in radians within [-2 pi, 2 pi] and
spanning at most 2 pi (a file in degrees is refused), and must be evenly spaced and ascending;
a range of NaN, inf or 0 means no return (``nan``/``inf`` are written as such). ``range_max_m`` (and
``range_min_m``, if given) must be > 0 with ``range_min_m < range_max_m``. A UTF-8 byte-order mark
(files saved by Excel) is accepted. The pose line gives the sensor pose in the world frame and is
optional (its keys may appear in any order; all four pose keys or none). A comment line that names none of
these keys is free text and ignored (``# operator=Anna`` too). On a metadata line every key must be one of
them; a comment with a near miss of one (``# range_mx_m=1.0``, ``# range_max=1.0``) or one written with a colon
(``# range_max_m: 1.0``) is refused too, so a misspelt limit is not silently lost.
"""

from __future__ import annotations

import difflib
import math
import re
from pathlib import Path

import numpy as np

from .atomic import write_atomic
from .types import LaserScan, Pose2D

__all__ = ["ScanFileError", "save_scan_csv", "load_scan_csv", "HEADER"]

HEADER = "angle_rad,range_m"
_POSE_KEYS = ("pose_x_m", "pose_y_m", "pose_yaw_rad", "stamp_s")
_META_ORDER = (*sorted((*_POSE_KEYS, "range_max_m", "range_min_m")), "beams")  # as the messages list them
_META_KEYS = frozenset(_META_ORDER)
_ANGLE_LIMIT_RAD = 2.0 * math.pi  # beyond this (or a wider span) the angles are taken to be degrees


class ScanFileError(ValueError):
    """A scan file could not be read; the message names the file and line."""


_COMMENT_KEY = re.compile(r"\s*([A-Za-z_][A-Za-z0-9_]*)\s*[=:]")


def _unknown_key_text(key: str) -> str:
    close = difflib.get_close_matches(key, sorted(_META_KEYS), n=1, cutoff=0.8)
    hint = f"did you mean {close[0]}? " if close else ""
    return f"unknown metadata key {key!r}; {hint}known: {', '.join(_META_ORDER)}"


def _misspelt_meta(body: str) -> str | None:
    """Why a comment that names no metadata key still reads as a metadata line gone wrong (an item ``key=`` or
    ``key:`` whose key is a near miss of a known one, or a known one with a colon), or None for free text."""
    for item in body.split(","):
        m = _COMMENT_KEY.match(item)
        if not m:
            continue
        key = m.group(1)
        if key in _META_KEYS:
            return f"metadata is written key=value ({key}=...), got {item.strip()!r}"
        if difflib.get_close_matches(key, _META_KEYS, n=1, cutoff=0.8):
            return _unknown_key_text(key)
    return None


def save_scan_csv(scan: LaserScan, path: str | Path) -> Path:
    """Write ``scan`` to ``path`` (parents created) in the form :func:`load_scan_csv` reads back: a
    clockwise scan (negative increment) is written in ascending angle order, and a ``-inf`` range (no
    return) as ``inf``. Raises ValueError for fewer than 2 beams or a negative range. Returns the path."""
    n = len(scan.ranges_m)
    if n < 2:
        raise ValueError(f"a scan file needs at least 2 beams, the scan has {n}")
    angles = np.asarray(scan.angles_rad, dtype=float)
    ranges = np.where(np.isneginf(scan.ranges_m), np.inf, np.asarray(scan.ranges_m, dtype=float))
    if np.any(ranges < 0):
        raise ValueError(f"negative range {float(ranges[ranges < 0][0])!r} in the scan")
    if scan.angle_increment_rad < 0:
        angles, ranges = angles[::-1], ranges[::-1]
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    lines = ["# agnav-scan v1"]
    meta = []
    if scan.pose is not None:
        meta += [f"pose_x_m={float(scan.pose.x_m)!r}", f"pose_y_m={float(scan.pose.y_m)!r}", f"pose_yaw_rad={float(scan.pose.yaw_rad)!r}"]
    meta.append(f"stamp_s={float(scan.stamp_s)!r}")
    meta.append(f"beams={n}")  # so a file cut short is told from a narrower scan
    if math.isfinite(scan.range_max_m):
        meta.append(f"range_max_m={float(scan.range_max_m)!r}")
    lines.append("# " + ",".join(meta))
    lines.append(HEADER)
    for a, r in zip(angles, ranges):
        lines.append(f"{float(a)!r},{float(r)!r}")
    write_atomic(p, "\n".join(lines) + "\n")
    return p


def load_scan_csv(path: str | Path) -> LaserScan:
    """Read a scan written by :func:`save_scan_csv` (or by hand in the same format).

    Raises :class:`ScanFileError` on a missing header, a malformed row, a non-numeric value, uneven or
    descending angles, angles that look like degrees, a bad range limit or a bad pose comment; the
    message gives ``file:line``.
    """
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8-sig")  # -sig: a leading BOM (Excel) is dropped
    except (OSError, UnicodeDecodeError) as e:
        raise ScanFileError(f"{p}: cannot read scan file: {e}") from None
    meta: dict[str, float] = {}
    angles: list[float] = []
    ranges: list[float] = []
    line_of: list[int] = []  # file line of each beam, for the messages below
    meta_line: dict[str, int] = {}
    header_seen = False
    for n, raw in enumerate(text.splitlines(), 1):
        line = raw.strip()
        if not line:
            continue
        if line.startswith("#"):
            body = line[1:].strip()
            keys = {item.split("=", 1)[0].strip() for item in body.split(",") if "=" in item}
            if keys & _META_KEYS:  # a metadata line (any other comment line is free text)
                for item in body.split(","):
                    if "=" not in item:
                        raise ScanFileError(f"{p}:{n}: bad metadata item {item.strip()!r} (expected key=value)")
                    k, v = (s.strip() for s in item.split("=", 1))
                    if k not in _META_KEYS:
                        raise ScanFileError(f"{p}:{n}: {_unknown_key_text(k)}")
                    try:
                        meta[k] = float(v)
                        meta_line[k] = n
                    except ValueError:
                        raise ScanFileError(f"{p}:{n}: metadata {k} is not a number: {v!r}") from None
            else:
                why = _misspelt_meta(body)
                if why:
                    raise ScanFileError(f"{p}:{n}: {why}")
            continue
        if not header_seen:
            if line.replace(" ", "") != HEADER:
                raise ScanFileError(f"{p}:{n}: expected header {HEADER!r}, got {line!r}")
            header_seen = True
            continue
        cells = line.split(",")
        if len(cells) != 2:
            raise ScanFileError(f"{p}:{n}: expected 2 columns (angle_rad,range_m), got {len(cells)}")
        try:
            a, r = float(cells[0]), float(cells[1])
        except ValueError:
            raise ScanFileError(f"{p}:{n}: not a number in {line!r}") from None
        if not math.isfinite(a):
            raise ScanFileError(f"{p}:{n}: angle must be finite, got {cells[0]!r}")
        if abs(a) > _ANGLE_LIMIT_RAD:
            raise ScanFileError(f"{p}:{n}: angle {a:g} is outside [-2 pi, 2 pi] rad: the angle_rad column looks like "
                                "degrees (angles must be in radians)")
        if r < 0:
            raise ScanFileError(f"{p}:{n}: negative range {r}")
        angles.append(a)
        ranges.append(r)
        line_of.append(n)
    if not header_seen:
        raise ScanFileError(f"{p}: no {HEADER!r} header line")
    if "beams" in meta and meta["beams"] != len(angles):
        why = "the file is cut short" if len(angles) < meta["beams"] else "more rows than declared"
        raise ScanFileError(f"{p}:{meta_line['beams']}: metadata beams={meta['beams']:g} but the file holds "
                            f"{len(angles)} beams ({why})")
    if "beams" in meta and not text.endswith("\n") and angles:  # our files end each line: its last number may be cut
        raise ScanFileError(f"{p}:{line_of[-1]}: the last line has no end (the file is cut short)")
    if len(angles) < 2:
        raise ScanFileError(f"{p}: need at least 2 beams, got {len(angles)}")
    ang = np.asarray(angles)
    if ang[-1] - ang[0] > _ANGLE_LIMIT_RAD + 1e-9:
        raise ScanFileError(f"{p}:{line_of[-1]}: the angles span {ang[-1] - ang[0]:g} rad, more than a full turn "
                            "(2 pi): the angle_rad column looks like degrees (angles must be in radians)")
    d = np.diff(ang)
    inc = float((ang[-1] - ang[0]) / (len(ang) - 1))
    if inc <= 0 or np.any(d <= 0):
        bad = int(np.argmax(d <= 0)) if np.any(d <= 0) else len(d) - 1
        raise ScanFileError(f"{p}:{line_of[bad + 1]}: angles must be strictly ascending "
                            f"(angle {angles[bad + 1]!r} after {angles[bad]!r} on line {line_of[bad]})")
    if np.max(np.abs(d - inc)) > 1e-6 + 1e-3 * inc:
        bad = int(np.argmax(np.abs(d - inc)))
        raise ScanFileError(f"{p}:{line_of[bad + 1]}: angles are not evenly spaced (step {d[bad]:.6g} rad before "
                            f"beam {bad + 1}, mean {inc:.6g})")
    present = [k for k in ("pose_x_m", "pose_y_m", "pose_yaw_rad") if k in meta]
    if present and len(present) != 3:
        raise ScanFileError(f"{p}:{meta_line[present[0]]}: pose metadata incomplete, have {present}, "
                            "need pose_x_m, pose_y_m, pose_yaw_rad")
    for k in (*_POSE_KEYS, "range_min_m"):
        if k in meta and not math.isfinite(meta[k]):
            raise ScanFileError(f"{p}:{meta_line[k]}: metadata {k} must be finite, got {meta[k]}")
    rmax = meta.get("range_max_m", math.inf)
    rmin = meta.get("range_min_m", 0.0)
    if "range_min_m" in meta and rmin < 0:
        raise ScanFileError(f"{p}:{meta_line['range_min_m']}: metadata range_min_m must be >= 0, got {rmin:g}")
    if "range_max_m" in meta and not rmax > max(rmin, 0.0):  # NaN refused too
        need = f"> range_min_m ({rmin:g})" if rmin > 0 else "> 0"
        raise ScanFileError(f"{p}:{meta_line['range_max_m']}: metadata range_max_m must be {need}, got {rmax:g}")
    pose = Pose2D(meta["pose_x_m"], meta["pose_y_m"], meta["pose_yaw_rad"]) if present else None
    return LaserScan(float(ang[0]), inc, np.asarray(ranges, dtype=float), rmax,
                     meta.get("stamp_s", 0.0), pose)
