"""The ROS 2 layer end to end: real node processes talking over real DDS (Cyclone from PyPI).

Every multi-process test runs its nodes as subprocesses on its own ROS_DOMAIN_ID (``ros_domain``,
test/conftest.py: unique across tests and concurrent runs), so tests cannot see each other, and reads the run back from the MCAP log with independent readers
(rosbags' AnyReader decodes with the schema text stored in the file; the ``mcap`` library reads
channel metadata and metadata records). Budgets are small; every wait ends on an event (a
result, an exit) and its bound is a safety net for a hung process, never the thing tested.
"""
from __future__ import annotations

import json
import math
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[2]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

import numpy as np  # noqa: E402
import pytest  # noqa: E402
from mcap.exceptions import McapError  # noqa: E402
from mcap.reader import make_reader  # noqa: E402
from rosbags.highlevel import AnyReader  # noqa: E402
from rosbags.interfaces import QosDurability, QosReliability  # noqa: E402

from ambiegen_ros.problems import get_problem  # noqa: E402
from ambiegen_ros.ros import conversions, topics  # noqa: E402
from ambiegen_ros.ros.conversions import ScenarioMeta  # noqa: E402
from ambiegen_ros.ros.mcap_log import recover  # noqa: E402
from ambiegen_ros.ros.qos import LATCHED, STREAM  # noqa: E402
from ambiegen_ros.ros.runlog import iter_messages, summarize  # noqa: E402
from ambiegen_ros.campaign import SIM_MODULES  # noqa: E402
from ambiegen_ros.ros.types import get_registry  # noqa: E402
from ambiegen_ros.sims.outcome import FAILURE_KINDS  # noqa: E402

pytestmark = pytest.mark.skipif(
    os.environ.get("AMBIEGEN_TRANSPORT", "auto") == "rclpy", reason="these tests drive the DDS backend"
)

SIM_TIMEOUT = FAILURE_KINDS["sim_timeout"]
INVALID = FAILURE_KINDS["invalid_scenario"]
DONE = re.compile(
    r"run (\S+) done: (\d+) scenarios, (\d+) settled, (\d+) failures, (\d+) invalid tests, (\d+) timeouts, "
    r"(\d+) errors, (\d+) invalid"
)


# --- process helpers -------------------------------------------------------------------------------
def _env(domain: int) -> dict[str, str]:
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain), PYTHONUNBUFFERED="1")
    env.pop("AMBIEGEN_TRANSPORT", None)
    return env


def _value(v: Any) -> str:
    return ("true" if v else "false") if isinstance(v, bool) else str(v)


class Nodes:
    """Node subprocesses of one test; whatever is still running at teardown is stopped by pid."""

    def __init__(self, domain: int, log_dir: Path):
        self.domain = domain
        self.log_dir = log_dir
        self.procs: dict[str, subprocess.Popen] = {}

    def start(self, name: str, module: str, **params: Any) -> subprocess.Popen:
        args = [sys.executable, "-m", module, "--ros-args", "-r", f"__node:={name}"]
        for key, value in params.items():
            args += ["-p", f"{key}:={_value(value)}"]
        self.log_dir.mkdir(parents=True, exist_ok=True)
        with open(self.log_dir / f"{name}.log", "wb") as log:
            proc = subprocess.Popen(args, cwd=REPO, env=_env(self.domain), stdout=log, stderr=subprocess.STDOUT)
        self.procs[name] = proc
        return proc

    def log(self, name: str) -> str:
        return (self.log_dir / f"{name}.log").read_text(errors="replace")

    def wait(self, name: str, timeout: float) -> int:
        try:
            return self.procs[name].wait(timeout)
        except subprocess.TimeoutExpired:
            pytest.fail(f"{name} still running after {timeout} s; log:\n{self.log(name)[-3000:]}")

    def stop(self, name: str, timeout: float = 10.0) -> int:
        proc = self.procs[name]
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
            try:
                proc.wait(timeout)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
                pytest.fail(f"{name} ignored SIGINT for {timeout} s")
        return proc.returncode

    def cleanup(self) -> None:
        for proc in self.procs.values():
            if proc.poll() is None:
                proc.kill()
                proc.wait()


