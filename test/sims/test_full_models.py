"""Full-model simulators: crafted scenarios with known outcomes per oracle, determinism, CLI, plots.

Known outcomes come from geometry and physics, not from earlier runs: a robot wider than every
corridor gets no route; a body meeting a wall stops there (stall); a robot sent straight at a goal
behind a U-shaped pocket gets stuck in it; a long route gets a time limit it can meet; a car
entering a tight right-hand hairpin at speed runs out of its lane while gentle bends pass; a slow
room cannot follow hourly 4-degree swings.
"""
from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from ambiegen_ros.core.attributes import ScenarioError
from ambiegen_ros.problems import get_problem
from ambiegen_ros.sims import car, robot, room
from ambiegen_ros.sims.full_model import FullModelExecutor, full_model_executor
from ambiegen_ros.sims.outcome import FAILURE_KINDS

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def problems():
    """The default (replication) profile, except the vehicle: the hand-made roads below are drawn
    with the refined road builder (20 m turn radius, heading north), where the hairpin is on the map."""
    out = {name: get_problem(name) for name in ("robot", "thermostat")}
    out["vehicle"] = get_problem("vehicle", {"profile": "refined"})
    return out


def scenario(problem, elements):
    return problem.parse({"problem": problem.name, "elements": elements})


# --- robot -------------------------------------------------------------------------------------
FIXED = {"timeout_route_factor": 0.0, "timeout_margin": 0.0}  # a fixed time limit (``timeout``)


def box(n: int = 30) -> np.ndarray:
    g = np.zeros((n, n), dtype=bool)
    g[0, :] = g[-1, :] = g[:, 0] = g[:, -1] = True
    return g


def corridor_map() -> np.ndarray:
    """Two open rooms joined only by a bent one-cell (1 m) corridor through a 6 m thick wall."""
    g = box()
    g[12:18, :] = True
    g[12:15, 15] = False
    g[14, 15:19] = False
    g[14:18, 18] = False
    return g


def door_map() -> np.ndarray:
    """Two rooms joined by a 1 m door in a straight wall."""
    g = box()
    g[15, :] = True
    g[15, 20] = False
    return g


def u_pocket_map() -> np.ndarray:
    """A U-shaped pocket (2 m wide, 4 m deep) open towards x = 0, its back wall at x = 16."""
    g = box()
    g[13, 12:17] = g[16, 12:17] = True
    g[13:17, 16] = True
    return g


def serpentine_map() -> np.ndarray:
    """Three walls across a 30 m room, passages at alternate ends: a route of about 84 m."""
    g = box()
    g[8, 1:26] = g[15, 4:29] = g[22, 1:26] = True
    return g


def easy_robot_elements():
    """Every wall stacked on column 48 (away from the start-goal diagonal) plus two far walls."""
    els = [{"type": "vertical", "size": 5, "position": 48} for _ in range(48)]
    els[9] = {"type": "horizontal", "size": 5, "position": 40}
    els[29] = {"type": "horizontal", "size": 5, "position": 8}
    return els


def brute_body_distance(grid, x, y, yaw, res=1.0):
    """Distance from the body (boundary sampled every ~2 mm) to wall squares; outside = wall."""
    fp = robot.PIONEER2DX
    e = np.roll(fp, -1, axis=0) - fp
    s = np.linspace(0, 1, 100, endpoint=False)
    pts = (fp[:, None, :] + s[None, :, None] * e[:, None, :]).reshape(-1, 2)
    c, si = math.cos(yaw), math.sin(yaw)
    px, py = x + c * pts[:, 0] - si * pts[:, 1], y + si * pts[:, 0] + c * pts[:, 1]
    gp = np.ones((grid.shape[0] + 8, grid.shape[1] + 8), dtype=bool)
    gp[4:-4, 4:-4] = grid
    ys, xs = np.nonzero(gp)
    gx = np.maximum(np.abs(px[:, None] - (xs - 4 + 0.5) * res) - 0.5 * res, 0.0)
    gy = np.maximum(np.abs(py[:, None] - (ys - 4 + 0.5) * res) - 0.5 * res, 0.0)
    return float(np.hypot(gx, gy).min())


