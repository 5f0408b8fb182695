"""The host-side loop around :class:`~.pose_filter.PoseFilter`: odometry reports in, laser scans in,
the pose for the planner out."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping

from ..types import FloatArray, Pose2D
from .landmarks import LandmarkMap, landmarks_from_meta, sight_posts
from .pose_filter import FilterParams, PoseFilter

__all__ = ["PostLocaliser", "localiser_for"]


@dataclass
class PostLocaliser:
    """Odometry (in the firmware's frame, which starts at ``start``) fused with post sightings.

    :meth:`odometry` takes each report, :meth:`scan` each laser scan (ranges and beam angles in the
    laser frame; the laser sits at ``mount`` on the robot), :meth:`pose_at` gives the estimate at a
    time. ``gate_m``: how far from its predicted place a post's returns may be."""

    start: Pose2D
    posts: LandmarkMap
    mount: Pose2D = Pose2D()
    params: FilterParams | None = None
    gate_m: float = 0.3

    def __post_init__(self) -> None:
        self.filter = PoseFilter(self.start, self.posts, self.mount, self.params)
        self.sighted = 0

    def odometry(self, x_m: float, y_m: float, yaw_rad: float, stamp_s: float, speed_m_s: float, yaw_rate_rad_s: float) -> None:
        """One odometry report, pose in the firmware's frame (origin at ``start``). The first report,
        wherever it is, places the estimate at ``start`` (+) that pose; see :meth:`PoseFilter.odometry`."""
        self.filter.odometry(Pose2D(x_m, y_m, yaw_rad), stamp_s, speed_m_s, yaw_rate_rad_s)

    def scan(self, ranges_m: FloatArray, angles_rad: FloatArray, t_s: float, range_max_m: float = math.inf) -> int:
        """Correct with one scan taken at ``t_s``; returns the number of posts used."""
        sensor = self.filter.pose_at(t_s).compose(self.mount)
        seen = sight_posts(ranges_m, angles_rad, sensor, self.posts, range_max_m=range_max_m, gate_m=self.gate_m)
        used = self.filter.sightings(seen, t_s)
        self.sighted += used
        return used

    def pose_at(self, t_s: float) -> Pose2D:
        return self.filter.pose_at(t_s)


def localiser_for(meta: Mapping[str, Any], start: Pose2D, mount: Pose2D) -> PostLocaliser | None:
    """A :class:`PostLocaliser` when the scenario lists surveyed posts (``meta.landmarks``), else None."""
    posts = landmarks_from_meta(meta)
    if posts is None:
        return None
    return PostLocaliser(start, posts, mount)
