"""Pictures of a run in its world (matplotlib): the world's objects, the start and the goals, the path coloured
by speed and the robot's outline along it.

    ax = plt.subplots()[1]
    draw_world(ax, scenario)                   # walls, boxes, posts, plants, holes, ruts, movers, ...
    draw_goals(ax, scenario.goals, scenario.start)
    draw_run(ax, rows, Footprint.of_scenario(scenario))

:func:`run_figure` does all three with a colour bar and a legend; :func:`plot_run` writes that as a PNG
(``agnav sim``'s and ``agnav run``'s ``trajectory.png``). ``rows`` are trajectory samples in
``sim.runner.TRAJECTORY_COLUMNS`` order (t_s, x_m, y_m, yaw_rad, speed_m_s, ...). Every artist drawn carries its
kind as its ``gid`` (``wall``, ``box``, ``plant``, ``path``, ``footprint``, ``goal``, ...), so a test or a caller
can find what was drawn.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Iterable, Sequence

import numpy as np
import numpy.typing as npt

from ..atomic import savefig_atomic
from ..types import FloatArray, Goal, Pose2D

if TYPE_CHECKING:
    from ..planning.base import RobotSpec
    from ..sim.scenario import Scenario
    from ..sim.world import World

__all__ = ["Footprint", "RunArtists", "world_extent", "draw_world", "draw_goals", "draw_run", "run_figure", "plot_run",
           "footprint_times", "rows_from_poses", "KIND_LABELS"]

#: Legend text of each kind of object :func:`draw_world` draws.
KIND_LABELS = {
    "wall": "wall",
    "box": "box",
    "polygon": "obstacle (polygon)",
    "post": "post / obstacle",
    "plant": "plants",
    "row_line": "row design line",
    "weed": "weeds",
    "mover": "person's path (o: at start, filled: at the end)",
    "hole": "hole",
    "step_up": "raised ground (step)",
    "step_down": "lowered ground (step)",
    "rut": "rut",
    "landmark": "surveyed post (localisation)",
    "given_path": "given path",
}

_STYLE: dict[str, dict[str, Any]] = {
    "wall": dict(color="black", lw=1.6),
    "box": dict(fc="0.55", ec="black", lw=0.8),
    "polygon": dict(fc="0.7", ec="black", lw=0.8),
    "post": dict(fc="0.25", ec="black", lw=0.4),
    "plant": dict(fc="#2e8b57", ec="none"),
    "row_line": dict(color="#2e8b57", lw=0.8, ls=":"),
    "weed": dict(fc="#9acd32", ec="none"),
    "mover": dict(color="#8a2be2", lw=1.0, ls="--"),
    "hole": dict(fc="#5b3a1e", ec="black", lw=0.6, alpha=0.75),
    "step_up": dict(fc="#d2b48c", ec="#8b5a2b", lw=1.2, alpha=0.55, hatch="//"),
    "step_down": dict(fc="#8b5a2b", ec="#5b3a1e", lw=1.2, alpha=0.45, hatch="\\\\"),
    "rut": dict(fc="#a0522d", ec="none", alpha=0.45),
    "landmark": dict(color="red", marker="o", mfc="none", ms=9, ls="none", mew=1.2),
    "given_path": dict(color="0.45", lw=1.0, ls="--"),
}
_AREAS = {"box", "polygon", "post", "plant", "weed", "hole", "step_up", "step_down", "rut"}


@dataclass(frozen=True)
class Footprint:
    """The robot's outline in plan: a circle (``radius_m``) or a rectangle (``length_m`` x ``width_m``), centred
    ``offset_m`` ahead of the pose's reference point (Ackermann: the rear axle's centre)."""

    shape: str = "circle"
    radius_m: float = 0.225
    length_m: float = 0.0
    width_m: float = 0.0
    offset_m: float = 0.0

    @staticmethod
    def of_params(params: Any) -> "Footprint":
        """From the simulator's robot parameters: a differential drive is its footprint circle; an Ackermann car
        the rectangle of its wheels, tyre to tyre (wheelbase plus one wheel diameter) by the track, centred half
        a wheelbase ahead of the rear axle."""
        from ..sim.robots import AckermannParams

        if isinstance(params, AckermannParams):
            return Footprint("rectangle", params.radius_m, params.wheelbase_m + 2.0 * params.wheel_radius_m,
                             params.track_m, 0.5 * params.wheelbase_m)
        return Footprint("circle", float(params.radius_m))

    @staticmethod
    def of_scenario(sc: "Scenario") -> "Footprint":
        return Footprint.of_params(sc.robot_params)

    @staticmethod
    def of_spec(spec: "RobotSpec") -> "Footprint":
        """From a planner's robot description: a differential drive is its disc; an Ackermann car a rectangle the
        track wide that fills the footprint disc (the wheelbase long when the disc is narrower than the track)."""
        if spec.kinematics == "ackermann":
            half_w = 0.5 * spec.track_m
            length = 2.0 * math.sqrt(spec.radius_m ** 2 - half_w ** 2) if spec.radius_m > half_w else spec.wheelbase_m
            return Footprint("rectangle", spec.radius_m, length, spec.track_m, spec.footprint_offset_m)
        return Footprint("circle", spec.radius_m, offset_m=spec.footprint_offset_m)

    def outline(self, x_m: float, y_m: float, yaw_rad: float, n: int = 32) -> FloatArray:
        """Closed outline (k, 2) in m at the pose (x, y, yaw)."""
        c, s = math.cos(yaw_rad), math.sin(yaw_rad)
        cx, cy = x_m + self.offset_m * c, y_m + self.offset_m * s
        if self.shape == "rectangle":
            hx, hy = 0.5 * self.length_m, 0.5 * self.width_m
            local = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])
        else:
            a = np.linspace(0.0, 2.0 * math.pi, n, endpoint=False)
            local = self.radius_m * np.column_stack((np.cos(a), np.sin(a)))
        outline: FloatArray = local @ np.array([[c, s], [-s, c]]) + (cx, cy)
        return outline

    def front_m(self) -> float:
        """Distance from the outline's centre to its front, m."""
        return 0.5 * self.length_m if self.shape == "rectangle" else self.radius_m


