"""A stack with its own recoveries is judged by its own outcome (``early_verdicts=False``): the
paper's stall and loitering monitors are recorded beside it, never instead of it."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

from ambiegen_ros.sims import oracles, robot  # noqa: E402
from test_full_models import feed  # noqa: E402

T = np.arange(0, 400, 0.1)
CIRCLE = (50 + 0.3 * np.cos(T * 0.5), 50 + 0.3 * np.sin(T * 0.5))  # swings round one spot, never stops


def open_grid(n: int = 100) -> np.ndarray:
    grid = np.zeros((n, n), dtype=bool)
    grid[0, :] = grid[-1, :] = grid[:, 0] = grid[:, -1] = True
    return grid


def test_loitering_is_recorded_not_decided_and_the_time_limit_still_decides():
    cfg = robot.RobotSimConfig()
    early = feed(robot.RobotMonitors(cfg, (100, 100), 300), T, *CIRCLE)
    late = feed(robot.RobotMonitors(cfg, (100, 100), 300, early_verdicts=False), T, *CIRCLE)
    assert early.kind == "loiter" and early.t == pytest.approx(10.0)
    assert late.kind == "timeout" and late.t == pytest.approx(300.0)
    m = late.metrics()
    assert (m["early_verdict"], m["early_time"]) == ("loiter", pytest.approx(10.0)) and "loitering" in m["early_detail"]
    assert early.metrics()["early_verdict"] == "loiter" and early.metrics()["early_verdicts"] is True
    assert m["early_verdicts"] is False


def test_a_touch_is_a_collision_for_a_stack_and_a_stall_for_the_paper():
    cfg = robot.RobotSimConfig()
    t = np.arange(0, 5, 0.1)
    paper = feed(robot.RobotMonitors(cfg, (100, 100), 300), t, 0.1 * t, 0 * t, clearance=0.0)
    stack = feed(robot.RobotMonitors(cfg, (100, 100), 300, early_verdicts=False), t, 0.1 * t, 0 * t, clearance=0.0)
    assert (paper.kind, paper.stall_cause) == ("stall", "contact")
    assert (stack.kind, stack.stall_cause) == ("collision", "contact")
    assert stack.metrics()["early_verdict"] == "collision"  # what both verdicts share


def test_the_stacks_result_decides_after_an_early_verdict():
    grid = open_grid()
    judges = {}
    for name, succeeded in (("pass", True), ("abort", False)):
        judge = oracles.RobotJudge(grid, 1.0, (90.5, 90.5), early_verdicts=False)
        judge.start(50.5, 50.5)
        assert not judge.add(T[:300], *(c[:300] for c in CIRCLE))  # 30 s of swinging: loiter recorded only
        judge.stack_result(succeeded, "nav2_aborted", "Nav2 aborted its goal (error 102)")
        judges[name] = judge.outcome()
    assert judges["pass"].failure_kind == "none" and not judges["pass"].failed
    assert judges["abort"].failure_kind == "nav2_aborted" and judges["abort"].failed
    for out in judges.values():
        assert out.metrics["early_verdict"] == "loiter" and out.metrics["decided_by"] == "stack"


def test_the_paper_monitors_decide_first_when_asked():
    judge = oracles.RobotJudge(open_grid(), 1.0, (90.5, 90.5))
    judge.start(50.5, 50.5)
    assert judge.add(T[:300], *(c[:300] for c in CIRCLE))
    judge.stack_result(True, "nav2_aborted", "Nav2 reached the goal")  # too late: the monitors' verdict stands
    out = judge.outcome()
    assert out.failure_kind == "loiter" and out.metrics["decided_by"] == "monitors"


def test_a_stack_that_decides_before_the_monitors_leaves_them_undecided():
    judge = oracles.RobotJudge(open_grid(), 1.0, (90.5, 90.5), early_verdicts=False)
    judge.start(50.5, 50.5)
    judge.add(T[:20], 50.5 + 0.2 * T[:20], 50.5 + 0 * T[:20])
    judge.stack_result(False, "nav2_aborted", "Nav2 aborted its goal (error 208)")
    out = judge.outcome()
    assert out.failure_kind == "nav2_aborted" and out.metrics["early_verdict"] == "undecided"


def test_the_time_limit_follows_the_stacks_speed():
    cfg = robot.RobotSimConfig()
    assert cfg.time_limit(100.0, 0.5) == pytest.approx(2 * 100 / 0.5 + 60)
    assert cfg.time_limit(100.0) == pytest.approx(2 * 100 / 0.3 + 60)
    slow = oracles.RobotJudge(open_grid(), 1.0, (90.5, 50.5), speed=0.1)
    fast = oracles.RobotJudge(open_grid(), 1.0, (90.5, 50.5), speed=1.0)
    for judge in (slow, fast):
        judge.start(10.5, 50.5)
    assert slow.time_limit == pytest.approx(2 * 80 / 0.1 + 60, rel=0.05)
    assert fast.time_limit == 300.0  # the floor
