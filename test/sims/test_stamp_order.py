"""Verdicts by stamps, not by arrival (``sims.stamp_order`` + ``oracles.RobotJudge``).

The crafted run: a robot wiggling in a 0.4 m square in an open box, so the loitering monitor fires
at 10 s; the stack's status stream reports "emergency_stop" decided on what it saw at 9.9 s, which
applies to the next sample, 10.0 s: two monitors at one stamp. In process the stack's stall flag
wins there, so over any interleaving of the odometry and status streams (each in its own order,
as DDS keeps one writer's order and no other) the verdict must be that stall, at 10.0 s.
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

sys.path.insert(0, str(Path(__file__).resolve().parent))

from ambiegen_ros.sims.oracles import RobotJudge  # noqa: E402
from ambiegen_ros.sims.robot import RobotSimConfig  # noqa: E402
from ambiegen_ros.sims.stamp_order import DECISION, STATE, StampOrder  # noqa: E402
from test_full_models import box  # noqa: E402

DT = 100_000_000  # 0.1 s in ns
T0 = 5_000_000_000  # the run's first stamp


def wiggle(n: int = 120) -> list[tuple[int, float, float]]:
    """(stamp, x, y): round a 0.4 m square at (10, 10), one corner per 0.1 s."""
    corners = [(10.0, 10.0), (10.4, 10.0), (10.4, 10.4), (10.0, 10.4)]
    return [(T0 + k * DT, *corners[k % 4]) for k in range(n)]


def judge_arrivals(arrivals, streams=(("stall", DECISION),), collision_label="the world") -> RobotJudge:
    """Feed messages in the given arrival order through a StampOrder into a judge."""
    judge = RobotJudge(box(30), 1.0, (25.0, 25.0), RobotSimConfig())
    order = StampOrder(streams)
    for kind, stamp, what in arrivals:
        if kind == "odom":
            order.sample(stamp, what)
        else:
            order.message(kind, stamp, what)
        released = order.release()
        if released and not judge.decided:
            t = np.array([(s - T0) / 1e9 for s, _, _ in released])
            xy = np.array([row for _, row, _ in released])
            judge.add(t, xy[:, 0], xy[:, 1], np.zeros(len(t)), stall=[e.get("stall") for *_, e in released],
                      collision=[collision_label if "collision" in e else None for *_, e in released])
    return judge


def streams_of_the_crafted_run():
    odom = [("odom", s, (x, y)) for s, x, y in wiggle()]
    status = [("stall", s, "emergency_stop" if s == T0 + 99 * DT else None) for s, _, _ in wiggle()]
    return odom, status


def test_the_crafted_run_has_two_monitors_at_one_stamp():
    """Without the stall flag it loiters at 10.0 s; in stamp order the stack's flag wins there."""
    odom, status = streams_of_the_crafted_run()
    alone = judge_arrivals(odom, streams=())
    assert alone.kind == "loiter" and "after 10.0 s" in alone.detail
    ordered = judge_arrivals(sorted(odom + status, key=lambda m: (m[1], m[0] == "odom")))
    assert ordered.kind == "stall" and "after 10.0 s: emergency stop" in ordered.detail, ordered.detail


@settings(max_examples=60, deadline=None)
@given(st.randoms(use_true_random=False))
def test_any_arrival_order_gives_the_same_verdict(rnd):
    """Two streams merged at random (each kept in its own order): always the stall at 10.0 s."""
    odom, status = streams_of_the_crafted_run()
    arrivals, i, j = [], 0, 0
    while i < len(odom) or j < len(status):
        if j >= len(status) or (i < len(odom) and rnd.random() < 0.5):
            arrivals.append(odom[i])
            i += 1
        else:
            arrivals.append(status[j])
            j += 1
    judge = judge_arrivals(arrivals)
    assert judge.kind == "stall" and "after 10.0 s: emergency stop" in judge.detail, judge.detail


def test_samples_wait_for_every_open_stream():
    order = StampOrder([("stall", DECISION), ("collision", STATE)])
    order.sample(T0, "a")
    order.sample(T0 + DT, "b")
    assert order.release() == [] and order.waiting_for() == ["stall", "collision"]
    order.message("stall", T0 + DT)
    assert order.release() == [] and order.waiting_for() == ["collision"]
    order.message("collision", T0)  # the world has passed the first sample only
    assert [row for _, row, _ in order.release()] == ["a"]
    order.close("collision", "nobody publishes /collision")
    assert [row for _, row, _ in order.release()] == ["b"] and order.watermark == T0 + DT


def test_a_state_applies_at_its_stamp_a_decision_after_it():
    order = StampOrder([("stall", DECISION), ("collision", STATE)])
    for k in range(4):
        order.sample(T0 + k * DT, k)
    order.message("collision", T0 + 2 * DT, "touching a wall")  # its first event closes the stream
    order.message("stall", T0 + 2 * DT, "emergency_stop")
    events = {row: what for _, row, what in order.release()}
    assert events == {0: {}, 1: {}, 2: {"collision": "touching a wall"},
                      3: {"collision": "touching a wall", "stall": "emergency_stop"}}


def test_an_earlier_runs_event_is_not_this_runs():
    """A status from the last run that reached us late (stamped before this run's first sample)."""
    order = StampOrder([("stall", DECISION)])
    order.message("stall", T0 - DT, "emergency_stop")
    order.sample(T0, "first")
    assert order.release() == [] and order.waiting_for() == ["stall"]  # still open, still awaited
    order.message("stall", T0)
    assert order.release() == [(T0, "first", {})]


def test_the_worlds_collision_outranks_the_monitors_at_one_sample():
    """A collision report and the stack's flag at one sample: the world's report decides."""
    odom, status = streams_of_the_crafted_run()
    collision = [("collision", s, "touching a wall" if s >= T0 + 100 * DT else None) for s, _, _ in wiggle()]
    streams = (("stall", DECISION), ("collision", STATE))
    judge = judge_arrivals(sorted(odom + status + collision, key=lambda m: m[1]), streams, "reported on /collision")
    assert judge.kind == "collision" and "after 10.0 s (reported on /collision)" in judge.detail, judge.detail
    assert judge.failure_point == pytest.approx(wiggle()[100][1:])


def test_a_bare_true_flag_still_reads_as_reported():
    judge = RobotJudge(box(30), 1.0, (25.0, 25.0), RobotSimConfig())
    judge.add([0.0, 0.1], [10.0, 10.1], [10.0, 10.0], stall=[False, True])
    assert judge.kind == "stall" and "reported" in judge.detail
    assert math.isfinite(judge.elapsed)


def test_the_run_starts_at_the_state_the_stack_first_acted_on():
    """A world that showed the start twice (a map reset, then the teleport) before the stack's
    first status: sample 0 is the one the stack acted on, the older one is dropped."""
    order = StampOrder([("stall", DECISION)])
    order.message("stall", T0 - 5 * DT)  # the last run's
    order.sample(T0, "reset by the map")
    order.sample(T0 + DT, "reset by the teleport")
    assert not order.start_at_first("stall")  # the stack has not acted yet: wait
    order.sample(T0 + 2 * DT, "first step")
    order.message("stall", T0 + DT)
    assert order.start_at_first("stall") and order.start == T0 + DT
    assert [row for _, row, _ in order.release()] == ["reset by the teleport"]
    order.message("stall", T0 + 2 * DT)
    assert [row for _, row, _ in order.release()] == ["first step"]
