"""The fidelity profile on the ROS side (issue 7, section 1): the ``profile`` parameter.

The generator, every sim node and the SUT adapter build their problem with the profile they are
given; ``ambiegen campaign --profile P`` hands it to every node and records it in the MCAP
metadata, ``summary.json`` and ``suite.json``; a worker of another profile is never given a
scenario, and answers scenarios offered to anyone with an ``ERROR`` result instead of scoring them
in another environment.

In-process nodes and node processes over real DDS, each test on its own ROS_DOMAIN_ID
(``ros_domain``, test/conftest.py). Every wait ends on an event; its bound is a safety net.
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from ambiegen_ros.core.config import ConfigError  # noqa: E402
from ambiegen_ros.problems import PROFILES, get_problem  # noqa: E402
from ambiegen_ros.ros import topics  # noqa: E402
from ambiegen_ros.ros.qos import STREAM  # noqa: E402
from ambiegen_ros.ros.runlog import iter_messages, read_metadata  # noqa: E402
from ambiegen_ros.sims.outcome import FAILURE_KINDS  # noqa: E402

pytestmark = pytest.mark.skipif(
    os.environ.get("AMBIEGEN_TRANSPORT", "auto") == "rclpy", reason="these tests drive the DDS backend"
)

NODE_MODULES = ("ambiegen_ros.nodes.generator", "sim_nodes.thermostat_sim", "sim_nodes.robot_sim",
                "sim_nodes.car_sim", "sim_nodes.sut_adapter", "sim_nodes.external_sim")
ERROR = FAILURE_KINDS["error"]


def _env(domain: int) -> dict[str, str]:
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain), PYTHONUNBUFFERED="1")
    env.pop("AMBIEGEN_TRANSPORT", None)
    return env


def test_every_node_lists_the_profile_parameter_in_its_help(ros_domain):
    procs = {m: subprocess.Popen([sys.executable, "-m", m, "--help"], cwd=REPO, env=_env(ros_domain), text=True,
                                 stdout=subprocess.PIPE, stderr=subprocess.STDOUT) for m in NODE_MODULES}
    for module, proc in procs.items():
        out, _ = proc.communicate(timeout=60)
        assert proc.returncode == 0, f"{module}: {out[-2000:]}"
        text = " ".join(out.split())
        assert "profile" in text and "replication" in text and "refined" in text, f"{module} --help:\n{out}"


@pytest.fixture
def in_process(monkeypatch, ros_domain):
    """make(build, node name, **parameters): ``build(node)`` in this process on the test's domain."""
    from ambiegen_ros.ros.transport import create_node

    made = []
    monkeypatch.setenv("ROS_DOMAIN_ID", str(ros_domain))

    def make(build, name: str, **params: Any):
        node = create_node(name, argv=[], parameter_overrides=params)
        try:
            obj = build(node=node)
        except Exception:
            node.shutdown()
            raise
        made.append(obj)
        return obj

    yield make
    for obj in made:
        endpoint = getattr(obj, "endpoint", None)
        if endpoint is not None:
            endpoint.stop()
        obj.node.shutdown()


def test_nodes_build_their_problem_with_the_profile_parameter(in_process, tmp_path):
    from functools import partial

    from ambiegen_ros.nodes.generator import Generator
    from sim_nodes.external_sim import ExternalSim
    from sim_nodes.sut_adapter import SutAdapter
    from sim_nodes.worker import SimWorker as AnySimWorker

    SimWorker = partial(AnySimWorker, "thermostat")

    refined_file = tmp_path / "refined.yaml"
    refined_file.write_text("problem_config:\n  profile: refined\n")
    for profile in PROFILES:
        gen = in_process(Generator, "generator", problem="thermostat", profile=profile, evaluations=10)
        assert gen.problem.profile == profile and gen.search.problem.profile == profile
        assert gen.config["profile"] == profile and gen.config["problem_config"]["profile"] == profile
        sim = in_process(SimWorker, "thermostat_sim", profile=profile, model="surrogate")
        assert sim.problem.profile == profile and sim.executor.problem.profile == profile
        adapter = in_process(SutAdapter, "sut_adapter", problem="thermostat", profile=profile)
        assert adapter.problem.profile == profile
        external = in_process(ExternalSim, "external_sim", problem="robot", profile=profile)
        assert external.problem.profile == profile
    # no parameter: the config file's profile, else the default; the parameter wins over the file
    assert in_process(SimWorker, "thermostat_sim", model="surrogate").problem.profile == PROFILES[0]
    from_file = in_process(SimWorker, "thermostat_sim", model="surrogate", config_file=str(refined_file))
    assert from_file.problem.profile == "refined"
    overridden = in_process(Generator, "generator", problem="thermostat", config_file=str(refined_file),
                            profile="replication", evaluations=10)
    assert overridden.problem.profile == "replication"
    with pytest.raises(ConfigError, match="profile"):
        in_process(SimWorker, "thermostat_sim", profile="paper")
    with pytest.raises(ConfigError, match="profile"):
        in_process(Generator, "generator", problem="thermostat", profile="paper")


