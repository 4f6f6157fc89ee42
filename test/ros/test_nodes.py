"""The ROS 2 layer's nodes as real processes over real DDS (Cyclone from PyPI), under faults: a
worker killed with work in hand, malformed scenario messages, scenarios nobody answers; and the
message contents the nodes rely on. The recorder interrupted: ``test_nodes_recorder.py``; whole
campaigns through the CLI: ``test_nodes_campaigns.py``.

Every multi-process test runs its nodes as subprocesses on its own ROS_DOMAIN_ID (``ros_domain``,
test/conftest.py: unique across tests and concurrent runs), so tests cannot see each other, and reads the run back from the MCAP log with independent readers
(rosbags' AnyReader decodes with the schema text stored in the file). Budgets are small; every
wait ends on an event (a result, an exit) and its bound is a safety net for a hung process, never
the thing tested.
"""
from __future__ import annotations

import json
import math
import os
import signal
import sys
import time
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[2]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

import numpy as np  # noqa: E402
import pytest  # noqa: E402

from ambiegen_ros.problems import get_problem  # noqa: E402
from ambiegen_ros.ros import conversions, topics  # noqa: E402
from ambiegen_ros.ros.conversions import ScenarioMeta  # noqa: E402
from ambiegen_ros.ros.qos import STREAM  # noqa: E402
from ambiegen_ros.ros.runlog import summarize  # noqa: E402
from ambiegen_ros.campaign import SIM_MODULES  # noqa: E402
from ambiegen_ros.ros.types import get_registry  # noqa: E402
from ambiegen_ros.sims.outcome import FAILURE_KINDS  # noqa: E402
from helpers.node_runs import _done_line, _read_run  # noqa: E402
# other test files import the node helpers from here (test_hostile_input, test_launch_logic, test_no_overwrite)
from helpers.node_runs import Nodes, _env, nodes_factory  # noqa: E402,F401

pytestmark = pytest.mark.skipif(
    os.environ.get("AMBIEGEN_TRANSPORT", "auto") == "rclpy", reason="these tests drive the DDS backend"
)


SIM_TIMEOUT = FAILURE_KINDS["sim_timeout"]
INVALID = FAILURE_KINDS["invalid_scenario"]


# --- no DDS: message contents the nodes rely on ---------------------------------------------------
def test_thermostat_message_matches_its_environment():
    """The thermostat message is built from the genome (no simulation); it must equal environment()."""
    reg = get_registry()
    problem = get_problem("thermostat")
    X = problem.codec.join(*problem.sample(20, np.random.default_rng(4)))
    # a day running past 24 h: the replication profile's schedule (and message) stops at 24 h
    long_day = problem.codec.to_row(problem.parse({"problem": "thermostat", "elements": [
        {"temperature": 20 + i % 3, "duration": 240, "model": 1 + i} for i in range(7)]}))
    X = np.vstack([X, long_day])
    for i, row in enumerate(X):
        scenario = problem.codec.from_row(row)
        env = problem.environment(scenario)
        msg = conversions.scenario_message(reg.new, 0, problem, scenario, ScenarioMeta("r", i))
        assert list(msg.setpoints) == [float(v) for v in env.setpoints]
        assert list(msg.durations_min) == list(env.durations)
        assert list(msg.room_models) == list(env.models)
        assert msg.initial_temperature == env.initial_temperature
        assert sum(msg.durations_min) <= 1440
        back, info = conversions.scenario_from_message(problem, reg.deserialize(reg.serialize(msg, msg.__msgtype__), msg.__msgtype__))
        assert back.elements == scenario.elements and info["scenario_id"] == i


def test_vehicle_message_carries_raw_and_interpolated_road():
    reg = get_registry()
    problem = get_problem("vehicle")
    scenario = problem.codec.from_row(problem.codec.join(*problem.sample(1, np.random.default_rng(2)))[0])
    env = problem.environment(scenario)
    msg = conversions.scenario_message(reg.new, 0, problem, scenario, ScenarioMeta("r", 0))
    assert [(p.x, p.y) for p in msg.road_points] == [tuple(map(float, p)) for p in env.spine]
    assert len(msg.road.poses) == len(env.nodes) and msg.lane_width == env.lane_width


