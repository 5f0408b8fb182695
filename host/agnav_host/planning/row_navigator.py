"""Whole fields: the row navigator drives a lane, finds the rows' end, counts the rows on the headland with the
laser, turns into the lane its turn pattern names, and stops when the pattern is done (the Field Robot Event's
navigation task).

**Turn patterns** are written as the event writes them: ``S-1L-2R-1L-3R-F``. S is the start (the lane the robot
stands in), each ``nL`` / ``nR`` is a headland turn to the left / right (as the robot drives) into the n-th lane
on that side of the lane just driven (1 = the next lane), and F is the finish: after the last lane the robot
leaves the rows and stops. :func:`parse_pattern` reads one (``-``, en dashes, commas or blanks between the parts,
any case); :func:`format_pattern` writes one.

**Phases** (``RowNavigator.phase``):

* ``follow``: the centre line between the two rows (:class:`~agnav_host.perception.RowFollower`, with its soft
  gate on). The rows' end is where the plants of both rows, looked along the filtered lane from the robot, stop
  for good: the *reach* is how far ahead the rows hold plants, counting over empty stretches shorter than
  ``gap_max_m`` (the event's gaps are at most 1 m, on one side or both); the end is reported when the reach has
  stayed under ``end_reach_m`` for ``end_scans`` fresh scans. A gap, even on both sides, leaves plants in sight
  beyond it, so it is no end.
* ``exit``: straight on along the lane to ``u = x_a``, just past the furthest row end the turn must clear;
* ``arc1``, ``leg``, ``arc2``: the headland turn, tracked by pure pursuit in the *lane-end frame* (origin where
  the lane's rows end, u out of the field along the lane, v to the left): a quarter arc onto the headland, a leg
  along it at ``u = x_h``, a quarter arc into the target lane and a straight into it. Every arc has radius
  ``1.1 R`` with ``R`` the robot's tightest turn (an Ackermann car: ``L / tan(max steer)``; a differential drive:
  its track, the firmware's steering limit). When the lanes are closer than ``2 R`` the leg is driven in reverse
  (``reverse``); ``omega``: without reverse such a turn is an omega
  (:func:`~agnav_host.perception.headland_path`: away, round, back). The follower takes over 0.3 m inside.
* ``finish``: after the last lane, straight on out of the rows by ``finish_m`` and stop (``done``).

**Rows are counted from the laser.** From the end of a lane on, every scan goes into a *row-end map* in the
lane-end frame: a 5 cm grid over the last metres of the rows. Each row's end shows as a band of cells along u,
narrow across; the bands are the rows, their lateral places are where the rows stand and their furthest cells are
where they end (uneven row ends included). The target lane of ``nL`` lies between the n-th and (n+1)-th row on the
left, counted outwards from the lane just driven; its centre, and the headland leg's clearance of every row end in
between, are taken from the map at every scan until the last arc begins. Poses come from ``obs.pose`` (odometry
on the robot, the truth in the simulator): only the few metres of a turn rest on it.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

import numpy as np

from ..perception import RowFollower, RowFollowerParams, headland_path, points_from_scan
from ..types import DriveCommand, FloatArray, Observation, Pose2D, norm_angle_rad

__all__ = ["PatternError", "Turn", "parse_pattern", "format_pattern", "RowNavigatorParams", "RowNavigator",
           "RowEndMap", "RowEnd", "row_reach_m"]

SIDES = ("left", "right")


class PatternError(ValueError):
    """A turn pattern that is not in the event's notation (the message shows the form)."""


@dataclass(frozen=True)
class Turn:
    """One headland turn of a pattern: to the ``side`` (``left`` / ``right`` as the robot drives) into the
    ``lanes``-th lane on that side (1 = the next one)."""

    side: str
    lanes: int

    def __str__(self) -> str:
        return f"{self.lanes}{self.side[0].upper()}"


_PART = re.compile(r"^(\d+)([LR])$")
_FORM = "S-nL/nR-...-F, e.g. S-1L-2R-1L-3R-F (S start, nL / nR the n-th lane to the left / right, F finish)"


