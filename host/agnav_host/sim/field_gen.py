"""Whole fields: generate one as a scenario, lay out its lanes, and score a run on it as the Field Robot Event does.

**The generated field** (:func:`generate_field`, ``agnav field new``). Rows k = 0 .. N-1 run along x; row k's design
line is

    y_k(x) = k * spacing + C * x * (L - x)

for x from its start ``a_k`` to its end ``L + b_k``. C (1/m) is the curvature option: the lateral bend is C times
x (L - x) m^2, so the rows bow by ``C L^2 / 4`` at mid-length (to the left for C > 0), leave their ends at
``atan(C L)`` to the x axis and curve by ``2 C`` (1/m) along their length (0 = straight). ``a_k`` and ``b_k`` are
uniform in ``[-ragged, +ragged]``: the rows' ends are not in one line. Plants stand every ``plant spacing`` along
each design line, each displaced by N(0, jitter) in x and y (``plants_along``): maize-like stems (one 3 cm circle
each, 0.15 m apart) or bushes (four circles within 0.12 m, 0.35 m apart). ``gap share`` of each row's length,
away from its first and last metre, is left without plants in gaps: 0.3-0.85 m of row without its plants, so
that with the plants either side the bare stretch is at most about 1 m (the event's longest gap), each gap a metre
from the next; a third of the gaps are repeated on the next row (where that row has none near), so that some
lanes have gaps on both sides. A further share of single plants is missing (half a metre from any gap), and
weeds (1.5 cm) stand in the lanes. A fence runs round the field
``headland`` m beyond the furthest row end on both headlands and 1.2 m beside the outer rows. The robot starts in
the outermost lane on the right (lane 0, between rows 0 and 1), 0.7 m before the rows, facing along them.

**Lanes** (:class:`FieldLayout`): lane i lies between row i and row i + 1 of the scenario's ``[[rows]]`` (in the
order they are listed, across the field), its centre line halfway between them where both rows stand. The start
lane is the one whose centre line the start is nearest to.

**Scoring** (:func:`score_field`), the Field Robot Event's navigation task (fieldrobot.com, task 1 "Navigation"):

* a lane is *driven* when the robot's footprint centre passes through it from one end to the other without
  leaving it (inside half a lane's width of its centre line). ``rows_completed`` counts the lanes driven in the
  pattern's order, the start lane first; the first lane entered out of order (deeper than 1 m) ends the count, as
  the event stops measuring "as soon as the robot leaves the specified path";
* the *distance in rows* S is the length of the lanes driven in order plus how far the robot got along the next
  lane of the pattern, counted up to the task's time (``[field] time_limit_s``, the event's 3 min);
* ``plants_touched`` counts the stems (a plant's centre) that were ever inside the robot's footprint disc; each
  costs 2 % of the pattern's total lane length (the event: "a penalty of 2 % of total row length distance in
  meter per damaged plant");
* the score is ``S_final = (S - penalties) * T / t`` with T the task's time and t the time the pattern was
  finished (the last lane's end), or T when it was not finished within T: the event's bonus for reaching the end
  of the field sooner ("S_final = S_corrected * 3 min / t_measured").
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from ..types import FloatArray, Goal, Pose2D
from .metrics import along_and_offset_m
from .world import polyline_length_m, resample_polyline

if TYPE_CHECKING:
    from .scenario import Scenario

__all__ = ["FieldSpec", "FieldSpecError", "generate_field", "random_pattern", "FieldLayout", "Lane", "LaneVisit",
           "FieldScore", "score_field", "with_pattern", "lane_sequence", "PLANT_KINDS", "ROBOT_KINDS",
           "DIFFICULTIES", "difficulty_spec", "plants_touched", "lane_visits", "BUILTIN_FIELDS"]

PLANT_KINDS = ("maize", "bush")
ROBOT_KINDS = ("diff_drive", "ackermann")

# plant kind -> (plant spacing m, plant radius m, circles per plant)
_PLANTS = {"maize": (0.15, 0.03, 1), "bush": (0.35, 0.12, 4)}
# robot kind -> (robot table lines, footprint radius m, footprint offset m)
_ROBOTS = {
    "diff_drive": ('model = "diff_drive"\nradius_m = 0.2\ntrack_m = 0.4\nmax_speed_m_s = 0.5', 0.2, 0.0),
    # the ref-003 RC car with its PWM tables, as the firmware drives it: 0.435 m/s at the least, no reverse
    "ackermann": ('model = "ackermann"\nmax_speed_m_s = 0.6\ncalib = { tables = "default" }', 0.16, 0.087),
}
FOLLOW_SPEED_M_S = 0.4  # the row navigator's speed in the lanes (the registry's min(0.4, max speed))
TURN_TIME_S = 12.0  # a headland turn, about, for the time limit of a long pattern


class FieldSpecError(ValueError):
    """A field that cannot be generated (the message names the option and why)."""


@dataclass(frozen=True)
class FieldSpec:
    """What ``agnav field new`` generates (module docstring); lengths in m."""

    rows: int = 6
    spacing_m: float = 0.75
    length_m: float = 10.0
    curvature: float = 0.0  # C, 1/m: y = C x (L - x)
    gap_share: float = 0.0
    jitter_m: float = 0.02
    seed: int = 0
    plants: str = "maize"
    robot: str = "diff_drive"
    pattern: str = ""  # "" = a random pattern from the seed
    missing_share: float = 0.03
    weeds_per_m: float = 0.3  # per metre of lane
    ragged_m: float = 0.25
    headland_m: float = 2.0
    time_limit_s: float = 0.0  # 0 = the event's 180 s, longer when the pattern needs it
    name: str = ""

    def command(self, out: str = "FIELD.toml") -> str:
        """The ``agnav field new`` command line that generates this field."""
        d = FieldSpec()
        opts = [("--rows", self.rows, d.rows), ("--spacing-m", self.spacing_m, d.spacing_m),
                ("--length-m", self.length_m, d.length_m), ("--curvature", self.curvature, d.curvature),
                ("--gap-share", self.gap_share, d.gap_share), ("--jitter-m", self.jitter_m, d.jitter_m),
                ("--seed", self.seed, d.seed), ("--plants", self.plants, d.plants), ("--robot", self.robot, d.robot),
                ("--pattern", self.pattern, d.pattern), ("--missing-share", self.missing_share, d.missing_share),
                ("--weeds-per-m", self.weeds_per_m, d.weeds_per_m), ("--ragged-m", self.ragged_m, d.ragged_m),
                ("--headland-m", self.headland_m, d.headland_m), ("--time-limit-s", self.time_limit_s, d.time_limit_s),
                ("--name", self.name, d.name)]
        return " ".join(["agnav field new", *(f"{k} {v:g}" if isinstance(v, float) else f"{k} {v}"
                                               for k, v, dv in opts if v != dv), "--out", out])

    def problem(self) -> str:
        """Why this field cannot be generated ("" when it can)."""
        if not 2 <= self.rows <= 60:
            return f"--rows must be 2-60 (a lane needs two rows), got {self.rows}"
        if not 0.3 <= self.spacing_m <= 5.0:
            return f"--spacing-m must be 0.3-5 m, got {self.spacing_m:g}"
        if not 3.0 <= self.length_m <= 200.0:
            return f"--length-m must be 3-200 m (a metre without gaps at each end), got {self.length_m:g}"
        if not abs(self.curvature * self.length_m) <= 0.3:
            return (f"--curvature {self.curvature:g}: the rows would leave their ends at atan(C L) = "
                    f"{math.degrees(math.atan(abs(self.curvature * self.length_m))):.0f} deg to the headland; at most "
                    f"|C| L = 0.3 (17 deg), here |C| <= {0.3 / self.length_m:.4g} 1/m")
        if not 0.0 <= self.gap_share <= 0.3:
            return f"--gap-share must be 0-0.3 (share of the row without plants), got {self.gap_share:g}"
        if not 0.0 <= self.jitter_m <= 0.1:
            return f"--jitter-m must be 0-0.1 m, got {self.jitter_m:g}"
        if self.plants not in _PLANTS:
            return f"--plants must be one of {', '.join(PLANT_KINDS)}, got {self.plants!r}"
        if self.robot not in _ROBOTS:
            return f"--robot must be one of {', '.join(ROBOT_KINDS)}, got {self.robot!r}"
        if not 0.0 <= self.missing_share <= 0.3 or not 0.0 <= self.weeds_per_m <= 5.0:
            return "missing plants must be a share 0-0.3 and weeds 0-5 per metre of lane"
        if not 0.0 <= self.ragged_m <= 1.0:
            return f"--ragged-m must be 0-1 m, got {self.ragged_m:g}"
        if not 2.0 <= self.headland_m <= 10.0:
            return f"--headland-m must be 2-10 m (room to turn, as the event's 2 m), got {self.headland_m:g}"
        if not (self.time_limit_s == 0.0 or 10.0 <= self.time_limit_s <= 36000.0):
            return f"--time-limit-s must be 10-36000 s (or 0: from the pattern), got {self.time_limit_s:g}"
        _, radius, cluster = _PLANTS[self.plants]
        free = self.spacing_m - 2.0 * radius - 6.0 * self.jitter_m
        width = 2.0 * _ROBOTS[self.robot][1]
        if free < width + 0.1:
            return (f"--spacing-m {self.spacing_m:g}: a lane between rows of {self.plants} (radius {radius:g} m, "
                    f"jitter {self.jitter_m:g} m) leaves {free:.2f} m, too little for the robot's {width:.2f} m "
                    "and 5 cm on each side")
        if self.pattern:
            from ..planning.row_navigator import PatternError, parse_pattern

            try:
                turns = parse_pattern(self.pattern)
            except PatternError as e:
                return f"--pattern: {e}"
            try:
                lane_sequence(turns, self.rows - 1, 0, 1)
            except ValueError as e:
                return f"--pattern {self.pattern}: {e}"
        return ""


def lane_sequence(turns: Any, lanes: int, start: int, left_sign: int) -> list[int]:
    """The lanes a pattern drives (start lane first) in a field of ``lanes`` lanes; ``left_sign`` +1 when the lane
    numbers grow to the left of the start lane's driving direction. ValueError when a turn leaves the field."""
    seq = [start]
    d = left_sign
    for t in turns:
        nxt = seq[-1] + (t.lanes if t.side == "left" else -t.lanes) * d
        if not 0 <= nxt < lanes:
            raise ValueError(f"turn {t} from lane {seq[-1]} leads out of the field (lanes 0-{lanes - 1}, lane 0 "
                             "on the right at the start)")
        seq.append(nxt)
        d = -d
    return seq