def test_rays_match_dense_sampling():
    rng = np.random.default_rng(0)
    g = rng.random((30, 40)) < 0.15
    g[0, :] = g[-1, :] = g[:, 0] = g[:, -1] = True
    mismatches = total = 0
    for _ in range(60):
        x, y = rng.uniform(1, 39), rng.uniform(1, 29)
        if g[int(y), int(x)]:
            continue
        angles = rng.uniform(-np.pi, np.pi, 40)
        r = robot.cast_rays(g, 1.0, x, y, angles, 10.0)
        d = np.arange(0, 10, 0.001)
        px = x + d[None] * np.cos(angles)[:, None]
        py = y + d[None] * np.sin(angles)[:, None]
        occ = g[np.clip(py.astype(int), 0, 29), np.clip(px.astype(int), 0, 39)]
        ref = np.where(occ.any(1), d[np.argmax(occ, 1)], 10.0)
        mismatches += int((np.abs(ref - r) > 0.002).sum())  # only rays grazing a cell corner differ
        total += len(angles)
    assert mismatches <= 0.002 * total
    half = robot.cast_rays(g, 0.5, 10.0, 7.5, np.array([0.0, np.pi / 2]), 5.0)  # 0.5 m cells
    ref = [brute for brute in (robot.cast_rays(np.kron(g, np.ones((2, 2), bool)), 0.25, 10.0, 7.5,
                                               np.array([0.0, np.pi / 2]), 5.0))]
    assert np.allclose(half, ref)


def test_rdp_keeps_ends_and_stays_within_epsilon():
    rng = np.random.default_rng(1)
    pts = np.cumsum(rng.normal(size=(80, 2)), axis=0)
    for eps in (0.0, 0.5, 2.0):
        kept = robot.rdp(pts, eps)
        assert np.array_equal(kept[0], pts[0]) and np.array_equal(kept[-1], pts[-1])
        # every original point lies within eps of the simplified polyline
        a, b = kept[:-1], kept[1:]
        ab = b - a
        t = np.clip(((pts[:, None] - a[None]) * ab[None]).sum(-1) / np.maximum((ab ** 2).sum(-1), 1e-12), 0, 1)
        dist = np.hypot(*(pts[:, None] - (a[None] + t[..., None] * ab[None])).transpose(2, 0, 1)).min(axis=1)
        assert dist.max() <= eps + 1e-9
    assert len(robot.rdp(pts, 0.0)) <= len(pts) and len(robot.rdp(pts, 2.0)) < len(robot.rdp(pts, 0.5))


def test_body_clearance_is_exact():
    """Against the body's boundary sampled densely: equal where apart, <= 0 where it overlaps."""
    rng = np.random.default_rng(0)
    g = rng.random((20, 25)) < 0.25
    walls = robot.WallGeometry(g, 1.0, cells=3)
    checked = overlaps = 0
    for _ in range(300):
        x, y, yaw = rng.uniform(0, 25), rng.uniform(0, 20), rng.uniform(-np.pi, np.pi)
        exact, brute = walls.clearance_at(x, y, yaw), min(brute_body_distance(g, x, y, yaw), 3.0)
        if brute > 0:
            assert exact == pytest.approx(brute, abs=2e-3), (x, y, yaw)
            checked += 1
        else:
            assert exact <= 0, (x, y, yaw)
            overlaps += 1
    assert checked > 50 and overlaps > 50
    # a wall cell entirely inside the body (0.1 m cells) is an overlap too
    fine = np.zeros((40, 40), dtype=bool)
    fine[20, 20] = True
    walls = robot.WallGeometry(fine, 0.1, cells=5)  # clearance capped at 0.5 m
    assert walls.clearance_at(2.05, 2.05, 0.3) <= 0
    assert walls.clearance_at(2.05, 2.6, 0.0) == pytest.approx(2.6 - 0.19 - 2.1, abs=1e-9)  # flat side over the cell
    assert walls.clearance_at(2.05, 3.0, 0.0) == pytest.approx(0.5)


def test_numba_and_numpy_engines_give_the_same_numbers():
    """The compiled loops (laser, body clearance) repeat the numpy code operation for operation."""
    pytest.importorskip("numba")
    rng = np.random.default_rng(4)
    for res in (1.0, 0.5):
        g = rng.random((30, 40)) < 0.2
        fast, slow = robot.WallGeometry(g, res, engine="numba"), robot.WallGeometry(g, res, engine="numpy")
        poses = rng.uniform([-1, -1, -4], [41 * res, 31 * res, 4], size=(300, 3))
        assert np.array_equal(fast.clearance(*poses.T), slow.clearance(*poses.T))
        for x, y, a in poses[:30]:
            beams = np.linspace(-np.pi / 2, np.pi / 2, 181) + a
            assert np.array_equal(robot.cast_rays(g, res, x, y, beams, 10.0, engine="numba"),
                                  robot.cast_rays(g, res, x, y, beams, 10.0, engine="numpy"))
    diagonal = np.array([np.pi / 4, -np.pi / 4, 0.0, np.pi / 2])  # rays through lattice corners
    assert np.array_equal(robot.cast_rays(g, 1.0, 1.5, 1.5, diagonal, 10.0, engine="numba"),
                          robot.cast_rays(g, 1.0, 1.5, 1.5, diagonal, 10.0, engine="numpy"))
    runs = [robot.navigate(corridor_map(), 1.0, (5, 5), (24, 24), robot.RobotSimConfig(engine=e), seed=3)
            for e in ("numba", "numpy")]
    assert all(np.array_equal(runs[0]["timeline"][k], runs[1]["timeline"][k]) for k in runs[0]["timeline"])


