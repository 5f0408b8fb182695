import json

from agnav_host.cli import build_parser, main

KEYS = {"feasible", "reason", "earliest_arrival_s", "duration_s", "max_steering_deg", "max_speed_mps"}


def test_plan_json_keys_and_negative_numbers(capsys):
    rc = main(["plan", "--start", "0,0,0", "--goal", "-3,5,90", "--arrive-in", "20", "--json"])
    out = json.loads(capsys.readouterr().out)
    assert rc == 0
    assert KEYS <= set(out)
    assert out["feasible"] is True and out["duration_s"] == 20.0
    assert out["max_steering_deg"] <= 20.0 and out["max_speed_mps"] <= 2.0


def test_plan_infeasible_reports_reason_and_earliest(capsys):
    rc = main(["plan", "--start", "0,0,45", "--goal", "100,100,45", "--arrive-in", "60", "--json"])
    out = json.loads(capsys.readouterr().out)
    assert rc == 3
    assert out["feasible"] is False and "too early" in out["reason"]
    assert 72.0 < out["earliest_arrival_s"] < 74.0


def test_plan_negative_start_and_steer_parse():
    ns = build_parser().parse_args(["plan", "--start=-1,-2,-30", "--goal", "3,4,5", "--start-steer-deg=-5"])
    assert ns.start == (-1.0, -2.0, -30.0)
    assert main(["plan", "--start", "-1,-2,-30", "--goal", "-6,-4,-150", "--start-steer-deg", "-5", "--arrive-in", "30"]) in (0, 3)


def test_plan_text_output(capsys):
    assert main(["plan", "--start", "0,2,0", "--goal", "4,2,0", "--arrive-in", "20"]) == 0
    assert "feasible" in capsys.readouterr().out
