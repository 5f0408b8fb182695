"""The run pictures (viz.world_plot): every kind of world object drawn, the goals, the speed-coloured path, the
robot's outline along it, and the PNGs of ``agnav sim``, ``agnav run``, ``agnav replay`` and the planner benchmark."""

import math

import numpy as np
import pytest

matplotlib = pytest.importorskip("matplotlib")
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from agnav_host.planning.base import RobotSpec  # noqa: E402
from agnav_host.sim.robots import AckermannParams, DiffDriveParams  # noqa: E402
from agnav_host.sim.runner import run_scenario  # noqa: E402
from agnav_host.sim.scenario import builtin_names, load_scenario, parse_scenario  # noqa: E402
from agnav_host.sim.world import World  # noqa: E402
from agnav_host.types import Goal, Pose2D  # noqa: E402
from agnav_host.viz.world_plot import (KIND_LABELS, Footprint, draw_goals, draw_run, draw_world,  # noqa: E402
                                       footprint_times, plot_run, rows_from_poses, run_figure)


@pytest.fixture
def ax():
    fig, a = plt.subplots()
    yield a
    plt.close(fig)


def by_gid(ax, gid):
    """Every artist on ``ax`` whose gid is ``gid``."""
    return [a for a in ax.findobj() if a.get_gid() == gid]


def n_items(artist):
    """Objects in one drawn collection (a circle collection counts its centres, a patch collection its paths)."""
    offs = artist.get_offsets()
    return len(offs) if len(artist.get_paths()) == 1 and len(offs) > 1 else len(artist.get_paths())


def rows_of(t, x, y, yaw, v):
    t = np.asarray(t, dtype=float)
    z = np.zeros_like(t)
    return np.column_stack((t, np.broadcast_to(x, t.shape), np.broadcast_to(y, t.shape), np.broadcast_to(yaw, t.shape),
                            np.broadcast_to(v, t.shape), z, z, z))


# ---- the world ------------------------------------------------------------------------------------------------

def test_draw_world_draws_every_object_kind_of_the_built_in_scenarios():
    seen = set()
    for name in builtin_names():
        fig, a = plt.subplots()
        try:
            counts = draw_world(a, load_scenario(name), t_s=5.0)
            for kind, n in counts.items():
                assert n > 0 and by_gid(a, kind), f"{name}: {kind} counted but not drawn"
            seen |= set(counts)
        finally:
            plt.close(fig)
    # every scenario object the built-ins use (steps that lower the ground and a given path: see the next test)
    assert seen >= {"wall", "box", "polygon", "post", "plant", "row_line", "weed", "mover", "hole", "step_up", "rut",
                    "landmark"}


def test_draw_world_draws_lowered_steps_and_the_given_path_of_a_scenario_file(ax):
    sc = parse_scenario("""
[scenario]
name = "drop"
[robot]
model = "diff_drive"
start = { x_m = 0.0, y_m = 0.0 }
[[goals]]
x_m = 5.0
y_m = 0.0
[[steps]]
x_m = 3.0
y_m = 0.0
height_m = -0.2
width_m = 2.0
depth_m = 1.0
[meta]
path = [[0.0, 0.0], [2.0, 1.0], [5.0, 0.0]]
""")
    counts = draw_world(ax, sc)
    assert counts["step_down"] == 1 and counts["given_path"] == 1
    (step,) = by_gid(ax, "step_down")
    box = step.get_paths()[0].vertices
    assert box[:, 0].min() == pytest.approx(3.0) and box[:, 0].max() == pytest.approx(4.0)  # 1 m beyond the edge
    assert box[:, 1].min() == pytest.approx(-1.0) and box[:, 1].max() == pytest.approx(1.0)  # 2 m wide
    (line,) = by_gid(ax, "given_path")
    assert line.get_xydata().tolist() == [[0.0, 0.0], [2.0, 1.0], [5.0, 0.0]]


