"""A starved stack is never a failure (issue 70), in the adapter, without a node or a middleware: the
Nav2 judge's timing watch fed /rosout lines, /cmd_vel_nav messages, the world's /clock and our
goal's acknowledgement on a stand-in node, and ``SutAdapter.finish`` on a stand-in adapter turning a
starved Nav2 abort (or pass) into an error record of the kind ``starved``, its figures in the result's
metrics."""
from __future__ import annotations

import sys
from pathlib import Path
from types import SimpleNamespace

REPO = Path(__file__).resolve().parents[1]
for extra in (REPO, REPO / "test", REPO / "test" / "sims"):
    if str(extra) not in sys.path:
        sys.path.insert(0, str(extra))

from ambiegen_ros.sims import Outcome  # noqa: E402
from sim_nodes.adapter import nav2_rules  # noqa: E402
from sim_nodes.adapter.job import Job  # noqa: E402
from sim_nodes.adapter.node import SutAdapter  # noqa: E402
from sim_nodes.adapter.robot_nav2 import Nav2Robot  # noqa: E402
from sim_nodes.adapter.timing_watch import TimingWatch  # noqa: E402
from sim_nodes.adapter.judge import DECIDED  # noqa: E402
from test_adapter_judges import REG, along_the_diagonal, make_judge, robot, robot_job, view  # noqa: E402,F401

MISSED = "Control loop missed its desired rate of 20.0000 Hz. Current loop rate is 3.2000 Hz."
ABORT = {"status": "aborted", "error_code": 105, "error_msg": "Failed to make progress"}


def watched(robot, **values):
    """A Nav2 judge with its timing watch on a stand-in node, its goal sent and acknowledged."""
    judge, node, _ = make_judge(Nav2Robot, robot[0], **values)
    judge.timing = TimingWatch(node, judge.settings)
    job = robot_job(judge, node, robot[1])
    judge.begin(job)
    judge.send_goal(job)
    judge.nav2.handle = object()  # accepted
    t, rows = along_the_diagonal(2.0)
    judge.feed(job, t, rows, [{}] * len(t))
    return judge, node, job


def say(node, text: str, name: str = "controller_server") -> None:
    node.subs["/rosout"](REG.new("rcl_interfaces/msg/Log", name=name, msg=text, level=30))


def finished(judge, job, outcome: Outcome) -> Outcome:
    """``SutAdapter.finish`` on a stand-in adapter around ``judge``: what it published."""
    sent = []
    stand_in = SimpleNamespace(
        job=job, _fast=None, nav2=judge.nav2, mode=judge, topics={}, order=SimpleNamespace(streams={}),
        ours_error_codes=set(), reference=False, problem_name="robot", problem=SimpleNamespace(hazards=False),
        known_failures=[], time_scale=1.0, stamp_clock="sim", idle=lambda: None,
        publish=lambda run_id, sid, out: sent.append(out), node=SimpleNamespace(logger=SimpleNamespace(info=print)))
    SutAdapter.finish(stand_in, outcome)
    (out,) = sent
    return out


def test_the_watch_subscribes_to_rosout_and_the_controllers_output_and_can_be_turned_off(robot):
    judge, node, _ = watched(robot)
    assert {"/rosout", "/cmd_vel_nav", "/scan", "/clock"} <= set(node.subs)
    for _ in range(3):
        node.subs["/scan"](REG.new("sensor_msgs/msg/LaserScan"))
    node.subs["/clock"](REG.new("rosgraph_msgs/msg/Clock"))
    figures, _ = judge.timing.verdict()
    assert figures["timing.scan_msgs"] == 3 and figures["timing.clock_msgs"] == 1
    assert figures["timing.scan_max_gap_s"] >= 0.0 and "timing.clock_max_gap_s" not in figures
    off, node_off, _ = make_judge(Nav2Robot, robot[0], timing_rosout_topic="", timing_cmd_vel_topic="",
                                  timing_scan_topic="", timing_clock_topic="")
    TimingWatch(node_off, off.settings)
    assert not {"/rosout", "/cmd_vel_nav", "/scan", "/clock"} & set(node_off.subs)


def test_a_starved_nav2_abort_is_an_error_record_of_the_kind_starved(robot):
    judge, node, job = watched(robot)
    assert judge.step(job, view()) is None and judge.timing.sent is None  # acknowledged: its time on record
    for _ in range(30):  # 30 of a 2 s window's 40 cycles said missed
        say(node, MISSED)
    judge.nav2.result = ABORT
    assert judge.step(job, view()) == DECIDED and job.judge.outcome().failure_kind == "nav2_aborted"
    out = finished(judge, job, job.judge.outcome())
    assert out.failure_kind == "error" and not out.failed and out.verdict == "ERROR"
    assert out.metrics["error_kind"] == "starved" and out.metrics["sut_failure_kind"] == "nav2_aborted"
    assert out.detail.startswith("starved: ") and "missed 75% of its cycles" in out.detail
    assert "FAIL(nav2_aborted)" in out.detail and "Failed to make progress" in out.detail
    assert out.metrics["timing.missed_loops"] == 30 and "timing.ack_s" in out.metrics
    assert out.metrics["nav2_error_code"] == 105, "Nav2's word stays beside it"


