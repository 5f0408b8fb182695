"""Live view and recordings with rerun-sdk (optional dependency) and matplotlib PNGs.

    rec = Recorder.to_file("out/run.rrd")        # or Recorder.spawn() for a live viewer
    rec.set_time(t_s)
    rec.log_pose(pose); rec.log_sonar(sonar, pose); rec.log_scan(points_world)
    rec.log_plan(path_xy); rec.log_behaviour(behaviour); rec.log_text("...")
    rec.close()

Open a recording with ``rerun out/run.rrd`` (the viewer ships in the rerun-sdk wheel). Entity
paths: ``world/robot`` (pose arrow), ``world/path/<k>`` (driven path, in pieces), ``world/sonar`` (cones),
``world/laser`` (points), ``world/plan`` (planner path), ``world/goal``, ``behaviour/layer`` and
``behaviour/reason`` (scalars over time), ``behaviour/flags``, ``log`` (text).

When rerun is not installed :func:`require_rerun` raises :class:`VizUnavailable` naming the pip
command; nothing else in AgNav needs it.
"""

from .recorder import Recorder, VizUnavailable, record_tlog, require_rerun

__all__ = ["Recorder", "VizUnavailable", "require_rerun", "record_tlog"]
