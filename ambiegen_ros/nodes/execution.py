"""Executing scenarios on remote sim workers: publish, collect, re-assign, record timeouts.

Shared by the generator and replay nodes. ``core.dispatch.Dispatcher`` decides who gets what and
when to give up; this class only turns its decisions into messages and results into outcomes.
Every scenario added ends in ``outcomes`` with the worker's outcome or a ``sim_timeout`` outcome
that is also published as an explicit result record. Only open scenarios are kept, and outcomes
only until ``take``n, so memory does not grow with the length of a run (``bench/soak.py``).

A worker whose heartbeat names another fidelity profile than this run's problem is never given a
scenario (it would score another environment); it is reported once in the log. Scenarios offered
to anyone still reach it, and it answers them with an ``ERROR`` result (``sim_nodes.worker``).
"""
from __future__ import annotations

import json
import time
from typing import Any

from ..core.attributes import ScenarioError
from ..core.dispatch import Dispatcher
from ..core.problem import Problem
from ..ros import conversions, topics
from ..ros.conversions import ScenarioMeta
from ..ros.limits import MAX_JSON_DEPTH, check_name, json_depth
from ..ros.qos import DEFAULT, STREAM
from ..sims.outcome import FAILURE_KINDS, Outcome

DISPATCH_PARAMETERS = {
    "result_timeout": (30.0, "seconds one execution may take at its worker (waiting in its queue does not count)"),
    "worker_timeout": (3.0, "a worker is dead after this many silent seconds"),
    "worker_wait": (2.0, "with no worker known after this, offer scenarios to anyone"),
    "max_attempts": (2, "attempts per scenario before recording a timeout"),
    "max_in_flight": (8, "scenarios in flight per worker"),
}


def run_profile(config_json: str) -> str | None:
    """The fidelity profile a run config (``RunConfig.config_json``) names; None when it names none."""
    if json_depth(config_json) > MAX_JSON_DEPTH:
        return None
    try:
        config = json.loads(config_json)
    except ValueError:
        return None
    if not isinstance(config, dict):
        return None
    problem_config = config.get("problem_config")
    profile = config.get("profile") or (problem_config.get("profile") if isinstance(problem_config, dict) else None)
    return str(profile) if isinstance(profile, str) and profile else None


class RemoteExecution:
    def __init__(self, node: Any, problem: Problem, run_id: str):
        self.node = node
        self.problem = problem
        self.run_id = run_id
        values = {name: node.declare_parameter(name, default, text) for name, (default, text) in DISPATCH_PARAMETERS.items()}
        self.dispatcher = Dispatcher(**values, start=time.monotonic())
        self.pub_scenarios = node.create_publisher(
            topics.SCENARIO_TYPES[problem.name], topics.scenarios(problem.name), STREAM
        )
        self.pub_results = node.create_publisher(topics.RESULT_TYPE, topics.RESULTS, STREAM)
        node.create_subscription(topics.RESULT_TYPE, topics.RESULTS, self.on_result, STREAM)
        node.create_subscription(topics.WORKERS_TYPE, topics.WORKERS, self.on_worker, DEFAULT)
        self.scenarios: dict[int, tuple[Any, ScenarioMeta]] = {}  # not settled yet (a re-assignment re-sends them)
        self.outcomes: dict[int, Outcome] = {}  # settled, until the caller ``take``s them
        self.added = 0
        self.settled = 0
        self.published = 0
        self.withdrawn = 0  # added but never sent: the budget ran out first
        self.not_sent = 0  # never sent: the caller settled them itself (``settle_unsent``)
        self.failures = 0
        self.timeouts = 0
        self.errors = 0
        self.invalid = 0
        self.invalid_tests = 0  # INVALID_TEST: no reference passes the scenario (never a failure)
        self.foreign_workers: set[str] = set()  # workers of another fidelity profile, never used

    def add(self, scenario: Any, meta: ScenarioMeta) -> None:
        self.dispatcher.add(meta.scenario_id, meta.scenario_id)
        self.scenarios[meta.scenario_id] = (scenario, meta)
        self.added += 1

    def settle_unsent(self, scenario_id: int, outcome: Outcome) -> None:
        """A scenario the caller keeps from the workers: it takes its id (the next scenario's id and
        seed are as if it had been sent) and settles at once with ``outcome``, for ``take``."""
        self.added += 1
        self.not_sent += 1
        self.outcomes[scenario_id] = outcome

    def withdraw(self) -> int:
        """Stop: the scenarios not sent yet never will be (``Dispatcher.withdraw``); how many."""
        withdrawn = self.dispatcher.withdraw()
        for scenario_id in withdrawn:
            self.scenarios.pop(scenario_id, None)
        self.withdrawn += len(withdrawn)
        return len(withdrawn)

    def next_id(self) -> int:
        return self.added

    def take(self, scenario_ids: list[int]) -> list[Outcome]:
        """The outcomes of settled scenarios, forgotten here and in the dispatcher (a long
        in-the-loop run keeps only its open scenarios in memory)."""
        outcomes = [self.outcomes.pop(i) for i in scenario_ids]
        self.dispatcher.forget(scenario_ids)
        return outcomes

    def begin(self) -> None:
        self.dispatcher.begin(time.monotonic())

    def done(self) -> bool:
        return self.dispatcher.done()

    def tick(self) -> None:
        sent, given_up = self.dispatcher.tick(time.monotonic())
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
            self._settle(ticket.scenario_id, outcome)
            self.pub_results.publish(
                conversions.result_message(make, stamp, self.run_id, ticket.scenario_id, self.problem.name, self.node.name, outcome)
            )

    def on_result(self, msg: Any) -> None:
        if msg.run_id != self.run_id or msg.worker == self.node.name:
            return
        # a rejection is answered on arrival, an execution in the order sent (see core.dispatch)
        executed = int(msg.failure_kind) not in (FAILURE_KINDS["invalid_scenario"], FAILURE_KINDS["error"])
        if not self.dispatcher.result(int(msg.scenario_id), msg.worker, executed, time.monotonic()):
            return
        try:
            outcome = conversions.outcome_from_message(msg)
        except ScenarioError as exc:
            outcome = Outcome.rejected(f"unreadable result: {exc}", kind="error")
        self._settle(int(msg.scenario_id), outcome)

    def _settle(self, scenario_id: int, outcome: Outcome) -> None:
        self.scenarios.pop(scenario_id, None)  # never sent again
        self.outcomes[scenario_id] = outcome
        self.settled += 1
        self.failures += outcome.failed
        self.timeouts += outcome.failure_kind == "sim_timeout"
        self.errors += outcome.failure_kind == "error"
        self.invalid += outcome.failure_kind == "invalid_scenario"
        self.invalid_tests += outcome.failure_kind == "invalid_test"

    def on_worker(self, msg: Any) -> None:
        if msg.hardware_id != self.problem.name:
            return
        check_name(msg.name, "heartbeat name")  # raises: the transport drops and counts the sample
        profile = next((kv.value for kv in msg.values if kv.key == "profile"), self.problem.profile)
        if profile != self.problem.profile:
            if msg.name not in self.foreign_workers:
                self.foreign_workers.add(msg.name)
                self.node.logger.error(
                    f"worker {msg.name} scores the {profile!r} profile, run {self.run_id} uses "
                    f"{self.problem.profile!r}: not sending it scenarios"
                )
            return
        self.dispatcher.heartbeat(msg.name, time.monotonic())