def random_pattern(lanes: int, rng: np.random.Generator, turns: int | None = None) -> str:
    """A pattern of the event's kind for a field of ``lanes`` lanes, started in lane 0 (the outermost on the
    right): a few turns into the next lane, then skips of up to three lanes; no lane twice."""
    from ..planning.row_navigator import Turn, format_pattern

    want = min(lanes - 1, 6) if turns is None else turns
    lane, d, seen, out = 0, 1, {0}, []
    for k in range(want):
        opts = []
        for n in (1, 2, 3):
            for side in ("left", "right"):
                nxt = lane + (n if side == "left" else -n) * d
                if 0 <= nxt < lanes and nxt not in seen:
                    opts.append(Turn(side, n))
        if not opts:
            break
        if k < 2:  # the event starts with adjacent turns
            ones = [t for t in opts if t.lanes == 1]
            opts = ones or opts
        t = opts[int(rng.integers(len(opts)))]
        lane += (t.lanes if t.side == "left" else -t.lanes) * d
        seen.add(lane)
        d = -d
        out.append(t)
    return format_pattern(out)


def _row_y(x: FloatArray, k: int, sp: float, c: float, length: float) -> FloatArray:
    return k * sp + c * x * (length - x)


GAP_M = (0.3, 0.85)  # the stretch of row whose plants are left out; with the plants either side, at most ~1 m bare
GAP_APART_M = 1.0  # two gaps of one row are at least this far apart (plants between them)


