"""The robot's reference (``sims.reference.robot``): a route keeping the footprint plus a margin
clear of every wall, on hand-made maps both ways.

Known answers come from geometry: two wall cells touching at a corner leave a gap of zero width
(no route); a one-cell gap leaves 0.5 m either side of its centre line, more than the 0.26 m
footprint radius + 0.1 m margin; the replication profile's A* (``diagonal="always"``) steps through
the first and brushes wall corners at zero clearance, which the clearance route never does.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from ambiegen_ros.core.attributes import ScenarioError
from ambiegen_ros.problems import get_problem
from ambiegen_ros.problems.robot import RobotMap
from ambiegen_ros.sims import robot
from ambiegen_ros.sims.full_model import full_model_executor
from ambiegen_ros.sims.reference import robot as ref
from ambiegen_ros.sims.robot_world import PIONEER2DX, clearances, pad_grid

DATA = Path(__file__).resolve().parents[1] / "data"
REQUIRED = 0.26 + 0.1  # the pioneer2dx's rear lid corner from its rotation centre + the default margin
OLD = robot.RobotSimConfig(reference=False)


def box(n: int = 20) -> np.ndarray:
    g = np.zeros((n, n), dtype=bool)
    g[0, :] = g[-1, :] = g[:, 0] = g[:, -1] = True
    return g


def zero_gap_map(n: int = 20) -> np.ndarray:
    """A wall across the room whose two halves meet only at a corner: cells (x 10, y 10) and (11, 11)."""
    g = box(n)
    g[n // 2, :n // 2 + 1] = True
    g[n // 2 + 1, n // 2 + 1:] = True
    return g


def one_metre_gap_map(n: int = 20) -> np.ndarray:
    """A wall across the room with one free cell (x 10, y 10) in it."""
    g = box(n)
    g[n // 2, :] = True
    g[n // 2, n // 2] = False
    return g


def post_map() -> np.ndarray:
    """A wall from the bottom border up to y 11 at x 8: the diagonal route must round its top end."""
    g = box()
    g[1:12, 8] = True
    return g


def exact_clearance(grid: np.ndarray, waypoints: np.ndarray, step: float = 0.002) -> float:
    """The polyline's distance to the wall squares (outside = wall), sampled every 2 mm."""
    pts = np.concatenate([a + np.linspace(0, 1, max(2, int(np.hypot(*(b - a)) / step) + 1))[:, None] * (b - a)
                          for a, b in zip(waypoints[:-1], waypoints[1:])])
    return float(clearances(pad_grid(grid), 1.0, pts[:, 0], pts[:, 1], 3, origin=(-1.0, -1.0)).min())


def test_required_clearance_is_the_footprint_radius_plus_the_margin():
    assert ref.footprint_radius() == pytest.approx(float(np.hypot(*PIONEER2DX.T).max()))
    assert ref.footprint_radius() == pytest.approx(0.26)
    assert ref.required_clearance(robot.RobotSimConfig()) == pytest.approx(REQUIRED)
    assert ref.required_clearance(robot.RobotSimConfig(clearance_margin=0.0)) == pytest.approx(0.26)
    for bad in ({"clearance_margin": -0.1}, {"route_resolution": 0.0}):
        with pytest.raises(ScenarioError):
            robot.RobotSimConfig(**bad)


def test_clearance_field_is_the_exact_distance_to_the_wall_squares():
    g = np.random.default_rng(1).random((12, 15)) < 0.25
    for fine in (0.1, 0.25):
        field = ref.clearance_field(g, 1.0, fine)
        ys, xs = np.mgrid[0:field.shape[0], 0:field.shape[1]]
        exact = clearances(pad_grid(g), 1.0, ((xs + 0.5) * fine).ravel(), ((ys + 0.5) * fine).ravel(), 4,
                           origin=(-1.0, -1.0))
        assert field.shape == (12 / fine, 15 / fine) and exact.max() < 3  # never capped: exact
        assert np.allclose(field.ravel(), exact, atol=1e-9)
    assert ref.fine_size(1.0, 0.3) == pytest.approx(1 / 3)  # a whole number of fine cells per map cell


def test_zero_width_diagonal_gap_has_no_route():
    g = zero_gap_map()
    old, _ = robot.plan_route(g, 1.0, (1, 1), (18, 18), OLD, "always")
    assert len(old) and ref.polyline_clearance(g, 1.0, old, REQUIRED) < 1e-9  # the old route squeezes through
    route = ref.route_for(g, 1.0, (1, 1), (18, 18), robot.RobotSimConfig())
    assert not route.found and route.reason == "no route keeps 0.36 m from the walls"
    assert not len(robot.plan_route(g, 1.0, (1, 1), (18, 18), robot.RobotSimConfig())[0])


