"""``agnav rows``: crop-row detection on a saved scan (CSV of :mod:`agnav_host.scanio`) or on the scans of a
laser log (``.alog`` of :mod:`agnav_host.lasers.log`).

Exit codes: 0 = an estimate was printed (when no rows are found it has confidence 0 and end of row
yes, as :class:`~agnav_host.perception.RowEstimate` reports it); 2 = a bad option or scan file;
3 = the scan holds no usable return at all (every range NaN, inf, 0 or out of range): nothing was
measured, the message goes to stderr and ``--json`` prints nulls for offset, heading, spacing and end
of row, with confidence 0.

A laser log (suffix ``.alog``, or a file whose first line is the log's header) gives one result per scan of
one laser (``--laser-id``, default the first declared) or of one scan (``--index K``, counted from 0 among
that laser's scans): a line each, with ``--json`` a JSON object each with the keys above plus ``index`` and
``t_s`` (the scan's time on the run's clock). The laser's logged mount is used unless ``--mount`` is given.
A scan without a usable return prints its line of nulls and the run goes on; exit 3 when no scan had one.
The whole log is checked before the first line is printed (a corrupt log exits 2 with nothing on stdout);
a cut-off last record (a run killed mid-write) is ignored with a note on stderr.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from typing import Any

from .argtypes import nonneg_int, positive_float
from .progress import ProgressLine
from .registry import subcommand

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
    from ..perception import row_method_names

    return row_method_names()


@subcommand(
    "rows",
    help="detect crop rows in a scan CSV or a laser log: lateral offset, heading, spacing, confidence, end of row",
    epilog="exit codes: 0 = an estimate was printed (no rows found: confidence 0), 2 = a bad option or scan file, "
           "3 = no usable return in the scan (nothing measured; --json prints nulls); for a laser log: one result "
           "per scan, 3 when no scan had a usable return",
    args=[
        (("--scan",), {"required": True, "metavar": "FILE",
                       "help": "scan file (agnav-scan v1 CSV) or laser log (.alog: every scan of one laser)"}),
        (("--method",), {"default": "ransac", "help": "offset, lsq, triangle, ransac or hough (default ransac)"}),
        (("--mount",), {"type": _mount, "default": None, "metavar": "X,Y[,YAW_DEG]",
                        "help": "laser pose on the robot (m, m, deg); negatives allowed (default 0,0,0; for a laser "
                                "log the logged mount)"}),
        (("--spacing",), {"type": _spacing, "default": 0.75, "metavar": "M",
                          "help": f"expected row spacing, m, > 0 and <= {_MAX_SPACING_M:g} (default 0.75)"}),
        (("--laser-id",), {"type": nonneg_int, "default": None, "metavar": "N",
                           "help": "laser log only: the laser whose scans to read (default the first declared)"}),
        (("--index",), {"type": nonneg_int, "default": None, "metavar": "K",
                        "help": "laser log only: just the K-th scan of that laser (from 0; default every scan)"}),
        (("--json",), {"action": "store_true", "help": "print one JSON object (a laser log: one per line)"}),
    ],
)
def _cmd_rows(ns: argparse.Namespace) -> int:
    from ..scanio import ScanFileError, load_scan_csv
    from ..types import Pose2D
    from ..perception import RowParams, check_scan, detect_rows

    if ns.method not in _method_names():
        print(f"agnav rows: unknown method {ns.method!r}; known: {', '.join(_method_names())}", file=sys.stderr)
        return 2
    if _is_log(ns.scan):
        return _rows_on_log(ns)
    if ns.laser_id is not None or ns.index is not None:
        opt = "--laser-id" if ns.laser_id is not None else "--index"
        print(f"agnav rows: {opt} reads a laser log (.alog); {ns.scan} is taken for a scan CSV", file=sys.stderr)
        return 2
    try:
        scan = load_scan_csv(ns.scan)
    except ScanFileError as e:
        print(f"agnav rows: {e}", file=sys.stderr)
        return 2
    x, y, yaw_deg = ns.mount if ns.mount is not None else (0.0, 0.0, 0.0)
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
    else:
        print(_human(ns.method, est, n_usable))
    return 0


def _human(method: str, est: Any, n_usable: int) -> str:
    """The one-line human reading of a row estimate."""
    if not est.valid:
        return (f"method {method}: no rows found ({n_usable} usable returns), confidence 0.00, end of row: "
                f"{'yes' if est.end_of_row else 'no'}")
    return (f"method {method}: offset {est.lateral_offset_m:+.3f} m (+ = robot left of centre), heading "
            f"{math.degrees(est.heading_rad):+.1f} deg (+ = CCW), spacing {est.row_spacing_m:.3f} m, confidence "
            f"{est.confidence:.2f}, end of row: {'yes' if est.end_of_row else 'no'}")


def _is_log(path: str) -> bool:
    """A laser log by its suffix or by its first line (anything else is read as a scan CSV)."""
    from ..lasers.log import SUFFIX, is_laser_log

    return path.lower().endswith(SUFFIX) or is_laser_log(path)


_PROGRESS_MIN_SCANS = 200  # a shorter log needs no progress line
_PROGRESS_EVERY_S = 0.25


def _rows_on_log(ns: argparse.Namespace) -> int:
    """``agnav rows --scan LOG.alog``: the row detection on every scan of one laser, or on scan ``--index``."""
    from ..lasers.log import LaserLogError, laser_log_info, read_laser_log
    from ..types import Pose2D
    from ..perception import RowParams, check_scan, detect_rows

    def fail(msg: str) -> int:
        print(f"agnav rows: {msg}", file=sys.stderr)
        return 2

    try:
        info = laser_log_info(ns.scan)
    except LaserLogError as e:
        return fail(str(e))
    except OSError as e:
        return fail(f"{ns.scan}: cannot read laser log: {e.strerror or e}")
    if info.truncated_bytes:
        print(f"agnav rows: {ns.scan}: ignored a cut-off last record ({info.truncated_bytes} bytes; the run was "
              "stopped mid-write)", file=sys.stderr)
    if not info.lasers:
        print(f"agnav rows: {ns.scan}: the log declares no laser (the run ended before its first scan): nothing "
              "measured", file=sys.stderr)
        return EXIT_NO_RETURNS
    lid = info.first_laser if ns.laser_id is None else ns.laser_id
    if lid not in info.lasers:
        return fail(f"{ns.scan}: --laser-id {lid}: no such laser in the log; it declares "
                    f"{', '.join(str(k) for k in info.lasers)}")
    assert lid is not None
    total = info.scans.get(lid, 0)
    if total == 0:
        print(f"agnav rows: {ns.scan}: laser {lid} has no scans in the log: nothing measured", file=sys.stderr)
        return EXIT_NO_RETURNS
    if ns.index is not None and ns.index >= total:
        return fail(f"{ns.scan}: --index {ns.index}: laser {lid} has {total} scan{'s' if total != 1 else ''} "
                    f"(index 0..{total - 1})")
    params = RowParams(expected_spacing_m=ns.spacing)
    explicit = None
    if ns.mount is not None:
        x, y, yaw_deg = ns.mount
        explicit = Pose2D(x, y, math.radians(yaw_deg))
    want = total if ns.index is None else 1
    # a line that says how far the reading is, while the results go to a file or a pipe
    show_progress = want >= _PROGRESS_MIN_SCANS and sys.stderr.isatty() and not sys.stdout.isatty()
    line = ProgressLine(every_s=_PROGRESS_EVERY_S, wipe=True)
    measured = 0
    try:
        with read_laser_log(ns.scan, lid) as reader:
            for k, rec in enumerate(reader):
                if ns.index is not None and k != ns.index:
                    continue
                scan = rec.scan
                n_usable = int(check_scan(scan, params.scan).sum())
                head = {"index": k, "t_s": rec.t_s}
                if n_usable == 0:
                    if ns.json:
                        print(json.dumps({**head, "lateral_offset_m": None, "heading_rad": None, "row_spacing_m": None,
                                          "confidence": 0.0, "end_of_row": None}))
                    else:
                        print(f"scan {k} t={rec.t_s:.3f} s: no usable return ({len(scan.ranges_m)} beams): nothing "
                              "measured")
                else:
                    measured += 1
                    mount = explicit if explicit is not None else rec.laser.mount.pose
                    est = detect_rows(scan, ns.method, params, mount)
                    if ns.json:
                        print(json.dumps({**head, **{k2: getattr(est, k2) for k2 in _KEYS}}))
                    else:
                        print(f"scan {k} t={rec.t_s:.3f} s: {_human(ns.method, est, n_usable)}")
                if show_progress:
                    line.show(f"agnav rows: scan {k + 1}/{total} ({100 * (k + 1) // total}%)")
                if ns.index is not None:
                    break
    except LaserLogError as e:  # the file changed after the check above
        return fail(str(e))
    except BrokenPipeError:  # the reader of stdout went away: agnav's main() ends quietly
        raise
    except OSError as e:
        return fail(f"{ns.scan}: cannot read laser log: {e.strerror or e}")
    finally:
        line.end()
    if measured == 0:
        which = f"scan {ns.index}" if ns.index is not None else f"none of the {want} scans of laser {lid}"
        print(f"agnav rows: {ns.scan}: no usable return in {which}: nothing measured", file=sys.stderr)
        return EXIT_NO_RETURNS
    return 0