def test_easy_map_completes(problems):
    p = problems["robot"]
    out = full_model_executor(p).execute(scenario(p, easy_robot_elements()))
    assert out.failure_kind == "none" and not out.failed, out.detail
    m = out.metrics
    assert m["outcome"] == "success" and m["valid"] and m["planner"] == "nd"
    assert 65.5 <= m["path_length"] <= 70.0  # ~ the diagonal (47 * sqrt 2 = 66.5 m) less the 0.5 m tolerance
    assert m["time"] < m["time_limit"] and m["min_clearance"] > 0
    end = out.trajectory[-1]
    assert math.hypot(end[0] - 48.5, end[1] - 48.5) <= 0.5
    assert set(out.timeline) >= {"t", "x", "y", "yaw", "v", "stall"} and len(out.timeline["t"]) == len(out.trajectory)
    assert np.all(np.abs(out.timeline["v"]) <= 0.3 + 1e-9)  # the ND driver's max speed


@pytest.mark.parametrize("planner", ["nd", "gap"])
def test_corridor_and_door_are_driven_through(planner):
    """(The gap planner squeezes round the bent corridor at 0.1 m/s, slow enough for the loitering
    monitor with some noise seeds: not asserted.)"""
    cfg = robot.RobotSimConfig(planner=planner)
    for g in ((corridor_map(), door_map(), box()) if planner == "nd" else (door_map(), box())):
        out = robot.navigate(g, 1.0, (5, 5), (24, 24), cfg, seed=1)
        assert out["outcome"] == "success", (planner, out["detail"])
        assert out["timeline"]["y"][-1] > 18 and out["min_clearance"] > 0.1
        assert out["waypoints_reached"] == len(out["waypoints"]) - 1


def test_u_shaped_pocket_between_robot_and_goal_traps_the_nd_robot():
    """Told to go straight to a goal behind a U-shaped pocket, the robot enters it and stays stuck
    there (the stall or loitering monitor), never passing the pocket's back wall."""
    g = u_pocket_map()
    start, goal = (4.5, 15.0), (25.5, 15.0)
    for seed in (0, 1):
        out = robot.drive(g, 1.0, start, goal, np.array([start, goal]), robot.RobotSimConfig(), seed=seed)
        assert out["failure_kind"] in ("stall", "loiter"), out["detail"]
        x, y = out["timeline"]["x"], out["timeline"]["y"]
        assert x.max() < 16 - 0.18 and 11.5 < x[-1] and 14 < y[-1] < 16  # inside the pocket
        assert out["time"] < 120 and out["min_clearance"] > -1e-6
    # with the route planned around the pocket, the same robot gets there
    assert robot.navigate(g, 1.0, (4, 15), (25, 15), robot.RobotSimConfig())["outcome"] == "success"


def test_a_body_meeting_a_wall_stalls_there():
    """A planner that believes the robot is a 0.1 m disc and sees only 60 deg ahead clips the
    corridor's corner: the body stops at the contact (Stage's stall). On the old route (A* through
    the corridor's cell centres, ``reference=False``): on the clearance route, which passes the
    bends' inner corners at 0.36 m, the earlier gap planner's 0.35 m disc loiters at a bend."""
    cfg = robot.RobotSimConfig(planner="gap", radius=0.1, margin=0.0, squeeze_margin=0.0, fov_deg=60, beams=61,
                               directions=31, reference=False)
    g = corridor_map()
    out = robot.navigate(g, 1.0, (5, 5), (24, 24), cfg)
    assert out["failure_kind"] == "stall" and out["stall_cause"] == "contact", out["detail"]
    tl = out["timeline"]
    assert brute_body_distance(g, tl["x"][-1], tl["y"][-1], tl["yaw"][-1]) < 1e-3  # independently: touching
    assert -1e-3 < out["min_clearance"] <= 0
    before = zip(tl["x"][:-1:50], tl["y"][:-1:50], tl["yaw"][:-1:50])
    assert all(brute_body_distance(g, x, y, a) > 0 for x, y, a in before)
    wide = robot.navigate(g, 1.0, (5, 5), (24, 24),
                          robot.RobotSimConfig(planner="gap", fov_deg=60, beams=61, directions=31, reference=False))
    assert wide["outcome"] == "success"  # the same sensor with a disc that covers the body