def parse_pattern(text: str) -> tuple[Turn, ...]:
    """The turns of a pattern in the Field Robot Event's notation (module docstring); :class:`PatternError` with
    the accepted form for anything else. ``S-F`` is one lane and no turn."""
    if not isinstance(text, str):
        raise PatternError(f"turn pattern must be text ({_FORM}), got {text!r}")
    parts = [p for p in re.split(r"[\s,\-\u2013\u2014]+", text.strip().upper()) if p]
    if len(parts) < 2 or parts[0] != "S" or parts[-1] != "F":
        raise PatternError(f"turn pattern {text!r}: must start with S and end with F: {_FORM}")
    turns = []
    for p in parts[1:-1]:
        m = _PART.match(p)
        if m is None or not 1 <= int(m.group(1)) <= 20:
            raise PatternError(f"turn pattern {text!r}: {p!r} is not a turn (1-20 lanes, then L or R): {_FORM}")
        turns.append(Turn("left" if m.group(2) == "L" else "right", int(m.group(1))))
    return tuple(turns)


def format_pattern(turns: tuple[Turn, ...] | list[Turn]) -> str:
    """``S-1L-2R-F`` for the given turns."""
    return "-".join(["S", *(str(t) for t in turns), "F"])


# ---- the row-end map -------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class RowEnd:
    """One row as the row-end map sees it, in the lane-end frame: ``v_m`` its lateral place (left positive),
    ``end_u_m`` how far out of the field it reaches, ``cells`` how many cells hold its points."""

    v_m: float
    end_u_m: float
    cells: int


class RowEndMap:
    """Scan points of the rows' last metres, on a 5 cm grid in the lane-end frame (module docstring)."""

    def __init__(self, origin: Pose2D, half_width_m: float, u_min_m: float = -2.5, u_max_m: float = 1.4,
                 cell_m: float = 0.05) -> None:
        self.origin = origin
        self.cell = cell_m
        self.u0, self.v0 = u_min_m, -half_width_m
        self.nu = int(math.ceil((u_max_m - u_min_m) / cell_m))
        self.nv = int(math.ceil(2.0 * half_width_m / cell_m))
        self.count = np.zeros((self.nv, self.nu), dtype=np.int32)

    def to_lane(self, x: FloatArray, y: FloatArray) -> tuple[FloatArray, FloatArray]:
        o = self.origin
        c, s = math.cos(o.yaw_rad), math.sin(o.yaw_rad)
        dx, dy = x - o.x_m, y - o.y_m
        return c * dx + s * dy, -s * dx + c * dy

    def pose_in_lane(self, pose: Pose2D) -> tuple[float, float, float]:
        u, v = self.to_lane(np.array([pose.x_m]), np.array([pose.y_m]))
        return float(u[0]), float(v[0]), norm_angle_rad(pose.yaw_rad - self.origin.yaw_rad)

    def add(self, xy_world: FloatArray) -> None:
        """Fold in scan points (k, 2) in the world frame, m."""
        if not len(xy_world):
            return
        u, v = self.to_lane(xy_world[:, 0], xy_world[:, 1])
        iu = np.floor((u - self.u0) / self.cell).astype(int)
        iv = np.floor((v - self.v0) / self.cell).astype(int)
        ok = (iu >= 0) & (iu < self.nu) & (iv >= 0) & (iv < self.nv)
        np.add.at(self.count, (iv[ok], iu[ok]), 1)

    def rows(self, min_cells: int = 5, min_extent_m: float = 0.4, min_hits: int = 2) -> list[RowEnd]:
        """The rows in the map, by lateral place. A cell counts once it holds ``min_hits`` points; a lateral strip
        (one cell wide, along u) belongs to a row when ``min_cells`` of its cells count (a row's end seen along
        a stretch; a weed or a stray return fills one or two); neighbouring strips (one empty strip bridged) make
        one row, whose points must reach over ``min_extent_m`` along u."""
        occ = self.count >= min_hits
        strip = occ.sum(axis=1) >= min_cells
        out: list[RowEnd] = []
        i = 0
        while i < self.nv:
            if not strip[i]:
                i += 1
                continue
            j = i
            while j + 1 < self.nv and (strip[j + 1] or (j + 2 < self.nv and strip[j + 2])):
                j += 1
            band = occ[i:j + 1]
            cols = self._body(np.nonzero(band.any(axis=0))[0])
            if len(cols) and (cols[-1] - cols[0] + 1) * self.cell >= min_extent_m:
                w = (self.count[i:j + 1] * band).sum(axis=1).astype(float)
                vs = self.v0 + (np.arange(i, j + 1) + 0.5) * self.cell
                out.append(RowEnd(float((w * vs).sum() / max(w.sum(), 1.0)), self.u0 + (cols[-1] + 1) * self.cell,
                                  int(band.sum())))
            i = j + 1
        return out

    def _body(self, cols: np.ndarray, gap_m: float = 0.5) -> np.ndarray:
        """The row itself among a band's occupied cells along u: the run (no empty stretch of ``gap_m``) holding
        the most of them. A fence or a post further out on the headland, in the same strips, is not its end."""
        if len(cols) < 2:
            return cols
        cut = np.nonzero(np.diff(cols) * self.cell > gap_m)[0]
        runs = np.split(cols, cut + 1)
        return max(runs, key=len)