def _pyplot() -> Any:
    """pyplot on the Agg backend; RuntimeError naming the package when matplotlib is missing."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise RuntimeError("plots need matplotlib: .venv/bin/pip install matplotlib") from None
    return plt


def _proxy(ax: Any, kind: str, label: str | None = None) -> None:
    """A legend entry for ``kind`` that draws nothing and leaves the data limits alone."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Rectangle

    st = _STYLE[kind]
    text = label or KIND_LABELS[kind]
    if kind in _AREAS:
        ax.add_patch(Rectangle((0.0, 0.0), 0.0, 0.0, label=text,
                               **{k: v for k, v in st.items() if k in ("fc", "ec", "lw", "alpha", "hatch")}))
    else:
        ax.add_line(Line2D([], [], label=text, **st))


def _circles(ax: Any, circ: FloatArray, kind: str) -> None:
    from matplotlib.collections import EllipseCollection

    st = _STYLE[kind]
    d = 2.0 * circ[:, 2]
    coll = EllipseCollection(d, d, np.zeros(len(d)), units="xy", offsets=circ[:, :2], offset_transform=ax.transData,
                             facecolors=st["fc"], edgecolors=st["ec"], linewidths=st.get("lw", 0.0))
    coll.set_gid(kind)
    ax.add_collection(coll, autolim=False)


def _patches(ax: Any, polys: list[FloatArray], kind: str, zorder: float = 1.0) -> None:
    from matplotlib.collections import PatchCollection
    from matplotlib.patches import Polygon

    st = _STYLE[kind]
    coll = PatchCollection([Polygon(p, closed=True) for p in polys], match_original=False, facecolors=st["fc"],
                           edgecolors=st["ec"], linewidths=st.get("lw", 0.0), alpha=st.get("alpha"),
                           hatch=st.get("hatch"), zorder=zorder)
    coll.set_gid(kind)
    ax.add_collection(coll, autolim=False)


