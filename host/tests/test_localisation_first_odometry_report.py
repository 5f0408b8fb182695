"""The localisers (pose filter, post localiser) use the first odometry report, composed on the start pose."""

from __future__ import annotations

import math

import numpy as np
import pytest

from agnav_host.localisation import LandmarkMap, PoseFilter, PostLocaliser
from agnav_host.types import Pose2D


def test_pose_filter_uses_the_first_odometry_report() -> None:
    start = Pose2D(1.0, 2.0, math.pi / 2)
    f = PoseFilter(start, None)
    f.odometry(Pose2D(1.0, 0.0, math.pi / 2), 2.0, 0.0, 0.0)
    want = start.compose(Pose2D(1.0, 0.0, math.pi / 2))
    assert (f.pose.x_m, f.pose.y_m, f.pose.yaw_rad) == pytest.approx((want.x_m, want.y_m, want.yaw_rad), abs=1e-9)
    f.odometry(Pose2D(2.0, 0.0, math.pi / 2), 3.0, 0.0, 0.0)
    want = start.compose(Pose2D(2.0, 0.0, math.pi / 2))
    assert (f.pose.x_m, f.pose.y_m, f.pose.yaw_rad) == pytest.approx((want.x_m, want.y_m, want.yaw_rad), abs=1e-9)


@pytest.mark.parametrize("start", [Pose2D(0.0, 0.0, 0.0), Pose2D(-1.0, 3.0, 0.7)])
def test_post_localiser_uses_the_first_odometry_report(start: Pose2D) -> None:
    loc = PostLocaliser(start, LandmarkMap(np.array([[10.0, 10.0]]), np.array([0.05])))
    loc.odometry(1.0, 0.0, math.pi / 2, stamp_s=2.0, speed_m_s=0.0, yaw_rate_rad_s=0.0)
    p, want = loc.pose_at(2.0), start.compose(Pose2D(1.0, 0.0, math.pi / 2))
    assert (p.x_m, p.y_m, p.yaw_rad) == pytest.approx((want.x_m, want.y_m, want.yaw_rad), abs=1e-9)
    loc.odometry(2.0, 0.0, math.pi / 2, stamp_s=3.0, speed_m_s=0.0, yaw_rate_rad_s=0.0)
    p, want = loc.pose_at(3.0), start.compose(Pose2D(2.0, 0.0, math.pi / 2))
    assert (p.x_m, p.y_m, p.yaw_rad) == pytest.approx((want.x_m, want.y_m, want.yaw_rad), abs=1e-9)