def test_corridor_walls_boxes_polygon_and_post_are_drawn_one_by_one(ax):
    sc = load_scenario("corridor_obstacles")
    counts = draw_world(ax, sc)
    assert counts == {"wall": 4, "box": 2, "polygon": 1, "post": 1}
    (boxes,) = by_gid(ax, "box")
    assert len(boxes.get_paths()) == 2
    (walls,) = by_gid(ax, "wall")
    n_wall_segments = sum(b - a for k, a, b in sc.world.segment_kinds if k == "wall")
    assert len(walls.get_segments()) == n_wall_segments
    (post,) = by_gid(ax, "post")
    assert n_items(post) == 1
    assert set(ax.get_legend_handles_labels()[1]) == {KIND_LABELS[k] for k in counts}


def test_plants_weeds_and_row_lines_keep_their_own_kind(ax):
    sc = load_scenario("crop_rows")
    counts = draw_world(ax, sc)
    plants = sum(b - a for k, a, b in sc.world.circle_kinds if k == "plant")
    weeds = sum(b - a for k, a, b in sc.world.circle_kinds if k == "weed")
    assert plants > 100 and weeds > 0 and plants + weeds == len(sc.world.circles)
    assert counts["plant"] == plants and counts["weed"] == weeds and "post" not in counts
    assert n_items(by_gid(ax, "plant")[0]) == plants and n_items(by_gid(ax, "weed")[0]) == weeds
    assert len(by_gid(ax, "row_line")) == len(sc.world.row_lines) == counts["row_line"]


def test_ground_features_holes_steps_and_both_grooves_of_a_rut(ax):
    sc = load_scenario("hole_field")
    counts = draw_world(ax, sc)
    assert counts["hole"] == 3 and counts["step_up"] == 1 and counts["rut"] == 1
    (holes,) = by_gid(ax, "hole")
    assert len(holes.get_paths()) == 3
    (rut,) = by_gid(ax, "rut")
    assert len(rut.get_paths()) == 2  # count = 2: two grooves, 1.5 m apart
    # the cavity and the trench reach beyond the scenario's bounds, and the picture holds them
    x0, x1 = ax.get_xlim()
    y0, y1 = ax.get_ylim()
    assert y1 >= 3.0 + 2.0 and y0 <= -6.0 and x1 >= 25.0


def test_movers_path_and_where_they_are_at_the_start_and_at_t(ax):
    sc = load_scenario("him_moving")
    m = sc.world.movers[0]
    draw_world(ax, sc, t_s=3.0)
    assert len(by_gid(ax, "mover")) == 1
    (ring,) = by_gid(ax, "mover_start")
    (disc,) = by_gid(ax, "mover_end")
    assert ring.center == pytest.approx(m.position(0.0)) and disc.center == pytest.approx(m.position(3.0))
    assert disc.radius == pytest.approx(m.radius_m)


def test_surveyed_posts_of_the_scenario_are_marked(ax):
    sc = load_scenario("timed_static")
    counts = draw_world(ax, sc)
    (marks,) = by_gid(ax, "landmark")
    assert counts["landmark"] == len(sc.meta["landmarks"]) == len(marks.get_xdata())


def test_a_world_built_in_code_draws_its_untagged_objects_as_walls_and_posts(ax):
    w = World()
    w.add_segments(np.array([[0.0, 0.0, 1.0, 0.0], [1.0, 0.0, 1.0, 1.0]]))
    w.add_circles(np.array([[2.0, 2.0, 0.1], [3.0, 2.0, 0.2]]))
    w.segments = np.vstack((w.segments, [[5.0, 5.0, 6.0, 5.0]]))  # added behind add_segments' back
    counts = draw_world(ax, w)
    assert counts == {"wall": 2, "post": 2}
    assert len(by_gid(ax, "wall")[0].get_segments()) == 3


# ---- start, goals, path, footprints ---------------------------------------------------------------------------

def test_goals_show_tolerance_heading_and_start_arrow(ax):
    ax.set_xlim(-1, 5)
    ax.set_ylim(-1, 5)
    n = draw_goals(ax, [Goal(3.0, 1.0, math.radians(90.0), tolerance_m=0.4), Goal(1.0, 3.0, arrival_s=12.0)],
                   Pose2D(0.0, 0.0, 0.0))
    assert n == 2
    assert len(by_gid(ax, "goal")) == 2 and len(by_gid(ax, "goal_heading")) == 1
    rings = by_gid(ax, "goal_tolerance")
    assert sorted(r.radius for r in rings) == [0.3, 0.4]
    assert by_gid(ax, "start") and by_gid(ax, "start_heading")
    texts = [t.get_text() for t in ax.texts]
    assert "1" in texts and "2 t=12 s" in texts