def _apart(a: float, b: float, gaps: list[tuple[float, float]], sep: float) -> bool:
    return all(b2 + sep < a or b + sep < a2 for a2, b2 in gaps)


def _gaps(rng: np.random.Generator, length: float, share: float) -> list[tuple[float, float]]:
    """Gaps (GAP_M long, GAP_APART_M apart) covering about ``share`` of the row's length between its first and last
    metre."""
    inner0, inner1 = 1.0, length - 1.0
    want = share * max(0.0, inner1 - inner0)
    gaps: list[tuple[float, float]] = []
    tries = 0
    while sum(b - a for a, b in gaps) < want - 0.15 and tries < 400:
        tries += 1
        g = float(rng.uniform(*GAP_M))
        a = float(rng.uniform(inner0, max(inner0, inner1 - g)))
        if _apart(a, a + g, gaps, GAP_APART_M):
            gaps.append((a, a + g))
    return sorted(gaps)


def generate_field(spec: FieldSpec) -> str:
    """The scenario text (TOML) of a generated field (module docstring). FieldSpecError for a spec that
    :meth:`FieldSpec.problem` refuses."""
    why = spec.problem()
    if why:
        raise FieldSpecError(why)
    rng = np.random.default_rng(spec.seed)
    n, sp, L, C = spec.rows, spec.spacing_m, spec.length_m, spec.curvature
    lanes = n - 1
    ps, pr, cluster = _PLANTS[spec.plants]
    pattern = spec.pattern or random_pattern(lanes, rng)
    from ..planning.row_navigator import parse_pattern

    turns = parse_pattern(pattern)
    seq = lane_sequence(turns, lanes, 0, 1)
    a = rng.uniform(-spec.ragged_m, spec.ragged_m, n)
    b = rng.uniform(-spec.ragged_m, spec.ragged_m, n)
    rows = []
    gaps_of: list[list[tuple[float, float]]] = [[] for _ in range(n)]
    for k in range(n):
        gaps_of[k] += _gaps(rng, L + b[k] - a[k], spec.gap_share)
    for k in range(n - 1):  # a third of the gaps on both sides of a lane
        for g0, g1 in list(gaps_of[k]):
            if rng.random() < 1.0 / 3.0:
                off = a[k] - a[k + 1]  # the same stretch of x on the next row
                lo, hi = g0 + off, g1 + off
                if lo > 1.0 and hi < L + b[k + 1] - a[k + 1] - 1.0 and _apart(lo, hi, gaps_of[k + 1], GAP_APART_M):
                    gaps_of[k + 1].append((lo, hi))
    for k in range(n):
        length_k = L + b[k] - a[k]
        xs = np.linspace(a[k], L + b[k], max(2, int(math.ceil((L + b[k] - a[k]) / 0.25)) + 1))
        pts = np.column_stack((xs, _row_y(xs, k, sp, C, L)))
        arc = polyline_length_m(pts)
        s_plants = np.arange(0.0, arc + 1e-9, ps)
        inner = s_plants[(s_plants > 1.0) & (s_plants < arc - 1.0)]
        miss = [m for m in inner[rng.random(len(inner)) < spec.missing_share]  # single plants, away from the gaps
                if _apart(float(m), float(m), gaps_of[k], 0.5)]
        gaps = sorted(gaps_of[k] + [(float(s) - 0.01, float(s) + 0.01) for s in miss])
        rows.append((pts, gaps, length_k))
    lines = [
        f"# `{spec.command()}`",
        f"# {n} rows {sp:g} m apart, {L:g} m long, curvature {C:g} 1/m (row k: y = k * {sp:g} + {C:g} x ({L:g} - x)),",
        f"# gap share {spec.gap_share:g}, planting jitter {spec.jitter_m:g} m, {spec.plants}, seed {spec.seed}. "
        "Lane 0 (the start) is on the right.",
        "[scenario]",
        f"name = {json.dumps(spec.name or _default_name(spec))}",
        f'description = "{n} rows of {spec.plants}, {L:g} m, curvature {C:g}, gaps {spec.gap_share:g}, '
        f'jitter {spec.jitter_m:g} m: pattern {pattern}"',
    ]
    est = sum(L / FOLLOW_SPEED_M_S for _ in seq) + TURN_TIME_S * len(turns)
    limit = spec.time_limit_s or (180.0 if est <= 150.0 else 10.0 * math.ceil(1.3 * est / 10.0))
    lines += [f"duration_s = {limit:g}", f"world_seed = {spec.seed}", ""]
    robot_lines, _, _ = _ROBOTS[spec.robot]
    x0 = float(min(a[0], a[1])) - 0.7
    y0 = 0.5 * sp + C * x0 * (L - x0)
    yaw0 = math.degrees(math.atan(C * (L - 2.0 * x0)))
    lines += ["[robot]", robot_lines, f"start = {{ x_m = {x0:.4f}, y_m = {y0:.4f}, yaw_deg = {yaw0:.4f} }}", "",
              "[laser]", 'model = "tim561"', "mount = { x_m = 0.2, y_m = 0.0, yaw_deg = 0.0 }", ""]
    lines += ["[field]", f'pattern = "{pattern}"', f"time_limit_s = {limit:g}", f"row_spacing_m = {sp:g}", ""]
    for pts, gaps, _ in rows:
        lines += ["[[rows]]", "points = [" + ", ".join(f"[{x:.4f}, {y:.4f}]" for x, y in pts) + "]",
                  f"plant_spacing_m = {ps:g}", f"plant_radius_m = {pr:g}", f"cluster = {cluster}",
                  f"jitter_m = {spec.jitter_m:g}"]
        if gaps:
            lines.append("gaps = [" + ", ".join(f"[{g0:.3f}, {g1:.3f}]" for g0, g1 in gaps) + "]")
        lines.append("")
    if spec.weeds_per_m > 0:
        for k in range(lanes):
            x_lo, x_hi = float(max(a[k], a[k + 1])) + 0.5, float(min(b[k], b[k + 1])) + L - 0.5
            for x in np.arange(x_lo, x_hi - 0.5, 1.0):
                cnt = int(rng.poisson(spec.weeds_per_m))
                if cnt == 0:
                    continue
                xm = x + 0.5
                yc = (k + 0.5) * sp + C * xm * (L - xm)
                half = 0.5 * sp - pr - 3.0 * spec.jitter_m - 0.03 - abs(C * (L - 2.0 * xm)) * 0.5
                if half <= 0.02:
                    continue
                lines += ["[[weeds]]", f"region = [{x:.3f}, {yc - half:.3f}, {x + 1.0:.3f}, {yc + half:.3f}]",
                          f"count = {cnt}", "radius_m = 0.015", ""]
    xs = np.linspace(0.0, L, 50)
    bow = C * xs * (L - xs)
    fx0 = float(a.min()) - spec.headland_m
    fx1 = L + float(b.max()) + spec.headland_m
    fy0 = float(bow.min()) - 1.2
    fy1 = (n - 1) * sp + float(bow.max()) + 1.2
    lines += ["# the fence round the headlands", "[[walls]]",
              f"points = [[{fx0:.3f}, {fy0:.3f}], [{fx1:.3f}, {fy0:.3f}], [{fx1:.3f}, {fy1:.3f}], [{fx0:.3f}, {fy1:.3f}]]",
              "closed = true", ""]
    layout = _layout_of_rows([r[0] for r in rows], Pose2D(x0, y0, math.radians(yaw0)))
    for g in layout.goals(seq):
        lines += ["[[goals]]", f"x_m = {g.x_m:.4f}", f"y_m = {g.y_m:.4f}", f"tolerance_m = {g.tolerance_m:g}", ""]
    lines += ["[meta]", 'row_method = "ransac"', ""]
    return "\n".join(lines)


