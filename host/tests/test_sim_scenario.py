import pytest

from agnav_host.sim import DEFAULT_SCENARIO, ScenarioError, builtin_names, load_scenario, parse_scenario
from agnav_host.sim.scenario import builtin_text

GOOD = """\
[scenario]
name = "t"
description = "test"

[robot]
model = "diff_drive"
start = { x_m = 0.0, y_m = 0.0, yaw_deg = 0.0 }

[[goals]]
x_m = 3.0
y_m = 0.0

[[circles]]
x_m = 1.0
y_m = 1.0
radius_m = 0.2

[[circles]]
x_m = 2.0
y_m = 1.0
radius_m = 0.2
"""


def test_all_builtins_parse():
    names = builtin_names()
    for n in ("corridor_obstacles", "canyon", "greenhouse", "crop_rows", "curvy_row", "hole_field", "timed_yard"):
        assert n in names
        sc = load_scenario(n)
        assert sc.goals and sc.name == n
    assert load_scenario(None).name == DEFAULT_SCENARIO


def test_good_text_parses():
    sc = parse_scenario(GOOD)
    assert sc.world.circles.shape == (2, 3)


def _err(text):
    with pytest.raises(ScenarioError) as ei:
        parse_scenario(text, "x.toml")
    return ei.value


def test_bad_value_names_field_and_line():
    e = _err(GOOD.replace("radius_m = 0.2\n", "radius_m = -1\n", 2).replace("radius_m = -1\n", "radius_m = 0.2\n", 1))
    assert e.field == "circles[1].radius_m"
    assert e.line == 21
    assert "x.toml:21" in str(e) and "> 0" in str(e)


def test_wrong_type_and_unknown_key_and_inline_table():
    e = _err(GOOD.replace('x_m = 3.0', 'x_m = "far"'))
    assert (e.field, e.line) == ("goals[0].x_m", 10)
    e = _err(GOOD.replace('y_m = 0.0\n\n[[circles]]', 'y_m = 0.0\nspeed = 3\n\n[[circles]]'))
    assert (e.field, e.line) == ("goals[0].speed", 12)
    e = _err(GOOD.replace("yaw_deg = 0.0 }", "yaw_deg = true }"))
    assert (e.field, e.line) == ("robot.start.yaw_deg", 7)
    e = _err(GOOD.replace('model = "diff_drive"', 'model = "tank"'))
    assert (e.field, e.line) == ("robot.model", 6)


def test_missing_field_points_at_its_table_and_syntax_error_has_line():
    e = _err(GOOD.replace("x_m = 2.0\n", ""))
    assert "x_m" in e.message and e.line == 18 and e.field == "circles[1]"
    e = _err(GOOD.replace("y_m = 1.0\nradius_m = 0.2\n\n[[circles]]", "y_m = = 1\nradius_m = 0.2\n\n[[circles]]"))
    assert e.field == "<toml>" and e.line == 15


def test_multiline_arrays_do_not_confuse_the_locator():
    text = GOOD + '\n[[walls]]\npoints = [\n  [0.0, 0.0],\n  [1.0, "x"],\n]\n'
    e = _err(text)
    assert e.field == "walls[0].points[1]" and e.line == 26  # the line of the element


def test_unknown_builtin_and_missing_file():
    with pytest.raises(ScenarioError, match="built-ins"):
        load_scenario("no_such_scenario")
    with pytest.raises(ScenarioError, match="cannot read"):
        load_scenario("/nonexistent/dir/s.toml")


def test_builtin_text_is_toml():
    assert "[scenario]" in builtin_text("canyon")
