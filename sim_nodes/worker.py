"""A simulation worker node: scenarios in, results out, heartbeats so the generator can share work.

Parameters: ``worker_id`` (unique per worker; default ``<node name>_<pid>``), ``model``
(``full``: the full-model simulator with the paper's oracles, default; ``surrogate``: the case
study's fast surrogate), ``seed`` (full models: scenario k runs with seed + k), ``timeline_period``
(simulated seconds between the Odometry / Temperature samples streamed on
``/ambiegen/<problem>/odom|temperature``; 0 = none), ``config_file`` (problem numbers under
``problem_config``), ``heartbeat_period`` (s), ``min_result_subscribers`` (wait for that many
result subscribers, e.g. generator + recorder, before announcing itself).

Heartbeats come from a small thread of their own, so a worker busy with a long execution (a
full-model run, a JIT compile on first use) is not declared dead and robbed of its scenarios; a
worker that hangs is caught by the generator's per-scenario ``result_timeout`` instead.

Every scenario message addressed to this worker (or to anyone) gets exactly one result: the
execution outcome, ``INVALID_SCENARIO`` naming the bad field, or ``ERROR`` with the exception.

Scenarios are validated as they arrive and executed every ``batch_period`` seconds. When the
executor offers ``execute_batch`` (vectorised case-study models: one thermostat schedule costs
about as much as a hundred simulated together), whatever arrived meanwhile (at most
``max_batch``) runs as one batch and shares its wall time equally in ``elapsed_sec``; otherwise
scenarios run one by one and each result is published as soon as it exists.
"""
from __future__ import annotations

import os
import threading
import time
from collections import deque
from typing import Any, Callable

from ambiegen_ros.core.attributes import ScenarioError
from ambiegen_ros.core.config import ConfigError, load_config_file
from ambiegen_ros.problems import get_problem
from ambiegen_ros.ros import conversions, topics
from ambiegen_ros.ros.qos import DEFAULT, STREAM
from ambiegen_ros.ros.transport import create_node
from ambiegen_ros.sims import Outcome, SurrogateExecutor, full_model_executor
from ambiegen_ros.nodes import run_node

MODELS = ("full", "surrogate")


class WorkerEndpoint:
    """The worker side every executing node shares (sim workers, the SUT adapter).

    Declares ``worker_id``, ``heartbeat_period`` and ``min_result_subscribers``; heartbeats from a
    thread of its own once enough result subscribers are matched; takes the scenario messages
    addressed to this worker (or to anyone), answers malformed ones at once (``INVALID_SCENARIO``
    naming the field, or ``ERROR``) and hands valid ones to ``accept(run_id, scenario_id,
    scenario, msg)``; publishes results with ``publish``.
    """

    def __init__(self, node: Any, problem: Any, accept: Callable[[str, int, Any, Any], None],
                 in_flight: Callable[[], int]):
        self.node = node
        self.problem = problem
        self._accept = accept
        self._in_flight = in_flight
        n = node
        self.worker_id = n.declare_parameter("worker_id", f"{n.name}_{os.getpid()}", "unique id of this worker")
        period = n.declare_parameter("heartbeat_period", 0.5, "seconds between heartbeats")
        self.min_result_subscribers = n.declare_parameter(
            "min_result_subscribers", 1, "wait for this many result subscribers before announcing"
        )
        self.results = n.create_publisher(topics.RESULT_TYPE, topics.RESULTS, STREAM)
        self.heartbeats = n.create_publisher(topics.WORKERS_TYPE, topics.WORKERS, DEFAULT)
        n.create_subscription(
            topics.SCENARIO_TYPES[problem.name], topics.scenarios(problem.name), self.on_scenario, STREAM
        )
        self.executed = 0
        self.ready = False
        self._stop = threading.Event()
        self._beats = threading.Thread(target=self._beat_loop, args=(period,), name="heartbeat", daemon=True)
        self._beats.start()

    def heartbeat(self) -> None:
        if not self.ready:
            self.ready = self.results.subscription_count() >= self.min_result_subscribers
            if not self.ready:
                return
        make = self.node.new_message
        self.heartbeats.publish(
            conversions.heartbeat_message(make, self.worker_id, self.problem.name, self._in_flight(), self.executed)
        )

    def _beat_loop(self, period: float) -> None:
        while not self._stop.wait(period):
            try:
                self.heartbeat()
            except Exception as exc:  # the node is going down: stop beating, never crash it
                if not self._stop.is_set():
                    self.node.logger.warning(f"heartbeats stopped: {exc}")
                return

    def stop(self) -> None:
        """Stop the heartbeat thread (before the node's entities go away)."""
        self._stop.set()
        self._beats.join(timeout=2.0)

    def on_scenario(self, msg: Any) -> None:
        meta = msg.meta
        if meta.assigned_worker not in ("", self.worker_id):
            return
        start = time.perf_counter()
        try:
            scenario, _ = conversions.scenario_from_message(self.problem, msg)
            self._accept(meta.run_id, int(meta.scenario_id), scenario, msg)
        except ScenarioError as exc:
            self.publish(meta.run_id, meta.scenario_id, Outcome.rejected(str(exc)), start)
        except Exception as exc:  # e.g. arrays of inconsistent shapes: still an answer
            self.publish(meta.run_id, meta.scenario_id, Outcome.rejected(f"{type(exc).__name__}: {exc}", kind="error"), start)

    def publish(self, run_id: str, scenario_id: int, outcome: Outcome, start: float | None = None) -> None:
        if start is not None:
            outcome.elapsed_sec = time.perf_counter() - start
        msg = conversions.result_message(
            self.node.new_message, self.node.now_ns(), run_id, int(scenario_id), self.problem.name, self.worker_id, outcome
        )
        self.results.publish(msg)
        self.executed += 1