def _default_name(spec: FieldSpec) -> str:
    return f"field_{spec.rows}x{spec.length_m:g}_s{spec.seed}"


# ---- lanes -------------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Lane:
    """One lane: its centre line (k, 2) in the rows' direction, m, where both its rows stand; half the distance
    between its rows; how far its rows reach beyond the centre line's start and end (the longer row), m."""

    centre: FloatArray
    length_m: float
    half_width_m: float
    over_m: tuple[float, float] = (0.0, 0.0)

    def end_over_m(self, direction: int) -> float:
        """How far the lane's rows reach beyond its centre line's end when it is driven in ``direction``."""
        return self.over_m[1] if direction > 0 else self.over_m[0]


@dataclass(frozen=True)
class FieldLayout:
    """The lanes of a field (module docstring): ``lanes[i]`` between row i and row i + 1; ``start_lane`` the lane
    of the start and ``start_dir`` +1 when the start faces along the rows' direction (their points' order);
    ``left_sign`` +1 when lane numbers grow to the left of the rows' direction."""

    lanes: tuple[Lane, ...]
    start_lane: int
    start_dir: int
    left_sign: int

    @staticmethod
    def of(sc: "Scenario") -> "FieldLayout":
        return _layout_of_rows(sc.world.row_lines, sc.start)

    def sequence(self, pattern: str) -> list[int]:
        """The lanes the pattern drives, the start lane first (ValueError when it leads out of the field)."""
        from ..planning.row_navigator import parse_pattern

        return lane_sequence(parse_pattern(pattern), len(self.lanes), self.start_lane, self.left_sign * self.start_dir)

    def directions(self, seq: list[int]) -> list[int]:
        """The direction each lane of ``seq`` is driven in (+1 along the rows' direction)."""
        return [self.start_dir * (1 if k % 2 == 0 else -1) for k in range(len(seq))]

    def goals(self, seq: list[int]) -> list[Goal]:
        """The pattern's goals: where each lane of ``seq`` is left, 0.4 m beyond its furthest row end on its centre
        line, reached within 0.4 m (the last, where the robot stops, within 0.25 m at 0.5 m)."""
        out = []
        for k, (lane, d) in enumerate(zip(seq, self.directions(seq))):
            ln = self.lanes[lane]
            c = ln.centre if d > 0 else ln.centre[::-1]
            last = k == len(seq) - 1
            beyond = 0.5 if last else 0.4
            tang = c[-1] - c[-2]
            tang = tang / max(float(np.hypot(*tang)), 1e-9)
            end = c[-1] + tang * (ln.end_over_m(d) + beyond)
            out.append(Goal(float(end[0]), float(end[1]), tolerance_m=0.25 if last else 0.4))
        return out


