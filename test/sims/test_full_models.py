"""Full-model simulators: crafted scenarios with known outcomes per oracle, determinism, CLI, plots.

Known outcomes come from geometry and physics, not from earlier runs: a robot wider than every
corridor gets no route; a forward sensor too narrow to see a corner clips it; a route longer than
speed x time limit cannot finish; a car entering a tight right-hand hairpin at speed runs out of
its lane while gentle bends pass; a slow room cannot follow hourly 4-degree swings.
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
from ambiegen_ros.sims.full_model import full_model_executor
from ambiegen_ros.sims.outcome import FAILURE_KINDS

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def problems():
    return {name: get_problem(name) for name in ("robot", "vehicle", "thermostat")}


def scenario(problem, elements):
    return problem.parse({"problem": problem.name, "elements": elements})


# --- robot -------------------------------------------------------------------------------------
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


def easy_robot_elements():
    """Every wall stacked on column 48 (away from the start-goal diagonal) plus two far walls."""
    els = [{"type": "vertical", "size": 5, "position": 48} for _ in range(48)]
    els[9] = {"type": "horizontal", "size": 5, "position": 40}
    els[29] = {"type": "horizontal", "size": 5, "position": 8}
    return els


def brute_wall_distance(grid, x, y):
    ys, xs = np.nonzero(grid)
    gx = np.maximum(np.abs(x - (xs + 0.5)) - 0.5, 0.0)
    gy = np.maximum(np.abs(y - (ys + 0.5)) - 0.5, 0.0)
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


def test_easy_map_completes(problems):
    p = problems["robot"]
    out = full_model_executor(p).execute(scenario(p, easy_robot_elements()))
    assert out.failure_kind == "none" and not out.failed, out.detail
    m = out.metrics
    assert m["outcome"] == "success" and m["valid"]
    assert 65.5 <= m["path_length"] <= 70.0  # ~ the diagonal (47 * sqrt 2 = 66.5 m) less the 0.5 m tolerance
    assert m["time"] < 300 and m["min_clearance"] > 0
    end = out.trajectory[-1]
    assert math.hypot(end[0] - 48.5, end[1] - 48.5) <= 0.5
    assert set(out.timeline) >= {"t", "x", "y", "yaw", "v"} and len(out.timeline["t"]) == len(out.trajectory)
    assert np.all(np.abs(out.timeline["v"]) <= 0.8 + 1e-9)


def test_corridor_too_narrow_for_the_footprint_gives_no_route():
    g = corridor_map()
    wide = robot.navigate(g, 1.0, (5, 5), (24, 24), robot.RobotSimConfig(radius=0.55))
    assert wide["outcome"] == "no_route" and wide["failure_kind"] == "stall"
    assert wide["path_length"] == 0.0 and wide["time"] == pytest.approx(10.0)
    slim = robot.navigate(g, 1.0, (5, 5), (24, 24), robot.RobotSimConfig(radius=0.3))
    assert slim["outcome"] == "success", slim["detail"]
    assert slim["timeline"]["y"][-1] > 18  # it went through the corridor


def test_dead_end_for_a_robot_that_only_just_fits_stalls():
    """Radius 0.45 m fits the 1 m corridor on paper (so it gets a route) but cannot enter it."""
    out = robot.navigate(corridor_map(), 1.0, (5, 5), (24, 24), robot.RobotSimConfig(radius=0.45))
    assert out["route_length"] is not None
    assert out["failure_kind"] in ("stall", "loiter"), out["detail"]
    assert out["timeline"]["y"][-1] < 13  # stuck at the mouth, never through
    assert out["min_clearance"] >= 0


def test_enclosed_goal_is_a_dead_end():
    g = box()
    g[20, 18:27] = g[27, 18:27] = True
    g[20:28, 18] = g[20:28, 26] = True
    out = robot.navigate(g, 1.0, (3, 3), (22, 23))
    assert out["outcome"] == "no_route" and out["failure_kind"] == "stall"


@pytest.mark.parametrize("seed", [0, 1])
def test_narrow_sensor_clips_the_corner_it_cannot_see(seed):
    g = corridor_map()
    cfg = robot.RobotSimConfig(fov_deg=60, beams=61, directions=31)
    out = robot.navigate(g, 1.0, (5, 5), (24, 24), cfg, seed=seed)
    assert out["failure_kind"] == "collision", out["detail"]
    x, y = out["failure_point"]
    assert brute_wall_distance(g, x, y) < cfg.radius  # independently: the disc overlaps a wall
    wide = robot.navigate(g, 1.0, (5, 5), (24, 24), robot.RobotSimConfig(), seed=seed)
    assert wide["outcome"] == "success"


def test_long_route_times_out_at_the_paper_speed(problems):
    p = problems["robot"]
    X = p.sample_rows(60, np.random.default_rng(7))
    ev = p.evaluate_rows(X)
    i = int(np.flatnonzero(ev.valid & (ev.f1 > 110.0))[0])  # 110 m > 0.3 m/s x 300 s = 90 m
    sc = p.codec.from_row(X[i])
    out = full_model_executor(p).execute(sc)
    assert out.failure_kind == "timeout" and out.metrics["time"] == pytest.approx(300.0)
    assert out.metrics["path_length"] <= 0.3 * 300 + 1e-6
    fast = full_model_executor(p, cruise_speed=0.8, timeout=600).execute(sc)
    assert fast.metrics["outcome"] == "success", fast.detail


# --- car ---------------------------------------------------------------------------------------
HAIRPIN = [("left", 5, 60), ("straight", 50, 5), ("straight", 30, 5), ("right", 5, 85), ("right", 5, 85)]
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
    assert m["oob_arc_length"] > 80  # in the hairpin, after the ~90 m of bend + straights
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
    out = full_model_executor(p, accel=0.01).execute(road(p, GENTLE))  # 0.5 m in 10 s
    assert out.failure_kind == "stall" and out.metrics["time"] == pytest.approx(10.0, abs=0.06)


# --- thermostat --------------------------------------------------------------------------------
def test_room_cannot_follow_hourly_swings(problems):
    p = problems["thermostat"]
    els = [{"temperature": 16 if i % 2 == 0 else 20, "duration": 60, "model": 7} for i in range(24)]
    for controller in ("onoff", "pid"):
        out = full_model_executor(p, controller=controller).execute(scenario(p, els))
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


def test_room_reduces_to_the_fitted_curves(problems):
    """No noise, no quantisation, control on the 3-minute grid: the surrogate's RMSE exactly."""
    p = problems["thermostat"]
    X = p.sample_rows(30, np.random.default_rng(3))
    G, lengths = p.codec.split(X)
    G[:, :, 2] = G[:, :1, 2]  # one room model per schedule (the models differ on changes)
    rows = p.codec.join(G, lengths)
    cfg = room.RoomSimConfig(dt=180, control_period=180, sensor_noise=0, sensor_resolution=0)
    f1 = p.evaluate_rows(rows).f1
    for row, expect in zip(rows, f1):
        sp, du, mo = room.schedule_of(p, p.codec.from_row(row))
        assert room.heat(sp, du, mo, p.config.room_models, cfg)["rmse"] == pytest.approx(expect, abs=1e-9)


