"""A simulation worker node: scenarios in, results out, heartbeats so the generator can share work.

Parameters: ``worker_id`` (unique per worker; see ``worker_node`` for how it and the node name
relate: two workers started alike never share a node name), ``model``
(``full``: the full-model simulator with the paper's oracles, default; ``surrogate``: the case
study's fast surrogate), ``profile`` (fidelity profile of the problem: ``replication`` |
``refined``; '' = the config file's ``problem_config.profile``, else ``replication``),
``timeline_period`` (simulated seconds between the Odometry / Temperature samples streamed on
``/ambiegen/<problem>/odom|temperature``; 0 = none), ``config_file`` (problem numbers under
``problem_config``), ``heartbeat_period`` (s), ``min_result_subscribers`` (wait for that many
result subscribers, e.g. generator + recorder, before announcing itself), ``batch_period`` (s),
``max_batch``.

Reproducibility: a scenario's outcome depends only on the scenario, the run's seed (from its
message) and this node's problem config, never on which worker runs it or what it was batched
with. The full models' noise is seeded with ``scenario_seed(run seed, scenario id)``.

Profiles: heartbeats say which profile this worker scores, and the generator does not use a
worker of another profile. A scenario of a run whose latched run config (``/ambiegen/run_config``)
names another profile is answered with an ``ERROR`` result saying so, never scored in the wrong
environment.

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
import re
import sys
import threading
import time
from collections import deque
from typing import Any, Callable

from ambiegen_ros.core.attributes import ScenarioError
from ambiegen_ros.core.config import ConfigError, load_config_file
from ambiegen_ros.problems import PROFILES, get_problem
from ambiegen_ros.ros import conversions, topics
from ambiegen_ros.ros.limits import check_name
from ambiegen_ros.ros.qos import DEFAULT, LATCHED, STREAM
from ambiegen_ros.ros.transport import create_node
from ambiegen_ros.ros.transport.base import normalize_namespace
from ambiegen_ros.ros.transport.params import parse_ros_args, resolve_parameters
from ambiegen_ros.sims import Outcome, SurrogateExecutor, full_model_executor
from ambiegen_ros.sims.full_model import scenario_seed
from ambiegen_ros.nodes import run_node
from ambiegen_ros.nodes.execution import run_profile

MODELS = ("full", "surrogate")
MAX_RUNS_REMEMBERED = 256  # run configs (run id -> profile) a worker keeps; the oldest is forgotten
MAX_DETAIL = 2000  # characters of a rejection's detail (a hostile field name could be megabytes)


def load_problem(node: Any, problem_name: str) -> Any:
    """The node's problem from its ``config_file`` and ``profile`` parameters (declared here).

    ``profile`` wins over the file's ``problem_config.profile``; '' leaves the file's (else the
    default, ``replication``).
    """
    config_file = node.declare_parameter("config_file", "", "YAML with problem_config overrides")
    profile = node.declare_parameter(
        "profile", "", f"fidelity profile: {' | '.join(PROFILES)} ('' = the config file's, else {PROFILES[0]})"
    )
    problem_config = dict(load_config_file(config_file).get("problem_config") or {})
    if profile:
        if profile not in PROFILES:
            raise ConfigError(f"profile: unknown {profile!r} (allowed: {'|'.join(PROFILES)})")
        problem_config["profile"] = profile
    try:
        return get_problem(problem_name, problem_config)
    except TypeError as exc:
        raise ConfigError(f"config: problem_config: {exc}")


def sim_options(node: Any, config_cls: type, fields: Any = None, defaults: dict[str, Any] | None = None) -> Any:
    """A simulator config from ``sim.<field>`` parameters (every field of the dataclass
    ``config_cls``, or only ``fields``; ``defaults`` overrides the dataclass's own defaults)."""
    import dataclasses

    options = dict(defaults or {})
    for f in dataclasses.fields(config_cls):
        if f.name == "run_invalid" or (fields is not None and f.name not in fields):
            continue
        default = options.get(f.name, f.default)
        value = node.declare_parameter(f"sim.{f.name}", default, f"simulator option {f.name}")
        if value != f.default or f.name in options:
            options[f.name] = value
    return config_cls(**options)


def node_name_for(worker_id: str) -> str:
    """A valid ROS node name for a worker id: letters, digits and '_', not starting with a digit."""
    name = re.sub(r"[^A-Za-z0-9_]", "_", worker_id)
    return name if name and not name[0].isdigit() else f"w_{name}"


def worker_node(default_name: str, argv: list[str] | None = None) -> tuple[Any, str]:
    """The node of a worker, named so that workers started alike (``ros2 run`` twice) never collide.

    Returns the node and the ``worker_id`` default. The rule:

    * ``-r __node:=NAME`` names the node, as in any ROS node; ``worker_id`` defaults to ``NAME_<pid>``;
    * else a given ``worker_id`` names the node (made a valid node name);
    * else both are ``<default_name>_<pid>``.

    Parameter-file entries keyed by ``default_name`` still apply to the renamed node.
    """
    args = list(sys.argv if argv is None else argv)
    ros_args = parse_ros_args(args)
    remapped = ros_args.node_name_override(default_name)
    namespace = normalize_namespace(ros_args.namespace_override(default_name) or "").rstrip("/")
    base = remapped or default_name
    given = resolve_parameters(ros_args, f"{namespace}/{base}")
    default_id = f"{base}_{os.getpid()}"
    worker_id = given.get("worker_id")
    if remapped:
        name = remapped
    elif isinstance(worker_id, str) and worker_id:
        name = node_name_for(worker_id)
    else:
        name = default_id
    own = resolve_parameters(ros_args, f"{namespace}/{name}")
    inherited = {k: v for k, v in given.items() if k not in own}  # file entries keyed by the default name
    return create_node(name, argv=args, parameter_overrides=inherited or None), default_id


class WorkerEndpoint:
    """The worker side every executing node shares (sim workers, the SUT adapter).

    Declares ``worker_id``, ``heartbeat_period`` and ``min_result_subscribers``; heartbeats from a
    thread of its own once enough result subscribers are matched; takes the scenario messages
    addressed to this worker (or to anyone), answers malformed ones at once (``INVALID_SCENARIO``
    naming the field, or ``ERROR``) and those of a run with another fidelity profile (``ERROR``),
    and hands valid ones to ``accept(run_id, scenario_id, scenario, msg)``; publishes results
    with ``publish``.
    """

    def __init__(self, node: Any, problem: Any, accept: Callable[[str, int, Any, Any], None],
                 in_flight: Callable[[], int], default_id: str | None = None):
        self.node = node
        self.problem = problem
        self._accept = accept
        self._in_flight = in_flight
        n = node
        self.worker_id = n.declare_parameter(
            "worker_id", default_id or f"{n.name}_{os.getpid()}", "unique id of this worker"
        )
        check_name(self.worker_id, "worker_id")  # it names files downstream (logs, reports)
        period = n.declare_parameter("heartbeat_period", 0.5, "seconds between heartbeats")
        self.min_result_subscribers = n.declare_parameter(
            "min_result_subscribers", 1, "wait for this many result subscribers before announcing"
        )
        self.results = n.create_publisher(topics.RESULT_TYPE, topics.RESULTS, STREAM)
        self.heartbeats = n.create_publisher(topics.WORKERS_TYPE, topics.WORKERS, DEFAULT)
        n.create_subscription(
            topics.SCENARIO_TYPES[problem.name], topics.scenarios(problem.name), self.on_scenario, STREAM
        )
        self.run_profiles: dict[str, str] = {}  # run id -> profile its (latched) run config names
        n.create_subscription(topics.RUN_CONFIG_TYPE, topics.RUN_CONFIG, self.on_run_config, LATCHED)
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
            conversions.heartbeat_message(
                make, self.worker_id, self.problem.name, self._in_flight(), self.executed,
                {"profile": self.problem.profile, **{f"input_{k}": v for k, v in self.node.input_stats().items()}}
            )
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

    def on_run_config(self, msg: Any) -> None:
        profile = run_profile(msg.config_json)
        if profile is not None:
            if len(self.run_profiles) >= MAX_RUNS_REMEMBERED and msg.run_id not in self.run_profiles:
                self.run_profiles.pop(next(iter(self.run_profiles)))  # the oldest run: memory stays bounded
            self.run_profiles[msg.run_id] = profile
            if profile != self.problem.profile:
                self.node.logger.error(
                    f"run {msg.run_id} uses the {profile!r} profile, this worker scores {self.problem.profile!r}: "
                    f"its scenarios get ERROR results (start the worker with profile:={profile})"
                )

    def profile_mismatch(self, run_id: str) -> str | None:
        """Why this worker must not score a run's scenarios (None when it may, or cannot tell)."""
        theirs = self.run_profiles.get(run_id)
        if theirs is None or theirs == self.problem.profile:
            return None
        return (
            f"profile mismatch: run {run_id} uses the {theirs!r} profile, worker {self.worker_id} scores "
            f"{self.problem.profile!r} (start it with profile:={theirs})"
        )

    def on_scenario(self, msg: Any) -> None:
        meta = msg.meta
        if meta.assigned_worker not in ("", self.worker_id):
            return
        start = time.perf_counter()
        run_id = conversions.safe_echo(meta.run_id)  # a hostile run id is not echoed as is
        mismatch = self.profile_mismatch(meta.run_id)
        if mismatch is not None:
            self.publish(run_id, meta.scenario_id, Outcome.rejected(mismatch[:MAX_DETAIL], kind="error"), start)
            return
        try:
            scenario, _ = conversions.scenario_from_message(self.problem, msg)
            self._accept(meta.run_id, int(meta.scenario_id), scenario, msg)
        except ScenarioError as exc:
            self.publish(run_id, meta.scenario_id, Outcome.rejected(str(exc)[:MAX_DETAIL]), start)
        except Exception as exc:  # e.g. arrays of inconsistent shapes: still an answer
            self.publish(run_id, meta.scenario_id, Outcome.rejected(f"{type(exc).__name__}: {exc}"[:MAX_DETAIL], kind="error"), start)

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
        self.node, default_id = (node, None) if node is not None else worker_node(f"{problem_name}_sim", argv)
        n = self.node
        batch_period = n.declare_parameter("batch_period", 0.002, "seconds to collect scenarios into one batch")
        self.max_batch = max(1, n.declare_parameter("max_batch", 256, "most scenarios executed in one batch"))
        self.model = n.declare_parameter("model", "full", "full (full-model simulator + oracle) | surrogate")
        default_period = 180.0 if problem_name == "thermostat" else 0.5
        self.timeline_period = n.declare_parameter(
            "timeline_period", default_period, "simulated seconds between streamed samples (0 = none)"
        )
        if self.model not in MODELS:
            raise ConfigError(f"model: unknown {self.model!r} (allowed: {'|'.join(MODELS)})")
        self.problem = load_problem(n, problem_name)
        if self.model == "full":
            self.executor = full_model_executor(self.problem)
            self.timeline = n.create_publisher(topics.TIMELINE_TYPES[problem_name], topics.timeline(problem_name), STREAM)
        else:
            self.executor = SurrogateExecutor(self.problem)
            self.timeline = None
        self.pending: deque[tuple[str, int, Any, int]] = deque()  # (run id, scenario id, scenario, run seed)
        self.endpoint = WorkerEndpoint(n, self.problem, self.accept, lambda: len(self.pending), default_id)
        self.worker_id = self.endpoint.worker_id
        self.publish = self.endpoint.publish
        self.stop = self.endpoint.stop
        n.create_timer(batch_period, self.execute_pending)
        n.logger.info(
            f"{self.worker_id}: executing {problem_name} scenarios ({self.model} model, {self.problem.profile} profile)"
        )

    def accept(self, run_id: str, scenario_id: int, scenario: Any, msg: Any) -> None:
        self.pending.append((run_id, scenario_id, scenario, int(msg.meta.seed)))
        if len(self.pending) >= self.max_batch:
            self.execute_pending()

    def execute_pending(self) -> None:
        if not self.pending:
            return
        execute_batch = getattr(self.executor, "execute_batch", None)  # vectorised, when the executor has it
        if execute_batch is None or len(self.pending) == 1:
            # one per turn: its result leaves at once, heartbeats and new scenarios are served between
            run_id, scenario_id, scenario, run_seed = self.pending.popleft()
            start, start_ns = time.perf_counter(), self.node.now_ns()
            outcome = self._execute_one(scenario, scenario_id, run_seed)
            self.publish(run_id, scenario_id, outcome, start)
            self.publish_timeline(outcome, start_ns)
            return
        batch = list(self.pending)
        self.pending.clear()
        start = time.perf_counter()
        try:
            outcomes = list(execute_batch([s for _, _, s, _ in batch]))
        except Exception:  # find the culprit: each scenario alone gets its own answer
            outcomes = [self._execute_one(s, sid, seed) for _, sid, s, seed in batch]
        share = (time.perf_counter() - start) / len(batch)
        for (run_id, scenario_id, _, _), outcome in zip(batch, outcomes):
            outcome.elapsed_sec = share
            self.publish(run_id, scenario_id, outcome)

    def _execute_one(self, scenario: Any, scenario_id: int, run_seed: int) -> Outcome:
        try:
            if self.model == "full":
                return self.executor.execute(scenario, seed=scenario_seed(run_seed, scenario_id))
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