def test_no_route_and_enclosed_goal_stall():
    """No route: the robot never starts; after the loitering window without any motion, a stall.
    The 1 m corridor has no route keeping 0.26 + 0.3 m from its walls, nor an A* route for a 0.55 m
    robot (the old route, ``reference=False``)."""
    for cfg in (robot.RobotSimConfig(clearance_margin=0.3), robot.RobotSimConfig(radius=0.55, reference=False)):
        wide = robot.navigate(corridor_map(), 1.0, (5, 5), (24, 24), cfg)
        assert wide["outcome"] == "no_route" and wide["failure_kind"] == "stall" and wide["stall_cause"] == "no_route"
        assert wide["path_length"] == 0.0 and wide["time"] == pytest.approx(10.0)
    g = box()
    g[20, 18:27] = g[27, 18:27] = True
    g[20:28, 18] = g[20:28, 26] = True
    assert robot.navigate(g, 1.0, (3, 3), (22, 23))["outcome"] == "no_route"


def test_a_long_route_alone_never_times_out():
    """About 84 m of route, more than 0.3 m/s covers in a 200 s floor: the time limit grows with
    the route (2 x route / 0.3 m/s + 60 s) and the robot arrives; a fixed 200 s limit cuts it."""
    g = serpentine_map()
    out = robot.navigate(g, 1.0, (3, 3), (26, 26), robot.RobotSimConfig(timeout=200.0))
    assert out["route_length"] > 0.3 * 200
    assert out["time_limit"] == pytest.approx(max(200.0, 2 * out["route_length"] / 0.3 + 60.0))
    assert out["outcome"] == "success" and out["time"] > 200, out["detail"]
    fixed = robot.navigate(g, 1.0, (3, 3), (26, 26), robot.RobotSimConfig(timeout=200.0, **FIXED))
    assert fixed["outcome"] == "timeout" and fixed["time"] == pytest.approx(200.0)
    assert fixed["path_length"] <= 0.3 * 200 + 1e-6
    assert robot.RobotSimConfig().time_limit(100.0) == pytest.approx(2 * 100 / 0.3 + 60)
    assert robot.RobotSimConfig().time_limit(30.0) == 300.0


def feed(monitors, t, x, y, clearance=1.0):
    for ti, xi, yi in zip(t, x, y):
        if monitors.update(float(ti), float(xi), float(yi), clearance):
            break
    return monitors


def test_loitering_monitor_follows_the_window_centroid():
    cfg = robot.RobotSimConfig()
    t = np.arange(0, 60, 0.1)
    circling = feed(robot.RobotMonitors(cfg, (100, 100), 300), t, 0.3 * np.cos(t * 0.5), 0.3 * np.sin(t * 0.5))
    assert circling.kind == "loiter" and circling.t == pytest.approx(10.0)
    standing = feed(robot.RobotMonitors(cfg, (100, 100), 300), t, np.zeros_like(t), np.zeros_like(t))
    assert standing.kind == "stall" and standing.stall_cause == "stationary" and standing.t == pytest.approx(10.0)
    slow = feed(robot.RobotMonitors(cfg, (100, 100), 300), t, 0.12 * t, np.zeros_like(t))  # 0.6 m from the centroid
    assert slow.kind is None and slow.path_length == pytest.approx(0.12 * t[-1])
    late = feed(robot.RobotMonitors(cfg, (100, 100), 300), t, np.minimum(0.2 * t, 6.0), np.zeros_like(t))
    assert late.kind == "loiter" and 32.5 < late.t < 33.5  # stopped at 30 s: 3 s on, the window's mean is 0.49 m behind
    arrive = feed(robot.RobotMonitors(cfg, (5.0, 0.0), 300, np.array([[2.0, 0.0], [4.6, 0.0]])), t, 0.2 * t, 0 * t)
    assert arrive.kind == "none" and arrive.waypoints_reached == 2 and arrive.t == pytest.approx(22.5)
    near = feed(robot.RobotMonitors(cfg, (100, 100), 20), t, t, 0 * t, clearance=0.1)
    assert near.kind == "timeout" and near.proximity_events == 1 and near.proximity_time == pytest.approx(20.0)