def _offset_line(points: FloatArray, off: float) -> FloatArray:
    """The polyline moved ``off`` m to its left (vertex normals)."""
    p = np.asarray(points, dtype=float)
    tan = np.gradient(p, axis=0) if len(p) > 2 else np.repeat(np.diff(p, axis=0), len(p), axis=0)
    tan = tan / np.maximum(np.hypot(tan[:, 0], tan[:, 1]), 1e-12)[:, None]
    return p + off * np.column_stack((-tan[:, 1], tan[:, 0]))


def _rect(cx: float, cy: float, lx0: float, lx1: float, ly0: float, ly1: float, yaw: float) -> FloatArray:
    local = np.array([[lx0, ly0], [lx1, ly0], [lx1, ly1], [lx0, ly1]])
    c, s = math.cos(yaw), math.sin(yaw)
    corners: FloatArray = local @ np.array([[c, s], [-s, c]]) + (cx, cy)
    return corners


def _world_of(world_or_scenario: "World | Scenario") -> tuple["World", dict[str, Any]]:
    w = getattr(world_or_scenario, "world", None)
    if w is not None:
        return w, dict(getattr(world_or_scenario, "meta", {}) or {})
    return world_or_scenario, {}  # type: ignore[return-value]


def _kinds(n: int, ranges: Sequence[tuple[str, int, int]], default: str) -> list[tuple[str, int, int]]:
    """The blocks of an array of ``n`` objects by kind, the untagged stretches as ``default`` blocks."""
    out, at = [], 0
    for kind, a, b in sorted(ranges, key=lambda r: r[1]):
        a, b = max(a, at), min(b, n)
        if a > at:
            out.append((default, at, a))
        if b > a:
            out.append((kind, a, b))
            at = b
    if at < n:
        out.append((default, at, n))
    return out


def world_extent(world_or_scenario: "World | Scenario") -> tuple[float, float, float, float]:
    """(xmin, ymin, xmax, ymax) in m that holds the world's bounds and everything :func:`draw_world` draws of
    finite size (holes, ruts, the finite part of steps, the movers' paths, the scenario's surveyed posts and given
    path), 0.3 m around the features."""
    w, meta = _world_of(world_or_scenario)
    pts = [np.array([[w.bounds[0], w.bounds[1]], [w.bounds[2], w.bounds[3]]], dtype=float)]
    feats = []
    for hole in w.holes:
        r = 0.5 * math.hypot(hole.size_x_m, hole.size_y_m)
        feats.append(np.array([[hole.x_m - r, hole.y_m - r], [hole.x_m + r, hole.y_m + r]]))
    for st in w.steps:
        half = 0.5 * st.width_m if math.isfinite(st.width_m) else 0.0
        depth = st.depth_m if math.isfinite(st.depth_m) else 0.0
        feats.append(_rect(st.x_m, st.y_m, 0.0, depth, -half, half, st.yaw_rad))
    for rut in w.ruts:
        reach = 0.5 * (rut.spacing_m if rut.count > 1 else 0.0) + 0.5 * rut.width_m
        p = np.asarray(rut.points, dtype=float)
        feats += [p - reach, p + reach]
    for m in w.movers:
        feats.append(np.asarray(m.waypoints, dtype=float).reshape(-1, 2))
    if meta.get("landmarks"):
        feats.append(np.asarray(meta["landmarks"], dtype=float).reshape(-1, 3)[:, :2])
    if meta.get("path") is not None:
        feats.append(np.asarray(meta["path"], dtype=float).reshape(-1, 2))
    if feats:
        f = np.vstack(feats)
        pts.append(np.vstack((f.min(axis=0) - 0.3, f.max(axis=0) + 0.3)))
    a = np.vstack(pts)
    return float(a[:, 0].min()), float(a[:, 1].min()), float(a[:, 0].max()), float(a[:, 1].max())


