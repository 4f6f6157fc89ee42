"""`generator`: runs the search and sends scenarios to the simulation nodes.

Modes:
* ``surrogate`` (default): search in-process with the surrogate (in short slices on a timer, so
  the executor stays responsive and run status is published), then publish the final suite as
  scenarios and collect a result for each.
* ``in_the_loop``: pymoo ask/tell where F1 of every scenario comes from the sim nodes' results
  (the paper's "full model" setting); nothing blocks the executor.

Every published scenario ends with a result from a worker or an explicit ``SIM_TIMEOUT`` result
written by this node (``execution.RemoteExecution`` over ``core.dispatch``).

A scenario the problem calls invalid (``Problem.evaluate(...).valid``, the validity the search
takes as its constraint) is never sent to a simulator or a stack, in either mode: it is logged on
``/ambiegen/<problem>/not_sent`` (its header names the broken rule) and settles here as the sims
would have answered it (``INVALID_SCENARIO``, "restriction broken: <rule>"), so the search is
told what it was told before, scenario ids and seeds stay those of a run that sent everything, and
a seed gives the same run. Random search draws valid samples only (``Search(valid_samples=True)``),
so its budget goes to scenarios that are executed.

Reproducible: a seed gives the same scenarios, F1 values and suite with any number of workers
and any batching on their side. Each generation is told in scenario order once all its results
are in, and no clock enters the search unless ``time_budget`` or ``execution_budget`` is set (a
``SIM_TIMEOUT`` result, by nature, depends on the clock too). This holds as long as each problem's
``evaluate`` gives a scenario the same bits whatever it is batched with
(``test/core/test_batch_invariance.py``).

A spent budget stops the sending at once, not at the end of a generation: ``execution_budget``
(wall seconds from the first scenario sent) in either mode, and in ``in_the_loop`` also
``time_budget``. Scenarios already sent finish and are logged; those never sent are dropped, so a
campaign given an hour of a real-time stack takes an hour plus at most one run per worker.

Parameters: problem (thermostat | robot | vehicle), algorithm (ga | nsga2 | random), evaluations
(0 = the paper's budget), time_budget (s, 0 = none), execution_budget (s, 0 = none), population,
offspring (0 = the paper's), seed (-1 = drawn and recorded), profile (fidelity profile: replication | refined; '' = the config
file's problem_config.profile, else replication), config_file (run config YAML), mode (surrogate |
in_the_loop), run_id, suite_file (write the final suite there as JSON; '' = none),
min_subscribers, min_workers, min_recorders, subscriber_wait (s), exit_when_done, status_period (s),
result_timeout (s), worker_timeout (s), worker_wait (s), max_attempts, max_in_flight.
The run config (latched, and in the recorder's MCAP metadata) records the profile.

No scenario goes out before the recorders are ready (``/ambiegen/recorder_status``: each reads
every topic it was told to record, a robot's ``/scan`` and ``/cmd_vel`` included), so a bag holds
the first run from its first message: at least ``min_recorders`` of them (``ambiegen campaign``: its
one), and every recorder heard or seen in the graph, within the same ``subscriber_wait`` bound as
subscribers and workers.
Topics: publishes /ambiegen/run_config (latched), /ambiegen/status, /ambiegen/<problem>/scenarios,
/ambiegen/<problem>/not_sent and SIM_TIMEOUT records on /ambiegen/results; subscribes
/ambiegen/results, /ambiegen/workers and /ambiegen/recorder_status.
"""
from __future__ import annotations

import json
import sys
import time
import uuid
from pathlib import Path

import numpy as np

from .. import __version__
from ..core.config import ConfigError
from ..run_config import make_run
from ..core.runs import run_config, suite_document
from ..core.search import Search
from ..core.problem import PROFILES, Evaluation
from ..ros import conversions, topics
from ..ros.conversions import ScenarioMeta
from ..ros.limits import check_name
from ..ros.qos import DEFAULT, LATCHED, Qos
from ..ros.transport import create_node
from ..sims.known_failures import is_known
from ..sims.outcome import Outcome
from .execution import RemoteExecution
from . import run_node

SLICE_S = 0.05  # longest stretch of search work between two executor turns
RECORDER_STATUS_QOS = Qos(reliable=True, transient_local=True, depth=10)  # each recorder's last status, all of them