def test_robot_oracle_gives_the_simulator_verdicts():
    """The monitors restated over the timelines (``oracles.RobotJudge``): same verdicts, times,
    path lengths and clearances, also when the samples arrive in batches."""
    from ambiegen_ros.sims import oracles

    runs = [
        (box(), (5, 5), (24, 24), robot.RobotSimConfig()),
        (corridor_map(), (5, 5), (24, 24), robot.RobotSimConfig(planner="gap", radius=0.1, margin=0.0,
                                                                squeeze_margin=0.0, fov_deg=60, beams=61,
                                                                directions=31)),
        (corridor_map(), (5, 5), (24, 24), robot.RobotSimConfig(clearance_margin=0.3)),  # no route
        (corridor_map(), (5, 5), (24, 24), robot.RobotSimConfig(planner="gap", radius=0.45)),
        (door_map(), (5, 5), (24, 24), robot.RobotSimConfig(timeout=20.0, **FIXED)),
    ]
    kinds = set()
    rng = np.random.default_rng(3)
    for g, start, goal, cfg in runs:
        run = robot.navigate(g, 1.0, start, goal, cfg, seed=2)
        tl = run["timeline"]
        goal_xy = (goal[0] + 0.5, goal[1] + 0.5)
        out = oracles.judge_robot(tl["t"], tl["x"], tl["y"], g, 1.0, goal_xy, cfg, yaw=tl["yaw"], stall=tl["stall"])
        assert out.failure_kind == run["failure_kind"], (out.detail, run["detail"])
        for key in ("time", "time_limit", "path_length", "min_clearance", "waypoints_reached", "unsafe_proximity_s"):
            assert out.metrics[key] == pytest.approx(run[key], abs=1e-9), key
        judge = oracles.RobotJudge(g, 1.0, goal_xy, cfg)
        cuts = np.sort(rng.choice(np.arange(1, len(tl["t"])), size=min(5, len(tl["t"]) - 1), replace=False))
        for part in np.split(np.arange(len(tl["t"])), cuts):
            judge.add(tl["t"][part], tl["x"][part], tl["y"][part], tl["yaw"][part], tl["stall"][part])
        assert judge.outcome().failure_kind == run["failure_kind"]
        kinds.add(out.failure_kind)
    assert kinds == {"none", "stall", "loiter", "timeout"}
    # without yaw the heading of the motion stands in; the first run has no near miss to tell apart
    tl = robot.navigate(box(), 1.0, (5, 5), (24, 24), seed=2)["timeline"]
    assert oracles.judge_robot(tl["t"], tl["x"], tl["y"], box(), 1.0, (24.5, 24.5)).failure_kind == "none"


# --- car ---------------------------------------------------------------------------------------
# The hairpin keeps its two lanes inside the map (a 30 m second straight took its left edge 2.6 m past the
# margin: now an invalid test); the cautious reference driver completes it, so the failure is certified.
HAIRPIN = [("left", 5, 60), ("straight", 50, 5), ("straight", 10, 5), ("right", 5, 80), ("right", 5, 80)]
GENTLE = [("straight", 30, 5), ("left", 5, 20), ("straight", 30, 5), ("right", 5, 25), ("straight", 20, 5)]


def road(problem, spec):
    return scenario(problem, [{"type": t, "length": l, "angle": a} for t, l, a in spec])


def test_oob_fraction_geometry():
    line = np.column_stack([np.linspace(0, 100, 101), np.zeros(101)])  # road along +x
    lane = car.right_lane(line, 4.0)  # right lane: y in [-4, 0]
    assert np.allclose(lane.centre[:, 1], -2.0)
    x = np.full(4, 50.0)
    y = np.array([-2.0, 0.0, 0.5, 3.0])  # centred, half over the centre line, 1.4 m over, fully out
    frac = car.oob_fraction(lane, x, y, np.zeros(4), 4.5, 1.8)
    assert frac == pytest.approx([0.0, 0.5, 1.4 / 1.8, 1.0], abs=1e-9)
    rotated = car.oob_fraction(lane, [50.0], [-2.0], [np.pi / 2], 4.5, 1.8)[0]  # 4.5 m across 4 m
    assert rotated == pytest.approx(0.5 / 4.5, abs=1e-9)