def draw_world(ax: Any, world_or_scenario: "World | Scenario", t_s: float | None = None,
               legend_entries: bool = True) -> dict[str, int]:
    """Draw a world (or a scenario's world and its ``meta`` path and surveyed posts) on ``ax``: walls, boxes,
    polygons, posts, plants and their rows' design lines, weeds, holes, steps, ruts and the movers' paths (their
    disc at the start and, with ``t_s``, where they are at t_s). Sets equal axes on :func:`world_extent`, in m.
    Returns the number of objects drawn per kind (a wall is one polyline, a box one rectangle, a plant one
    circle)."""
    w, meta = _world_of(world_or_scenario)
    counts: dict[str, int] = {}
    xmin, ymin, xmax, ymax = world_extent(world_or_scenario)
    far = 2.0 * math.hypot(xmax - xmin, ymax - ymin) + 1.0  # "unlimited" extents, drawn to well past the bounds

    # ground features first (under everything)
    holes = []
    for hole in w.holes:
        if hole.elliptic:
            a = np.linspace(0.0, 2.0 * math.pi, 48, endpoint=False)
            local = np.column_stack((0.5 * hole.size_x_m * np.cos(a), 0.5 * hole.size_y_m * np.sin(a)))
            c, s = math.cos(hole.yaw_rad), math.sin(hole.yaw_rad)
            poly = local @ np.array([[c, s], [-s, c]]) + (hole.x_m, hole.y_m)
        else:
            hx, hy = 0.5 * hole.size_x_m, 0.5 * hole.size_y_m
            poly = _rect(hole.x_m, hole.y_m, -hx, hx, -hy, hy, hole.yaw_rad)
        holes.append(poly)
    steps: dict[str, list[FloatArray]] = {}
    for st in w.steps:
        half = 0.5 * min(st.width_m, far)
        steps.setdefault("step_up" if st.height_m > 0 else "step_down", []).append(
            _rect(st.x_m, st.y_m, 0.0, min(st.depth_m, far), -half, half, st.yaw_rad))
    bands = []
    for rut in w.ruts:
        pts = np.asarray(rut.points, dtype=float)
        offs = [0.0] if rut.count == 1 else [-0.5 * rut.spacing_m, 0.5 * rut.spacing_m]
        bands += [np.vstack((_offset_line(pts, o - 0.5 * rut.width_m), _offset_line(pts, o + 0.5 * rut.width_m)[::-1]))
                  for o in offs]
    for kind, polys, z in (("step_up", steps.get("step_up", []), 0.4), ("step_down", steps.get("step_down", []), 0.4),
                           ("rut", bands, 0.45), ("hole", holes, 0.5)):
        if polys:
            _patches(ax, polys, kind, zorder=z)
    counts.update({k: len(v) for k, v in steps.items()})
    if holes:
        counts["hole"] = len(holes)
    if w.ruts:
        counts["rut"] = len(w.ruts)

    # segments: walls as lines, boxes and polygons filled
    from matplotlib.collections import LineCollection

    seg = np.asarray(w.segments, dtype=float).reshape(-1, 4)
    wall_segs = []
    solids: dict[str, list[FloatArray]] = {}
    for kind, i0, i1 in _kinds(len(seg), w.segment_kinds, "wall"):
        if kind in ("box", "polygon"):
            solids.setdefault(kind, []).append(seg[i0:i1, :2])
        else:
            kind = "wall"
            wall_segs.append(seg[i0:i1])
        counts[kind] = counts.get(kind, 0) + 1
    for kind, polys in solids.items():
        _patches(ax, polys, kind, zorder=2.0)
    if wall_segs:
        walls = np.vstack(wall_segs)
        # matplotlib's stubs ask for a Sequence; its documented (n, 2, 2) array is what it is given
        lc = LineCollection(walls.reshape(-1, 2, 2),  # type: ignore[arg-type]
                            colors=_STYLE["wall"]["color"], linewidths=_STYLE["wall"]["lw"], zorder=2.0)
        lc.set_gid("wall")
        ax.add_collection(lc, autolim=False)

    # circles by kind
    circ = np.asarray(w.circles, dtype=float).reshape(-1, 3)
    by_kind: dict[str, list[FloatArray]] = {}
    for kind, i0, i1 in _kinds(len(circ), w.circle_kinds, "post"):
        by_kind.setdefault(kind if kind in ("plant", "weed") else "post", []).append(circ[i0:i1])
    for kind, parts in by_kind.items():
        kind_circles = np.vstack(parts)
        _circles(ax, kind_circles, kind)
        counts[kind] = len(kind_circles)
    for k, line in enumerate(w.row_lines):
        ln, = ax.plot(line[:, 0], line[:, 1], zorder=1.5, **_STYLE["row_line"])
        ln.set_gid("row_line")
        counts["row_line"] = k + 1

    # movers: the path each walks, its disc at the start and at t_s
    from matplotlib.patches import Circle

    for m in w.movers:
        wp = np.asarray(m.waypoints, dtype=float)
        if m.loop and len(wp) > 2:
            wp = np.vstack((wp, wp[:1]))
        ln, = ax.plot(wp[:, 0], wp[:, 1], zorder=2.5, **_STYLE["mover"])
        ln.set_gid("mover")
        x0, y0 = m.position(0.0)
        ring = Circle((x0, y0), m.radius_m, fc="none", ec=_STYLE["mover"]["color"], lw=1.0, zorder=2.5)
        ring.set_gid("mover_start")
        ax.add_patch(ring)
        if t_s is not None:
            x1, y1 = m.position(t_s)
            disc = Circle((x1, y1), m.radius_m, fc=_STYLE["mover"]["color"], ec="none", alpha=0.6, zorder=2.5)
            disc.set_gid("mover_end")
            ax.add_patch(disc)
        counts["mover"] = counts.get("mover", 0) + 1

    # what the scenario's [meta] says about the world
    if meta.get("landmarks"):
        lm = np.asarray(meta["landmarks"], dtype=float).reshape(-1, 3)
        ln, = ax.plot(lm[:, 0], lm[:, 1], zorder=3.0, **_STYLE["landmark"])
        ln.set_gid("landmark")
        counts["landmark"] = len(lm)
    if meta.get("path") is not None:
        gp = np.asarray(meta["path"], dtype=float).reshape(-1, 2)
        ln, = ax.plot(gp[:, 0], gp[:, 1], zorder=1.8, **_STYLE["given_path"])
        ln.set_gid("given_path")
        counts["given_path"] = 1

    if legend_entries:
        for kind in KIND_LABELS:
            if counts.get(kind):
                _proxy(ax, kind)
    ax.set_xlim(xmin, xmax)
    ax.set_ylim(ymin, ymax)
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("x, m")
    ax.set_ylabel("y, m")
    return counts


