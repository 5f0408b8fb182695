"""Localisation for the host: wheel odometry fused with laser sightings of surveyed marker posts.

The firmware's odometry (one Hall sensor on the rear axle, the steering angle) drifts with wheel
slip, tick quantisation and steering error: a few degrees of heading and tens of centimetres over a
10 m run. A real field robot corrects it against something fixed; here that is a set of marker posts
(thin poles at surveyed positions, ``meta.landmarks`` of a scenario) that the laser sees.

* :mod:`.landmarks`: the post map and pure functions that find the posts in a scan (range and
  bearing of each post's centre from the sensor);
* :mod:`.pose_filter`: :class:`PoseFilter`, an extended Kalman filter over the planar pose that
  moves with the odometry increments, extrapolates over the odometry's latency, and is corrected by
  the post sightings.

Laser SLAM offline (``agnav slam``): :mod:`.slam` (scan-matching odometry fused with the wheel odometry, loop
closure on a pose graph) with :mod:`.scan_match`, :mod:`.pose_graph`, :mod:`.occupancy` (map_server maps),
:mod:`.carmen` and :mod:`.slam_io` (the logs), :mod:`.relations` (the relative-pose score) and :mod:`.killian`.

See ``docs/localisation.md`` for the approach and its limits.
"""

from .landmarks import LandmarkMap, PostSighting, landmarks_from_meta, sight_posts
from .pose_filter import FilterParams, PoseFilter, compose, extrapolate, relative
from .post_localiser import PostLocaliser, localiser_for

__all__ = ["LandmarkMap", "PostSighting", "landmarks_from_meta", "sight_posts", "FilterParams", "PoseFilter",
           "compose", "extrapolate", "relative", "PostLocaliser", "localiser_for"]