def test_hairpin_after_a_long_straight_leaves_the_lane(problems):
    p = problems["vehicle"]
    sc = road(p, HAIRPIN)
    assert p.evaluate_scenarios([sc]).valid[0]
    out = full_model_executor(p).execute(sc)
    assert out.failed and out.failure_kind == "out_of_lane", out.detail
    m = out.metrics
    assert m["max_oob"] > 0.85
    assert m["oob_arc_length"] > 80  # in the hairpin, after the ~80 m of bend + straights
    assert out.verdict == "FAIL(out_of_lane)" and out.reference["check"] == "reference_driver"
    assert m["departure_arc_length"] <= m["oob_arc_length"]
    x, y = out.failure_point
    lane = car.right_lane(car.road_of(p, sc)[0], 4.0)
    box_frac = car.oob_fraction(lane, [x], [y], [out.timeline["yaw"][-1]], 4.5, 1.8)
    assert box_frac[0] > 0.85  # the failure point really is out of the lane
    sbft = full_model_executor(p, oob_tolerance=0.95).execute(sc)
    assert sbft.metrics["max_oob"] > 0.0


def test_gentle_road_is_driven(problems):
    p = problems["vehicle"]
    for controller in ("pure_pursuit", "stanley"):
        out = full_model_executor(p, controller=controller).execute(road(p, GENTLE))
        assert out.failure_kind == "none" and out.metrics["outcome"] == "success", (controller, out.detail)
        assert out.metrics["max_oob"] < 0.1 and out.metrics["max_lateral_offset"] < 1.0
        assert out.metrics["max_speed"] <= 70 / 3.6 + 1e-9


def test_car_that_barely_moves_stalls(problems):
    p = problems["vehicle"]
    # 0.5 m in 10 s; unchecked: the cautious reference driver has the same 0.01 m/s^2 and stalls too
    out = full_model_executor(p, accel=0.01, reference=False).execute(road(p, GENTLE))
    assert out.failure_kind == "stall" and out.metrics["time"] == pytest.approx(10.0, abs=0.06)


# --- thermostat --------------------------------------------------------------------------------
def test_room_cannot_follow_hourly_swings(problems):
    """The thermostat's own verdict (``reference=False``): even an ideal controller misses these
    swings, so with the reference check they are an invalid test (test_reference_thermostat.py)."""
    p = problems["thermostat"]
    els = [{"temperature": 16 if i % 2 == 0 else 20, "duration": 60, "model": 7} for i in range(24)]
    for controller in ("onoff", "pid"):
        out = full_model_executor(p, controller=controller, reference=False).execute(scenario(p, els))
        assert out.failed and out.failure_kind == "requirement", controller
        assert out.metrics["rmse"] > 1.0 and out.objectives["thermostat_rmse"] == out.metrics["rmse"]


def test_steady_schedule_is_followed(problems):
    p = problems["thermostat"]
    els = [{"temperature": 20, "duration": 240, "model": m} for m in (1, 2, 3, 4, 5, 6)]
    for controller in ("onoff", "pid"):
        out = full_model_executor(p, controller=controller).execute(scenario(p, els))
        assert not out.failed and out.metrics["rmse"] < 1.0, controller
    tl = out.timeline
    assert len(tl["t"]) == 24 * 360 + 1 and tl["t"][-1] == pytest.approx(86400)
    q = tl["measured"] / 0.1
    assert np.allclose(q, np.round(q), atol=1e-6)  # 0.1 degC sensor resolution


# --- common ------------------------------------------------------------------------------------
def test_determinism_and_seeds(problems):
    cases = [
        (problems["robot"], scenario(problems["robot"], easy_robot_elements()), {"timeout": 40.0, **FIXED}),
        (problems["vehicle"], road(problems["vehicle"], HAIRPIN), {}),
        (problems["thermostat"], scenario(problems["thermostat"], [
            {"temperature": 18 + i % 3, "duration": 120, "model": 1 + i % 7} for i in range(12)]), {}),
    ]
    for p, sc, opts in cases:
        ex = full_model_executor(p, **opts)
        a, b = ex.execute(sc, seed=5), ex.execute(sc, seed=5)
        assert (a.failed, a.failure_kind, a.metrics) == (b.failed, b.failure_kind, b.metrics)
        for key in a.timeline:
            assert np.array_equal(a.timeline[key], b.timeline[key]), (p.name, key)
        assert a.failure_kind in FAILURE_KINDS
    # noisy sensors: another seed, another run (the robot's laser matters near walls)
    th = cases[2]
    ex = full_model_executor(th[0])
    measured = [ex.execute(th[1], seed=s).timeline["measured"] for s in (5, 6)]
    assert not np.array_equal(*measured)
    runs = [robot.navigate(corridor_map(), 1.0, (5, 5), (24, 24), seed=s)["timeline"] for s in (5, 5, 6)]
    assert np.array_equal(runs[0]["x"], runs[1]["x"]) and np.array_equal(runs[0]["y"], runs[1]["y"])
    assert not np.array_equal(runs[0]["x"], runs[2]["x"])