def row_reach_m(xy: FloatArray, heading_rad: float, left_c_m: float, right_c_m: float, band_m: float = 0.2,
                bin_m: float = 0.1, gap_max_m: float = 1.3, look_m: float = 6.0) -> float:
    """How far ahead (m, along the rows) the two row lines hold plants, robot-frame points ``xy`` (k, 2): from the
    robot outwards, the last 0.1 m bin with a point within ``band_m`` of either row line before the first empty
    stretch of ``gap_max_m`` or more. A row line is (heading, c) as in perception's row detection: its points p
    satisfy ``n . p = c`` with n the left normal of direction ``-heading_rad``. 0 when no plant is ahead."""
    phi = -heading_rad
    ux, uy = math.cos(phi), math.sin(phi)
    nx, ny = -uy, ux
    along = xy[:, 0] * ux + xy[:, 1] * uy
    lat = xy[:, 0] * nx + xy[:, 1] * ny
    near = (np.abs(lat - left_c_m) < band_m) | (np.abs(lat - right_c_m) < band_m)
    sel = near & (along >= 0.0) & (along < look_m)
    nb = int(math.ceil(look_m / bin_m))
    occ = np.zeros(nb, dtype=bool)
    occ[np.clip((along[sel] / bin_m).astype(int), 0, nb - 1)] = True
    reach, empty = 0.0, 0
    gap_bins = int(math.ceil(gap_max_m / bin_m))
    for k in range(nb):
        if occ[k]:
            reach, empty = (k + 1) * bin_m, 0
        else:
            empty += 1
            if empty >= gap_bins:
                break
    return reach


# ---- path tracking in the lane-end frame -------------------------------------------------------------------------


def _line(u0: float, v0: float, u1: float, v1: float, step: float = 0.02) -> FloatArray:
    d = math.hypot(u1 - u0, v1 - v0)
    n = max(2, int(math.ceil(d / step)) + 1)
    t = np.linspace(0.0, 1.0, n)
    yaw = math.atan2(v1 - v0, u1 - u0) if d > 1e-9 else 0.0
    return np.column_stack((u0 + t * (u1 - u0), v0 + t * (v1 - v0), np.full(n, yaw)))


def _arc(u: float, v: float, yaw: float, radius: float, sweep: float, step: float = 0.02) -> FloatArray:
    """Poses (k, 3) along an arc of ``radius`` from (u, v, yaw) turning by ``sweep`` (left positive), start
    included."""
    n = max(2, int(math.ceil(abs(sweep) * radius / step)) + 1)
    s = np.linspace(0.0, sweep, n)
    sg = 1.0 if sweep > 0 else -1.0
    cu, cv = u - sg * radius * math.sin(yaw), v + sg * radius * math.cos(yaw)
    th = yaw + s
    return np.column_stack((cu + sg * radius * np.sin(th), cv - sg * radius * np.cos(th), th))


