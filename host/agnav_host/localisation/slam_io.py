"""The files of ``agnav slam``.

Input: :func:`read_slam_log` reads AgNav laser logs (``.alog``, :mod:`agnav_host.lasers.log`; the robot's
believed pose of each scan is its odometry) and CARMEN logs (:mod:`.carmen`, also inside a zip archive) as
:class:`~.slam.SlamScan` records; which one a file is, is told from its first bytes.

Output: :func:`write_slam_outputs` writes ``trajectory.csv`` (``t,x,y,yaw``: one row per scan, ``t`` the scan's
time as written in the log, x and y in m, yaw in rad), the occupancy grid as ``map.pgm`` + ``map.yaml``
(:mod:`.occupancy`, ROS map_server's format) and ``map.png``, the map with the trajectory drawn on it.
"""

from __future__ import annotations

import math
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..types import FloatArray
from .carmen import CarmenLogError, looks_like_carmen, read_carmen_log
from .occupancy import OccupancyGrid, map_picture, occupancy_from_scans, save_map
from .slam import SlamResult, SlamScan

__all__ = ["SlamLogError", "SlamLog", "read_slam_log", "write_trajectory", "read_trajectory", "write_slam_outputs",
           "OUTPUT_FILES"]

#: The files :func:`write_slam_outputs` writes in its folder
OUTPUT_FILES = ("trajectory.csv", "map.pgm", "map.yaml", "map.png")


class SlamLogError(ValueError):
    """A log that ``agnav slam`` cannot use; the message names the file and says why."""


@dataclass(frozen=True)
class SlamLog:
    """The scans of a log in time order, its format (``alog`` / ``carmen``), one line saying what was read
    (scans, skipped and ignored lines, the odometry's source) and the count of skipped lines or records."""

    scans: list[SlamScan]
    format: str
    summary: str
    skipped: int


def _head(p: Path) -> bytes:
    if zipfile.is_zipfile(p):
        with zipfile.ZipFile(p) as zf:
            names = [n for n in zf.namelist() if not n.endswith("/") and "__MACOSX" not in n]
            if len(names) != 1:
                raise SlamLogError(f"{p}: a zip archive must hold one log, this one holds {len(names)} files")
            with zf.open(names[0]) as f:
                return f.read(4096)
    with open(p, "rb") as f:
        return f.read(4096)


def _read_alog(p: Path, laser_id: int | None) -> SlamLog:
    from ..lasers.log import LaserLogError, laser_log_info, read_laser_log

    try:
        info = laser_log_info(p)
    except LaserLogError as e:
        raise SlamLogError(str(e)) from None
    if not info.lasers:
        raise SlamLogError(f"{p}: the laser log declares no laser (the run ended before its first scan)")
    lid = info.first_laser if laser_id is None else laser_id
    if lid not in info.lasers:
        raise SlamLogError(f"{p}: no laser {laser_id} in the log (it has {', '.join(map(str, info.lasers))})")
    scans: list[SlamScan] = []
    last_t = -math.inf
    unordered = 0
    try:
        with read_laser_log(p, lid) as reader:
            for rec in reader:
                if rec.t_s < last_t:
                    unordered += 1
                    continue
                last_t = rec.t_s
                m = rec.laser.mount
                sc = rec.scan
                odom = None if rec.pose is None else np.array([rec.pose.x_m, rec.pose.y_m, rec.pose.yaw_rad])
                if odom is not None and not np.all(np.isfinite(odom)):
                    odom = None
                scans.append(SlamScan(rec.t_s, repr(rec.t_s), sc.angle_min_rad, sc.angle_increment_rad,
                                      np.asarray(sc.ranges_m, dtype=float), float(sc.range_max_m),
                                      np.array([m.x_m, m.y_m, m.yaw_rad]), odom))
    except LaserLogError as e:
        raise SlamLogError(str(e)) from None
    if not scans:
        raise SlamLogError(f"{p}: laser {lid} has no scan in the log")
    parts = [f"{len(scans)} scans of laser {lid}"]
    no_odom = sum(1 for s in scans if s.odom is None)
    if no_odom:
        parts.append(f"{no_odom} without a pose (odometry)")
    parts.append("odometry from the logged poses")
    if unordered:
        parts.append(f"skipped {unordered} scans stamped before the scan ahead of them")
    if info.truncated_bytes:
        parts.append(f"ignored a cut-off last record ({info.truncated_bytes} bytes)")
    return SlamLog(scans, "alog", "; ".join(parts), unordered)