def test_invalid_scenarios_are_not_executed_unless_asked(problems):
    p = problems["thermostat"]
    bad = p.codec.from_row(p.codec.join(np.array([[[16, 240, 1], [25, 240, 1]] + [[0, 0, 0]] * 22]), [2])[0])
    out = full_model_executor(p).execute(bad)
    assert out.failure_kind == "invalid_scenario" and not out.failed and out.metrics["valid"] is False
    forced = full_model_executor(p, run_invalid=True).execute(bad)
    assert forced.metrics["valid"] is False and "rmse" in forced.metrics


def test_unknown_or_bad_options_are_named(problems):
    with pytest.raises(ScenarioError, match="option.foo"):
        full_model_executor(problems["robot"], foo=1)
    with pytest.raises(ScenarioError, match="option.controller"):
        full_model_executor(problems["vehicle"], controller="magic")
    with pytest.raises(ScenarioError, match="option.oob_tolerance"):
        full_model_executor(problems["vehicle"], oob_tolerance=1.5)


@pytest.mark.parametrize("problem, pair, expected", [
    # a wrong type used to reach the config's range checks: "'>' not supported between 'str' and 'int'"
    ("robot", "cruise_speed=abc", "option.cruise_speed: expected a number, got 'abc' (allowed: finite numbers; default 0.3)"),
    ("robot", "cruise_speed=-1", "option.cruise_speed: value -1: must be > 0"),
    ("robot", "cruise_speed=0.9", "option.cruise_speed: value 0.9: above max_speed (allowed: <= 0.8)"),
    ("robot", "cruise_speed=0.05", "option.nd_min_speed: minimum speeds above the maximum ones (with cruise_speed=0.05)"),
    ("robot", "nd_sectors=4", "option.nd_sectors: value 4: a multiple of 4, at least 8"),
    ("robot", "beams=2.5", "option.beams: expected an integer, got 2.5 (allowed: integers; default 181)"),
    ("robot", "run_invalid=1", "option.run_invalid: expected true or false, got 1 (allowed: true|false; default false)"),
    ("robot", "planner=1", "option.planner: unknown planner '1' (allowed: nd|gap)"),
    ("robot", "engine=null", 'option.engine: expected text, got None (allowed: text; default "auto")'),
    ("vehicle", "controller=[1]", 'option.controller: expected text, got [1] (allowed: text; default "pure_pursuit")'),
    ("vehicle", "oob_tolerance=1.5", "option.oob_tolerance: value 1.5: must be a fraction (allowed: [0, 1])"),
    ("thermostat", "dt=true", "option.dt: expected a number, got True (allowed: finite numbers; default 10.0)"),
    ("thermostat", "control_period=65", "option.control_period: value 65: must be a multiple of dt (allowed: k * 10 s)"),
])
def test_every_set_value_error_names_option_value_and_allowed(problems, pair, problem, expected):
    """`--set` values reach the executor as parse_options gives them; each error is one such line."""
    from ambiegen_ros.sims.options import parse_options

    with pytest.raises(ScenarioError) as err:
        full_model_executor(problems[problem], **parse_options([pair]))
    assert str(err.value) == expected


def test_good_set_values_are_taken(problems):
    from ambiegen_ros.sims.options import parse_options

    ex = full_model_executor(problems["robot"], **parse_options(["beams=91.0", "route_diagonal=null", "planner=gap"]))
    assert ex.config.beams == 91 and isinstance(ex.config.beams, int)
    assert ex.config.route_diagonal is None and ex.config.planner == "gap"
    with pytest.raises(ScenarioError, match="option.cruise_speed: expected a number"):  # with a config too
        FullModelExecutor(problems["robot"], ex.config, cruise_speed="abc")


# --- CLI and plots -----------------------------------------------------------------------------
def write(tmp_path, name, data) -> str:
    path = tmp_path / name
    path.write_text(data if isinstance(data, str) else json.dumps(data))
    return str(path)


