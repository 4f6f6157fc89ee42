"""`generator`: runs the search and sends scenarios to the simulation nodes.

Modes:
* ``surrogate`` (default): search in-process with the surrogate (in short slices on a timer, so
  the executor stays responsive and run status is published), then publish the final suite as
  scenarios and collect a result for each.
* ``in_the_loop``: pymoo ask/tell where F1 of every scenario comes from the sim nodes' results
  (the paper's "full model" setting); nothing blocks the executor.

Every published scenario ends with a result from a worker or an explicit ``SIM_TIMEOUT`` result
written by this node (``core.dispatch`` decides re-assignment and giving up).
"""
from __future__ import annotations

import sys
import time
import uuid
from typing import Any

import numpy as np

from .. import __version__
from ..core.attributes import ScenarioError
from ..core.config import ConfigError, make_run
from ..core.dispatch import Dispatcher
from ..core.runs import run_config
from ..core.search import Search
from ..problems.base import Evaluation
from ..ros import conversions, topics
from ..ros.conversions import ScenarioMeta
from ..ros.qos import DEFAULT, LATCHED, STREAM
from ..ros.transport import create_node
from ..sims.outcome import Outcome

SLICE_S = 0.05  # longest stretch of search work between two executor turns


class Generator:
    def __init__(self, argv: list[str] | None = None, node=None):
        self.node = node or create_node("generator", argv=argv)
        n = self.node
        p = n.declare_parameter
        problem = p("problem", "robot", "thermostat | robot | vehicle")
        algorithm = p("algorithm", "nsga2", "ga | nsga2 | random")
        evaluations = p("evaluations", 0, "evaluation budget (0 = the paper's, unless time_budget is set)")
        time_budget = p("time_budget", 0.0, "wall-clock budget in seconds (0 = none)")
        population = p("population", 0, "population size (0 = the paper's)")
        offspring = p("offspring", 0, "offspring per generation (0 = the paper's)")
        seed = p("seed", -1, "random seed (-1 = drawn and recorded)")
        config_file = p("config_file", "", "YAML run config (search settings + problem_config)")
        self.mode = p("mode", "surrogate", "surrogate | in_the_loop")
        self.run_id = p("run_id", "", "run id ('' = generated)") or f"run-{uuid.uuid4().hex[:8]}"
        self.min_subscribers = p("min_subscribers", 1, "scenario subscribers to wait for before publishing")
        self.min_workers = p("min_workers", 0, "sim workers (heartbeats) to wait for before publishing")
        self.subscriber_wait = p("subscriber_wait", 10.0, "seconds to wait for subscribers and workers")
        self.exit_when_done = p("exit_when_done", True, "shut down when every scenario is settled")
        status_period = p("status_period", 0.5, "seconds between run status messages")
        self.dispatcher = Dispatcher(
            result_timeout=p("result_timeout", 30.0, "seconds to wait for a scenario's result"),
            worker_timeout=p("worker_timeout", 3.0, "a worker is dead after this many silent seconds"),
            worker_wait=p("worker_wait", 2.0, "with no worker known after this, offer scenarios to anyone"),
            max_attempts=p("max_attempts", 2, "attempts per scenario before recording a timeout"),
            max_in_flight=p("max_in_flight", 8, "scenarios in flight per worker"),
            start=time.monotonic(),
        )
        if self.mode not in ("surrogate", "in_the_loop"):
            raise ConfigError(f"mode: unknown {self.mode!r} (allowed: surrogate|in_the_loop)")
        self.problem, self.settings = make_run(
            problem,
            config_file or None,
            algorithm=algorithm,
            evaluations=evaluations or None,
            time_budget=time_budget or None,
            population=population or None,
            offspring=offspring or None,
            seed=None if seed < 0 else seed,
        )
        self.search = Search(self.problem, self.settings)
        self.config = run_config(self.problem, self.settings, {"run_id": self.run_id, "mode": self.mode})

        self.pub_config = n.create_publisher(topics.RUN_CONFIG_TYPE, topics.RUN_CONFIG, LATCHED)
        self.pub_status = n.create_publisher(topics.STATUS_TYPE, topics.STATUS, DEFAULT)
        self.pub_scenarios = n.create_publisher(
            topics.SCENARIO_TYPES[self.problem.name], topics.scenarios(self.problem.name), STREAM
        )
        self.pub_results = n.create_publisher(topics.RESULT_TYPE, topics.RESULTS, STREAM)
        n.create_subscription(topics.RESULT_TYPE, topics.RESULTS, self.on_result, STREAM)
        n.create_subscription(topics.WORKERS_TYPE, topics.WORKERS, self.on_worker, DEFAULT)

        self.state = "waiting"
        self.waiting_since = time.monotonic()
        self.scenarios: dict[int, tuple[Any, ScenarioMeta]] = {}
        self.outcomes: dict[int, Outcome] = {}
        self.published = 0
        self.timeouts = 0
        self.failures = 0
        self.errors = 0
        self.invalid = 0
        self.batch: list[int] = []  # in_the_loop: scenario ids of the rows asked last
        self.generation = 0
        self.pub_config.publish(
            conversions.run_config_message(n.new_message, n.now_ns(), self.run_id, self.config, __version__)
        )
        n.create_timer(0.01, self.step)
        n.create_timer(status_period, self.publish_status)
        n.logger.info(
            f"run {self.run_id}: {self.problem.name}/{self.settings.algorithm} seed {self.settings.seed}, mode {self.mode}"
        )

    # --- the state machine, one short slice per timer tick -------------------------------------
    def step(self) -> None:
        now = time.monotonic()
        if self.state == "waiting":
            subscribers = self.pub_scenarios.subscription_count()
            workers = len(self.dispatcher.alive(now))
            matched = subscribers >= self.min_subscribers and workers >= self.min_workers
            if matched or now - self.waiting_since > self.subscriber_wait:
                if not matched:
                    self.node.logger.warning(
                        f"{subscribers} of {self.min_subscribers} subscribers and {workers} of "
                        f"{self.min_workers} workers after {self.subscriber_wait:g} s; going on"
                    )
                if self.mode == "surrogate":
                    self.state = "searching"
                else:
                    self.dispatcher.begin(now)
                    self.state = "executing"
        elif self.state == "searching":
            deadline = now + SLICE_S
            while time.monotonic() < deadline:
                if not self.search.step():
                    self.start_suite()
                    break
        elif self.state == "executing":
            if self.mode == "in_the_loop" and not self.batch and not self.ask_batch():
                self.finish()
                return
            self.dispatch(now)
            if self.mode == "in_the_loop":
                self.tell_if_complete()
            elif self.dispatcher.done():
                self.finish()

    def start_suite(self) -> None:
        result = self.search.result()
        self.node.logger.info(
            f"search done: {result.evaluations} evaluations, best F1 {result.best_f1:.3f}; "
            f"executing {len(result.suite)} suite scenarios"
        )
        for entry in result.suite:
            scenario = self.problem.parse(entry["scenario"])
            meta = ScenarioMeta(
                self.run_id, self.published_id(), 0, self.settings.seed, entry["f1"], entry["f2"], entry["valid"], entry["reason"] or ""
            )
            self.add(scenario, meta)
        self.dispatcher.begin(time.monotonic())
        self.state = "executing"

    def published_id(self) -> int:
        return len(self.scenarios)

    def add(self, scenario: Any, meta: ScenarioMeta) -> None:
        self.scenarios[meta.scenario_id] = (scenario, meta)
        self.dispatcher.add(meta.scenario_id, meta.scenario_id)

    def ask_batch(self) -> bool:
        X = self.search.ask()
        if X is None:
            return False
        self.generation += 1
        surrogate = self.problem.evaluate_rows(X)  # recorded in the header for comparison only
        self.batch = []
        for i, row in enumerate(X):
            meta = ScenarioMeta(
                self.run_id, self.published_id(), self.generation, self.settings.seed,
                float(surrogate.f1[i]), float("nan"), bool(surrogate.valid[i]), surrogate.reasons[i] or "",
            )
            self.add(self.problem.codec.from_row(row), meta)
            self.batch.append(meta.scenario_id)
        return True

    def tell_if_complete(self) -> None:
        if any(i not in self.outcomes for i in self.batch):
            return
        outcomes = [self.outcomes[i] for i in self.batch]
        usable = np.array([o.failure_kind not in ("invalid_scenario", "error", "sim_timeout") for o in outcomes])
        f1 = np.array([o.f1 if ok else 0.0 for o, ok in zip(outcomes, usable)])
        reasons = [None if ok else f"{o.failure_kind}: {o.detail}" for o, ok in zip(outcomes, usable)]
        metrics = {"failed": np.array([o.failed for o in outcomes])}
        self.search.tell(Evaluation(f1, usable, reasons, metrics))
        self.batch = []

    def dispatch(self, now: float) -> None:
        sent, given_up = self.dispatcher.tick(now)
        make, stamp = self.node.new_message, self.node.now_ns()
        for assignment in sent:
            scenario, meta = self.scenarios[assignment.scenario_id]
            meta.worker, meta.attempt = assignment.worker, assignment.attempt
            self.pub_scenarios.publish(conversions.scenario_message(make, stamp, self.problem, scenario, meta))
            self.published += assignment.attempt == 1
        for ticket in given_up:
            outcome = Outcome.rejected(
                f"no result after {ticket.attempts} attempt(s) (workers tried: {', '.join(ticket.tried) or 'any'})",
                kind="sim_timeout",
            )
            self.outcomes[ticket.scenario_id] = outcome
            self.timeouts += 1
            self.pub_results.publish(
                conversions.result_message(make, stamp, self.run_id, ticket.scenario_id, self.problem.name, self.node.name, outcome)
            )

    def finish(self) -> None:
        self.state = "done"
        self.publish_status()
        self.node.logger.info(
            f"run {self.run_id} done: {self.published} scenarios, {len(self.outcomes)} settled, "
            f"{self.failures} failures, {self.timeouts} timeouts, {self.errors} errors, {self.invalid} invalid"
        )
        if self.exit_when_done:
            # let reliable writers deliver the last samples before the process ends
            deadline = time.monotonic() + 1.0
            while time.monotonic() < deadline and self.node.ok():
                self.node.spin_once(0.05)
            self.node.shutdown()

    # --- callbacks ---------------------------------------------------------------------------------
    def on_result(self, msg: Any) -> None:
        if msg.run_id != self.run_id or msg.worker == self.node.name:
            return
        if not self.dispatcher.result(int(msg.scenario_id), msg.worker):
            return
        try:
            outcome = conversions.outcome_from_message(msg)
        except ScenarioError as exc:
            outcome = Outcome.rejected(f"unreadable result: {exc}", kind="error")
        self.outcomes[int(msg.scenario_id)] = outcome
        self.failures += outcome.failed
        self.errors += outcome.failure_kind == "error"
        self.invalid += outcome.failure_kind == "invalid_scenario"

    def on_worker(self, msg: Any) -> None:
        if msg.hardware_id == self.problem.name:
            self.dispatcher.heartbeat(msg.name, time.monotonic())

    def publish_status(self) -> None:
        s = self.settings
        history = self.search.history[-1] if self.search.history else {"front_size": 0}
        left = float("nan") if s.time_budget is None else max(s.time_budget - self.search.elapsed, 0.0)
        n = self.node
        self.pub_status.publish(
            conversions.status_message(
                n.new_message,
                n.now_ns(),
                run_id=self.run_id,
                problem=self.problem.name,
                algorithm=s.algorithm,
                seed=int(s.seed),
                evaluations=int(self.search.evaluations),
                budget_evaluations=int(s.evaluations or 0),
                budget_seconds_left=left,
                best_f1=float(self.search.best_f1),
                front_size=int(history["front_size"]),
                scenarios_published=int(self.published),
                results_received=int(len(self.outcomes)),
                state=self.state,
                detail="",
            )
        )


def main(argv: list[str] | None = None) -> int:
    try:
        generator = Generator(argv)
    except (ConfigError, ScenarioError, ValueError) as exc:
        print(f"generator: error: {exc}", file=sys.stderr)
        return 2
    try:
        generator.node.spin()
    finally:
        generator.node.shutdown()
    return 0 if generator.state == "done" else 1


if __name__ == "__main__":
    sys.exit(main())