def loop_evaluation(outcomes: list, f1=lambda o: o.f1) -> Evaluation:
    """What an in-the-loop search is told of executed scenarios: each one's F1 (``f1``: the
    problem's ``loop_f1``; default ``Outcome.f1``).
    An INVALID_TEST (no reference passes it either), an error or a timeout is no failure to climb
    towards: F1 0, invalid. A known failure (``sims.known_failures``, e.g. NavFn's path cap) is a
    valid test that teaches nothing new: F1 0, so the search does not climb towards it either."""
    unusable = ("invalid_scenario", "error", "sim_timeout", "invalid_test")
    usable = np.array([o.failure_kind not in unusable for o in outcomes])
    f1 = np.array([f1(o) if ok and not is_known(o) else 0.0 for o, ok in zip(outcomes, usable)])
    reasons = [None if ok else f"{o.failure_kind}: {o.detail}" for o, ok in zip(outcomes, usable)]
    return Evaluation(f1, usable, reasons, {"failed": np.array([o.failed for o in outcomes])})


class Generator:
    def __init__(self, argv: list[str] | None = None, node=None):
        self.node = node or create_node("generator", argv=argv)
        n = self.node
        p = n.declare_parameter
        problem = p("problem", "robot", "thermostat | robot | vehicle")
        algorithm = p("algorithm", "nsga2", "ga | nsga2 | random")
        evaluations = p("evaluations", 0, "evaluation budget (0 = the paper's, unless time_budget is set)")
        time_budget = p("time_budget", 0.0, "wall-clock budget in seconds (0 = none)")
        self.execution_budget = p(
            "execution_budget", 0.0, "wall seconds of sending scenarios, from the first one (0 = none); then the sent ones finish"
        )
        population = p("population", 0, "population size (0 = the paper's)")
        offspring = p("offspring", 0, "offspring per generation (0 = the paper's)")
        seed = p("seed", -1, "random seed (-1 = drawn and recorded)")
        profile = p("profile", "", f"fidelity profile: {' | '.join(PROFILES)} ('' = the config file's, else {PROFILES[0]})")
        config_file = p("config_file", "", "YAML run config (search settings + problem_config)")
        self.suite_file = p("suite_file", "", "write the final suite here as JSON ('' = none)")
        self.mode = p("mode", "surrogate", "surrogate | in_the_loop")
        self.run_id = check_name(p("run_id", "", "run id ('' = generated)") or f"run-{uuid.uuid4().hex[:8]}", "run_id")
        self.min_subscribers = p("min_subscribers", 1, "scenario subscribers to wait for before publishing")
        self.min_workers = p("min_workers", 0, "sim workers (heartbeats) to wait for before publishing")
        self.min_recorders = p("min_recorders", 0, "recorders to hear ready (every topic to record read) before publishing")
        self.subscriber_wait = p("subscriber_wait", 10.0, "seconds to wait for subscribers, workers and recorders")
        self.exit_when_done = p("exit_when_done", True, "shut down when every scenario is settled")
        status_period = p("status_period", 0.5, "seconds between run status messages")
        if self.mode not in ("surrogate", "in_the_loop"):
            raise ConfigError(f"mode: unknown {self.mode!r} (allowed: surrogate|in_the_loop)")
        if profile and profile not in PROFILES:
            raise ConfigError(f"profile: unknown {profile!r} (allowed: {'|'.join(PROFILES)})")
        self.problem, self.settings = make_run(
            problem,
            config_file or None,
            profile=profile or None,
            algorithm=algorithm,
            evaluations=evaluations or None,
            time_budget=time_budget or None,
            population=population or None,
            offspring=offspring or None,
            seed=None if seed < 0 else seed,
        )
        self.search = Search(self.problem, self.settings, valid_samples=True)
        extra = {"run_id": self.run_id, "mode": self.mode, "profile": self.problem.profile}
        if self.settings.algorithm == "random":
            extra["random_samples"] = "valid"  # what the problem calls invalid would never be sent
        self.config = run_config(self.problem, self.settings, extra)

        self.pub_config = n.create_publisher(topics.RUN_CONFIG_TYPE, topics.RUN_CONFIG, LATCHED)
        self.pub_status = n.create_publisher(topics.STATUS_TYPE, topics.STATUS, DEFAULT)
        self.remote = RemoteExecution(n, self.problem, self.run_id)
        self.pub_not_sent = n.create_publisher(
            topics.SCENARIO_TYPES[self.problem.name], topics.not_sent(self.problem.name), topics.NOT_SENT_QOS
        )
        self.recorders = self.listen_to_recorders()

        self.state = "waiting"
        self.waiting_since = time.monotonic()
        self.batch: list[int] = []  # in_the_loop: scenario ids of the rows asked last
        self.executing_since: float | None = None
        self.closed = False  # a budget is spent: nothing more is sent
        self.generation = 0
        self.pub_config.publish(
            conversions.run_config_message(n.new_message, n.now_ns(), self.run_id, self.config, __version__)
        )
        n.create_timer(0.01, self.step)
        n.create_timer(status_period, self.publish_status)
        n.logger.info(
            f"run {self.run_id}: {self.problem.name}/{self.settings.algorithm} seed {self.settings.seed}, "
            f"mode {self.mode}, profile {self.problem.profile}"
        )

    # --- the state machine, one short slice per timer tick -------------------------------------
    def step(self) -> None:
        now = time.monotonic()
        if self.state == "waiting":
            subscribers = self.remote.pub_scenarios.subscription_count()
            workers = len(self.remote.dispatcher.alive(now))
            recorders, expected = self.recorders_ready()
            matched = subscribers >= self.min_subscribers and workers >= self.min_workers and recorders >= expected
            if matched or now - self.waiting_since > self.subscriber_wait:
                if not matched:
                    self.node.logger.warning(
                        f"{subscribers} of {self.min_subscribers} subscribers, {recorders} of {expected} recorders "
                        f"ready and {workers} of {self.min_workers} workers after {self.subscriber_wait:g} s; going on"
                    )
                else:
                    without = sorted({t for _, gone in self.recorders.values() for t in gone.split(",") if t})
                    self.node.logger.info(
                        f"{subscribers} subscribers, {recorders} recorders ready and {workers} workers: starting"
                        + (f" (recorded without {', '.join(without)})" if without else ""))
                if self.mode == "surrogate":
                    self.state = "searching"
                else:
                    self.begin_execution()
        elif self.state == "searching":
            deadline = now + SLICE_S
            while time.monotonic() < deadline:
                if not self.search.step():
                    self.start_suite()
                    break
        elif self.state == "executing":
            if self.mode == "in_the_loop" and not self.batch and not self.closed:
                asked = time.monotonic()
                more = self.ask_batch()
                self.remote.dispatcher.busy(asked, time.monotonic())
                if not more:
                    self.finish()
                # asking can take long (a first JIT compile): read the heartbeats and results
                # that came meanwhile before judging workers on the next tick
                return
            self.remote.tick()
            self.log_worker_events()
            if self.mode == "in_the_loop" and not self.closed:
                self.tell_if_complete()
            if not self.closed and self.budget_spent(now):
                self.close()
            if (self.closed or self.mode == "surrogate") and self.remote.done():
                self.finish()

    def listen_to_recorders(self) -> dict[str, tuple[bool, str]]:
        """Recorder node -> (ready, the topics it goes on without), as their latched statuses say."""
        self.node.create_subscription(topics.RECORDER_STATUS_TYPE, topics.RECORDER_STATUS, self.on_recorder_status,
                                      RECORDER_STATUS_QOS)
        return {}

    def on_recorder_status(self, msg) -> None:
        values = {kv.key: kv.value for kv in msg.values}
        self.recorders[str(msg.name)] = (values.get("state") == "ready", values.get("missing", ""))

    def recorders_ready(self) -> tuple[int, int]:
        """Recorders that said they are ready, and how many must: ``min_recorders``, or more if more
        were heard (one still waiting holds the start) or are in the graph (their status on its way)."""
        ready = sum(1 for ok, _ in self.recorders.values() if ok)
        seen = len(self.node.publishers_info(topics.RECORDER_STATUS))
        return ready, max(self.min_recorders, len(self.recorders), seen)

    def begin_execution(self) -> None:
        self.remote.begin()
        self.executing_since = time.monotonic()
        self.state = "executing"

    def budget_spent(self, now: float) -> bool:
        if self.execution_budget and now - self.executing_since >= self.execution_budget:
            return True
        budget = self.settings.time_budget
        return self.mode == "in_the_loop" and budget is not None and self.search.elapsed >= budget

    def close(self) -> None:
        """The budget is spent: send nothing more, finish the scenarios already sent."""
        self.closed = True
        self.batch = []
        withdrawn = self.remote.withdraw()
        self.node.logger.info(
            f"budget spent: {withdrawn} scenarios not sent; finishing the {self.remote.dispatcher.open} already sent"
        )

    def log_worker_events(self) -> None:
        """Workers lost, joined or back, as the dispatcher saw them (how long detection took)."""
        for e in self.remote.dispatcher.drain_events():
            if e.kind == "lost":
                self.node.logger.warning(
                    f"worker {e.worker} lost (silent {e.silent_s:.2f} s): {e.requeued} scenarios re-queued for live workers"
                )
            elif e.kind == "unanswered":
                self.node.logger.info(f"worker {e.worker} has not answered its first scenario yet: giving it more")
            elif e.kind == "skipped":
                self.node.logger.warning(
                    f"worker {e.worker} answered later scenarios but never got {e.requeued}: re-queued"
                )
            elif e.kind == "back":
                self.node.logger.info(f"worker {e.worker} is back after {e.silent_s:.2f} s of silence")
            elif self.state == "executing":
                self.node.logger.info(f"worker {e.worker} joined")

    def start_suite(self) -> None:
        result = self.search.result()
        self.write_suite(result)
        for entry in result.suite:
            scenario = self.problem.parse(entry["scenario"])
            meta = ScenarioMeta(
                self.run_id, self.remote.next_id(), 0, self.settings.seed, entry["f1"], entry["f2"], entry["valid"], entry["reason"] or ""
            )
            self.hand_over(scenario, meta)
        not_sent = self.remote.not_sent
        self.node.logger.info(
            f"search done: {result.evaluations} evaluations, best F1 {result.best_f1:.3f}; "
            f"executing {len(result.suite) - not_sent} suite scenarios"
            + (f" ({not_sent} more not sent: the problem calls them invalid)" if not_sent else "")
        )
        self.begin_execution()

    def ask_batch(self) -> bool:
        X = self.search.ask()
        if X is None:
            return False
        self.generation += 1
        surrogate = self.problem.evaluate_rows(X)  # recorded in the header for comparison only
        self.batch = []
        for i, row in enumerate(X):
            meta = ScenarioMeta(
                self.run_id, self.remote.next_id(), self.generation, self.settings.seed,
                float(surrogate.f1[i]), float("nan"), bool(surrogate.valid[i]), surrogate.reasons[i] or "",
            )
            self.hand_over(self.problem.codec.from_row(row), meta)
            self.batch.append(meta.scenario_id)
        return True

    def hand_over(self, scenario, meta: ScenarioMeta) -> None:
        """Send a scenario to the workers, unless the problem calls it invalid (``meta.valid``):
        then log it on the not_sent topic with its reason and settle it here (module docstring)."""
        if meta.valid:
            self.remote.add(scenario, meta)
            return
        meta.attempt = 0  # never dispatched
        n = self.node
        self.pub_not_sent.publish(conversions.scenario_message(n.new_message, n.now_ns(), self.problem, scenario, meta))
        self.remote.settle_unsent(meta.scenario_id, Outcome.rejected(f"restriction broken: {meta.reason}"))

    def tell_if_complete(self) -> None:
        if not self.batch or any(i not in self.remote.outcomes for i in self.batch):
            return
        outcomes = self.remote.take(self.batch)  # told once: nothing of a generation is kept after
        self.search.tell(loop_evaluation(outcomes, self.problem.loop_f1))
        self.batch = []

    def write_suite(self, result) -> None:
        """The suite as ``suite.json`` of a search run: clock-free, so a seed gives the same bytes."""
        if self.suite_file:
            path = Path(self.suite_file)
            path.parent.mkdir(parents=True, exist_ok=True)
            document = {"mode": self.mode, "profile": self.problem.profile, **suite_document(self.problem, result)}
            path.write_text(json.dumps(document, indent=2) + "\n")

    def finish(self) -> None:
        if self.mode == "in_the_loop":
            self.write_suite(self.search.result())
        self.state = "done"
        self.publish_status()
        r = self.remote
        self.node.logger.info(
            f"run {self.run_id} done: {r.published} scenarios, {r.settled} settled, "
            f"{r.failures} failures, {r.invalid_tests} invalid tests, {r.timeouts} timeouts, {r.errors} errors, "
            f"{r.invalid} invalid" + (f"; {r.not_sent} not sent (the problem calls them invalid)" if r.not_sent else "")
            + (f"; {r.withdrawn} not sent (budget spent)" if r.withdrawn else "")
        )
        if self.exit_when_done:
            # the spin ends; run_node then waits until the last samples are acknowledged (finish_io)
            self.node.request_shutdown()

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
                scenarios_published=int(self.remote.published),
                results_received=int(self.remote.settled),
                state=self.state,
                detail="",
            )
        )


def main(argv: list[str] | None = None) -> int:
    return run_node("generator", lambda: Generator(argv), lambda g: 0 if g.state == "done" else 1, doc=__doc__)


if __name__ == "__main__":
    sys.exit(main())
