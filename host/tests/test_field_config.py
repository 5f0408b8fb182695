"""The row navigator's field on the robot path: `[field] pattern`, `row_spacing_m` and `reverse` in the host
config, `agnav run --pattern / --row-spacing / --no-reverse` over them, and the served SIL's host config
carrying a whole field's pattern and spacing to the `agnav run` it prints."""

from __future__ import annotations

import argparse

import pytest

from agnav_host.cli.run import field_from
from agnav_host.link.config import ConfigError, load_config
from agnav_host.sil.server import host_config_text
from agnav_host.sim import load_scenario


def _ns(**kw: object) -> argparse.Namespace:
    base = dict(turns=None, row_side=None, row_offset=None, row_half_width=None, row_method=None, pattern=None,
                row_spacing=None, no_reverse=False)
    base.update(kw)
    return argparse.Namespace(**base)


def _cfg(tmp_path, text: str):
    p = tmp_path / "host.toml"
    p.write_text(text, encoding="utf-8")
    return load_config(p)


def test_the_field_table_gives_the_row_navigator_its_pattern_spacing_and_reverse(tmp_path):
    cfg = _cfg(tmp_path, '[field]\npattern = "S-2L-1R-F"\nrow_spacing_m = 0.5\nreverse = false\n')
    f = field_from(_ns(), cfg)
    assert (f.pattern, f.row_spacing_m, f.reverse) == ("S-2L-1R-F", 0.5, False)
    assert f.problem() == ""


def test_the_options_win_over_the_field_table(tmp_path):
    cfg = _cfg(tmp_path, '[field]\npattern = "S-2L-1R-F"\nrow_spacing_m = 0.5\n')
    f = field_from(_ns(pattern="S-1R-F", row_spacing=0.9, no_reverse=True), cfg)
    assert (f.pattern, f.row_spacing_m, f.reverse) == ("S-1R-F", 0.9, False)


def test_without_a_field_table_the_defaults_hold(tmp_path):
    f = field_from(_ns(), _cfg(tmp_path, ""))
    assert (f.pattern, f.row_spacing_m, f.reverse) == ("", 0.75, True)


@pytest.mark.parametrize("line, words", [
    ('pattern = "S-9Q-F"', ["[field] pattern"]),
    ("row_spacing_m = 50.0", ["[field] row_spacing_m", "0.2-10"]),
    ("row_spacing_m = 0.1", ["[field] row_spacing_m", "0.2-10"]),
    ('reverse = "yes"', ["[field] reverse", "true or false"]),
])
def test_a_bad_field_value_is_named(tmp_path, line, words):
    with pytest.raises(ConfigError) as e:
        _cfg(tmp_path, f"[field]\n{line}\n")
    for w in words:
        assert w in str(e.value), str(e.value)


def test_a_row_spacing_option_out_of_range_is_refused_by_the_field_check(tmp_path):
    f = field_from(_ns(row_spacing=25.0), _cfg(tmp_path, ""))
    assert "row spacing must be a number 0.2-10 m" in f.problem()


def test_the_served_sil_writes_a_whole_field_s_pattern_and_spacing_into_the_host_config(tmp_path):
    sc = load_scenario("field_easy")
    assert sc.field is not None
    p = tmp_path / "host.toml"
    p.write_text(host_config_text(sc, [], "tcp:127.0.0.1:5760"), encoding="utf-8")
    cfg = load_config(p)
    assert cfg.field.pattern == sc.field.pattern and cfg.field.pattern
    assert cfg.field.row_spacing_m == pytest.approx(sc.field.row_spacing_m)