def _lane_between(r0: FloatArray, r1: FloatArray) -> Lane:
    """The centre line halfway between two rows where both stand (from row 0's points, 0.1 m apart)."""
    n = max(2, int(math.ceil(polyline_length_m(r0) / 0.1)) + 1)
    p0, _ = resample_polyline(r0, np.linspace(0.0, polyline_length_m(r0), n))
    s1, off = along_and_offset_m(p0[:, 0], p0[:, 1], r1)
    inside = (s1 > 1e-6) & (s1 < polyline_length_m(r1) - 1e-6)
    foot, _ = resample_polyline(r1, s1)
    mid = 0.5 * (p0 + foot)[inside]
    if len(mid) < 2:
        raise ValueError("two neighbouring rows do not stand side by side")
    return Lane(mid, polyline_length_m(mid), 0.5 * float(np.median(np.abs(off[inside]))),
                (_over(mid, (r0[0], r0[-1], r1[0], r1[-1]), True), _over(mid, (r0[0], r0[-1], r1[0], r1[-1]), False)))


def _over(mid: FloatArray, ends: tuple[FloatArray, ...], start: bool) -> float:
    """How far beyond the centre line's start (or end) the furthest of the rows' end points reaches, m (>= 0)."""
    p, q = (mid[0], mid[1]) if start else (mid[-1], mid[-2])
    t = (p - q) / max(float(np.hypot(*(p - q))), 1e-9)
    return max(0.0, *(float((e - p) @ t) for e in ends))


