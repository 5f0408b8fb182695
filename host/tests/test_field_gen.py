"""Whole fields: the generator (`agnav field new`), the lanes of a field, and the Field Robot Event's scoring."""

from __future__ import annotations

import math

import numpy as np
import pytest

from agnav_host.cli import main
from agnav_host.planning.row_navigator import PatternError, Turn, format_pattern, parse_pattern
from agnav_host.sim.field_gen import (
    BUILTIN_FIELDS,
    DIFFICULTIES,
    FieldLayout,
    FieldSpec,
    FieldSpecError,
    generate_field,
    lane_sequence,
    plants_touched,
    score_field,
    with_pattern,
)
from agnav_host.sim.metrics import along_and_offset_m
from agnav_host.sim.scenario import builtin_text, load_scenario, parse_scenario


def _field(**kw: object) -> object:
    return parse_scenario(generate_field(FieldSpec(**kw)), "<field>")  # type: ignore[arg-type]


# ---- patterns --------------------------------------------------------------------------------------------------

def test_pattern_reads_the_events_notation_with_any_dashes_and_case():
    assert parse_pattern("S-1L-2R-1L-3R-F") == (Turn("left", 1), Turn("right", 2), Turn("left", 1), Turn("right", 3))
    assert parse_pattern("s \u2013 3l \u2013 2L, 12r - f") == (Turn("left", 3), Turn("left", 2), Turn("right", 12))
    assert parse_pattern("S-F") == ()
    assert format_pattern(parse_pattern("s-1l-2r-f")) == "S-1L-2R-F"


@pytest.mark.parametrize("text,why", [("1L-2R-F", "start with S"), ("S-1L-2R", "end with F"), ("S-2X-F", "'2X'"),
                                      ("S-0L-F", "'0L'"), ("S-L-F", "'L'"), ("", "start with S")])
def test_pattern_refuses_what_is_not_the_notation(text, why):
    with pytest.raises(PatternError, match=why):
        parse_pattern(text)


def test_lane_sequence_turns_left_and_right_as_the_robot_drives():
    # lane 0 driven up (+x): 1L is the next lane up; lane 1 driven back: 1R (the robot's right) is lane 2 again
    assert lane_sequence(parse_pattern("S-1L-1R-2L-1R-3R-F"), 8, 0, 1) == [0, 1, 2, 4, 5, 2]
    with pytest.raises(ValueError, match="out of the field"):
        lane_sequence(parse_pattern("S-1R-F"), 5, 0, 1)  # lane 0 is the outermost on the right


# ---- the generated field -------------------------------------------------------------------------------------

def test_rows_bend_as_the_documented_form():
    L, C, sp = 10.0, 0.01, 0.75
    sc = _field(rows=4, length_m=L, curvature=C, spacing_m=sp, jitter_m=0.0, seed=3)
    assert len(sc.world.row_lines) == 4
    for k, line in enumerate(sc.world.row_lines):
        x = line[:, 0]
        np.testing.assert_allclose(line[:, 1], k * sp + C * x * (L - x), atol=1e-3)
    mid = sc.world.row_lines[0][np.argmin(np.abs(sc.world.row_lines[0][:, 0] - L / 2)), 1]
    assert mid == pytest.approx(C * L * L / 4, abs=0.01)  # the bow at mid-length


def test_stems_follow_the_design_lines_with_the_planting_jitter():
    sc = _field(rows=3, length_m=20.0, spacing_m=1.0, jitter_m=0.04, seed=5, missing_share=0.0, weeds_per_m=0.0)
    offs = np.concatenate([along_and_offset_m(st[:, 0], st[:, 1], ln)[1]
                           for ln, st in zip(sc.world.row_lines, sc.world.row_plants)])
    assert np.std(offs) == pytest.approx(0.04, rel=0.15)


def _bare_stretches(sc: object) -> list[tuple[float, float, float]]:
    """(start along the row, bare length, row length) between neighbouring stems, every row."""
    out = []
    for ln, st in zip(sc.world.row_lines, sc.world.row_plants):  # type: ignore[attr-defined]
        s = np.sort(along_and_offset_m(st[:, 0], st[:, 1], ln)[0])
        length = float(np.hypot(*np.diff(ln, axis=0).T).sum())
        out += [(float(a), float(b - a), length) for a, b in zip(s[:-1], s[1:])]
    return out