def test_campaign_profile_reaches_every_node_and_every_output(tmp_path, ros_domain):
    out = tmp_path / "run"
    args = [sys.executable, "-m", "ambiegen_ros", "campaign", "--problem", "thermostat", "--algorithm", "ga",
            "--mode", "in_the_loop", "--sim-model", "surrogate", "--profile", "refined", "--population", "16",
            "--offspring", "16", "--evaluations", "48", "--seed", "5", "--workers", "2", "--domain-id", str(ros_domain),
            "--timeout", "300", "--out", str(out)]  # timeouts: safety nets for a hung node
    proc = subprocess.run(args, cwd=REPO, env=_env(ros_domain), capture_output=True, text=True, timeout=400)
    assert proc.returncode == 0, proc.stderr[-3000:]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["profile"] == "refined"
    config = json.loads(read_metadata(summary["mcap"])["ambiegen_run"]["config_json"])
    assert config["profile"] == "refined" and config["problem_config"]["profile"] == "refined"
    assert json.loads((out / "suite.json").read_text())["profile"] == "refined"
    for k in range(2):
        assert "refined profile" in (out / "logs" / f"thermostat_sim_{k}.log").read_text()

    # every F1 the workers sent is the refined model's, and the replication model would differ
    refined, replication = (get_problem("thermostat", {"profile": p}) for p in ("refined", "replication"))
    scenarios, results = {}, {}
    for topic, _, _, msg in iter_messages(summary["mcap"], {topics.scenarios("thermostat"), topics.RESULTS}):
        if topic == topics.RESULTS:
            results[int(msg.scenario_id)] = msg
        else:
            scenarios[int(msg.meta.scenario_id)] = msg.meta
    assert len(results) == len(scenarios) == summary["scenarios_published"]
    assert summary["scenarios_published"] + summary["not_sent"] == 48  # the invalid ones are never sent
    ids = sorted(scenarios)
    rows = np.stack([refined.codec.to_row(refined.parse(json.loads(scenarios[i].scenario_json))) for i in ids])
    want = refined.evaluate_rows(rows)
    got = np.array([results[i].objectives[0] if len(results[i].objectives) else 0.0 for i in ids])
    assert np.array_equal(got, want.f1), "the workers did not score with the refined profile"
    assert np.array_equal([scenarios[i].f1 for i in ids], want.f1), "the generator did not use the refined profile"
    differ = 0
    for i, f1 in zip(ids, want.f1):
        try:
            scenario = replication.parse(json.loads(scenarios[i].scenario_json))
        except Exception:  # outside the replication domains: a difference, but not one that proves much
            continue
        differ += replication.evaluate_scenarios([scenario]).f1[0] != f1
    assert differ > 0, "both profiles score these scenarios alike: the test proves nothing"