def _arrow(ax: Any, x: float, y: float, yaw: float, length: float, color: str, gid: str) -> None:
    from matplotlib.patches import FancyArrow

    a = FancyArrow(x, y, length * math.cos(yaw), length * math.sin(yaw), width=0.12 * length,
                   head_width=0.4 * length, head_length=0.35 * length, length_includes_head=True, color=color, zorder=6)
    a.set_gid(gid)
    ax.add_patch(a)


def _arrow_length(ax: Any) -> float:
    x0, x1 = ax.get_xlim()
    y0, y1 = ax.get_ylim()
    return max(0.25, 0.04 * float(max(abs(x1 - x0), abs(y1 - y0))))


def draw_goals(ax: Any, goals: Iterable[Goal], start: Pose2D | None = None, numbers: int = 12) -> int:
    """The start pose (a black dot and heading arrow) and each goal: a star, its tolerance circle and, where the
    goal has a heading, an arrow (a goal listed again, as in a cycle of goals, is drawn once); goals are numbered
    when there are 2 to ``numbers`` of them and a timed goal is labelled with its arrival time. Returns the number
    of goals (listed, not drawn)."""
    from matplotlib.patches import Circle

    gl = list(goals)
    length = _arrow_length(ax)
    if start is not None:
        dot, = ax.plot([start.x_m], [start.y_m], "ko", ms=5, zorder=6, label="start")
        dot.set_gid("start")
        _arrow(ax, start.x_m, start.y_m, start.yaw_rad, length, "black", "start_heading")
    groups: dict[tuple[float, ...], list[int]] = {}  # a goal visited again (a cycle of goals) is drawn once
    for i, g in enumerate(gl):
        key = (round(g.x_m, 6), round(g.y_m, 6), round(g.tolerance_m, 6),
               math.nan if g.yaw_rad is None else round(g.yaw_rad, 6))
        groups.setdefault(key, []).append(i)
    for k, members in enumerate(groups.values()):
        g = gl[members[0]]
        ring = Circle((g.x_m, g.y_m), g.tolerance_m, fc="#2ca02c", ec="#1a6e1a", alpha=0.25, lw=1.0, ls="--", zorder=5)
        ring.set_gid("goal_tolerance")
        ax.add_patch(ring)
        star, = ax.plot([g.x_m], [g.y_m], "*", color="#1a6e1a", ms=11, zorder=6,
                        label="goal (tolerance circle, heading)" if k == 0 else None)
        star.set_gid("goal")
        if g.yaw_rad is not None:
            _arrow(ax, g.x_m, g.y_m, g.yaw_rad, length, "#1a6e1a", "goal_heading")
        text = []
        if 1 < len(gl) <= numbers:
            text.append(",".join(str(i + 1) for i in members))
        times = [gl[i].arrival_s for i in members if gl[i].arrival_s is not None]
        if times:
            text.append("t=" + ",".join(f"{t:g}" for t in times) + " s")
        if text:
            ax.annotate(" ".join(text), (g.x_m, g.y_m), xytext=(5, 5), textcoords="offset points", fontsize=7,
                        color="#1a6e1a", zorder=7)
    return len(gl)