def test_a_cycle_of_goals_is_drawn_once_per_place(ax):
    sc = load_scenario("greenhouse_cycles")
    places = {(g.x_m, g.y_m) for g in sc.goals}
    assert draw_goals(ax, sc.goals, sc.start) == len(sc.goals) > len(places)
    assert len(by_gid(ax, "goal")) == len(by_gid(ax, "goal_tolerance")) == len(places)


def test_footprint_times_are_every_interval_from_the_start_and_not_the_end():
    t = np.arange(0.0, 10.01, 0.1)
    idx = footprint_times(t, 2.0)
    assert t[idx] == pytest.approx([0.0, 2.0, 4.0, 6.0, 8.0])
    assert len(footprint_times(t[:1], 2.0)) == 0


def test_path_is_coloured_by_speed_and_the_footprint_drawn_every_two_seconds(ax):
    t = np.arange(0.0, 10.01, 0.1)
    rows = rows_of(t, 0.1 * t, 0.0, 0.0, 0.05 * t)
    art = draw_run(ax, rows, Footprint("circle", 0.3), every_s=2.0, end_reason="arrived")
    (path,) = by_gid(ax, "path")
    assert len(path.get_segments()) == len(t) - 1
    assert np.asarray(path.get_array()).tolist() == pytest.approx(0.5 * (rows[:-1, 4] + rows[1:, 4]))  # speed of each piece, m/s
    assert art.speed_range == pytest.approx((0.0, 0.5))
    (fps,) = by_gid(ax, "footprint")
    assert art.footprints == len(fps.get_paths()) == 5
    (end,) = by_gid(ax, "footprint_end")
    r = np.hypot(end.get_xy()[:, 0] - 1.0, end.get_xy()[:, 1])
    assert r == pytest.approx(0.3)  # the disc at the end pose (1, 0)


def test_an_ackermann_outline_is_its_wheels_rectangle_ahead_of_the_rear_axle():
    p = AckermannParams()
    fp = Footprint.of_params(p)
    assert fp.shape == "rectangle"
    o = fp.outline(0.0, 0.0, 0.0)
    assert o[:, 0].min() == pytest.approx(-p.wheel_radius_m) and o[:, 0].max() == pytest.approx(p.wheelbase_m + p.wheel_radius_m)
    assert o[:, 1].max() - o[:, 1].min() == pytest.approx(p.track_m)
    turned = fp.outline(1.0, 2.0, math.pi / 2)  # facing +y: the length along y
    assert turned[:, 1].max() == pytest.approx(2.0 + p.wheelbase_m + p.wheel_radius_m)
    d = Footprint.of_params(DiffDriveParams(radius_m=0.4))
    assert d.shape == "circle" and np.hypot(*d.outline(0, 0, 1.0).T) == pytest.approx(0.4)


def test_a_robot_specs_outline_fills_its_footprint_disc():
    spec = RobotSpec(kinematics="ackermann", radius_m=0.16, track_m=0.191, wheelbase_m=0.174, footprint_offset_m=0.087)
    o = Footprint.of_spec(spec).outline(0.0, 0.0, 0.0)
    assert np.hypot(o[:, 0] - 0.087, o[:, 1]) == pytest.approx(0.16)  # every corner on the disc
    assert Footprint.of_spec(RobotSpec(radius_m=0.3)).shape == "circle"


def test_the_run_figure_has_the_world_a_colour_bar_in_m_s_and_the_end_reason():
    sc = load_scenario("corridor_obstacles")
    res = run_scenario(sc, "goal_seek", duration_s=4.0)
    fig, a = run_figure(res.trajectory, sc, title="corridor", end_reason=res.end_reason)
    try:
        assert by_gid(a, "box") and by_gid(a, "post") and by_gid(a, "wall") and by_gid(a, "goal")
        assert "timeout" in a.get_title() and a.get_xlabel() == "x, m" and a.get_ylabel() == "y, m"
        assert a.get_aspect() == 1.0
        (path,) = by_gid(a, "path")
        assert path.colorbar is not None and path.colorbar.ax.get_ylabel() == "speed, m/s"
        assert path.colorbar.ax in a.child_axes  # beside the path's axes
        assert len(by_gid(a, "footprint")[0].get_paths()) == 2  # t = 0 and 2 s of a 4 s run, then the end
        assert a.get_legend() is not None
    finally:
        plt.close(fig)


