from agnav_host.sim import load_scenario, run_scenario, write_outputs


def _files(tmp_path, name, seed, tag):
    out = tmp_path / f"{tag}"
    write_outputs(run_scenario(load_scenario("corridor_obstacles"), seed=seed, duration_s=6.0), out, plot=False)
    return (out / "summary.json").read_bytes(), (out / "trajectory.csv").read_bytes()


def test_same_seed_is_byte_identical_and_different_seed_differs(tmp_path):
    a = _files(tmp_path, "corridor_obstacles", 5, "a")
    b = _files(tmp_path, "corridor_obstacles", 5, "b")
    c = _files(tmp_path, "corridor_obstacles", 6, "c")
    assert a == b
    assert a[1] != c[1]


def test_moving_obstacles_move():
    sc = load_scenario("timed_yard")
    p0 = sc.world.circles_at(0.0)[-2]
    p1 = sc.world.circles_at(2.0)[-2]
    assert abs(p1[1] - p0[1]) == 2.0  # 1 m/s along x = 10
