"""Obstacles: clustering of scan points into objects, and tracking them across scans.

Clustering splits the beam-ordered points wherever two consecutive returns are more than
``gap_m`` apart. A cluster's size (radius) is half its end-to-end extent; its centre lies on the
bearing of the points' mean, one radius beyond the nearest point (a laser sees only the near side of
a round object, so the plain mean of its points sits in front of the centre).

Tracks are constant-velocity Kalman filters in the world frame (state x, y, vx, vy), associated to
clusters by nearest neighbour within a Mahalanobis gate. :class:`Track` is the small typed record the
planners consume.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..types import FloatArray, LaserScan, Pose2D, ScanXY
from ._scan import ScanParams, points_from_scan

__all__ = ["Cluster", "cluster_points", "clusters_from_scan", "Track", "TrackerParams", "ObstacleTracker"]


@dataclass(frozen=True)
class Cluster:
    """One object in one scan: centre (m), radius (m), point count, in the frame of the points."""

    x_m: float
    y_m: float
    radius_m: float
    n_points: int


def cluster_points(xy: ScanXY, sensor_xy: tuple[float, float] = (0.0, 0.0), gap_m: float = 0.2,
                   min_points: int = 2, max_radius_m: float = 1.5) -> list[Cluster]:
    """Split beam-ordered points (k, 2) into clusters (module docstring); clusters with fewer than
    ``min_points`` points or a radius above ``max_radius_m`` (walls, rows) are dropped."""
    if len(xy) == 0:
        return []
    d = np.hypot(np.diff(xy[:, 0]), np.diff(xy[:, 1]))
    cuts = np.flatnonzero(d > gap_m) + 1
    out = []
    for part in np.split(xy, cuts):
        if len(part) < min_points:
            continue
        r = 0.5 * float(np.hypot(*(part[-1] - part[0])))
        r = max(r, 0.5 * float(np.max(np.hypot(part[:, 0] - part[0, 0], part[:, 1] - part[0, 1]))))
        if r > max_radius_m:
            continue
        m = part.mean(axis=0)
        u = m - np.asarray(sensor_xy)
        nu = float(np.hypot(*u))
        near = float(np.min(np.hypot(part[:, 0] - sensor_xy[0], part[:, 1] - sensor_xy[1])))
        c = np.asarray(sensor_xy) + (near + r) / nu * u if nu > 1e-9 else m
        out.append(Cluster(float(c[0]), float(c[1]), r, len(part)))
    return out


def clusters_from_scan(scan: LaserScan, gap_m: float = 0.2, min_points: int = 2, max_radius_m: float = 1.5,
                       world: bool = True) -> list[Cluster]:
    """Clusters of a scan, in the world frame when the scan carries its pose (and ``world``), else the sensor frame."""
    pose = scan.pose if (world and scan.pose is not None) else Pose2D()
    pts = points_from_scan(scan, pose, ScanParams())
    return cluster_points(pts.xy, (pose.x_m, pose.y_m), gap_m, min_points, max_radius_m)


@dataclass(frozen=True)
class Track:
    """A tracked obstacle: position (m), velocity (m/s), radius (m) in the world frame; ``speed_sigma_m_s``
    is the 1-sigma uncertainty of the speed; ``covariance`` the 4 x 4 of (x, y, vx, vy)."""

    id: int
    x_m: float
    y_m: float
    vx_m_s: float
    vy_m_s: float
    radius_m: float
    speed_sigma_m_s: float
    covariance: tuple[tuple[float, ...], ...]
    age_s: float
    hits: int

    @property
    def speed_m_s(self) -> float:
        return math.hypot(self.vx_m_s, self.vy_m_s)

    @property
    def moving(self) -> bool:
        """Speed more than twice its uncertainty and above 0.1 m/s."""
        return self.speed_m_s > max(0.1, 2.0 * self.speed_sigma_m_s)


@dataclass(frozen=True)
class TrackerParams:
    gate_sigma: float = 3.5  # Mahalanobis gate
    max_gate_m: float = 1.0
    accel_std_m_s2: float = 1.0  # process noise of the constant-velocity model
    meas_std_m: float = 0.05
    max_misses: int = 5
    confirm_hits: int = 3
    cluster_gap_m: float = 0.2
    max_radius_m: float = 1.0


class _KF:
    def __init__(self, x: float, y: float, r: float, t: float, tid: int, meas_std: float) -> None:
        self.x = np.array([x, y, 0.0, 0.0])
        self.P = np.diag([meas_std**2, meas_std**2, 1.0, 1.0])
        self.r, self.t0, self.t, self.id = r, t, t, tid
        self.hits, self.misses = 1, 0

    def predict(self, t: float, q: float) -> None:
        dt = max(0.0, t - self.t)
        self.t = t
        F = np.eye(4)
        F[0, 2] = F[1, 3] = dt
        g = np.array([[0.5 * dt * dt, 0.0], [0.0, 0.5 * dt * dt], [dt, 0.0], [0.0, dt]])
        self.x = F @ self.x
        self.P = F @ self.P @ F.T + g @ g.T * q * q

    def update(self, z: FloatArray, r: float, R: FloatArray) -> None:
        H = np.zeros((2, 4))
        H[0, 0] = H[1, 1] = 1.0
        S = H @ self.P @ H.T + R
        K = self.P @ H.T @ np.linalg.inv(S)
        self.x = self.x + K @ (z - H @ self.x)
        self.P = (np.eye(4) - K @ H) @ self.P
        self.r = 0.7 * self.r + 0.3 * r
        self.hits += 1
        self.misses = 0


class ObstacleTracker:
    """Multi-object tracker over laser scans (module docstring). ``update(scan)`` returns the confirmed tracks."""

    def __init__(self, params: TrackerParams | None = None) -> None:
        self.params = params or TrackerParams()
        self.reset()

    def reset(self) -> None:
        self._tracks: list[_KF] = []
        self._next = 1

    def update(self, scan: LaserScan, t_s: float | None = None) -> list[Track]:
        p = self.params
        t = scan.stamp_s if t_s is None else t_s
        cl = clusters_from_scan(scan, p.cluster_gap_m, 2, p.max_radius_m)
        return self.update_clusters(cl, t)

    def update_clusters(self, clusters: list[Cluster], t_s: float) -> list[Track]:
        p = self.params
        for tr in self._tracks:
            tr.predict(t_s, p.accel_std_m_s2)
        R = np.eye(2) * p.meas_std_m**2
        used = set()
        # greedy nearest-neighbour association, best pairs first
        pairs = []
        for i, tr in enumerate(self._tracks):
            S = tr.P[:2, :2] + R
            Si = np.linalg.inv(S)
            for j, c in enumerate(clusters):
                dz = np.array([c.x_m, c.y_m]) - tr.x[:2]
                if float(np.hypot(*dz)) > p.max_gate_m:
                    continue
                m2 = float(dz @ Si @ dz)
                if m2 <= p.gate_sigma**2:
                    pairs.append((m2, i, j))
        done_t = set()
        for _, i, j in sorted(pairs):
            if i in done_t or j in used:
                continue
            c = clusters[j]
            self._tracks[i].update(np.array([c.x_m, c.y_m]), c.radius_m, R)
            done_t.add(i)
            used.add(j)
        for i, tr in enumerate(self._tracks):
            if i not in done_t:
                tr.misses += 1
        self._tracks = [tr for tr in self._tracks if tr.misses <= p.max_misses]
        for j, c in enumerate(clusters):
            if j not in used:
                self._tracks.append(_KF(c.x_m, c.y_m, c.radius_m, t_s, self._next, p.meas_std_m))
                self._next += 1
        return self.tracks()

    def tracks(self, confirmed_only: bool = True) -> list[Track]:
        out = []
        for tr in self._tracks:
            if confirmed_only and tr.hits < self.params.confirm_hits:
                continue
            P = tr.P
            v = tr.x[2:]
            sp = float(np.hypot(*v))
            # speed variance along the velocity direction (isotropic fallback when at rest)
            u = v / sp if sp > 1e-6 else np.array([1.0, 0.0])
            sig = math.sqrt(max(float(u @ P[2:, 2:] @ u), 0.0)) if sp > 1e-6 else math.sqrt(max(float(np.trace(P[2:, 2:])) / 2, 0.0))
            out.append(Track(tr.id, float(tr.x[0]), float(tr.x[1]), float(v[0]), float(v[1]), float(tr.r), sig,
                             tuple(tuple(float(a) for a in row) for row in P), tr.t - tr.t0, tr.hits))
        return out