class SimWorker:
    def __init__(self, problem_name: str, argv: list[str] | None = None, node=None):
        self.node = node or create_node(f"{problem_name}_sim", argv=argv)
        n = self.node
        config_file = n.declare_parameter("config_file", "", "YAML with problem_config overrides")
        batch_period = n.declare_parameter("batch_period", 0.002, "seconds to collect scenarios into one batch")
        self.max_batch = max(1, n.declare_parameter("max_batch", 256, "most scenarios executed in one batch"))
        self.model = n.declare_parameter("model", "full", "full (full-model simulator + oracle) | surrogate")
        self.seed = n.declare_parameter("seed", 0, "full models: scenario k runs with seed + k")
        default_period = 180.0 if problem_name == "thermostat" else 0.5
        self.timeline_period = n.declare_parameter(
            "timeline_period", default_period, "simulated seconds between streamed samples (0 = none)"
        )
        if self.model not in MODELS:
            raise ConfigError(f"model: unknown {self.model!r} (allowed: {'|'.join(MODELS)})")
        self.problem = get_problem(problem_name, load_config_file(config_file).get("problem_config") or {})
        if self.model == "full":
            self.executor = full_model_executor(self.problem)
            self.timeline = n.create_publisher(topics.TIMELINE_TYPES[problem_name], topics.timeline(problem_name), STREAM)
        else:
            self.executor = SurrogateExecutor(self.problem)
            self.timeline = None
        self.pending: deque[tuple[str, int, Any]] = deque()  # (run id, scenario id, validated scenario)
        self.endpoint = WorkerEndpoint(n, self.problem, self.accept, lambda: len(self.pending))
        self.worker_id = self.endpoint.worker_id
        self.publish = self.endpoint.publish
        self.stop = self.endpoint.stop
        n.create_timer(batch_period, self.execute_pending)
        n.logger.info(f"{self.worker_id}: executing {problem_name} scenarios ({self.model} model)")

    def accept(self, run_id: str, scenario_id: int, scenario: Any, msg: Any) -> None:
        self.pending.append((run_id, scenario_id, scenario))
        if len(self.pending) >= self.max_batch:
            self.execute_pending()

    def execute_pending(self) -> None:
        if not self.pending:
            return
        execute_batch = getattr(self.executor, "execute_batch", None)  # vectorised, when the executor has it
        if execute_batch is None or len(self.pending) == 1:
            # one per turn: its result leaves at once, heartbeats and new scenarios are served between
            run_id, scenario_id, scenario = self.pending.popleft()
            start, start_ns = time.perf_counter(), self.node.now_ns()
            outcome = self._execute_one(scenario, scenario_id)
            self.publish(run_id, scenario_id, outcome, start)
            self.publish_timeline(outcome, start_ns)
            return
        batch = list(self.pending)
        self.pending.clear()
        start = time.perf_counter()
        try:
            outcomes = list(execute_batch([s for _, _, s in batch]))
        except Exception:  # find the culprit: each scenario alone gets its own answer
            outcomes = [self._execute_one(s, sid) for _, sid, s in batch]
        share = (time.perf_counter() - start) / len(batch)
        for (run_id, scenario_id, _), outcome in zip(batch, outcomes):
            outcome.elapsed_sec = share
            self.publish(run_id, scenario_id, outcome)

    def _execute_one(self, scenario: Any, scenario_id: int) -> Outcome:
        try:
            if self.model == "full":
                return self.executor.execute(scenario, seed=self.seed + int(scenario_id))
            return self.executor.execute(scenario)
        except ScenarioError as exc:
            return Outcome.rejected(str(exc))
        except Exception as exc:  # a crashing simulator must still answer
            self.node.logger.error(f"execution failed: {type(exc).__name__}: {exc}")
            return Outcome.rejected(f"{type(exc).__name__}: {exc}", kind="error")

    def publish_timeline(self, outcome: Outcome, start_ns: int) -> None:
        if self.timeline is None or not outcome.timeline or self.timeline_period <= 0:
            return
        for msg in conversions.timeline_messages(
            self.node.new_message, start_ns, self.problem.name, outcome.timeline, self.timeline_period
        ):
            self.timeline.publish(msg)


def run_worker(problem_name: str, argv: list[str] | None = None) -> int:
    return run_node(f"{problem_name}_sim", lambda: SimWorker(problem_name, argv), lambda w: w.stop(), doc=__doc__)