class _Segment:
    """One stretch of a manoeuvre: poses (k, 3) in the lane-end frame, driven forwards (+1) or in reverse (-1)."""

    def __init__(self, poses: FloatArray, direction: int, name: str) -> None:
        self.poses, self.direction, self.name = poses, direction, name
        self.i = 0

    def passed_end(self, u: float, v: float) -> bool:
        e = self.poses[-1]
        tu, tv = math.cos(e[2]), math.sin(e[2])
        return (u - e[0]) * tu + (v - e[1]) * tv >= -0.01 or self.i >= len(self.poses) - 2


def _pursue(seg: _Segment, u: float, v: float, yaw: float, lookahead: float) -> float:
    """Pure pursuit: the curvature (1/m, left positive, of the motion's own direction) that takes the robot at
    (u, v, yaw) to the point ``lookahead`` ahead on ``seg``."""
    p = seg.poses
    hi = min(len(p), seg.i + 80)
    d = np.hypot(p[seg.i:hi, 0] - u, p[seg.i:hi, 1] - v)
    seg.i += int(np.argmin(d))
    dist = np.hypot(p[seg.i:, 0] - u, p[seg.i:, 1] - v)
    ahead = np.nonzero(dist >= lookahead)[0]
    j = seg.i + (int(ahead[0]) if len(ahead) else len(dist) - 1)
    th = yaw if seg.direction > 0 else yaw + math.pi  # the frame the motion faces
    du, dv = p[j, 0] - u, p[j, 1] - v
    c, s = math.cos(th), math.sin(th)
    lx, ly = c * du + s * dv, -s * du + c * dv
    if len(ahead) == 0 and lx <= 0.0:  # past the end: hold the end's heading
        return 0.0
    return float(2.0 * ly / max(lx * lx + ly * ly, 1e-6))


# ---- the navigator -------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class RowNavigatorParams:
    """The row navigator (module docstring), SI units.

    ``pattern``: the turns; ``finish``: stop after them (the pattern's F). With ``finish`` False the navigator
    never stops: it turns to the first turn's side by its lane count, then to the other side, and so on (a bare
    first side and lane count, ``left,1``). ``row_spacing_m``: the rows' spacing the robot is told (the map is
    read with it: rows further apart than one and a half spacings have rows hidden between them).
    ``radius_m`` / ``footprint_offset_m``: the robot's footprint disc and its centre ahead of the reference point
    (the headland leg keeps the disc ``clear_m`` off every row end it passes); ``reverse``: the robot may back
    up (the leg of a turn between lanes closer than two turning radii); ``min_speed_m_s``: the slowest the drive
    goes (a car's speed table), raising the turn and reverse speeds to it."""

    follower: RowFollowerParams = field(default_factory=RowFollowerParams)
    pattern: tuple[Turn, ...] = (Turn("left", 1),)
    finish: bool = True
    row_spacing_m: float = 0.75
    radius_m: float = 0.2
    footprint_offset_m: float = 0.0
    reverse: bool = True
    turn_speed_m_s: float = 0.3
    reverse_speed_m_s: float = 0.15
    min_speed_m_s: float = 0.0
    lookahead_m: float = 0.3
    clear_m: float = 0.1
    end_reach_m: float = 0.35
    end_scans: int = 3
    gap_max_m: float = 1.6
    finish_m: float = 0.6

    def __post_init__(self) -> None:
        if not self.finish and not self.pattern:
            raise ValueError("RowNavigatorParams: a navigator that never finishes needs a first turn")
        if not (self.row_spacing_m > 0 and self.radius_m > 0 and self.turn_speed_m_s > 0 and self.reverse_speed_m_s > 0):
            raise ValueError("RowNavigatorParams: row_spacing_m, radius_m and the speeds must be > 0")
        if not (self.gap_max_m > self.end_reach_m > 0 and self.end_scans >= 1):
            raise ValueError("RowNavigatorParams: need gap_max_m > end_reach_m > 0 and end_scans >= 1")