# --- 4: a worker killed mid-run ---------------------------------------------------------------------
def test_killed_worker_loses_nothing(nodes_factory, test_node, tmp_path, ros_domain):
    domain = ros_domain
    nodes = nodes_factory(domain)
    mcap = tmp_path / "kill.mcap"
    watcher = test_node("kill_watch", domain)
    nodes.start("recorder", "ambiegen_ros.nodes.recorder", output=str(mcap), flush_period=0.5)
    victim = nodes.start("w_a", "sim_nodes.thermostat_sim", worker_id="w_a", model="surrogate", min_result_subscribers=2)
    nodes.start("w_b", "sim_nodes.thermostat_sim", worker_id="w_b", model="surrogate", min_result_subscribers=2)
    state = {"a_results": 0, "killed_at": None}
    answered: set[int] = set()  # a result, or logged as not sent (invalid)

    def on_result(msg):
        state["a_results"] += msg.worker == "w_a"
        answered.add(int(msg.scenario_id))

    def on_scenario(msg):
        # kill w_a the moment it has work in hand (after it proved it was working)
        if state["killed_at"] is None and state["a_results"] >= 3 and msg.meta.assigned_worker == "w_a":
            os.kill(victim.pid, signal.SIGKILL)
            state["killed_at"] = int(msg.meta.scenario_id)

    watcher.create_subscription(topics.RESULT_TYPE, topics.RESULTS, on_result, STREAM)
    watcher.create_subscription(topics.SCENARIO_TYPES["thermostat"], topics.scenarios("thermostat"), on_scenario, STREAM)
    watcher.create_subscription(topics.SCENARIO_TYPES["thermostat"], topics.not_sent("thermostat"),
                                lambda m: answered.add(int(m.meta.scenario_id)), topics.NOT_SENT_QOS)
    gen = nodes.start(
        "generator", "ambiegen_ros.nodes.generator", problem="thermostat", algorithm="ga", mode="in_the_loop",
        evaluations=300, population=50, offspring=50, seed=5, run_id="kill-run", min_subscribers=4, min_workers=2,
        # subscriber_wait: a safety net (the start waits for the match); worker_timeout: the default, so
        # w_b's heartbeats, late on a busy machine, do not get it declared lost too
        subscriber_wait=120.0, worker_timeout=3.0, result_timeout=30.0, max_attempts=2,
    )
    deadline = time.monotonic() + 300  # a safety net: the loop ends when the generator does
    while gen.poll() is None and time.monotonic() < deadline:
        watcher.spin_once(0.05)
    assert gen.poll() == 0, nodes.log("generator")[-3000:]
    assert state["killed_at"] is not None, "w_a was never caught with work in hand"
    assert victim.wait(5) == -signal.SIGKILL
    # every scenario's last answer has been delivered (here; the recorder reads the same topic)
    assert watcher.spin_until(lambda: answered >= set(range(300)), 60), sorted(set(range(300)) - answered)[:10]
    nodes.stop("w_b")
    assert nodes.stop("recorder") == 0

    done = _done_line(nodes.log("generator"))
    run = _read_run(mcap)
    sids = {s[0] for s in run["scenarios"]}
    unsent = {s[0] for s in run["not_sent"]}
    by_sid: dict[int, list] = {}
    for sid, worker, kind, *_ in run["results"]:
        by_sid.setdefault(sid, []).append((worker, kind))
    assert sids | unsent == set(range(300)) and not sids & unsent and done["scenarios"] == len(sids)
    assert set(by_sid) == sids  # every scenario ended with a result or an explicit timeout
    # what w_a had in hand when it died was sent again, to w_b, and answered there (or timed out)
    lost = {s[0] for s in run["scenarios"] if s[1] == "w_a" and s[2] == 1} - {
        sid for sid, answers in by_sid.items() if any(w == "w_a" for w, _ in answers)
    }
    # SIGKILL lands a moment after the watcher saw the scenario: w_a may have answered that one
    # already, but it died holding later ones
    killed = state["killed_at"]
    assert killed in lost or any(w == "w_a" for w, _ in by_sid[killed]), f"scenario {killed} vanished"
    assert lost, "w_a died with no scenario in hand: nothing was tested"
    resent = {s[0]: s[1] for s in run["scenarios"] if s[2] == 2}
    for sid in lost:
        assert resent.get(sid) == "w_b", f"scenario {sid} was not re-assigned"
        assert any(w == "w_b" or k == SIM_TIMEOUT for w, k in by_sid[sid])
    assert {w for answers in by_sid.values() for w, _ in answers} >= {"w_a", "w_b"}
    assert done["settled"] == len(sids) and summarize(mcap, "kill-run")["unresolved"] == []