class Graph:
    """Node processes on one domain plus a results listener in this process."""

    def __init__(self, domain: int, log_dir: Path, monkeypatch):
        from ambiegen_ros.ros.transport import create_node

        self.domain, self.log_dir = domain, log_dir
        self.procs: dict[str, subprocess.Popen] = {}
        monkeypatch.setenv("ROS_DOMAIN_ID", str(domain))
        self.node = create_node("profile_listener", argv=[])
        self.results: list[Any] = []
        self.node.create_subscription(topics.RESULT_TYPE, topics.RESULTS, self.results.append, STREAM)
        self.not_sent: list[Any] = []  # scenarios the generator logs instead of sending (invalid)
        self.node.create_subscription(topics.SCENARIO_TYPES["thermostat"], topics.not_sent("thermostat"),
                                      self.not_sent.append, topics.NOT_SENT_QOS)

    def start(self, name: str, module: str, **params: Any) -> None:
        args = [sys.executable, "-m", module, "--ros-args", "-r", f"__node:={name}"]
        for key, value in params.items():
            args += ["-p", f"{key}:={value}"]
        self.log_dir.mkdir(parents=True, exist_ok=True)
        with open(self.log_dir / f"{name}.log", "wb") as log:
            self.procs[name] = subprocess.Popen(args, cwd=REPO, env=_env(self.domain), stdout=log,
                                                stderr=subprocess.STDOUT)

    def log(self, name: str) -> str:
        return (self.log_dir / f"{name}.log").read_text(errors="replace")

    def run_generator(self, answered: int, timeout: float = 300.0) -> None:
        """Until the generator has exited and this listener has results for ``answered`` scenarios
        of the run (the last ones may still be on the way when the generator ends); ``timeout`` is
        a safety net, not a measure."""
        gen = self.procs["generator"]
        deadline = time.monotonic() + timeout
        while (gen.poll() is None or len(self.answered() | self.unsent()) < answered) and time.monotonic() < deadline:
            self.node.spin_once(0.05)
        assert gen.poll() == 0, f"generator: exit {gen.poll()}\n{self.log('generator')[-3000:]}"

    def wait_for_log(self, name: str, text: str, timeout: float = 300.0) -> None:
        """Until ``text`` is in ``name``'s log (an event; ``timeout`` is a safety net)."""
        deadline = time.monotonic() + timeout
        while text not in self.log(name) and time.monotonic() < deadline:
            assert self.procs[name].poll() is None, f"{name} exited: {self.log(name)[-3000:]}"
            self.node.spin_once(0.05)
        assert text in self.log(name), f"{name} never logged {text!r}:\n{self.log(name)[-3000:]}"

    def answered(self) -> set[int]:
        return {r.scenario_id for r in self.results if r.run_id == GENERATOR["run_id"]}

    def unsent(self) -> set[int]:
        return {m.meta.scenario_id for m in self.not_sent if m.meta.run_id == GENERATOR["run_id"]}

    def close(self) -> None:
        for proc in self.procs.values():
            if proc.poll() is None:
                proc.send_signal(signal.SIGINT)
        for proc in self.procs.values():
            try:
                proc.wait(10)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
        self.node.shutdown()


GENERATOR = dict(problem="thermostat", algorithm="ga", population=8, offspring=8, evaluations=16, seed=2,
                 profile="refined", run_id="profile-run", worker_wait=1.0, result_timeout=20.0)


def test_a_worker_of_another_profile_gets_no_scenario(tmp_path, monkeypatch, ros_domain):
    graph = Graph(ros_domain, tmp_path / "logs", monkeypatch)
    try:
        worker = dict(model="surrogate", min_result_subscribers=2)
        # the foreign worker and the generator first: the generator waits for a worker of its own
        # profile, and the foreign one's heartbeats reach it (and its log) while it waits
        graph.start("w_replication", "sim_nodes.thermostat_sim", worker_id="w_replication", profile="replication",
                    **worker)
        graph.start("generator", "ambiegen_ros.nodes.generator", mode="in_the_loop", min_subscribers=2,
                    min_workers=1, subscriber_wait=300.0,  # the wait ends when both are matched
                    worker_timeout=60.0,  # late heartbeats on a busy machine must not open the run to anyone
                    **GENERATOR)
        graph.wait_for_log("generator", "w_replication scores the 'replication' profile")
        graph.start("w_refined", "sim_nodes.thermostat_sim", worker_id="w_refined", profile="refined", **worker)
        graph.run_generator(answered=16)
    finally:
        graph.close()
    mine = [r for r in graph.results if r.run_id == "profile-run"]
    assert len({r.scenario_id for r in mine}) + len(graph.unsent()) == 16
    assert {r.worker for r in mine} == {"w_refined"}, "a worker of another profile scored scenarios"


def test_a_worker_of_another_profile_answers_with_an_error(tmp_path, monkeypatch, ros_domain):
    graph = Graph(ros_domain, tmp_path / "logs", monkeypatch)
    try:
        graph.start("w_replication", "sim_nodes.thermostat_sim", worker_id="w_replication", profile="replication",
                    model="surrogate", min_result_subscribers=1)
        # no worker of its profile: after worker_wait the scenarios are offered to anyone
        graph.start("generator", "ambiegen_ros.nodes.generator", mode="surrogate", min_subscribers=1,
                    subscriber_wait=300.0, **GENERATOR)  # the wait ends when the worker is matched
        graph.run_generator(answered=1)
    finally:
        graph.close()
    mine = [r for r in graph.results if r.run_id == "profile-run"]
    assert mine, graph.log("generator")[-2000:]
    for r in mine:
        assert r.worker == "w_replication" and r.failure_kind == ERROR and not r.failed, r
        assert "profile mismatch" in r.detail and "'refined'" in r.detail and "profile:=refined" in r.detail
    assert "its scenarios get ERROR results" in graph.log("w_replication")