def footprint_times(t_s: FloatArray, every_s: float) -> npt.NDArray[np.intp]:
    """Indices of the samples at which a footprint is drawn: the first sample at or after each multiple of
    ``every_s`` (0 included), the last sample excluded (it gets the end outline)."""
    t = np.asarray(t_s, dtype=float)
    if len(t) < 2 or not every_s > 0:
        return np.zeros(0, dtype=int)
    marks = np.arange(0.0, t[-1], every_s)
    idx = np.unique(np.searchsorted(t, marks - 1e-9))
    return idx[idx < len(t) - 1]


@dataclass
class RunArtists:
    """What :func:`draw_run` drew: the speed-coloured path, the footprints along it and at the end."""

    path: Any
    footprints: int
    end: Any
    speed_range: tuple[float, float]


def draw_run(ax: Any, rows: FloatArray, footprint: Footprint | None = None, every_s: float = 2.0,
             end_reason: str | None = None, cmap: str = "viridis") -> RunArtists:
    """The path of ``rows`` (TRAJECTORY_COLUMNS: t, x, y, yaw, speed, ...) coloured by speed (m/s), and the robot's
    ``footprint`` every ``every_s`` seconds (grey) and at the end (red after a collision or a fall, else blue)."""
    from matplotlib.collections import LineCollection, PatchCollection
    from matplotlib.colors import Normalize
    from matplotlib.patches import Polygon, Rectangle

    r = np.asarray(rows, dtype=float)
    xy = r[:, 1:3]
    v = r[:, 4]
    lo = min(0.0, float(v.min())) if len(v) else 0.0
    hi = max(float(v.max()) if len(v) else 0.0, lo + 1e-3)
    pts = xy.reshape(-1, 1, 2)
    segs = np.concatenate((pts[:-1], pts[1:]), axis=1) if len(xy) > 1 else np.zeros((0, 2, 2))
    # an (n, 2, 2) array, as for the walls (matplotlib's stubs ask for a Sequence)
    lc = LineCollection(segs, cmap=cmap, norm=Normalize(lo, hi), linewidths=2.0, zorder=4)  # type: ignore[arg-type]
    lc.set_array(0.5 * (v[:-1] + v[1:]) if len(v) > 1 else np.zeros(0))
    lc.set_gid("path")
    ax.add_collection(lc, autolim=False)
    if len(xy):
        ax.update_datalim(xy)
    n_fp = 0
    end = None
    if footprint is not None and len(r):
        idx = footprint_times(r[:, 0], every_s)
        polys = [Polygon(footprint.outline(r[i, 1], r[i, 2], r[i, 3]), closed=True) for i in idx]
        if polys:
            coll = PatchCollection(polys, facecolors="none", edgecolors="0.35", linewidths=0.7, alpha=0.8, zorder=4.5)
            coll.set_gid("footprint")
            ax.add_collection(coll, autolim=False)
        n_fp = len(polys)
        bad = end_reason in ("collision", "fell_in_hole")
        colour = "#d62728" if bad else "#1f4e9c"
        x, y, yaw = r[-1, 1], r[-1, 2], r[-1, 3]
        end = Polygon(footprint.outline(x, y, yaw), closed=True, fc=colour, ec=colour, alpha=0.35, lw=1.4, zorder=4.6)
        end.set_gid("footprint_end")
        ax.add_patch(end)
        cx, cy = footprint.outline(x, y, yaw, n=4).mean(axis=0)  # the outline's centre
        f = footprint.front_m()
        tick, = ax.plot([cx, cx + f * math.cos(yaw)], [cy, cy + f * math.sin(yaw)], "-", color=colour, lw=1.4,
                        zorder=4.7)
        tick.set_gid("footprint_end_heading")
        ax.add_patch(Rectangle((0.0, 0.0), 0.0, 0.0, fc="none", ec="0.35", lw=0.7,
                               label=f"robot outline every {every_s:g} s"))
        ax.add_patch(Rectangle((0.0, 0.0), 0.0, 0.0, fc=colour, ec=colour, alpha=0.35, lw=1.4,
                               label=f"robot at the end{f' ({end_reason})' if end_reason else ''}"))
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("x, m")
    ax.set_ylabel("y, m")
    return RunArtists(lc, n_fp, end, (lo, hi))