def read_slam_log(path: str | Path, laser_id: int | None = None) -> SlamLog:
    """Read ``path`` (an AgNav laser log or a CARMEN log). ``laser_id``: the laser of an AgNav log (default:
    the first declared). Raises OSError when the file cannot be read, :class:`SlamLogError` when it is no
    log of either kind or holds no usable scan."""
    from ..lasers.log import MAGIC

    p = Path(path)
    if p.is_dir():
        raise SlamLogError(f"{p}: is a folder, not a log")
    head = _head(p)
    if head.startswith(MAGIC[:18]):
        return _read_alog(p, laser_id)
    if not looks_like_carmen(head):
        what = "empty" if not head else "neither an AgNav laser log (.alog) nor a CARMEN log"
        raise SlamLogError(f"{p}: {what}")
    try:
        log = read_carmen_log(p)
    except CarmenLogError as e:
        raise SlamLogError(str(e)) from None
    scans: list[SlamScan] = []
    unordered = 0
    last_t = -math.inf
    tag = log.scans[0].tag  # one laser: the first scan's
    other = sum(1 for s in log.scans if s.tag != tag)
    for s in log.scans:
        if s.tag != tag:
            continue
        if s.t_s < last_t:
            unordered += 1
            continue
        last_t = s.t_s
        odom = None if s.odom is None else np.array([s.odom.x_m, s.odom.y_m, s.odom.yaw_rad])
        scans.append(SlamScan(s.t_s, s.t_text, s.angle_min_rad, s.angle_increment_rad, s.ranges_m, s.range_max_m,
                              np.array([s.mount.x_m, s.mount.y_m, s.mount.yaw_rad]), odom))
    summary = log.summary()
    if other:
        summary += f"; used the {tag} scans, not the {other} of other lasers"
    if unordered:
        summary += f"; skipped {unordered} scans stamped before the scan ahead of them"
    return SlamLog(scans, "carmen", summary, log.skipped + unordered)


def write_trajectory(path: str | Path, t_text: list[str], poses: FloatArray) -> None:
    """``t,x,y,yaw`` and one row per pose (``t_text`` as given; m, m, rad)."""
    with open(path, "w", encoding="utf-8", newline="\n") as f:
        f.write("t,x,y,yaw\n")
        for t, (x, y, yaw) in zip(t_text, np.asarray(poses, dtype=float).reshape(-1, 3)):
            f.write(f"{t},{x:.6f},{y:.6f},{yaw:.6f}\n")


def read_trajectory(path: str | Path) -> tuple[FloatArray, FloatArray]:
    """The times (n,) and poses (n, 3) of a ``trajectory.csv``. Raises OSError or ValueError."""
    rows = Path(path).read_text(encoding="utf-8").splitlines()
    if not rows or rows[0].strip() != "t,x,y,yaw":
        raise ValueError(f"{path}: not a trajectory (the first line is not 't,x,y,yaw')")
    a = np.array([[float(v) for v in r.split(",")] for r in rows[1:] if r.strip()]).reshape(-1, 4)
    return a[:, 0], a[:, 1:]


def write_slam_outputs(result: SlamResult, out: str | Path, resolution_m: float = 0.05) -> tuple[Path, ...]:
    """Write the files of :data:`OUTPUT_FILES` for ``result`` into the folder ``out`` (made if missing); the
    grid has cells of ``resolution_m``. Returns their paths. Raises OSError when a file cannot be written."""
    import cv2

    d = Path(out)
    d.mkdir(parents=True, exist_ok=True)
    traj = d / OUTPUT_FILES[0]
    write_trajectory(traj, result.t_text, result.poses)
    grid: OccupancyGrid = occupancy_from_scans(result.poses, result.points, result.origins, resolution_m)
    yaml_path, pgm_path = save_map(grid, d / OUTPUT_FILES[2], OUTPUT_FILES[1])
    png = d / OUTPUT_FILES[3]
    if not cv2.imwrite(str(png), map_picture(grid, result.poses[:, :2])):
        raise OSError(f"cannot write {png}")
    return traj, pgm_path, yaml_path, png