# ---- the PNGs -------------------------------------------------------------------------------------------------

def pixels(path):
    img = matplotlib.image.imread(str(path))
    return (np.round(img[:, :, :3] * 255)).astype(int)


def count_colour(img, rgb, tol=3):
    return int((np.abs(img - np.array(rgb)).max(axis=2) <= tol).sum())


BOX_GREY = (140, 140, 140)  # fill "0.55"
POST_GREY = (64, 64, 64)  # fill "0.25"


def test_agnav_sim_writes_a_picture_with_the_corridors_world(tmp_path, capsys):
    from agnav_host.cli import main

    assert main(["sim", "--duration", "3", "--out", str(tmp_path), "--no-rrd", "--quiet"]) == 0
    img = pixels(tmp_path / "trajectory.png")
    # areas of the world's colours (the path alone on empty axes has under 100 such pixels, from its text)
    assert count_colour(img, BOX_GREY) > 1500  # the two boxes, filled
    assert count_colour(img, POST_GREY) > 800  # the post


def test_sim_results_carry_the_scenario_as_run(tmp_path):
    sc = load_scenario("corridor_obstacles")
    g = Goal(3.0, 1.5)
    res = run_scenario(sc, "goal_seek", duration_s=1.0, goal=g)
    assert res.scene is not None and res.scene.goals == [g] and res.scene.world is sc.world


def test_agnav_run_draws_the_world_it_knows_and_its_robots_outline(tmp_path):
    from agnav_host.robot import RunSettings, _plot_run

    t = np.arange(0.0, 6.0, 0.1)
    rows = rows_of(t, 0.3 * t, 0.0, 0.0, 0.3)
    spec = RobotSpec(kinematics="ackermann", radius_m=0.3, track_m=0.4, wheelbase_m=0.5, footprint_offset_m=0.25)
    bare = RunSettings((Goal(2.0, 0.0),), spec)
    w = World(bounds=(-1.0, -2.0, 3.0, 2.0))
    w.add_circles(np.array([[1.0, 1.0, 0.3]]))
    known = RunSettings((Goal(2.0, 0.0),), spec, world=w)
    a = _plot_run(rows, bare, tmp_path / "bare.png", "arrived")
    b = _plot_run(rows, known, tmp_path / "known.png", "arrived")
    assert count_colour(pixels(b), POST_GREY) > count_colour(pixels(a), POST_GREY) + 500  # the post, filled


def test_replay_plot_colours_the_logged_path_by_its_speed(tmp_path):
    from agnav_host.link.replay import TlogSummary
    from agnav_host.viz.plots import plot_run as replay_plot

    poses = [(0.5 * k, 0.5 * k, 0.0, 0.0) for k in range(10)]  # 0.5 m every 0.5 s
    rows = rows_from_poses(poses)
    assert rows[:, 4] == pytest.approx(1.0)
    s = TlogSummary(path="x.tlog", duration_s=4.5, poses=poses, layers=[(0.0, 0)], path_length_m=4.5)
    png = replay_plot(s, tmp_path / "r.png")
    assert png.read_bytes()[:4] == b"\x89PNG"


def test_the_planner_benchmarks_path_plot_draws_the_scenarios_world(tmp_path):
    from agnav_host.planning.bench import _plots

    tr = run_scenario(load_scenario("corridor_obstacles"), "goal_seek", duration_s=2.0).trajectory
    res = [{"scenario": "corridor_obstacles", "planner": "goal_seek", "seed": 0, "end": "timeout", "traj": tr,
            "kappa": np.zeros(5)}]
    written = _plots(res, tmp_path)
    assert tmp_path / "paths_corridor_obstacles.png" in written
    assert count_colour(pixels(tmp_path / "paths_corridor_obstacles.png"), BOX_GREY) > 1000


def test_plot_run_writes_a_png_for_a_run_without_samples_or_world(tmp_path):
    p = plot_run(tmp_path / "empty.png", np.zeros((0, 8)), goals=[Goal(1.0, 1.0)], end_reason="interrupted")
    assert p.read_bytes()[:4] == b"\x89PNG"