class RowNavigator:
    """Drive a whole field by a turn pattern (module docstring). ``phase`` names the state (``follow``, ``exit``,
    ``arc1``, ``leg``, ``arc2``, ``omega``, ``finish``, ``done``); ``lanes`` counts the lanes finished, ``turns``
    the headland turns; ``events`` logs (t_s, what) for a run's record."""

    def __init__(self, params: RowNavigatorParams | None = None) -> None:
        self.params = params or RowNavigatorParams()
        self.turn_radius_m = 1.1 * self.params.follower.limits.turn_radius_m
        self.follower = RowFollower(self.params.follower)
        self.reset()

    def reset(self) -> None:
        self.follower.reset()
        self.phase = "follow"
        self.lanes = 0
        self.turns = 0
        self.events: list[tuple[float, str]] = []
        self.map: RowEndMap | None = None
        self._armed = False
        self._low = 0
        self.reach_m = 0.0  # the last scan's reach (how far ahead the rows hold plants), m
        self._lane_yaw: float | None = None
        self._seg: _Segment | None = None
        self._turn: Turn | None = None
        self._x_a = 0.0
        self._x_h = 0.0
        self._target_v = 0.0
        self._target_end_u = 0.0

    @property
    def done(self) -> bool:
        """True once the pattern is done and the robot stands."""
        return self.phase == "done"

    def _next_turn(self) -> Turn | None:
        p = self.params
        k = self.turns
        if p.finish:
            return p.pattern[k] if k < len(p.pattern) else None
        first = p.pattern[0]
        other = "right" if first.side == "left" else "left"
        return Turn(first.side if k % 2 == 0 else other, first.lanes)

    def _speed(self, v: float) -> float:
        return max(v, self.params.min_speed_m_s)

    # -- the step

    def step(self, obs: Observation) -> DriveCommand:
        if self.phase == "follow":
            return self._follow(obs)
        if self.phase == "done":
            return DriveCommand()
        self._map_scan(obs)
        if self.phase == "finish":
            return self._finish(obs)
        return self._manoeuvre(obs)

    def _follow(self, obs: Observation) -> DriveCommand:
        p = self.params
        cmd = self.follower.step(obs)
        st = self.follower.state
        if obs.scan is None or st is None:  # only a fresh scan counts towards the rows' end
            return cmd
        # the reach along the filtered lane (one odd detection must not end the rows)
        pts = points_from_scan(obs.scan, p.follower.mount, p.follower.rows.scan)
        half = 0.5 * p.row_spacing_m
        reach = self.reach_m = row_reach_m(pts.xy, st[1], -st[0] + half, -st[0] - half, gap_max_m=p.gap_max_m)
        if reach >= 2.0:  # the rows' direction while they reach well ahead (near their end a fit sees little)
            self._lane_yaw = norm_angle_rad(obs.pose.yaw_rad - st[1])
        if not self._armed:  # between rows that reach ahead: from now on their end is looked for
            self._armed = reach > 1.5
            return cmd
        self._low = self._low + 1 if reach < p.end_reach_m else 0
        if self._low < p.end_scans:
            return cmd
        # the rows end: the lane-end frame at the last plants, on the lane's centre line
        e, psi = st
        yaw = self._lane_yaw if self._lane_yaw is not None else norm_angle_rad(obs.pose.yaw_rad - psi)
        c, sn = math.cos(yaw), math.sin(yaw)
        cx, cy = obs.pose.x_m + sn * e, obs.pose.y_m - c * e
        self.lanes += 1
        self._turn = self._next_turn()
        n = self._turn.lanes if self._turn is not None else 1
        self.map = RowEndMap(Pose2D(cx + c * reach, cy + sn * reach, yaw), (n + 2.5) * p.row_spacing_m)
        self._armed, self._low, self._x_h = False, 0, 0.0
        self.events.append((obs.t_s, f"lane {self.lanes} ends"))
        self._map_scan(obs)
        if self._turn is None:
            self.phase = "finish"
            return self._finish(obs)
        self.phase = "exit"
        return self._manoeuvre(obs)

    def _map_scan(self, obs: Observation) -> None:
        if self.map is None or obs.scan is None:
            return
        # robot-frame points through the laser's mount, carried into the world by the pose the scan was taken at
        pts = points_from_scan(obs.scan, self.params.follower.mount, self.params.follower.rows.scan)
        c, s = math.cos(obs.pose.yaw_rad), math.sin(obs.pose.yaw_rad)
        x, y = pts.xy[:, 0], pts.xy[:, 1]
        self.map.add(np.column_stack((obs.pose.x_m + c * x - s * y, obs.pose.y_m + s * x + c * y)))

    # -- the headland

    def side_rows(self, sg: float) -> list[RowEnd]:
        """The rows on the turn side (``sg`` +1 left, -1 right), outwards from the lane just driven; a row the map
        does not hold yet where the next one seen stands a spacing or more further out is put in at the spacing,
        with ``cells`` 0 and no end."""
        assert self.map is not None
        sp = self.params.row_spacing_m
        found = sorted((r for r in self.map.rows() if sg * r.v_m > 0.1 * sp), key=lambda r: sg * r.v_m)
        out: list[RowEnd] = []
        for r in found:
            d = sg * r.v_m
            prev = sg * out[-1].v_m if out else -0.5 * sp  # the lane's row on the other side
            if out and d - prev < 0.5 * sp:  # one row seen as two bands: keep the bigger
                if r.cells > out[-1].cells:
                    out[-1] = RowEnd(r.v_m, max(r.end_u_m, out[-1].end_u_m), r.cells)
                continue
            for k in range(1, int(round((d - prev) / sp))):
                out.append(RowEnd(sg * (prev + k * sp), -math.inf, 0))
            out.append(r)
        return out

    def _plan(self) -> None:
        """From the map: the exit point x_a (until the first arc starts), the headland leg x_h, the target lane's
        centre and where its rows end (until the last arc starts)."""
        p = self.params
        assert self._turn is not None and self.map is not None
        sg = 1.0 if self._turn.side == "left" else -1.0
        n, sp, R = self._turn.lanes, p.row_spacing_m, self.turn_radius_m
        rows = self.side_rows(sg)
        other = [r for r in self.map.rows() if abs(r.v_m + sg * 0.5 * sp) < 0.35 * sp]
        ends = [r.end_u_m for r in rows[:n + 1] if r.cells > 0] + [r.end_u_m for r in other]
        end_max = max(ends) if ends else 0.0
        reach = p.radius_m + abs(p.footprint_offset_m)
        if self.phase == "exit":
            self._x_a = max(0.0, end_max + p.clear_m, end_max + reach + p.clear_m - R)
        self._x_h = max(self._x_h, self._x_a + R, end_max + reach + p.clear_m)
        if len(rows) > n and rows[n - 1].cells and rows[n].cells:
            self._target_v = 0.5 * (rows[n - 1].v_m + rows[n].v_m)
        elif len(rows) >= n and rows[n - 1].cells:
            self._target_v = rows[n - 1].v_m + sg * 0.5 * sp
        else:
            self._target_v = sg * n * sp
        known = [r.end_u_m for r in rows[n - 1:n + 1] if r.cells > 0]
        self._target_end_u = min(known) if known else 0.0

    def _segment(self, u: float, v: float) -> _Segment:
        """The segment of the phase, from the robot at (u, v) in the lane-end frame."""
        assert self._turn is not None
        sg = 1.0 if self._turn.side == "left" else -1.0
        R, xa, xh, tv = self.turn_radius_m, self._x_a, self._x_h, self._target_v
        into = min(self._target_end_u, xh - R) - 1.0  # the last straight ends a metre inside the target lane
        if self.phase == "exit":
            return _Segment(_line(min(u, xa - 0.05), 0.0, xa, 0.0), 1, "exit")
        if self.phase == "arc1":
            return _Segment(_arc(xa, 0.0, 0.0, R, sg * math.pi / 2), 1, "arc1")
        v_s = tv - sg * R  # where the last arc starts on the leg
        if self.phase == "leg":
            return _Segment(_line(xh, v, xh, v_s), 1 if sg * (v_s - v) > 0.0 else -1, "leg")
        if self.phase == "omega":
            path = headland_path(tv, R)
            path[:, 0] += xa
            return _Segment(np.vstack((path, _line(xa, tv, min(into, xa - 1.0), tv)[1:])), 1, "omega")
        a2 = _arc(xh, v_s, sg * math.pi / 2, R, sg * math.pi / 2)
        return _Segment(np.vstack((a2, _line(a2[-1, 0], a2[-1, 1], into, tv)[1:])), 1, "arc2")

    def _manoeuvre(self, obs: Observation) -> DriveCommand:
        p = self.params
        assert self.map is not None and self._turn is not None
        u, v, yaw = self.map.pose_in_lane(obs.pose)
        if self.phase in ("exit", "arc1", "leg"):
            self._plan()
        if self.phase == "exit" and u >= self._x_a:
            omega = not p.reverse and abs(self._target_v) < 2.0 * self.turn_radius_m
            self.phase, self._seg = ("omega" if omega else "arc1"), None
        sg = 1.0 if self._turn.side == "left" else -1.0
        v_s = self._target_v - sg * self.turn_radius_m
        if self.phase == "arc1" and self._seg is not None and self._seg.passed_end(u, v):
            self.phase, self._seg = ("leg" if abs(v_s - v) > 0.02 else "arc2"), None
        if self.phase == "leg" and self._seg is not None and (self._seg.passed_end(u, v) or abs(v_s - v) <= 0.01):
            self.phase, self._seg = "arc2", None
        if self._seg is None or self.phase in ("exit", "leg"):  # the exit and the leg follow the map's updates
            if self._seg is None and self.phase != "exit":
                self.events.append((obs.t_s, self.phase))
            self._seg = self._segment(u, v)
        if self.phase in ("arc2", "omega"):
            if math.cos(yaw) < -0.8:  # facing into the target lane: the follower warms up on its rows
                self.follower.observe(obs)
            if u <= self._target_end_u - 0.3 and math.cos(yaw) < -0.95 and self.follower.state is not None:
                return self._enter_lane(obs)
        seg = self._seg
        kappa = _pursue(seg, u, v, yaw, p.lookahead_m)
        kmax = 1.0 / max(p.follower.limits.turn_radius_m, 1e-3)
        kappa = max(-kmax, min(kmax, kappa))
        speed = self._speed(p.reverse_speed_m_s if seg.direction < 0 else p.turn_speed_m_s)
        return p.follower.limits.command(seg.direction * speed, speed * kappa)

    def _enter_lane(self, obs: Observation) -> DriveCommand:
        self.turns += 1
        self.events.append((obs.t_s, f"turn {self.turns} done"))
        self.map, self._seg, self._lane_yaw = None, None, None
        self._armed, self._low = False, 0
        self.phase = "follow"
        return self._follow(obs)

    def _finish(self, obs: Observation) -> DriveCommand:
        p = self.params
        assert self.map is not None
        u, v, yaw = self.map.pose_in_lane(obs.pose)
        if u >= p.finish_m:
            self.phase = "done"
            self.events.append((obs.t_s, "pattern done"))
            return DriveCommand()
        seg = _Segment(_line(u - 0.5, 0.0, p.finish_m + 1.0, 0.0), 1, "finish")
        kappa = _pursue(seg, u, v, yaw, p.lookahead_m)
        sp = self._speed(p.turn_speed_m_s)
        return p.follower.limits.command(sp, sp * kappa)