# --- 5: malformed scenario messages ------------------------------------------------------------------
def test_malformed_scenarios_get_invalid_results_and_the_node_goes_on(nodes_factory, test_node, ros_domain):
    domain = ros_domain
    nodes = nodes_factory(domain)
    worker = nodes.start("thermostat_sim", "sim_nodes.thermostat_sim", worker_id="w_bad", model="surrogate", min_result_subscribers=1)
    node = test_node("malformed_test", domain)
    problem = get_problem("thermostat")
    typename = topics.SCENARIO_TYPES["thermostat"]
    pub = node.create_publisher(typename, topics.scenarios("thermostat"), STREAM)
    results: dict[int, Any] = {}
    node.create_subscription(
        topics.RESULT_TYPE, topics.RESULTS, lambda m: results.setdefault(int(m.scenario_id), m) if m.run_id == "bad" else None, STREAM
    )
    scenario = problem.codec.from_row(problem.codec.join(*problem.sample(1, np.random.default_rng(0)))[0])

    def message(sid: int):
        return conversions.scenario_message(node.new_message, node.now_ns(), problem, scenario, ScenarioMeta("bad", sid))

    def ask(msg, timeout=15.0):
        sid = int(msg.meta.scenario_id)
        pub.publish(msg)
        assert node.spin_until(lambda: sid in results, timeout), f"no answer to scenario {sid}"
        return results[sid]

    assert node.wait_for_subscribers(pub, 1, 120.0)  # a safety net
    # the worker's result publisher may match us a little later: retry a valid one until answered
    deadline = time.monotonic() + 20
    while 0 not in results and time.monotonic() < deadline:
        pub.publish(message(0))
        node.spin_until(lambda: 0 in results, 0.5)
    assert results[0].failure_kind != INVALID

    cases = []
    m = message(1); m.meta.scenario_json = '{"problem": "thermostat", "elements": [{'; cases.append((m, "meta.scenario_json"))
    m = message(2); m.meta.genome = m.meta.genome.copy(); m.meta.genome[1] = float("nan"); cases.append((m, "meta.genome"))
    data = scenario.to_dict(); data["elements"][0]["temperature"] = 99
    m = message(3); m.meta.scenario_json = json.dumps(data); cases.append((m, "elements[0].temperature"))
    m = message(4); m.meta.problem = "robot"; cases.append((m, "meta.problem"))
    m = message(5); m.meta.problem = "no_such_problem"; cases.append((m, "meta.problem"))
    m = message(6); m.meta.genome = m.meta.genome[:-1].copy(); cases.append((m, "meta.genome"))
    m = message(7); m.meta.scenario_json = '{"problem": "thermostat", "elements": [{"temperature": NaN}]}'
    cases.append((m, "meta.scenario_json"))
    data = scenario.to_dict(); data["elements"][0]["colour"] = "red"
    m = message(8); m.meta.scenario_json = json.dumps(data); cases.append((m, "colour"))
    m = node.new_message(typename); m.meta.run_id = "bad"; m.meta.scenario_id = 9; cases.append((m, "meta.problem"))
    for msg, field in cases:
        result = ask(msg)
        assert result.failure_kind == INVALID and not result.failed, (field, result.detail)
        assert field in result.detail, (field, result.detail)
        assert result.worker == "w_bad" and len(result.objectives) == 0
    assert worker.poll() is None
    valid = ask(message(10))
    assert valid.failure_kind != INVALID and valid.objectives[0] > 0 and math.isfinite(valid.elapsed_sec)
    assert valid.objectives[0] == pytest.approx(float(results[0].objectives[0]))
    assert nodes.stop("thermostat_sim") == 0


# --- 6: nobody answers --------------------------------------------------------------------------------
@pytest.mark.parametrize("other_worker", [None, "robot"], ids=["no_worker", "other_problem_worker"])
def test_unanswered_scenarios_end_as_sim_timeouts(nodes_factory, test_node, tmp_path, ros_domain, other_worker):
    nodes = nodes_factory(ros_domain)
    watcher = test_node("timeout_watch", ros_domain)
    answered: set[int] = set()
    watcher.create_subscription(topics.RESULT_TYPE, topics.RESULTS, lambda m: answered.add(int(m.scenario_id)), STREAM)
    mcap = tmp_path / "timeouts.mcap"
    nodes.start("recorder", "ambiegen_ros.nodes.recorder", output=str(mcap))
    if other_worker:
        nodes.start("robot_sim", SIM_MODULES[other_worker], worker_id="robot_w", model="surrogate", min_result_subscribers=1)
    gen = nodes.start(
        "generator", "ambiegen_ros.nodes.generator", problem="thermostat", algorithm="ga", evaluations=60,
        population=20, offspring=20, seed=2, run_id="silent-run", min_subscribers=1, subscriber_wait=120.0,
        worker_wait=0.3, result_timeout=0.5, max_attempts=2,  # nobody answers: these short times are the test
    )
    assert nodes.wait("generator", 300) == 0, nodes.log("generator")[-3000:]
    settled = _done_line(nodes.log("generator"))["settled"]
    assert watcher.spin_until(lambda: len(answered) >= settled, 60), (len(answered), settled)  # the last timeouts delivered
    if other_worker:
        assert nodes.procs["robot_sim"].poll() is None
        nodes.stop("robot_sim")
    assert nodes.stop("recorder") == 0
    done = _done_line(nodes.log("generator"))
    assert done["scenarios"] > 0 and done["timeouts"] == done["scenarios"] == done["settled"]
    run = _read_run(mcap)
    sids = {s[0] for s in run["scenarios"]}
    assert len(sids) == done["scenarios"]
    attempts = sorted((s[0], s[2]) for s in run["scenarios"])
    assert attempts == [(sid, a) for sid in sorted(sids) for a in (1, 2)]  # offered twice, to anyone
    assert all(s[1] == "" for s in run["scenarios"])
    assert sorted(r[0] for r in run["results"]) == sorted(sids)
    for sid, worker, kind, run_id, detail in run["results"]:
        assert kind == SIM_TIMEOUT and worker == "generator" and run_id == "silent-run"
        assert "2 attempt" in detail
    assert gen.returncode == 0