def test_execute_json_shape_and_bad_input(tmp_path, capsys, problems):
    from ambiegen_ros.cli import main

    p = problems["vehicle"]
    good = write(tmp_path, "hairpin.json", road(p, HAIRPIN).to_dict())
    assert main(["execute", good, "--json", "--seed", "3", "--profile", "refined"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert list(out) == ["problem", "valid", "failed", "failure_kind", "verdict", "reference", "metrics", "profile"]
    assert out["profile"] == "refined"
    assert out["problem"] == "vehicle" and out["valid"] is True
    assert out["failed"] is True and out["failure_kind"] == "out_of_lane"
    assert out["metrics"]["seed"] == 3 and out["metrics"]["max_oob"] > 0.85

    gentle = write(tmp_path, "gentle.json", road(p, GENTLE).to_dict())
    assert main(["execute", gentle, "--json", "--profile", "refined", "--set", "controller=\"stanley\""]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["failed"] is False and out["failure_kind"] is None

    bad_inputs = [
        write(tmp_path, "broken.json", "{not json"),
        write(tmp_path, "domain.json",
              {"problem": "vehicle", "elements": [{"type": "straight", "length": 500, "angle": 5}]}),
        write(tmp_path, "unknown.json", {"problem": "submarine", "elements": []}),
        str(tmp_path / "missing.json"),
    ]
    for path in bad_inputs:
        assert main(["execute", path, "--json"]) == 2, path
        err = capsys.readouterr().err
        assert err.startswith("ambiegen execute: error:") and "Traceback" not in err
    assert main(["execute", good, "--set", "nonsense=1"]) == 2
    assert "option.nonsense" in capsys.readouterr().err


def test_execute_through_the_ambiegen_command(tmp_path, problems):
    from ambiegen_ros.cli import build_parser

    sub = next(a for a in build_parser()._actions if a.dest == "command")
    assert "execute" in sub.choices
    p = problems["thermostat"]
    els = [{"temperature": 16 if i % 2 == 0 else 20, "duration": 60, "model": 7} for i in range(24)]
    good = write(tmp_path, "swing.json", scenario(p, els).to_dict())
    run = subprocess.run([sys.executable, "-m", "ambiegen_ros", "execute", good, "--json"],
                         cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    out = json.loads(run.stdout)
    # hourly 4-degree swings: the thermostat breaks the requirement, and so does an ideal controller
    assert out["failed"] is False and out["failure_kind"] == "invalid_test"
    assert out["verdict"].startswith("INVALID_TEST(even an ideal controller")
    assert out["metrics"]["sut_failure_kind"] == "requirement" and out["reference"]["check"] == "ideal_controller"
    run = subprocess.run([sys.executable, "-m", "ambiegen_ros", "execute", good, "--json", "--set", "reference=false"],
                         cwd=ROOT, capture_output=True, text=True, timeout=60)
    out = json.loads(run.stdout)
    assert out["failed"] is True and out["failure_kind"] == "requirement" and out["reference"] is None
    bad = write(tmp_path, "bad.json",
                {"problem": "thermostat", "elements": [{"temperature": 99, "duration": 60, "model": 1}]})
    run = subprocess.run([sys.executable, "-m", "ambiegen_ros", "execute", bad, "--json"],
                         cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert run.returncode == 2 and "temperature" in run.stderr and "Traceback" not in run.stderr


def test_plot_execution_draws_each_problem(tmp_path, problems):
    from ambiegen_ros.viz.execution import save_execution_plot

    cases = [
        (problems["robot"], scenario(problems["robot"], easy_robot_elements()), {"timeout": 20.0, **FIXED}),
        (problems["vehicle"], road(problems["vehicle"], HAIRPIN), {}),
        (problems["thermostat"],
         scenario(problems["thermostat"], [{"temperature": 20, "duration": 240, "model": 1}]), {}),
    ]
    for p, sc, opts in cases:
        out = full_model_executor(p, **opts).execute(sc)
        path = save_execution_plot(p, sc, out, tmp_path / f"{p.name}.png")
        assert path.stat().st_size > 10_000



def test_a_logged_robot_path_without_times_is_not_coloured_as_seconds(problems):
    """A result read from a bag has its path but no times: the colour bar says pose order, while
    a full-model run's says seconds."""
    import dataclasses

    import matplotlib.pyplot as plt

    from ambiegen_ros.viz.execution import plot_execution

    p = problems["robot"]
    sc = scenario(p, easy_robot_elements())
    out = full_model_executor(p, timeout=20.0, **FIXED).execute(sc)
    labels = []
    for o in (out, dataclasses.replace(out, timeline=None)):
        ax = plot_execution(p, sc, o)
        labels.append(ax.figure.axes[-1].get_ylabel())
        plt.close(ax.figure)
    assert labels == ["time [s]", "pose, in order driven"]
