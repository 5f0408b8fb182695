"""``agnav rows``: crop-row detection on a saved scan (CSV of :mod:`agnav_host.scanio`).

Exit codes: 0 = an estimate was printed (when no rows are found it has confidence 0 and end of row
yes, as :class:`~agnav_host.perception.RowEstimate` reports it); 2 = a bad option or scan file;
3 = the scan holds no usable return at all (every range NaN, inf, 0 or out of range): nothing was
measured, the message goes to stderr and ``--json`` prints nulls for offset, heading, spacing and end
of row, with confidence 0.
"""

from __future__ import annotations

import argparse
import json
import math
import sys

from ..cli import positive_float, subcommand

_KEYS = ("lateral_offset_m", "heading_rad", "row_spacing_m", "confidence", "end_of_row")
_MAX_SPACING_M = 5.0  # a wider --spacing is taken for centimetres or another unit
EXIT_NO_RETURNS = 3


def _spacing(text: str) -> float:
    """argparse type of ``--spacing``: metres, > 0 and at most :data:`_MAX_SPACING_M`."""
    v = positive_float(text)
    if v > _MAX_SPACING_M:
        raise argparse.ArgumentTypeError(f"{v:g} m is not a plausible row spacing: row spacing is in metres "
                                         f"(e.g. 0.75), at most {_MAX_SPACING_M:g}")
    return v


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
    epilog="exit codes: 0 = an estimate was printed (no rows found: confidence 0), 2 = a bad option or scan file, "
           "3 = no usable return in the scan (nothing measured; --json prints nulls)",
    args=[
        (("--scan",), {"required": True, "metavar": "FILE.csv", "help": "scan file (agnav-scan v1 CSV)"}),
        (("--method",), {"default": "ransac", "help": "offset, lsq, triangle, ransac or hough (default ransac)"}),
        (("--mount",), {"type": _mount, "default": (0.0, 0.0, 0.0), "metavar": "X,Y[,YAW_DEG]",
                        "help": "laser pose on the robot (m, m, deg); negatives allowed"}),
        (("--spacing",), {"type": _spacing, "default": 0.75, "metavar": "M",
                          "help": f"expected row spacing, m, > 0 and <= {_MAX_SPACING_M:g} (default 0.75)"}),
        (("--json",), {"action": "store_true", "help": "print one JSON object"}),
    ],
)
def _cmd_rows(ns: argparse.Namespace) -> int:
    from ..scanio import ScanFileError, load_scan_csv
    from ..types import Pose2D
    from ._rows import RowParams, detect_rows
    from ._scan import check_scan

    if ns.method not in _method_names():
        print(f"agnav rows: unknown method {ns.method!r}; known: {', '.join(_method_names())}", file=sys.stderr)
        return 2
    try:
        scan = load_scan_csv(ns.scan)
    except ScanFileError as e:
        print(f"agnav rows: {e}", file=sys.stderr)
        return 2
    x, y, yaw_deg = ns.mount
    params = RowParams(expected_spacing_m=ns.spacing)
    n_usable = int(check_scan(scan, params.scan).sum())
    if n_usable == 0:
        lo, hi = params.scan.min_range_m, min(params.scan.max_range_m, scan.range_max_m)
        span = f"{lo:g}..{hi:g} m" if math.isfinite(hi) else f">= {lo:g} m"
        print(f"agnav rows: {ns.scan}: no usable return in the scan ({len(scan.ranges_m)} beams, none finite and in "
              f"{span}): nothing measured", file=sys.stderr)
        if ns.json:
            print(json.dumps({"lateral_offset_m": None, "heading_rad": None, "row_spacing_m": None, "confidence": 0.0,
                              "end_of_row": None}))
        return EXIT_NO_RETURNS
    est = detect_rows(scan, ns.method, params, Pose2D(x, y, math.radians(yaw_deg)))
    out = {k: getattr(est, k) for k in _KEYS}
    if ns.json:
        print(json.dumps(out))
    elif not est.valid:
        print(f"method {ns.method}: no rows found ({n_usable} usable returns), confidence 0.00, end of row: "
              f"{'yes' if est.end_of_row else 'no'}")
    else:
        print(f"method {ns.method}: offset {est.lateral_offset_m:+.3f} m (+ = robot left of centre), heading "
              f"{math.degrees(est.heading_rad):+.1f} deg (+ = CCW), spacing {est.row_spacing_m:.3f} m, confidence "
              f"{est.confidence:.2f}, end of row: {'yes' if est.end_of_row else 'no'}")
    return 0