def rows_from_poses(poses: Sequence[tuple[float, float, float, float]]) -> FloatArray:
    """Trajectory rows (t, x, y, yaw, speed) from timed poses (t, x, y, yaw), the speed from the distance between
    neighbouring poses (m/s; 0 where the time does not advance)."""
    p = np.asarray(poses, dtype=float).reshape(-1, 4)
    speed = np.zeros(len(p))
    if len(p) > 1:
        d = np.hypot(np.diff(p[:, 1]), np.diff(p[:, 2]))
        dt = np.diff(p[:, 0])
        v = np.where(dt > 0, d / np.where(dt > 0, dt, 1.0), 0.0)
        speed[1:] = v
        speed[0] = v[0]
    return np.column_stack((p, speed))


def _fit_limits(ax: Any, xy: FloatArray, pad: float) -> None:
    """Widen the axes' limits to hold ``xy`` (n, 2) with ``pad`` m around it."""
    if not len(xy):
        return
    x0, x1 = ax.get_xlim()
    y0, y1 = ax.get_ylim()
    ax.set_xlim(min(x0, float(xy[:, 0].min()) - pad), max(x1, float(xy[:, 0].max()) + pad))
    ax.set_ylim(min(y0, float(xy[:, 1].min()) - pad), max(y1, float(xy[:, 1].max()) + pad))


