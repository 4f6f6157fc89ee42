"""INVALID_TEST through the whole record: outcome, message, MCAP, campaign summary.

A failure counts only when a reference passes the same scenario (``sims.reference``). These tests
check the plumbing every problem shares: ``certify`` keeps a failure only when the reference
passed, the result message carries the new kind and the reference's metrics both ways, and a log
read back by an independent reader (rosbags) and by our summary counts INVALID_TEST apart from
failures.
"""
from __future__ import annotations

import numpy as np
from rosbags.highlevel import AnyReader

from ambiegen_ros.ros import conversions, qos, topics
from ambiegen_ros.ros.mcap_log import McapLog
from ambiegen_ros.ros.runlog import summarize
from ambiegen_ros.ros.types import get_registry
from ambiegen_ros.sims.outcome import FAILURE_KINDS, SUT_FAILURES, Outcome
from ambiegen_ros.sims.reference import ReferenceVerdict, certify, invalid_test

RESULT = topics.RESULT_TYPE
NO_ROUTE = ReferenceVerdict(False, "clearance_route", "no route keeps 0.39 m from the walls", {"clearance_m": 0.39})
DRIVER_OK = ReferenceVerdict(True, "reference_driver", "", {"max_oob": 0.1})


def _failed(kind="loiter") -> Outcome:
    return Outcome({"robot_time": 300.0}, True, kind, "loitering", {"time": 12.0},
                   trajectory=np.zeros((3, 2)), failure_point=(1.0, 2.0))


def test_invalid_test_is_no_failure_and_says_why():
    out = invalid_test(NO_ROUTE)
    assert not out.failed and out.failure_kind == "invalid_test"
    assert out.verdict == "INVALID_TEST(no route keeps 0.39 m from the walls)"
    assert out.reference == {"check": "clearance_route", "passed": False, "reason": NO_ROUTE.reason}
    assert out.metrics["reference_clearance_m"] == 0.39 and "sut_failure_kind" not in out.metrics
    assert "invalid_test" not in SUT_FAILURES and set(SUT_FAILURES) < set(FAILURE_KINDS)


def test_certify_keeps_a_failure_only_when_the_reference_passed():
    kept = certify(_failed(), DRIVER_OK)
    assert kept.failed and kept.verdict == "FAIL(loiter)" and kept.reference["passed"]
    assert kept.metrics["reference_max_oob"] == 0.1 and kept.metrics["reference_check"] == "reference_driver"
    dropped = certify(_failed("out_of_lane"), NO_ROUTE)
    assert not dropped.failed and dropped.failure_kind == "invalid_test"
    assert dropped.metrics["sut_failure_kind"] == "out_of_lane" and dropped.metrics["time"] == 12.0
    assert dropped.trajectory is not None and dropped.failure_point == (1.0, 2.0)  # the evidence stays
    passed = Outcome({"x": 0.0}, False, "none", "ok", {})
    assert certify(passed, NO_ROUTE).verdict == "PASS"  # a pass is a pass
    assert certify(_failed(), None).verdict == "FAIL(loiter)"


def test_result_message_round_trip_and_log_summary(tmp_path):
    reg = get_registry()
    outcomes = [invalid_test(NO_ROUTE), certify(_failed(), DRIVER_OK), Outcome({"x": 0.0}, False, "none", "ok", {}),
                certify(_failed("stall"), NO_ROUTE)]
    path = tmp_path / "run.mcap"
    with McapLog(path) as log:
        channel = log.add_channel(topics.RESULTS, RESULT, qos.DEFAULT)
        for i, outcome in enumerate(outcomes):
            msg = conversions.result_message(reg.new, 1000 + i, "run-1", i, "robot", "w", outcome)
            assert msg.failure_kind == FAILURE_KINDS[outcome.failure_kind]
            back = conversions.outcome_from_message(msg)
            assert (back.failure_kind, back.failed, back.detail) == (outcome.failure_kind, outcome.failed, outcome.detail)
            assert back.reference == ({**outcome.reference, "reason": outcome.reference["reason"]}
                                      if outcome.reference else None)
            assert back.failure_point == outcome.failure_point  # where it failed crosses the wire too
            log.write(channel, reg.serialize(msg, RESULT), 1000 + i)
    with AnyReader([path]) as reader:  # an independent reader sees the kinds and reasons
        seen = [reg.deserialize(raw, conn.msgtype) for conn, _, raw in reader.messages()]
    assert [int(m.failure_kind) for m in seen] == [10, 9, 0, 10]
    assert seen[0].detail == NO_ROUTE.reason
    keys = {kv.key: kv.value for kv in seen[3].metrics}
    assert keys["sut_failure_kind"] == "stall" and keys["reference_check"] == "clearance_route"
    summary = summarize(path, "run-1")
    assert summary["failures"] == 1 and summary["invalid_tests"] == 2
    assert summary["outcomes"] == {"invalid_test": 2, "loiter": 1, "none": 1}


def test_a_result_logged_before_its_scenario_is_still_read(tmp_path):
    """The recorder's readers are separate: a result can land in the log a hair before the first
    scenario message (seen on Fast DDS). ``recorded_scenarios`` (replay, the Fast DDS bench) must
    still pair it with its run."""
    from ambiegen_ros.nodes.replay import recorded_scenarios
    from ambiegen_ros.problems import get_problem

    reg, problem = get_registry(), get_problem("thermostat")
    scenario = problem.codec.from_rows(problem.sample_rows(1, np.random.default_rng(0)))[0]
    path = tmp_path / "early.mcap"
    with McapLog(path) as log:
        results = log.add_channel(topics.RESULTS, RESULT, qos.DEFAULT)
        typename = topics.SCENARIO_TYPES["thermostat"]
        scenarios = log.add_channel(topics.scenarios("thermostat"), typename, qos.DEFAULT)
        result = conversions.result_message(reg.new, 1000, "run-1", 0, "thermostat", "w", _failed())
        log.write(results, reg.serialize(result, RESULT), 1000)  # the result first
        meta = conversions.ScenarioMeta(run_id="run-1", scenario_id=0)
        msg = conversions.scenario_message(reg.new, 1001, problem, scenario, meta)
        log.write(scenarios, reg.serialize(msg, typename), 1001)
    rec = recorded_scenarios(path)
    assert rec.run_id == "run-1" and set(rec.scenarios) == {0}
    assert set(rec.outcomes) == {0} and rec.outcomes[0].failure_kind == "loiter"