def test_a_starved_pass_is_no_verdict_either_and_a_clean_abort_stays_a_failure(robot):
    judge, node, job = watched(robot)
    say(node, "Timed out while waiting for action server to acknowledge goal request for follow_path",
        name="bt_navigator")
    judge.nav2.result = {"status": "succeeded", "error_code": 0, "error_msg": ""}
    assert judge.step(job, view()) == DECIDED
    out = finished(judge, job, job.judge.outcome())
    assert out.metrics["error_kind"] == "starved" and out.metrics["sut_failure_kind"] == "none"
    assert "late acknowledgement (follow_path)" in out.detail

    clean, node, job = watched(robot)
    for _ in range(3):
        say(node, MISSED)  # a few missed cycles: the stack still had its computer
    node.subs["/cmd_vel_nav"](REG.new("geometry_msgs/msg/Twist"))
    clean.nav2.result = ABORT
    assert clean.step(job, view()) == DECIDED
    out = nav2_rules.starved_not_failed(job.judge.outcome(), *clean.timing.verdict())
    assert out.failure_kind == "nav2_aborted" and out.failed and "error_kind" not in out.metrics
    assert out.metrics["timing.missed_loops"] == 3 and out.metrics["timing.cmd_vel_msgs"] == 1


def test_a_lapsed_bond_makes_the_taken_down_record_starved_and_a_crash_stays_a_crash(robot):
    judge, node, job = watched(robot)
    say(node, "CRITICAL FAILURE: SERVER controller_server IS DOWN after not receiving a heartbeat for 4000 ms.",
        name="lifecycle_manager_navigation")
    down = Outcome.rejected("Nav2's controller_server left the active state during the run", kind="error")
    out = finished(judge, job, down)
    assert out.metrics["error_kind"] == "starved" and "lost the bond of controller_server" in out.detail
    crash = Outcome(objectives={}, failed=True, failure_kind="sut_crashed", detail="the stack crashed")
    assert nav2_rules.starved_not_failed(crash, {}, "a lapsed bond").failure_kind == "sut_crashed"


def test_our_goal_acknowledged_late_starves_the_run(robot):
    judge, node, job = watched(robot, starved_ack_s=0.0)
    judge.nav2.handle = None
    assert judge.step(job, view()) is None and judge.timing.sent is not None  # not answered yet
    judge.nav2.handle = object()
    judge.step(job, view())
    figures, reason = judge.timing.verdict()
    assert figures["timing.ack_s"] > 0.0 and "to acknowledge our goal" in reason


def test_the_worlds_silence_limit_reaches_the_watch_and_nav2_drives_from_its_answer_to_the_end(robot,
                                                                                               monkeypatch):
    from sim_nodes.adapter import timing_watch

    now = [99.0]
    monkeypatch.setattr(timing_watch, "time", SimpleNamespace(monotonic=lambda: now[0]))
    for values, limit in (({}, 0.35), ({"starved_world_gap_s": 0.0}, 0.0), ({"time_scale": 2.0}, 0.35),
                          ({"starved_world_gap_s": 0.35, "time_scale": 0.5}, 0.7)):  # the world's messages 2x apart
        now[0] = 99.0
        judge, node, job = watched(robot, **values)  # its goal out at 99.0
        assert judge.timing.thresholds.max_world_gap_s == limit
        now[0] = 99.1
        node.subs["/clock"](REG.new("rosgraph_msgs/msg/Clock"))
        now[0] = 99.9
        judge.step(job, view())  # Nav2's answer seen: of the clock's 0.9 s silence around it, 0.1 s count
        for t in (100.0, 100.2, 100.7, 101.0):  # and a 0.5 s stall while Nav2 drives
            now[0] = t
            node.subs["/clock"](REG.new("rosgraph_msgs/msg/Clock"))
        assert judge.timing.record.span() == (99.9, None)
        now[0] = 101.1
        figures, reason = judge.timing.verdict()
        assert figures["timing.clock_max_gap_s"] == 0.5 and figures["timing.clock_msgs"] == 5
        assert figures["timing.ack_s"] == 0.9
        if limit == 0.35:
            assert reason == "the world's /clock was silent for 0.50 s (limit 0.35 s)"
        else:
            assert reason is None, values
        now[0] = 103.0
        node.subs["/clock"](REG.new("rosgraph_msgs/msg/Clock"))  # after the run's end: no record keeps it
        assert judge.timing.record is None and judge.timing.verdict() == ({}, None)