def _layout_of_rows(rows: list[FloatArray], start: Pose2D) -> FieldLayout:
    if len(rows) < 2:
        raise ValueError("a field needs at least two rows")
    lanes = tuple(_lane_between(np.asarray(rows[k], float), np.asarray(rows[k + 1], float)) for k in range(len(rows) - 1))
    best, dist = 0, math.inf
    for i, ln in enumerate(lanes):
        _, off = along_and_offset_m(np.array([start.x_m]), np.array([start.y_m]), ln.centre)
        if abs(off[0]) < dist:
            best, dist = i, abs(float(off[0]))
    c = lanes[best].centre
    tang = c[1] - c[0]
    d = 1 if math.cos(start.yaw_rad) * tang[0] + math.sin(start.yaw_rad) * tang[1] > 0 else -1
    left = 1
    if len(lanes) > 1:
        m = lanes[1].centre[len(lanes[1].centre) // 2]
        _, off = along_and_offset_m(np.array([m[0]]), np.array([m[1]]), lanes[0].centre)
        left = 1 if off[0] > 0 else -1
    return FieldLayout(lanes, best, d, left)


# ---- scoring -----------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class LaneVisit:
    """The robot in one lane without leaving it: from ``t_in_s`` to ``t_out_s``, along the lane's centre line from
    ``s_in_m`` to ``s_out_m`` (m from the centre line's start); ``complete`` when end to end."""

    lane: int
    t_in_s: float
    t_out_s: float
    s_in_m: float
    s_out_m: float
    length_m: float
    complete: bool

    @property
    def direction(self) -> int:
        return 1 if self.s_out_m >= self.s_in_m else -1

    @property
    def depth_m(self) -> float:
        """How far into the lane the robot got from the end it entered at."""
        return abs(self.s_out_m - self.s_in_m)


@dataclass(frozen=True)
class FieldScore:
    """A run scored on its field (module docstring). ``lanes`` are the lanes driven in the pattern's order with
    their times; ``expected`` the pattern's lanes."""

    rows_completed: int
    pattern_completed: bool
    plants_touched: int
    distance_m: float  # S: the distance in rows, within the task's time
    time_s: float  # t: the pattern's finish, or the task's time
    score_m: float  # S_final
    total_m: float  # the pattern's lanes end to end
    penalty_m: float
    time_limit_s: float
    expected: tuple[int, ...]
    visits: tuple[LaneVisit, ...] = field(default_factory=tuple)
    lanes: tuple[LaneVisit, ...] = field(default_factory=tuple)

    def summary(self) -> dict[str, Any]:
        """The summary.json entries."""
        return {"rows_completed": self.rows_completed, "pattern_completed": self.pattern_completed,
                "plants_touched": self.plants_touched, "field_distance_m": round(self.distance_m, 3),
                "field_time_s": round(self.time_s, 3), "field_score_m": round(self.score_m, 3)}

    def to_dict(self) -> dict[str, Any]:
        """field.json: the summary, the rule's inputs and every lane driven in order with its time."""
        return {**self.summary(), "pattern_lanes": list(self.expected), "total_lane_length_m": round(self.total_m, 3),
                "penalty_m": round(self.penalty_m, 3), "time_limit_s": self.time_limit_s,
                "lanes": [{"lane": v.lane, "t_in_s": round(v.t_in_s, 3), "t_out_s": round(v.t_out_s, 3),
                           "time_s": round(v.t_out_s - v.t_in_s, 3), "length_m": round(v.length_m, 3),
                           "direction": v.direction} for v in self.lanes],
                "turns_s": [round(b.t_in_s - a.t_out_s, 3) for a, b in zip(self.lanes, self.lanes[1:])]}


def plants_touched(stems: FloatArray, centres: FloatArray, radius_m: float) -> int:
    """How many stems (k, 2) were ever inside a disc of ``radius_m`` at any of the centres (n, 2), m."""
    if not len(stems) or not len(centres):
        return 0
    cell = max(radius_m, 0.05)
    # only the stems near the path: bucket the path's centres on a grid of the disc's size
    keys = np.floor(centres / cell).astype(np.int64)
    buckets: dict[tuple[int, int], list[int]] = {}
    for i, (kx, ky) in enumerate(map(tuple, keys)):
        buckets.setdefault((int(kx), int(ky)), []).append(i)
    hit = 0
    sk = np.floor(stems / cell).astype(np.int64)
    for j in range(len(stems)):
        near: list[int] = []
        for dx in (-1, 0, 1):
            for dy in (-1, 0, 1):
                near += buckets.get((int(sk[j, 0]) + dx, int(sk[j, 1]) + dy), [])
        if near:
            d = np.hypot(centres[near, 0] - stems[j, 0], centres[near, 1] - stems[j, 1])
            hit += int(d.min() < radius_m)
    return hit


def lane_visits(layout: FieldLayout, t_s: FloatArray, xy: FloatArray) -> list[LaneVisit]:
    """The robot's stays in the lanes (footprint centres ``xy`` (n, 2) at times ``t_s``), in time order."""
    n = len(t_s)
    label = np.full(n, -1)
    s_all = np.zeros(n)
    for i, ln in enumerate(layout.lanes):
        for k0 in range(0, n, 4000):  # in pieces: a (samples x segments) array per piece, not per run
            part = slice(k0, k0 + 4000)
            s, off = along_and_offset_m(xy[part, 0], xy[part, 1], ln.centre)
            inside = (np.abs(off) < ln.half_width_m) & (s > 0.02) & (s < ln.length_m - 0.02)
            label[part][inside] = i
            s_all[part][inside] = s[inside]
    out = []
    k = 0
    while k < n:
        if label[k] < 0:
            k += 1
            continue
        j = k
        while j + 1 < n and label[j + 1] == label[k]:
            j += 1
        ln = layout.lanes[int(label[k])]
        s0, s1 = float(s_all[k]), float(s_all[j])
        lo, hi = min(s0, s1), max(s0, s1)
        complete = lo <= 0.3 and hi >= ln.length_m - 0.3 and abs(s1 - s0) >= ln.length_m - 0.6
        out.append(LaneVisit(int(label[k]), float(t_s[k]), float(t_s[j]), s0, s1, ln.length_m, complete))
        k = j + 1
    return out


def score_field(sc: "Scenario", t_s: FloatArray, centres: FloatArray, radius_m: float) -> FieldScore:
    """The run on ``sc``'s field (``sc.field`` set): the robot's footprint centres (n, 2) at times ``t_s`` and its
    footprint radius (module docstring)."""
    assert sc.field is not None
    layout = FieldLayout.of(sc)
    seq = layout.sequence(sc.field.pattern)
    dirs = layout.directions(seq)
    limit = sc.field.time_limit_s
    t_s = np.asarray(t_s, dtype=float)
    centres = np.asarray(centres, dtype=float).reshape(-1, 2)
    stems = np.vstack(sc.world.row_plants) if sc.world.row_plants else np.zeros((0, 2))
    touched = plants_touched(stems, centres, radius_m)
    within = t_s <= limit + 1e-9
    visits = lane_visits(layout, t_s[within], centres[within]) if within.any() else []
    total = float(sum(layout.lanes[k].length_m for k in seq))
    done: list[LaneVisit] = []
    dist = 0.0
    j = 0
    for v in visits:
        if j >= len(seq):
            break
        if v.depth_m < 1.0 and not v.complete:  # a corner of a lane brushed on the headland
            continue
        if v.lane != seq[j]:
            break  # out of the pattern's order: the distance stops
        if v.complete and v.direction == dirs[j]:
            done.append(v)
            dist += v.length_m
            j += 1
            continue
        dist += v.depth_m  # the robot stopped or left the lane part way
        break
    finished = j == len(seq)
    t_meas = done[-1].t_out_s if finished and done else limit
    penalty = 0.02 * total * touched
    score = (dist - penalty) * limit / max(t_meas, 1e-6)
    return FieldScore(j, finished, touched, dist, t_meas, score, total, penalty, limit, tuple(seq), tuple(visits),
                      tuple(done))


def with_pattern(sc: "Scenario", pattern: str) -> "Scenario":
    """``sc`` with another turn pattern: the field's pattern and the goals (each lane's exit) replaced. ValueError
    when the scenario has no field or the pattern leaves it."""
    from ..planning.row_navigator import format_pattern, parse_pattern

    if sc.field is None:
        raise ValueError(f"scenario {sc.name!r} has no [field]: a turn pattern needs one")
    text = format_pattern(parse_pattern(pattern))
    layout = FieldLayout.of(sc)
    seq = layout.sequence(text)
    return replace(sc, field=replace(sc.field, pattern=text), goals=layout.goals(seq))


# ---- difficulties -----------------------------------------------------------------------------------------------

#: The built-in fields' levels: (name, rows, length m, curvature 1/m, gap share, jitter m, ragged ends m)
DIFFICULTIES = (
    ("easy", 6, 8.0, 0.0, 0.0, 0.015, 0.1),
    ("medium", 8, 10.0, 0.006, 0.08, 0.02, 0.25),
    ("hard", 10, 12.0, 0.015, 0.15, 0.03, 0.35),
)


#: The built-in fields (sim/scenarios/NAME.toml, generated by ``generate_field`` from these): name -> spec
BUILTIN_FIELDS: dict[str, FieldSpec] = {}


def difficulty_spec(level: str, seed: int, robot: str = "diff_drive") -> FieldSpec:
    """The :class:`FieldSpec` of a difficulty level (:data:`DIFFICULTIES`) with ``seed``; a random pattern."""
    for name, rows, length, curv, gaps, jitter, ragged in DIFFICULTIES:
        if name == level:
            return FieldSpec(rows=rows, length_m=length, curvature=curv, gap_share=gaps, jitter_m=jitter,
                             ragged_m=ragged, seed=seed, robot=robot, name=f"field_{level}_{robot}_{seed}")
    raise ValueError(f"difficulty must be one of {', '.join(d[0] for d in DIFFICULTIES)}, got {level!r}")


BUILTIN_FIELDS.update({
    "field_easy": replace(difficulty_spec("easy", 1), name="field_easy"),
    "field_medium": replace(difficulty_spec("medium", 1), name="field_medium"),
    "field_hard": replace(difficulty_spec("hard", 1), name="field_hard"),
    "field_hard_car": replace(difficulty_spec("hard", 2, "ackermann"), name="field_hard_car"),
})