def test_gaps_cover_the_share_asked_none_longer_than_the_events_metre_none_at_the_row_ends():
    sc = _field(rows=6, length_m=20.0, gap_share=0.2, jitter_m=0.02, seed=11, missing_share=0.0)
    bare = _bare_stretches(sc)
    gaps = [(a, g, n) for a, g, n in bare if g > 0.3]
    assert gaps, "no gaps"
    assert max(g for _, g, _ in gaps) <= 1.15
    assert all(a >= 0.8 and a + g <= n - 0.8 for a, g, n in gaps)  # the first and last metre are planted
    share = sum(g for _, g, _ in gaps) / sum(n - 2.0 for n in {n for _, _, n in bare})
    assert 0.12 < share < 0.28
    # some gaps are on both sides of a lane: the same stretch of x bare on two neighbouring rows
    bare_x = []
    for st in sc.world.row_plants:
        x = np.sort(st[:, 0])
        bare_x.append([(a, b) for a, b in zip(x[:-1], x[1:]) if b - a > 0.3])
    both = sum(1 for k in range(len(bare_x) - 1) for a, b in bare_x[k] for c, d in bare_x[k + 1]
               if min(b, d) - max(a, c) > 0.2)
    assert both >= 1


def test_row_ends_are_uneven_and_the_start_is_the_outermost_right_lane_facing_along_the_rows():
    sc = _field(rows=6, ragged_m=0.3, seed=2)
    ends = [ln[-1, 0] for ln in sc.world.row_lines]
    assert np.ptp(ends) > 0.1
    lay = FieldLayout.of(sc)
    assert (lay.start_lane, lay.start_dir, lay.left_sign) == (0, 1, 1)
    _, off = along_and_offset_m(np.array([sc.start.x_m]), np.array([sc.start.y_m]), lay.lanes[1].centre)
    assert off[0] < 0  # lane 1 is on the start's left: lane 0 is the outermost on the right
    assert abs(math.degrees(sc.start.yaw_rad)) < 1.0
    assert sc.start.x_m < min(ln[0, 0] for ln in sc.world.row_lines[:2])  # before the rows


def test_generated_field_has_its_task_goals_fence_and_soft_plants():
    sc = _field(rows=5, seed=4, pattern="S-2L-1R-F")
    assert sc.field is not None and sc.field.pattern == "S-2L-1R-F" and sc.field.time_limit_s == 180.0
    lay = FieldLayout.of(sc)
    assert lay.sequence(sc.field.pattern) == [0, 2, 3]
    assert len(sc.goals) == 3  # where each lane of the pattern is left
    assert sc.world.soft_kinds == ("plant", "weed")
    stem = sc.world.row_plants[1][10]
    assert float(sc.world.clearance_m(stem[0], stem[1])[0]) > 0.5  # a plant is no obstacle; the fence is
    assert len(sc.world.segments) == 4


@pytest.mark.parametrize("kw,why", [
    ({"plants": "bush"}, "too little for the robot"),
    ({"curvature": 0.05}, "atan\\(C L\\)"),
    ({"rows": 3, "pattern": "S-3L-F"}, "out of the field"),
    ({"gap_share": 0.5}, "gap-share"),
    ({"headland_m": 1.0}, "headland"),
    ({"rows": 1}, "rows"),
])
def test_generator_refuses_a_field_that_does_not_fit(kw, why):
    with pytest.raises(FieldSpecError, match=why):
        generate_field(FieldSpec(**kw))  # type: ignore[arg-type]


def test_builtin_fields_are_what_the_generator_writes_and_grow_harder():
    assert set(BUILTIN_FIELDS) == {"field_easy", "field_medium", "field_hard", "field_hard_car"}
    for name, spec in BUILTIN_FIELDS.items():
        assert builtin_text(name) == generate_field(spec), f"{name}: regenerate it from sim.field_gen.BUILTIN_FIELDS"
        assert load_scenario(name).field is not None
    levels = [d[0] for d in DIFFICULTIES]
    assert levels == ["easy", "medium", "hard"]
    for col in (3, 4, 5):  # curvature, gap share, jitter never fall from one level to the next
        assert [d[col] for d in DIFFICULTIES] == sorted(d[col] for d in DIFFICULTIES)
    assert load_scenario("field_hard_car").robot_kind == "ackermann"


def test_field_new_writes_a_scenario_that_sim_loads(tmp_path, capsys):
    out = tmp_path / "f.toml"
    assert main(["field", "new", "--rows", "5", "--spacing-m", "0.8", "--length-m", "7", "--curvature", "0.01",
                 "--gap-share", "0.1", "--jitter-m", "0.03", "--seed", "9", "--pattern", "S-1L-2R-F",
                 "--out", str(out)]) == 0
    assert "S-1L-2R-F" in capsys.readouterr().out
    sc = load_scenario(str(out))
    assert sc.field is not None and sc.field.row_spacing_m == 0.8 and len(sc.world.row_lines) == 5
    assert out.read_text().startswith("# `agnav field new --rows 5 --spacing-m 0.8")


