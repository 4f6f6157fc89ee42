"""A simulation worker node: scenarios in, results out, heartbeats so the generator can share work.

Parameters: ``worker_id`` (unique per worker; default ``<node name>_<pid>``), ``config_file``
(problem numbers under ``problem_config``), ``heartbeat_period`` (s), ``min_result_subscribers``
(wait for that many result subscribers, e.g. generator + recorder, before announcing itself).

Every scenario message addressed to this worker (or to anyone) gets exactly one result: the
execution outcome, ``INVALID_SCENARIO`` naming the bad field, or ``ERROR`` with the exception.
"""
from __future__ import annotations

import os
import sys
import time
from typing import Any

from ambiegen_ros.core.attributes import ScenarioError
from ambiegen_ros.core.config import ConfigError, load_config_file
from ambiegen_ros.problems import get_problem
from ambiegen_ros.ros import conversions, topics
from ambiegen_ros.ros.qos import DEFAULT, STREAM
from ambiegen_ros.ros.transport import create_node
from ambiegen_ros.sims import Outcome, SurrogateExecutor


class SimWorker:
    def __init__(self, problem_name: str, argv: list[str] | None = None, node=None):
        self.node = node or create_node(f"{problem_name}_sim", argv=argv)
        n = self.node
        self.worker_id = n.declare_parameter("worker_id", f"{n.name}_{os.getpid()}", "unique id of this worker")
        config_file = n.declare_parameter("config_file", "", "YAML with problem_config overrides")
        period = n.declare_parameter("heartbeat_period", 0.5, "seconds between heartbeats")
        self.min_result_subscribers = n.declare_parameter(
            "min_result_subscribers", 1, "wait for this many result subscribers before announcing"
        )
        self.problem = get_problem(problem_name, load_config_file(config_file).get("problem_config") or {})
        self.executor = SurrogateExecutor(self.problem)
        self.results = n.create_publisher(topics.RESULT_TYPE, topics.RESULTS, STREAM)
        self.heartbeats = n.create_publisher(topics.WORKERS_TYPE, topics.WORKERS, DEFAULT)
        n.create_subscription(
            topics.SCENARIO_TYPES[problem_name], topics.scenarios(problem_name), self.on_scenario, STREAM
        )
        self.executed = 0
        self.ready = False
        n.create_timer(period, self.heartbeat)
        n.logger.info(f"{self.worker_id}: executing {problem_name} scenarios (surrogate model)")

    def heartbeat(self) -> None:
        if not self.ready:
            self.ready = self.results.subscription_count() >= self.min_result_subscribers
            if not self.ready:
                return
        make = self.node.new_message
        self.heartbeats.publish(conversions.heartbeat_message(make, self.worker_id, self.problem.name, 0, self.executed))

    def on_scenario(self, msg: Any) -> None:
        meta = msg.meta
        if meta.assigned_worker not in ("", self.worker_id):
            return
        start = time.perf_counter()
        try:
            scenario, _ = conversions.scenario_from_message(self.problem, msg)
            outcome = self.executor.execute(scenario)
        except ScenarioError as exc:
            outcome = Outcome.rejected(str(exc))
        except Exception as exc:  # a crashing simulator must still answer
            outcome = Outcome.rejected(f"{type(exc).__name__}: {exc}", kind="error")
            self.node.logger.error(f"scenario {meta.scenario_id}: {outcome.detail}")
        outcome.elapsed_sec = time.perf_counter() - start
        make = self.node.new_message
        self.results.publish(
            conversions.result_message(
                make, self.node.now_ns(), meta.run_id, meta.scenario_id, self.problem.name, self.worker_id, outcome
            )
        )
        self.executed += 1


def run_worker(problem_name: str, argv: list[str] | None = None) -> int:
    try:
        worker = SimWorker(problem_name, argv)
    except (ConfigError, ScenarioError, ValueError) as exc:
        print(f"{problem_name}_sim: error: {exc}", file=sys.stderr)
        return 2
    try:
        worker.node.spin()
    finally:
        worker.node.shutdown()
    return 0