def test_one_metre_gap_is_passed_keeping_the_clearance_everywhere():
    g = one_metre_gap_map()
    route = ref.route_for(g, 1.0, (1, 1), (18, 18), robot.RobotSimConfig())
    assert route.found and route.reason == ""
    wp = route.waypoints
    assert tuple(wp[0]) == (1.5, 1.5) and tuple(wp[-1]) == (18.5, 18.5)
    assert exact_clearance(g, wp) >= REQUIRED - 0.006  # 1 cm checks, adjacent fine cells: a few mm
    assert route.min_clearance == pytest.approx(exact_clearance(g, wp), abs=0.006)
    crossing = [a + (10.5 - a[1]) / (b[1] - a[1]) * (b - a) for a, b in zip(wp[:-1], wp[1:]) if a[1] < 10.5 <= b[1]]
    assert len(crossing) == 1 and 10 + REQUIRED - 0.01 <= crossing[0][0] <= 11 - REQUIRED + 0.01  # inside the gap
    straight = math.hypot(17, 17)
    assert straight < route.length < straight + 2.0
    assert len(wp) <= 6  # pulled tight: a handful of segments, not the fine grid's steps


def test_a_corner_the_old_route_brushed_is_kept_clear():
    g = post_map()
    old, _ = robot.plan_route(g, 1.0, (1, 1), (18, 18), OLD, "always")
    assert exact_clearance(g, old) < 0.01
    new, length = robot.plan_route(g, 1.0, (1, 1), (18, 18), robot.RobotSimConfig())
    assert exact_clearance(g, new) >= REQUIRED - 0.006 and math.isfinite(length)
    wider = ref.route_for(g, 1.0, (1, 1), (18, 18), robot.RobotSimConfig(clearance_margin=0.2))
    assert exact_clearance(g, wider.waypoints) >= 0.46 - 0.006 and wider.length > length


def test_a_start_with_less_clearance_than_required_is_named():
    route = ref.route_for(box(), 1.0, (1, 1), (18, 18), robot.RobotSimConfig(clearance_margin=0.3))
    assert not route.found
    assert route.reason == "the start (1.50, 1.50) keeps only 0.50 m from the walls, less than the 0.56 m required"


@pytest.fixture()
def on_map(monkeypatch):
    """The replication robot problem, goal (18, 18), its environment replaced by a hand-made 20 x 20
    map in the corner of a 50 x 50 one (the rest wall)."""
    problem = get_problem("robot", {"profile": "replication", "goal": (18, 18)})
    scenario = problem.parse({"problem": "robot", "elements": [{"type": "vertical", "size": 5, "position": 48}] * 49})

    def use(small):
        grid = np.ones((50, 50), dtype=bool)
        grid[:20, :20] = small
        env = RobotMap(grid, 1.0, (1, 1), (18, 18), (1.5, 1.5), (18.5, 18.5))
        monkeypatch.setattr(problem, "environment", lambda sc: env)
        return problem, scenario

    return use


def test_full_executor_calls_a_zero_gap_map_an_invalid_test_without_running(on_map):
    problem, scenario = on_map(zero_gap_map())
    out = full_model_executor(problem).execute(scenario)
    assert out.failure_kind == "invalid_test" and not out.failed
    assert out.detail == "no route keeps 0.36 m from the walls"
    assert out.trajectory is None and out.timeline is None  # the robot never ran
    assert out.reference == {"check": "clearance_route", "passed": False, "reason": out.detail}
    assert out.metrics["reference_clearance_m"] == pytest.approx(REQUIRED)
    assert out.verdict.startswith("INVALID_TEST")


def test_full_executor_drives_the_clearance_route_through_a_one_metre_gap(on_map):
    problem, scenario = on_map(one_metre_gap_map())
    out = full_model_executor(problem).execute(scenario, seed=1)
    assert out.failure_kind == "none" and out.verdict == "PASS", out.detail
    assert out.metrics["route"] == "clearance" and out.reference["passed"]
    planned = ref.route_for(problem.environment(scenario).grid, 1.0, (1, 1), (18, 18), robot.RobotSimConfig())
    assert out.metrics["route_length"] == pytest.approx(planned.length)
    assert out.metrics["reference_route_length_m"] == pytest.approx(planned.length)
    assert out.metrics["min_clearance"] > 0


def test_replication_map_that_loitered_at_a_zero_gap_is_now_an_invalid_test():
    """A top map of ``ambiegen search --problem robot --profile replication --seed 0``: its A*
    route passes a zero-width diagonal gap, where the robot used to loiter (``reference=False``)."""
    doc = json.loads((DATA / "robot_zero_gap_map.json").read_text())
    problem = get_problem("robot", {"profile": doc["metadata"]["profile"]})
    scenario = problem.parse(doc)
    new = full_model_executor(problem).execute(scenario)
    assert new.failure_kind == "invalid_test" and new.detail == "no route keeps 0.36 m from the walls"
    old = full_model_executor(problem, reference=False).execute(scenario)
    assert old.failed and old.failure_kind in ("loiter", "stall"), old.detail