@pytest.mark.parametrize("args,why", [
    (["--rows", "4", "--pattern", "S-4L-F"], "leads out of the field"),
    (["--plants", "bush"], "too little for the robot"),
    (["--curvature", "1"], "curvature"),
])
def test_field_new_refuses_bad_options_with_exit_2_and_no_traceback(tmp_path, capsys, args, why):
    assert main(["field", "new", *args, "--out", str(tmp_path / "f.toml")]) == 2
    err = capsys.readouterr().err
    assert why in err and "Traceback" not in err
    assert not (tmp_path / "f.toml").exists()


def test_field_new_refuses_an_output_that_is_not_toml(tmp_path, capsys):
    assert main(["field", "new", "--out", str(tmp_path / "f.txt")]) == 2
    assert ".toml" in capsys.readouterr().err


# ---- scoring -----------------------------------------------------------------------------------------------------

def _drive(sc: object, lanes: list[int], speed: float = 0.4, dt: float = 0.05) -> tuple[np.ndarray, np.ndarray]:
    """A track along the given lanes' centre lines in turn, alternating directions, 0.5 m out at each end."""
    lay = FieldLayout.of(sc)  # type: ignore[arg-type]
    pts = []
    for k, lane in enumerate(lanes):
        c = lay.lanes[lane].centre
        c = c if k % 2 == 0 else c[::-1]
        t = (c[-1] - c[-2]) / np.hypot(*(c[-1] - c[-2]))
        t0 = (c[0] - c[1]) / np.hypot(*(c[0] - c[1]))
        pts += [c[0] + t0 * 0.5, *c, c[-1] + t * 0.5]
    p = np.array(pts)
    seg = np.hypot(*np.diff(p, axis=0).T)
    s = np.concatenate(([0.0], np.cumsum(seg)))
    tt = np.arange(0.0, s[-1] / speed, dt)
    xy = np.column_stack((np.interp(tt * speed, s, p[:, 0]), np.interp(tt * speed, s, p[:, 1])))
    return tt, xy


def test_score_counts_the_lanes_in_the_patterns_order_and_gives_the_time_bonus():
    sc = _field(rows=6, seed=1, pattern="S-1L-2R-F", ragged_m=0.0)
    t, xy = _drive(sc, [0, 1, 3])
    f = score_field(sc, t, xy, 0.2)
    assert (f.rows_completed, f.pattern_completed, f.plants_touched) == (3, True, 0)
    assert f.distance_m == pytest.approx(f.total_m) and f.penalty_m == 0.0
    assert f.time_s == pytest.approx(f.lanes[-1].t_out_s)
    assert f.score_m == pytest.approx(f.distance_m * 180.0 / f.time_s)
    s = f.summary()
    assert s["rows_completed"] == 3 and s["pattern_completed"] is True


def test_score_stops_at_the_first_lane_out_of_order():
    sc = _field(rows=6, seed=1, pattern="S-1L-2R-F", ragged_m=0.0)
    t, xy = _drive(sc, [0, 1, 2])  # 1R from lane 1 is lane 3, not 2
    f = score_field(sc, t, xy, 0.2)
    assert (f.rows_completed, f.pattern_completed) == (2, False)
    lay = FieldLayout.of(sc)
    assert f.distance_m == pytest.approx(lay.lanes[0].length_m + lay.lanes[1].length_m)
    assert f.time_s == 180.0 and f.score_m == pytest.approx(f.distance_m)  # no bonus: not finished


def test_score_penalises_each_plant_run_over_by_two_percent_of_the_patterns_length():
    sc = _field(rows=4, seed=1, pattern="S-F", ragged_m=0.0, weeds_per_m=0.0)
    t, xy = _drive(sc, [0])
    xy = xy.copy()
    xy[:, 1] -= 0.3  # 0.3 m to the right: the 0.2 m disc runs over row 0's stems
    f = score_field(sc, t, xy, 0.2)
    assert f.plants_touched > 10
    assert f.penalty_m == pytest.approx(0.02 * f.total_m * f.plants_touched)


def test_plants_touched_counts_each_stem_once_when_inside_the_disc():
    stems = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.3]])
    path = np.column_stack((np.linspace(-1, 3, 400), np.zeros(400)))
    assert plants_touched(stems, path, 0.2) == 2
    assert plants_touched(stems, path, 0.31) == 3
    assert plants_touched(stems, path[:0], 0.3) == 0


def test_with_pattern_replaces_the_pattern_and_the_goals():
    sc = _field(rows=6, seed=1, pattern="S-1L-F")
    sc2 = with_pattern(sc, "s-2l-1r-f")
    assert sc2.field.pattern == "S-2L-1R-F" and len(sc2.goals) == 3 and len(sc.goals) == 2
    with pytest.raises(ValueError, match="out of the field"):
        with_pattern(sc, "S-9L-F")
    with pytest.raises(ValueError, match="no \\[field\\]"):
        with_pattern(load_scenario("crop_rows"), "S-1L-F")
