"""Save and load laser scans as CSV.

Format::

    # agnav-scan v1
    # pose_x_m=1.0,pose_y_m=2.0,pose_yaw_rad=0.5,stamp_s=12.25,range_max_m=10.0
    angle_rad,range_m
    -2.356194,1.234000
    ...

Angles are in the sensor frame (0 = forward, CCW positive) and must be evenly spaced and ascending;
a range of NaN, inf or 0 means no return (``nan``/``inf`` are written as such). The pose line gives
the sensor pose in the world frame and is optional (its keys may appear in any order; all four pose
keys or none). Other comment lines are ignored.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .types import LaserScan, Pose2D

__all__ = ["ScanFileError", "save_scan_csv", "load_scan_csv", "HEADER"]

HEADER = "angle_rad,range_m"
_POSE_KEYS = ("pose_x_m", "pose_y_m", "pose_yaw_rad", "stamp_s")


class ScanFileError(ValueError):
    """A scan file could not be read; the message names the file and line."""


def save_scan_csv(scan: LaserScan, path: str | Path) -> Path:
    """Write ``scan`` to ``path`` (parents created). Returns the path."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    lines = ["# agnav-scan v1"]
    meta = []
    if scan.pose is not None:
        meta += [f"pose_x_m={float(scan.pose.x_m)!r}", f"pose_y_m={float(scan.pose.y_m)!r}", f"pose_yaw_rad={float(scan.pose.yaw_rad)!r}"]
    meta.append(f"stamp_s={float(scan.stamp_s)!r}")
    if math.isfinite(scan.range_max_m):
        meta.append(f"range_max_m={float(scan.range_max_m)!r}")
    lines.append("# " + ",".join(meta))
    lines.append(HEADER)
    for a, r in zip(scan.angles_rad, scan.ranges_m):
        lines.append(f"{float(a)!r},{float(r)!r}")
    p.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return p


def load_scan_csv(path: str | Path) -> LaserScan:
    """Read a scan written by :func:`save_scan_csv` (or by hand in the same format).

    Raises :class:`ScanFileError` on a missing header, a malformed row, a non-numeric value, uneven or
    descending angles, or a bad pose comment; the message gives ``file:line``.
    """
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
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
            if "=" in body:
                for item in body.split(","):
                    if "=" not in item:
                        raise ScanFileError(f"{p}:{n}: bad metadata item {item.strip()!r} (expected key=value)")
                    k, v = (s.strip() for s in item.split("=", 1))
                    try:
                        meta[k] = float(v)
                        meta_line[k] = n
                    except ValueError:
                        raise ScanFileError(f"{p}:{n}: metadata {k} is not a number: {v!r}") from None
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
        if r < 0:
            raise ScanFileError(f"{p}:{n}: negative range {r}")
        angles.append(a)
        ranges.append(r)
        line_of.append(n)
    if not header_seen:
        raise ScanFileError(f"{p}: no {HEADER!r} header line")
    if len(angles) < 2:
        raise ScanFileError(f"{p}: need at least 2 beams, got {len(angles)}")
    ang = np.asarray(angles)
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
    pose = Pose2D(meta["pose_x_m"], meta["pose_y_m"], meta["pose_yaw_rad"]) if present else None
    return LaserScan(float(ang[0]), inc, np.asarray(ranges, dtype=float), meta.get("range_max_m", math.inf),
                     meta.get("stamp_s", 0.0), pose)
