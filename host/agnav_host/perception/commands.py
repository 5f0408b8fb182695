"""``agnav rows``: crop-row detection on a saved scan (CSV of :mod:`agnav_host.scanio`)."""

from __future__ import annotations

import argparse
import json
import math
import sys

from ..cli import subcommand

_KEYS = ("lateral_offset_m", "heading_rad", "row_spacing_m", "confidence", "end_of_row")


def _mount(text: str) -> tuple[float, float, float]:
    parts = [p.strip() for p in text.split(",")]
    try:
        vals = [float(p) for p in parts]
    except ValueError:
        raise argparse.ArgumentTypeError(f"mount must be X,Y[,YAW_DEG] numbers, got {text!r}") from None
    if len(vals) not in (2, 3) or not all(math.isfinite(v) for v in vals):
        raise argparse.ArgumentTypeError(f"mount must be X,Y[,YAW_DEG] (m, m, deg), got {text!r}")
    return vals[0], vals[1], vals[2] if len(vals) == 3 else 0.0


def _method_names() -> list[str]:
    from ._rows import row_method_names

    return row_method_names()


@subcommand(
    "rows",
    help="detect crop rows in a scan CSV: lateral offset, heading, spacing, confidence, end of row",
    args=[
        (("--scan",), {"required": True, "metavar": "FILE.csv", "help": "scan file (agnav-scan v1 CSV)"}),
        (("--method",), {"default": "ransac", "help": "offset, lsq, triangle, ransac or hough (default ransac)"}),
        (("--mount",), {"type": _mount, "default": (0.0, 0.0, 0.0), "metavar": "X,Y[,YAW_DEG]",
                        "help": "laser pose on the robot (m, m, deg); negatives allowed"}),
        (("--spacing",), {"type": float, "default": 0.75, "help": "expected row spacing, m (default 0.75)"}),
        (("--json",), {"action": "store_true", "help": "print one JSON object"}),
    ],
    negative_ok=["--mount"],
)
def _cmd_rows(ns: argparse.Namespace) -> int:
    from ..scanio import ScanFileError, load_scan_csv
    from ..types import Pose2D
    from ._rows import RowParams, detect_rows

    if ns.method not in _method_names():
        print(f"agnav rows: unknown method {ns.method!r}; known: {', '.join(_method_names())}", file=sys.stderr)
        return 2
    if not (math.isfinite(ns.spacing) and ns.spacing > 0):
        print(f"agnav rows: --spacing must be > 0, got {ns.spacing}", file=sys.stderr)
        return 2
    try:
        scan = load_scan_csv(ns.scan)
    except ScanFileError as e:
        print(f"agnav rows: {e}", file=sys.stderr)
        return 2
    x, y, yaw_deg = ns.mount
    est = detect_rows(scan, ns.method, RowParams(expected_spacing_m=ns.spacing), Pose2D(x, y, math.radians(yaw_deg)))
    out = {k: getattr(est, k) for k in _KEYS}
    if ns.json:
        print(json.dumps(out))
    else:
        print(f"method {ns.method}: offset {est.lateral_offset_m:+.3f} m (+ = robot left of centre), heading "
              f"{math.degrees(est.heading_rad):+.1f} deg (+ = CCW), spacing {est.row_spacing_m:.3f} m, confidence "
              f"{est.confidence:.2f}, end of row: {'yes' if est.end_of_row else 'no'}")
    return 0
