"""Helpers of the SLAM tests: a small simulated building, a drive round it with drifting odometry, and the
logs of that drive (CARMEN text, AgNav laser log)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from agnav_host.sim import cast_rays

# a 24 x 14 m hall with a 16 x 6 m block in the middle (a loop round it), and posts and crates along the way
WALLS = np.array([
    [0, 0, 24, 0], [24, 0, 24, 14], [24, 14, 0, 14], [0, 14, 0, 0],
    [4, 4, 20, 4], [20, 4, 20, 10], [20, 10, 4, 10], [4, 10, 4, 4],
    [8, 0, 8, 1.2], [15, 14, 15, 12.5], [22, 6, 24, 6], [0, 8, 1.5, 8], [11, 4, 11, 3.0],
    [17, 10, 17.8, 11], [6, 12.5, 7, 12.5],
], dtype=float)
POSTS = np.array([[1, 1, 0.15], [14, 3.3, 0.15], [23, 1, 0.15], [23, 13, 0.2], [9, 13.2, 0.15], [1, 13, 0.2]])
N_BEAMS = 181


def drive(step_m: float = 0.25, laps: float = 1.25) -> np.ndarray:
    """True poses (n, 3) of a drive round the block, 2 m from the outer walls, anticlockwise."""
    corners = np.array([[2.0, 2.0], [22.0, 2.0], [22.0, 12.0], [2.0, 12.0]])
    pts = []
    seg_len = np.hypot(*np.diff(np.vstack([corners, corners[:1]]), axis=0).T)
    total = laps * seg_len.sum()
    s = 0.0
    while s < total:
        u = s % seg_len.sum()
        k = 0
        while u > seg_len[k]:
            u -= seg_len[k]
            k += 1
        a, b = corners[k], corners[(k + 1) % 4]
        d = (b - a) / seg_len[k]
        p = a + d * u
        pts.append([p[0], p[1], math.atan2(d[1], d[0])])
        s += step_m
    poses = np.array(pts)
    # round the corners' heading: the mean of the headings around each pose
    c, sn = np.cos(poses[:, 2]), np.sin(poses[:, 2])
    kern = np.ones(5) / 5
    poses[:, 2] = np.arctan2(np.convolve(sn, kern, "same"), np.convolve(c, kern, "same"))
    return poses


def scan_at(pose: np.ndarray, rng: np.random.Generator, max_range_m: float = 30.0) -> np.ndarray:
    r = cast_rays(pose[0], pose[1], pose[2], -math.pi / 2, math.pi / (N_BEAMS - 1), N_BEAMS, max_range_m, WALLS,
                  POSTS)
    r = r + rng.normal(0.0, 0.01, r.shape)
    r[~np.isfinite(r)] = 81.9  # a SICK's "no return"
    return r


def drifting_odometry(truth: np.ndarray, rng: np.random.Generator, yaw_bias_rad_m: float = math.radians(1.0)
                      ) -> np.ndarray:
    """Odometry of the drive: each step's increment with 2 % scale error, noise and a yaw bias per metre."""
    odo = [truth[0].copy()]
    for a, b in zip(truth[:-1], truth[1:]):
        c, s = math.cos(a[2]), math.sin(a[2])
        dx, dy = b[0] - a[0], b[1] - a[1]
        lx, ly = c * dx + s * dy, -s * dx + c * dy
        dth = math.remainder(b[2] - a[2], 2 * math.pi)
        d = math.hypot(lx, ly)
        lx, ly = 1.02 * lx + rng.normal(0, 0.005), ly + rng.normal(0, 0.005)
        dth = dth + yaw_bias_rad_m * d + rng.normal(0, 0.002)
        p = odo[-1]
        c, s = math.cos(p[2]), math.sin(p[2])
        odo.append(np.array([p[0] + c * lx - s * ly, p[1] + s * lx + c * ly, math.remainder(p[2] + dth, 2 * math.pi)]))
    return np.array(odo)


def carmen_lines(truth: np.ndarray, odom: np.ndarray, seed: int = 1, t0: float = 1031745824.658) -> list[str]:
    """FLASER lines of the drive (181 beams, 1 deg), 0.5 s apart, with the odometry as laser and robot pose."""
    rng = np.random.default_rng(seed)
    out = []
    for k, (p, o) in enumerate(zip(truth, odom)):
        r = scan_at(p, rng)
        t = t0 + 0.5 * k
        pose = f"{o[0]:.6f} {o[1]:.6f} {o[2]:.6f}"
        out.append(f"FLASER {N_BEAMS} " + " ".join(f"{v:.2f}" for v in r) + f" {pose} {pose} {t:.6f} host {k * 0.5:.6f}")
    return out


def write_carmen(path: Path, lines: list[str], header: bool = True) -> Path:
    text = ("# CARMEN Logfile\nPARAM robot_front_laser_max 81.9 host 0.0\n" if header else "") + "\n".join(lines) + "\n"
    path.write_text(text, encoding="utf-8")
    return path


def write_alog(path: Path, truth: np.ndarray, odom: np.ndarray, seed: int = 1) -> Path:
    """The drive as an AgNav laser log: one laser, the odometry as each scan's pose, stamps 0.5 s apart."""
    from agnav_host.lasers.base import LaserMount
    from agnav_host.lasers.log import LaserLogWriter
    from agnav_host.types import LaserScan, Pose2D

    rng = np.random.default_rng(seed)
    with LaserLogWriter(path) as w:
        tmpl = LaserScan(-math.pi / 2, math.pi / (N_BEAMS - 1), np.ones(N_BEAMS), 30.0)
        w.declare(0, "sim:", "sim", "sim", LaserMount(), tmpl)
        for k, (p, o) in enumerate(zip(truth, odom)):
            r = scan_at(p, rng)
            r[r > 30.0] = np.nan
            w.write(0, LaserScan(-math.pi / 2, math.pi / (N_BEAMS - 1), r, 30.0, 0.5 * k), 0.5 * k,
                    Pose2D(o[0], o[1], o[2]))
    return path


def relations_of(truth: np.ndarray, times: np.ndarray, pairs: list[tuple[int, int]]) -> str:
    """Relation-file text: the true motion between the poses of each pair, in the first one's frame."""
    rows = []
    for i, j in pairs:
        a, b = truth[i], truth[j]
        c, s = math.cos(a[2]), math.sin(a[2])
        dx, dy = b[0] - a[0], b[1] - a[1]
        rows.append(f"{times[i]:.6f} {times[j]:.6f} {c * dx + s * dy:.6f} {-s * dx + c * dy:.6f} 0 0 0 "
                    f"{math.remainder(b[2] - a[2], 2 * math.pi):.6f}")
    return "\n".join(rows) + "\n"