def run_figure(rows: FloatArray, scenario: "Scenario | None" = None, *, world: "World | None" = None,
               goals: Sequence[Goal] | None = None, start: Pose2D | None = None, footprint: Footprint | None = None,
               title: str = "", end_reason: str | None = None, every_s: float = 2.0, dpi: int = 100) -> tuple[Any, Any]:
    """The picture of one run as a (figure, axes) pair: the world (the scenario's, or ``world``; none for a run that
    knows nothing of its surroundings), the start and goals (the scenario's unless given), the path coloured by
    speed with a colour bar in m/s, the footprint (the scenario robot's unless given) every ``every_s`` s and at the
    end; the title ends with the end reason. Close the figure when done (:func:`plot_run` writes and closes it).
    RuntimeError without matplotlib."""
    plt = _pyplot()
    from matplotlib.transforms import offset_copy

    r = np.asarray(rows, dtype=float)
    r = r.reshape(-1, r.shape[-1]) if r.ndim == 2 else np.zeros((0, 5))
    w = scenario.world if scenario is not None else world
    if scenario is not None:
        goals = scenario.goals if goals is None else goals
        start = scenario.start if start is None else start
        footprint = Footprint.of_scenario(scenario) if footprint is None else footprint
    if start is None and len(r):
        start = Pose2D(float(r[0, 1]), float(r[0, 2]), float(r[0, 3]))
    pad = 0.5 + (footprint.front_m() + abs(footprint.offset_m) if footprint is not None else 0.0)
    pts = [r[:, 1:3] - pad, r[:, 1:3] + pad] if len(r) else []
    if goals:
        g = np.array([[g.x_m, g.y_m, g.tolerance_m] for g in goals])
        pts += [g[:, :2] - g[:, 2:] - 0.3, g[:, :2] + g[:, 2:] + 0.3]
    if start is not None:
        pts += [np.array([[start.x_m - 1.0, start.y_m - 1.0], [start.x_m + 1.0, start.y_m + 1.0]])]
    if w is not None:
        e = world_extent(scenario if scenario is not None else w)
        pts.append(np.array([[e[0], e[1]], [e[2], e[3]]]))
    allp = np.vstack(pts) if pts else np.array([[-1.0, -1.0], [1.0, 1.0]])
    lo, hi = allp.min(axis=0), allp.max(axis=0)
    span = np.maximum(hi - lo, 1e-6)
    width_in = 9.0
    height_in = float(np.clip(width_in * span[1] / span[0], 2.5, 10.0))
    fig, ax = plt.subplots(figsize=(width_in, height_in + 1.4), dpi=dpi)
    try:
        if w is not None:
            draw_world(ax, scenario if scenario is not None else w, t_s=float(r[-1, 0]) if len(r) else None)
        ax.set_xlim(float(lo[0]), float(hi[0]))
        ax.set_ylim(float(lo[1]), float(hi[1]))
        draw_goals(ax, goals or [], start)
        art = draw_run(ax, r, footprint, every_s, end_reason)
        cax = ax.inset_axes((1.015, 0.0, 0.022, 1.0))  # follows the axes' box, whatever its aspect made of it
        cb = fig.colorbar(art.path, cax=cax)
        cb.set_label("speed, m/s")
        ax.grid(alpha=0.25)
        if len(r):
            length = float(np.hypot(*np.diff(r[:, 1:3], axis=0).T).sum()) if len(r) > 1 else 0.0
            tail = f"{end_reason or 'end'} at t={r[-1, 0]:.1f} s, path {length:.2f} m"
        else:
            tail = end_reason or "no samples"
        ax.set_title(f"{title}: {tail}" if title else tail, fontsize=10)
        handles, labels = ax.get_legend_handles_labels()
        ax.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, 0.0), ncol=4, fontsize=7, frameon=False,
                  bbox_transform=offset_copy(ax.transAxes, fig, y=-30, units="points"))
    except BaseException:
        plt.close(fig)
        raise
    return fig, ax


def plot_run(path: str | Path, rows: FloatArray, scenario: "Scenario | None" = None, *, dpi: int = 100,
             **kw: Any) -> Path:
    """Write :func:`run_figure` to ``path`` (PNG, or what the suffix says); the keywords are run_figure's."""
    plt = _pyplot()
    fig, _ = run_figure(rows, scenario, dpi=dpi, **kw)
    try:
        out = Path(path)
        out.parent.mkdir(parents=True, exist_ok=True)
        savefig_atomic(fig, out, dpi=dpi, bbox_inches="tight")
    finally:
        plt.close(fig)
    return out