# --- common ------------------------------------------------------------------------------------
def test_determinism_and_seeds(problems):
    cases = [
        (problems["robot"], scenario(problems["robot"], easy_robot_elements()), {"timeout": 40.0}),
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


# --- CLI and plots -----------------------------------------------------------------------------
def write(tmp_path, name, data) -> str:
    path = tmp_path / name
    path.write_text(data if isinstance(data, str) else json.dumps(data))
    return str(path)


def test_execute_json_shape_and_bad_input(tmp_path, capsys, problems):
    from ambiegen_ros.sims.cli import main

    p = problems["vehicle"]
    good = write(tmp_path, "hairpin.json", road(p, HAIRPIN).to_dict())
    assert main(["execute", good, "--json", "--seed", "3"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert list(out) == ["problem", "valid", "failed", "failure_kind", "metrics"]
    assert out["problem"] == "vehicle" and out["valid"] is True
    assert out["failed"] is True and out["failure_kind"] == "out_of_lane"
    assert out["metrics"]["seed"] == 3 and out["metrics"]["max_oob"] > 0.85

    gentle = write(tmp_path, "gentle.json", road(p, GENTLE).to_dict())
    assert main(["execute", gentle, "--json", "--set", "controller=\"stanley\""]) == 0
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
    assert out["failed"] is True and out["failure_kind"] == "requirement"
    bad = write(tmp_path, "bad.json",
                {"problem": "thermostat", "elements": [{"temperature": 99, "duration": 60, "model": 1}]})
    run = subprocess.run([sys.executable, "-m", "ambiegen_ros", "execute", bad, "--json"],
                         cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert run.returncode == 2 and "temperature" in run.stderr and "Traceback" not in run.stderr


def test_plot_execution_draws_each_problem(tmp_path, problems):
    from ambiegen_ros.viz.execution import save_execution_plot

    cases = [
        (problems["robot"], scenario(problems["robot"], easy_robot_elements()), {"timeout": 20.0}),
        (problems["vehicle"], road(problems["vehicle"], HAIRPIN), {}),
        (problems["thermostat"],
         scenario(problems["thermostat"], [{"temperature": 20, "duration": 240, "model": 1}]), {}),
    ]
    for p, sc, opts in cases:
        out = full_model_executor(p, **opts).execute(sc)
        path = save_execution_plot(p, sc, out, tmp_path / f"{p.name}.png")
        assert path.stat().st_size > 10_000