@pytest.fixture
def nodes_factory(tmp_path):
    made: list[Nodes] = []

    def make(domain: int) -> Nodes:
        nodes = Nodes(domain, tmp_path / f"logs{domain}")
        made.append(nodes)
        return nodes

    yield make
    for nodes in made:
        nodes.cleanup()


@pytest.fixture
def test_node(monkeypatch):
    """A node in this process on a given domain (DDS backend, as AMBIEGEN_TRANSPORT defaults)."""
    from ambiegen_ros.ros.transport import create_node

    created = []

    def make(name: str, domain: int):
        monkeypatch.setenv("ROS_DOMAIN_ID", str(domain))
        node = create_node(name, argv=[])
        created.append(node)
        return node

    yield make
    for node in created:
        node.shutdown()


def _campaign(domain: int, out: Path, problem: str, algorithm: str, evaluations: int, **extra: Any) -> subprocess.Popen:
    args = [sys.executable, "-m", "ambiegen_ros", "campaign", "--problem", problem, "--algorithm", algorithm,
            "--evaluations", str(evaluations), "--seed", "1", "--domain-id", str(domain), "--out", str(out),
            "--timeout", "400"]  # a safety net: four campaigns share a (busy) machine
    for key, value in extra.items():
        args += [f"--{key.replace('_', '-')}", str(value)]
    return subprocess.Popen(args, cwd=REPO, env=_env(domain), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _read_run(mcap: Path) -> dict[str, Any]:
    """Everything of a run as rosbags decodes it from the schema text stored in the file."""
    run: dict[str, Any] = {"scenarios": [], "not_sent": [], "results": [], "status": [], "config": [], "connections": {}}
    with AnyReader([mcap]) as reader:
        run["connections"] = {c.topic: c for c in reader.connections}
        for conn, stamp, raw in reader.messages():
            msg = reader.deserialize(raw, conn.msgtype)
            if conn.topic.endswith("/scenarios"):
                m = msg.meta
                run["scenarios"].append((int(m.scenario_id), m.assigned_worker, int(m.attempt), m.run_id, m.problem))
            elif conn.topic.endswith("/not_sent"):
                m = msg.meta
                run["not_sent"].append((int(m.scenario_id), m.scenario_json, bool(m.surrogate_valid), m.invalid_reason,
                                        int(m.attempt), m.run_id))
            elif conn.topic == topics.RESULTS:
                run["results"].append((int(msg.scenario_id), msg.worker, int(msg.failure_kind), msg.run_id, msg.detail))
            elif conn.topic == topics.STATUS:
                run["status"].append(msg)
            elif conn.topic == topics.RUN_CONFIG:
                run["config"].append(msg)
    return run


def _done_line(log: str) -> dict[str, Any]:
    match = DONE.search(log)
    assert match, f"no 'done' line in the generator log:\n{log[-2000:]}"
    keys = ("run_id", "scenarios", "settled", "failures", "invalid_tests", "timeouts", "errors", "invalid")
    done = {k: (v if k == "run_id" else int(v)) for k, v in zip(keys, match.groups())}
    unsent = re.search(r"; (\d+) not sent \(the problem calls them invalid\)", log[match.end():].split("\n", 1)[0])
    done["not_sent"] = int(unsent.group(1)) if unsent else 0
    return done


def _assert_summary_consistent(summary: dict[str, Any], out: Path) -> None:
    brief = json.dumps({k: v for k, v in summary.items() if k != "outcomes"})
    assert "log_error" not in summary, brief
    assert all(code == 0 for code in summary["exit_codes"].values()), brief
    assert summary["unresolved"] == [], brief
    assert summary["scenarios_published"] > 0, brief
    assert summary["results_received"] == summary["scenarios_published"] == summary["scenario_messages"], brief
    assert sum(summary["outcomes"].values()) == summary["results_received"], brief
    assert summary["timeouts"] == 0 and summary["errors"] == 0 and summary["duplicate_results"] == 0, brief
    assert summary["final_state"] == "done", brief
    assert "ambiegen_run" in summary["metadata"], brief
    done = _done_line((out / "logs" / "generator.log").read_text())
    assert done["run_id"] == summary["run_id"]
    assert (done["scenarios"], done["settled"]) == (summary["scenarios_published"], summary["results_received"]), brief
    assert done["not_sent"] == summary["not_sent"] == sum(summary["not_sent_rules"].values()), brief
    assert "invalid_scenario" not in summary["outcomes"], brief  # what the problem calls invalid is never sent
    assert (done["failures"], done["invalid_tests"], done["timeouts"], done["errors"], done["invalid"]) == (
        summary["failures"], summary["invalid_tests"], summary["timeouts"], summary["errors"], summary["invalid"]
    ), brief


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


# --- 1-3: campaigns through the CLI ------------------------------------------------------------------
CAMPAIGNS = {
    # name: (unused, problem, algorithm, evaluations, extra CLI options); domains from ``module_domains``
    "thermostat": (None, "thermostat", "ga", 300, {"population": 20, "offspring": 20}),
    "robot": (None, "robot", "nsga2", 200, {"population": 20, "offspring": 20}),
    "vehicle": (None, "vehicle", "nsga2", 200, {"population": 20, "offspring": 20}),
    "in_the_loop": (None, "thermostat", "ga", 240, {"population": 30, "offspring": 30, "mode": "in_the_loop", "workers": 2}),
    # spent before the first generation is through: what was sent finishes, the rest is never sent
    "budget": (None, "thermostat", "ga", 240, {"population": 30, "offspring": 30, "mode": "in_the_loop",
                                               "execution_budget": 0.001}),
    # the README's first command, smaller: refined roads searched in the loop find certified failures
    "demo": (None, "vehicle", "nsga2", 300, {"population": 50, "offspring": 50, "mode": "in_the_loop", "workers": 2,
                                             "profile": "refined"}),
    # random maps in the loop: drawn from every sample, 17 of these 40 would have had no route
    "random": (None, "robot", "random", 40, {"population": 20, "mode": "in_the_loop", "profile": "refined",
                                             "sim_model": "surrogate"}),
}


@pytest.fixture(scope="module")
def campaigns(tmp_path_factory, module_domains):
    """All campaigns at once (each on its own domain): exit code, summary and output folder."""
    root = tmp_path_factory.mktemp("campaigns")
    procs = {}
    for name, (_, problem, algorithm, evaluations, extra) in CAMPAIGNS.items():
        procs[name] = _campaign(module_domains(), root / name, problem, algorithm, evaluations, **extra)
    out = {}
    try:
        for name, proc in procs.items():
            stdout, stderr = proc.communicate(timeout=480)  # a safety net beyond the campaigns' own
            summary_path = root / name / "summary.json"
            summary = json.loads(summary_path.read_text()) if summary_path.exists() else {}
            out[name] = (proc.returncode, summary, root / name, stdout + stderr)
    finally:
        for proc in procs.values():
            if proc.poll() is None:
                proc.kill()
                proc.wait()
    return out


@pytest.mark.parametrize("name", ["thermostat", "robot", "vehicle"])
def test_surrogate_campaign_end_to_end(campaigns, name):
    code, summary, out, output = campaigns[name]
    assert code == 0, output[-3000:]
    _assert_summary_consistent(summary, out)
    evaluations = CAMPAIGNS[name][3]
    assert summary["evaluations"] == evaluations and summary["mode"] == "surrogate"
    suite = re.search(r"executing (\d+) suite scenarios", (out / "logs" / "generator.log").read_text())
    assert suite and int(suite.group(1)) == summary["scenarios_published"]
    assert re.search(rf"^\s+MCAP\s+{re.escape(summary['mcap'])}$", output, re.M) and Path(summary["mcap"]).parent == out


FULL_MODEL_OBJECTIVES = {"thermostat": "thermostat_rmse", "robot": "robot_time", "vehicle": "vehicle_max_oob"}


@pytest.mark.parametrize("name", ["thermostat", "robot", "vehicle"])
def test_campaign_suites_run_on_the_full_models_and_stream_timelines(campaigns, name):
    """The suite is executed by the full-model simulators (their objective, their failure kinds),
    and each execution is streamed as standard messages (Odometry / Temperature) into the log."""
    _, summary, _, _ = campaigns[name]
    problem = CAMPAIGNS[name][1]
    results, samples = [], 0
    for topic, typename, _, msg in iter_messages(summary["mcap"], {topics.RESULTS, topics.timeline(problem)}):
        if topic == topics.RESULTS:
            results.append(msg)
        else:
            samples += 1
            assert typename == topics.TIMELINE_TYPES[problem]
    assert results and samples >= len(results)
    # a scenario that breaks a static reference check is answered INVALID_TEST without being run
    not_run = (FAILURE_KINDS["invalid_scenario"], FAILURE_KINDS["invalid_test"])
    executed = [r for r in results if r.failure_kind not in not_run or len(r.objective_names)]
    assert executed and all(list(r.objective_names) == [FULL_MODEL_OBJECTIVES[problem]] for r in executed)
    allowed = {"thermostat": {"none", "requirement"}, "robot": {"none", "collision", "stall", "loiter", "timeout"},
               "vehicle": {"none", "out_of_lane", "stall", "timeout"}}[problem]
    assert {k for k in summary["outcomes"] if k not in ("invalid_scenario", "invalid_test")} <= allowed
    assert summary["failures"] == sum(r.failed for r in results)


def test_in_the_loop_campaign_end_to_end(campaigns):
    code, summary, out, output = campaigns["in_the_loop"]
    assert code == 0, output[-3000:]
    _assert_summary_consistent(summary, out)
    evaluations = CAMPAIGNS["in_the_loop"][3]
    # in the loop every evaluation is a scenario executed by a sim node, or one the problem calls invalid
    assert summary["scenarios_published"] + summary["not_sent"] == evaluations == summary["evaluations"]
    assert summary["mode"] == "in_the_loop"


def test_a_spent_execution_budget_stops_sending_at_once_and_the_sent_scenarios_finish(campaigns):
    """Not at the end of a generation: a real-time stack given an hour gets an hour plus one run."""
    code, summary, out, output = campaigns["budget"]
    assert code == 0, output[-3000:]
    _assert_summary_consistent(summary, out)  # every scenario published has its result in the log
    log = (out / "logs" / "generator.log").read_text()
    withdrawn = re.search(r"budget spent: (\d+) scenarios not sent", log)
    assert withdrawn, log[-2000:]
    assert 1 <= summary["scenarios_published"] < 30  # one generation is 30 scenarios
    assert summary["scenarios_published"] + summary["not_sent"] + int(withdrawn.group(1)) == 30
    assert f"{withdrawn.group(1)} not sent (budget spent)" in log


def test_a_campaign_draws_each_distinct_certified_failure(campaigns, tmp_path):
    """The README's first command in small: failures found, certified, grouped by what failed and
    where, one picture each, the paths printed; drawing again never draws over a picture."""
    from ambiegen_ros.nodes.gallery import draw_failures

    code, summary, out, output = campaigns["demo"]
    assert code == 0, output[-3000:]
    assert summary["failures"] > 0 and summary["outcomes"].get("out_of_lane", 0) > 0, summary
    pictures = summary["failure_pictures"]
    assert 1 <= summary["distinct_failures"] <= summary["certified_failures"] == summary["failures"]
    assert len(pictures) == min(summary["distinct_failures"], 12)
    assert len({p["signature"] for p in pictures}) == len(pictures)  # distinct failures, described apart
    for picture in pictures:
        path = Path(picture["path"])
        assert path.parent == out / "failures" and path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert pictures[0]["path"] in output  # printed where a newcomer looks
    pair = summary["same_failure_pair"]  # two failures counted as one, side by side, for a reader to judge
    if summary["distinct_failures"] < summary["certified_failures"]:
        assert Path(pair["path"]).read_bytes()[:4] == b"\x89PNG" and pair["path"] in output
        assert pair["scenario_ids"][0] in [p["scenario_id"] for p in pictures]
    else:
        assert pair is None
    before = {p: p.stat().st_mtime_ns for p in (out / "failures").iterdir()}
    again = draw_failures(summary["mcap"], out / "failures")
    assert again["distinct_failures"] == summary["distinct_failures"] and again["failure_pictures"] == []
    assert again["same_failure_pair"] is None  # already drawn: not drawn over
    assert {p: p.stat().st_mtime_ns for p in (out / "failures").iterdir()} == before
    elsewhere = draw_failures(summary["mcap"], tmp_path / "pictures")
    assert [Path(p["path"]).name for p in elsewhere["failure_pictures"]] == [Path(p["path"]).name for p in pictures]


def _scenario_validity(summary: dict[str, Any], scenario_jsons: list[str]) -> list[tuple[bool, str | None]]:
    """What the run's own problem (rebuilt from the run config in the log) says of each scenario."""
    from ambiegen_ros.ros.runlog import read_metadata

    config = json.loads(read_metadata(summary["mcap"])["ambiegen_run"]["config_json"])
    problem = get_problem(config["problem"], config["problem_config"])
    ev = problem.evaluate_scenarios([problem.parse(json.loads(text)) for text in scenario_jsons])
    return list(zip(ev.valid.tolist(), ev.reasons))


def test_a_campaign_never_sends_a_scenario_the_problem_calls_invalid(campaigns):
    """Issue 47: the search's invalid roads (its constraint violations) are logged with their reason
    and told to the search, never sent to a simulator; the summary counts them apart."""
    code, summary, out, output = campaigns["demo"]
    assert code == 0, output[-3000:]
    _assert_summary_consistent(summary, out)
    assert summary["not_sent"] > 0 and summary["invalid"] == 0, summary  # the search makes invalid roads
    assert summary["scenarios_published"] + summary["not_sent"] == summary["evaluations"] == 300
    run = _read_run(Path(summary["mcap"]))
    sent = {s[0] for s in run["scenarios"]}
    unsent = {s[0]: s for s in run["not_sent"]}
    assert len(unsent) == len(run["not_sent"]) == summary["not_sent"]
    assert sorted(sent | set(unsent)) == list(range(300)) and not sent & set(unsent)
    # no simulator got one: every result is a sent scenario's, from a sim worker
    assert {r[0] for r in run["results"]} == sent and len(run["results"]) == len(sent)
    assert all(r[1].startswith("vehicle_sim_") and r[2] != INVALID for r in run["results"])
    # each one in the log with the rule the problem itself names; every sent one is valid by it
    judged = _scenario_validity(summary, [s[1] for s in unsent.values()])
    for (sid, _, valid, reason, attempt, _), (really_valid, rule) in zip(unsent.values(), judged):
        assert not valid and not really_valid and reason == rule and reason and attempt == 0, (sid, reason, rule)
    assert sum(summary["not_sent_rules"].values()) == summary["not_sent"]
    assert re.search(rf"^\s+not sent\s+{summary['not_sent']}\s", output, re.M), output[-3000:]


def test_random_search_in_a_campaign_sends_only_valid_maps(campaigns):
    """Random search draws valid scenarios (as an RQ3 executor's random fill does): its whole budget
    is executed, none is a map without a route."""
    code, summary, out, output = campaigns["random"]
    assert code == 0, output[-3000:]
    _assert_summary_consistent(summary, out)
    assert summary["not_sent"] == 0 and summary["scenarios_published"] == summary["evaluations"] == 40, summary
    run = _read_run(Path(summary["mcap"]))
    scenarios = {}
    for topic, _, _, msg in iter_messages(summary["mcap"], {topics.scenarios("robot")}):
        scenarios[int(msg.meta.scenario_id)] = msg.meta.scenario_json
    assert sorted(scenarios) == list(range(40)) and not run["not_sent"]
    assert all(valid for valid, _ in _scenario_validity(summary, list(scenarios.values())))
    assert json.loads(run["config"][0].config_json)["random_samples"] == "valid"


def test_mcap_read_back_by_rosbags_holds_the_whole_run(campaigns):
    code, summary, out, _ = campaigns["in_the_loop"]
    assert code == 0
    mcap = Path(summary["mcap"])
    run = _read_run(mcap)
    done = _done_line((out / "logs" / "generator.log").read_text())
    run_id = done["run_id"]
    sids = [s[0] for s in run["scenarios"] if s[3] == run_id]
    unsent = [s[0] for s in run["not_sent"] if s[5] == run_id]
    rids = [r[0] for r in run["results"] if r[3] == run_id]
    assert len(sids) == len(set(sids)) == done["scenarios"] == summary["scenario_messages"]
    assert len(unsent) == done["not_sent"]
    assert sorted(sids + unsent) == list(range(done["scenarios"] + done["not_sent"]))  # ids 0..N-1, each once
    assert sorted(rids) == sorted(sids) and len(rids) == done["settled"]
    assert len(run["config"]) == 1 and run["config"][0].run_id == run_id
    assert run["status"] and run["status"][-1].state == "done"
    assert run["status"][-1].results_received == done["settled"]

    reg = get_registry()
    conns = run["connections"]
    scen_topic = topics.scenarios("thermostat")
    for topic in (scen_topic, topics.RESULTS, topics.RUN_CONFIG, topics.STATUS):
        conn = conns[topic]
        assert conn.msgdef.data == reg.msgdef(conn.msgtype)  # the full ros2msg schema text
        (qos,) = conn.ext.offered_qos_profiles
        assert qos.reliability == QosReliability.RELIABLE
    assert "ScenarioHeader meta" in conns[scen_topic].msgdef.data
    assert conns[topics.RUN_CONFIG].ext.offered_qos_profiles[0].durability == QosDurability.TRANSIENT_LOCAL
    assert conns[scen_topic].ext.offered_qos_profiles[0].depth == STREAM.depth

    with open(mcap, "rb") as fh:
        reader = make_reader(fh)
        assert reader.get_header().profile == "ros2"
        summ = reader.get_summary()
        assert summ is not None and summ.statistics.message_count == sum(c.msgcount for c in conns.values())
        for channel in summ.channels.values():
            typename = summ.schemas[channel.schema_id].name
            assert channel.metadata["topic_type_hash"] == reg.type_hash(typename)
            assert channel.metadata["offered_qos_profiles"].startswith("- history: keep_last")
        meta = {m.name: m.metadata for m in reader.iter_metadata()}
    assert meta["ambiegen_run"]["run_id"] == run_id and meta["ambiegen_run"]["seed"] == "1"
    config = json.loads(meta["ambiegen_run"]["config_json"])
    assert config["seed"] == 1 and config["problem"] == "thermostat"
    assert "version" in meta["ambiegen_recorder"]
    assert meta["ambiegen_recorder"]["middleware"].startswith("dds backend over Cyclone DDS 11.")


def test_two_workers_share_without_executing_twice(campaigns):
    code, summary, out, _ = campaigns["in_the_loop"]
    assert code == 0
    run = _read_run(Path(summary["mcap"]))
    workers = {r[1] for r in run["results"]}
    suffix = summary["run_id"][-6:]  # worker ids are unique per run
    assert workers == {f"thermostat_sim_0_{suffix}", f"thermostat_sim_1_{suffix}"}  # both used, nobody else answered
    sids = [r[0] for r in run["results"]]
    assert len(sids) == len(set(sids)) == summary["scenarios_published"]  # each executed once
    assigned = {s[0]: s[1] for s in run["scenarios"]}
    assert all(assigned[sid] == worker for sid, worker, *_ in run["results"])  # by the worker it was sent to
    assert summary["scenario_messages"] == summary["scenarios_published"]  # nothing re-sent


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


# --- 7: the recorder interrupted ----------------------------------------------------------------------
def test_sigint_to_recorder_mid_run_leaves_a_valid_mcap(nodes_factory, test_node, tmp_path, ros_domain):
    domain = ros_domain
    nodes = nodes_factory(domain)
    mcap = tmp_path / "sigint.mcap"
    watcher = test_node("sigint_watch", domain)
    seen = {"results": 0}
    watcher.create_subscription(topics.RESULT_TYPE, topics.RESULTS, lambda m: seen.__setitem__("results", seen["results"] + 1), STREAM)
    recorder = nodes.start("recorder", "ambiegen_ros.nodes.recorder", output=str(mcap), flush_period=5.0)
    nodes.start("w", "sim_nodes.thermostat_sim", worker_id="w", model="surrogate", min_result_subscribers=2)
    gen = nodes.start(
        "generator", "ambiegen_ros.nodes.generator", problem="thermostat", algorithm="ga", mode="in_the_loop",
        evaluations=50000, population=50, offspring=50, seed=1, run_id="sigint-run", min_subscribers=2, min_workers=1,
    )
    assert watcher.spin_until(lambda: seen["results"] >= 40, 300), nodes.log("generator")[-2000:]
    recorder.send_signal(signal.SIGINT)
    assert nodes.wait("recorder", 60) == 0
    assert gen.poll() is None  # the run was still going
    nodes.stop("generator")
    nodes.stop("w")

    with open(mcap, "rb") as fh:
        reader = make_reader(fh)
        summ = reader.get_summary()
        assert summ is not None and summ.statistics.message_count > 0  # finalised: summary + footer
        meta = {m.name: m.metadata for m in reader.iter_metadata()}
    assert meta["ambiegen_run"]["run_id"] == "sigint-run"
    run = _read_run(mcap)  # rosbags reads every message
    assert len(run["config"]) == 1 and len(run["scenarios"]) >= 40
    assert len(run["results"]) >= 20  # the flush period was 5 s: all of this came from the final close
    assert sum(c.msgcount for c in run["connections"].values()) == summ.statistics.message_count


def test_a_stopped_recorder_takes_what_was_already_on_its_way(nodes_factory, test_node, tmp_path, ros_domain):
    """A burst of results, then SIGINT to the recorder the moment the last one is written: every
    result published before the stop is in the log (the recorder drains its readers before it
    closes, and the publisher waits for the recorder's acknowledgements before it goes)."""
    from ambiegen_ros.ros.qos import Qos

    nodes = nodes_factory(ros_domain)
    mcap = tmp_path / "burst.mcap"
    recorder = nodes.start("recorder", "ambiegen_ros.nodes.recorder", output=str(mcap), discover=False)
    node = test_node("burst", ros_domain)
    pub = node.create_publisher(topics.RESULT_TYPE, topics.RESULTS, Qos(reliable=True, depth=10, keep_all=True))
    assert node.spin_until(lambda: pub.subscription_count() >= 1, 120), nodes.log("recorder")  # a safety net
    make, burst = node.new_message, 3000
    for i in range(burst):
        pub.publish(make(topics.RESULT_TYPE, run_id="burst", scenario_id=i, worker="w", detail="x" * 200))
    recorder.send_signal(signal.SIGINT)
    node.finish_io(ack_s=60.0)  # this side: until the recorder acknowledged all (a safety net of a bound)
    assert nodes.wait("recorder", 120) == 0, nodes.log("recorder")
    with open(mcap, "rb") as fh:
        ids = [get_registry().deserialize(m.data, topics.RESULT_TYPE).scenario_id
               for _, ch, m in make_reader(fh).iter_messages() if ch.topic == topics.RESULTS]
    assert sorted(ids) == list(range(burst)), f"{burst - len(set(ids))} of {burst} results lost"


def test_sigkill_to_recorder_then_recover_keeps_everything_flushed(nodes_factory, test_node, tmp_path, ros_domain):
    domain = ros_domain
    nodes = nodes_factory(domain)
    mcap = tmp_path / "killed.mcap"
    flush_period = 0.25
    recorder = nodes.start("recorder", "ambiegen_ros.nodes.recorder", output=str(mcap), flush_period=flush_period)
    node = test_node("sigkill_publisher", domain)
    problem = get_problem("thermostat")
    pub = node.create_publisher(topics.SCENARIO_TYPES["thermostat"], topics.scenarios("thermostat"), STREAM)
    cfg = node.create_publisher(topics.RUN_CONFIG_TYPE, topics.RUN_CONFIG, LATCHED)
    assert node.wait_for_subscribers(pub, 1, 120) and node.wait_for_subscribers(cfg, 1, 120)  # safety nets
    cfg.publish(conversions.run_config_message(node.new_message, node.now_ns(), "kill-rec", {"seed": 77, "problem": "thermostat"}, "test"))
    X = problem.codec.join(*problem.sample(50, np.random.default_rng(1)))
    scenarios = [problem.codec.from_row(r) for r in X]
    sent = 300
    for i in range(sent):
        pub.publish(conversions.scenario_message(node.new_message, node.now_ns(), problem, scenarios[i % 50], ScenarioMeta("kill-rec", i)))
        node.spin_once(0.0)
    # kill once the file on disk holds every message (seen by recovering a copy): an event, so a
    # busy machine only makes the wait longer; the 120 s bound is a safety net
    probe_dir = tmp_path / "probe"
    probe_dir.mkdir()
    deadline, flushed, k = time.monotonic() + 120, 0, 0
    while flushed < sent + 1 and time.monotonic() < deadline:  # + 1: the run config
        copy, k = probe_dir / f"copy{k}.mcap", k + 1
        copy.write_bytes(mcap.read_bytes())
        try:
            flushed = recover(copy, probe_dir / f"fixed{k}.mcap")["messages"]
        except McapError:  # not even the header on disk yet
            flushed = 0
        node.spin_once(flush_period / 2)
    assert flushed == sent + 1, f"{flushed} of {sent + 1} messages flushed to {mcap}"
    os.kill(recorder.pid, signal.SIGKILL)
    assert recorder.wait(5) == -signal.SIGKILL

    fixed = tmp_path / "fixed.mcap"
    cli = subprocess.run([sys.executable, "-m", "ambiegen_ros", "recover", str(mcap), "-o", str(fixed)],
                         cwd=REPO, env=_env(domain), capture_output=True, text=True, timeout=60)
    assert cli.returncode == 0, cli.stderr
    report = json.loads(cli.stdout)
    assert report["complete"] is False and report["metadata"] >= 2
    run = _read_run(fixed)
    ids = [s[0] for s in run["scenarios"]]
    assert ids == list(range(len(ids)))  # a prefix, in order, nothing invented
    assert len(ids) == sent  # everything flushed before the kill survived it
    assert report["messages"] == len(ids) + len(run["config"]) and len(run["config"]) == 1
    with open(fixed, "rb") as fh:
        reader = make_reader(fh)
        summ = reader.get_summary()
        meta = {m.name: m.metadata for m in reader.iter_metadata()}
        hashes = {c.topic: c.metadata.get("topic_type_hash") for c in summ.channels.values()}
    assert meta["ambiegen_run"]["seed"] == "77"
    assert hashes[topics.scenarios("thermostat")] == get_registry().type_hash(topics.SCENARIO_TYPES["thermostat"])
