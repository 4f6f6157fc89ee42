"""The adapter's ROS side: the worker's topics, the queue, the turns, the watchdogs and the result.

To the generator the adapter is one more sim worker (``sim_nodes.worker``: heartbeats, scenarios,
one ``ScenarioResult`` per scenario). One scenario runs at a time; others queue. A scenario that
breaks the problem's restrictions is answered ``INVALID_SCENARIO`` (unless ``run_invalid``), one
that breaks the reference's static checks ``INVALID_TEST``, both without being sent. Any other
waits for the stack on the graph (``connecting``), is set up by this adapter's judge
(``sim_nodes.adapter.judge``) and runs: samples are put in stamp order with the status streams
(``ambiegen_ros.sims.stamp_order``), timed (``samples``), fed to the judge, and the run ends at the
oracle's verdict or at a watchdog (an ``error`` result saying so): no first sample within
``start_timeout``, no sample for ``silence_timeout``, or more than ``wall_slack`` x the simulated
limit / ``time_scale`` (+ ``start_timeout``) wall seconds.

What happens to the run's processes comes on ``stack_events_topic`` (from whoever started them:
``ambiegen rerun``): a process of the stack that died or hung during the run ends it as
FAIL(sut_crashed), certified like any failure; one of ours (the world, the recorder), or the
stack's before the run began, as an ``error`` record, to be run again.

Every scenario taken ends with a verdict or an ``error`` record (``finish``), with Nav2's word and
the rules that read it (``nav2_rules``). A failure counts only when the problem's reference passes
the same scenario (``reference``, ``ambiegen_ros.sims.reference``): else it becomes
``INVALID_TEST``, the system's kind in ``metrics["sut_failure_kind"]``. A failed hazards run
records how far it ended from the nearest unmapped obstacle (``unmapped_obstacle_m``), a contact
with a person both speeds along the line of contact. A failure that matches an entry of
``known_failures`` is FAIL(kind, known: name), ``metrics["known_failure"]``, not counted among new
distinct failures. Everything happens in callbacks and timers; nothing blocks the executor.
"""
from __future__ import annotations

import math
import time
import traceback
from collections import OrderedDict, deque
from typing import Any

from ambiegen_ros.ros import conversions, topics
from ambiegen_ros.ros.qos import STREAM, Qos
from ambiegen_ros.sims import Outcome, known_failures, reference
from ambiegen_ros.sims.full_model import FullModelExecutor, sim_config
from ambiegen_ros.sims.obstacles import contact_speeds
from ambiegen_ros.sims.oracles import warm_up_judge
from ambiegen_ros.sims.stamp_order import StampOrder
from ambiegen_ros.core.config import ConfigError
from sim_nodes.worker import WorkerEndpoint, load_problem, worker_node

from . import nav2_rules, params
from .job import Job
from .judge import DECIDED, HOLD, SAMPLE_PHASES, RunView
from .params import Param
from .registry import GOAL_MODES, JUDGES, PROBLEMS, judge_for
from .robot_topic import with_give_up
from .samples import timed

ANSWERS_KEPT = 256  # results kept for a scenario sent again (a driver that missed the first)
STAMP_CLOCKS = ("sim", "wall", "receive")
ODOM_FRAMES = ("map", "start")
# what a bad scenario message raises on its way to the contract (conversions, the problem's parsing:
# ScenarioError and ConfigError are ValueErrors); anything else is a fault of ours, logged in full
BAD_SCENARIO = (ValueError, KeyError, IndexError)

COMMON = (
    Param("problem", str, "robot", "the problem of the scenarios it runs", allowed=PROBLEMS),
    Param("frame_id", str, "map", "frame of the published map, poses and road"),
    Param("time_scale", float, 1.0, "simulated seconds per wall second of the system under test", minimum=0,
          above=True),
    Param("stamp_clock", str, "sim", "sim | wall | receive: how sample times are read", allowed=STAMP_CLOCKS),
    Param("odom_frame", str, "map", "map | start: frame of odometry poses (robot)", allowed=ODOM_FRAMES),
    Param("start_timeout", float, 10.0, "seconds to wait for the first sample"),
    Param("silence_timeout", float, 10.0, "seconds without a sample that end a run"),
    Param("wall_slack", float, 2.0, "a run may take this times its simulated limit / time_scale"),
    Param("run_invalid", bool, False, "also run scenarios the problem calls invalid"),
    Param("reference", bool, True, "a failure counts only when the problem's reference passes the scenario (false: "
                                   "the old, unchecked verdicts)"),
    Param("goal_mode", str, "topic", "topic | action (Nav2 navigate_to_pose) | plan (Nav2's planner_server alone: "
                                     "compute_path_to_pose)", allowed=GOAL_MODES),
    Param("known_failures", str, "", "YAML of known failures (ambiegen_ros/sims/known_failures.py): a failure "
                                     "matching one is recorded as FAIL(kind, known: name) ('' = none)"),
    Param("stack_events_topic", str, topics.STACK_EVENTS,
          "diagnostic_msgs/DiagnosticArray in: what happened to the run's processes, from whoever started them "
          "(ambiegen rerun); during a run, one of the stack's = FAIL(sut_crashed), one of ours = an error record "
          "('' = none)"),
    Param("crash_grace", float, 2.0, "wall seconds a failure of the stack's own (Nav2 aborted) waits for a crash "
                                     "report that explains it, when someone publishes them (0 = no wait)"),
    Param("tick_period", float, 0.002, "seconds between adapter turns while a scenario runs"),
    Param("odom_reliable", bool, True, "subscribe to samples reliably (false: best effort)"),
    Param("idle_period", float, 0.2, "seconds between checks for a waiting scenario while none runs"),
)


def help_doc() -> str:
    """Every parameter of the node, the judges' after the common ones (each once)."""
    sections, seen = [("Parameters of every adapter", COMMON)], {p.name for p in COMMON}
    for judge in JUDGES:
        new = tuple(p for p in judge.PARAMS if p.name not in seen)
        seen |= {p.name for p in new}
        mode = f", goal_mode:={judge.goal_mode}" if judge.goal_mode else ""
        sections.append((f"Parameters with problem:={judge.problem}{mode} ({judge.__module__})", new))
    fields = "; ".join(f"{judge.problem}: {', '.join(judge.ORACLE_FIELDS)}" for judge in JUDGES
                       if judge.goal_mode not in ("action", "plan"))
    return params.help_text(sections) + f"\n\noracle.<field>: the oracle's thresholds (defaults: the full model's); {fields}"


def oracle_config(problem: str, options: dict[str, Any], robot: str = "") -> Any:
    """The full model's config with ``options``, carrying the robot ``robot`` names (a robot
    profile, issue 69) so the references and the judge take its body: '' = the Pioneer, the config
    unchanged. A bad profile: one ``ConfigError`` line naming the field, as robot_world says it."""
    config = sim_config(problem, options)
    if not robot:
        return config
    from ambiegen_ros.sims.robot_profile import ProfileError, profiled

    try:
        return profiled(config, robot)
    except ProfileError as exc:
        raise ConfigError(f"robot_profile {robot}: {exc}") from None


class SutAdapter:
    def __init__(self, argv: list[str] | None = None, node=None):
        self.node, default_id = (node, None) if node is not None else worker_node("sut_adapter", argv)
        n = self.node
        s = self.settings = params.declare(n.declare_parameter, COMMON)
        judge_class = judge_for(s.problem, s.goal_mode)
        params.declare(n.declare_parameter, judge_class.PARAMS, into=s)
        self._read_settings(s)
        self.oracle = self._oracle(judge_class.ORACLE_FIELDS)
        self.problem = load_problem(n, self.problem_name)  # config_file + profile
        self.validity = FullModelExecutor(self.problem, config=self.oracle).validity

        # reliable samples are kept all: an adapter busy for a moment buffers them instead of losing
        # the oldest, which a judge by stamps would read as a robot standing still
        self.sample_qos = Qos(reliable=s.odom_reliable, transient_local=False, depth=STREAM.depth,
                              keep_all=s.odom_reliable)
        self.queue: deque[Job] = deque()
        self.job: Job | None = None
        self.samples: list[tuple] = []
        self.pre_goal: tuple | None = None  # the last sample before the goal went out
        self._fast = None
        self.mode = judge_class(n, s, self.oracle, self.problem)
        self.topics = self.mode.topics
        self.mode.wire(self)
        self.nav2 = self.mode.nav2
        if self.events_topic:
            n.create_subscription(topics.STACK_EVENTS_TYPE, self.events_topic, self.on_stack_event, STREAM)
        self.order = StampOrder([(name, how) for name, how in self.mode.STREAMS if self.topics.get(name)])
        for name in self.order.streams:  # every status kept: each one moves its stream's watermark
            n.create_subscription("diagnostic_msgs/msg/DiagnosticArray", self.topics[name],
                                  lambda msg, name=name: self.on_status(name, msg), self.sample_qos)
        self.finishing: Job | None = None  # a run being judged, its result not out yet: still held here
        self.endpoint = WorkerEndpoint(n, self.problem, self.accept, self.in_flight, default_id)
        self.worker_id = self.endpoint.worker_id
        self.answered: OrderedDict[tuple[str, int], Any] = OrderedDict()  # the last results, for a scenario sent again
        warm_up_judge(self.problem_name, self.oracle)  # not mid-run: see its docstring
        # the next scenario starts as the last one ends or as it arrives (finish, accept); this
        # timer only catches what those miss, so it need not wake the node 50 times a second
        n.create_timer(s.idle_period, self.idle)
        n.logger.info(
            f"{self.worker_id}: {self.problem_name} scenarios -> {', '.join(f'{k}={v}' for k, v in self.topics.items() if v)}"
            f" (time_scale {self.time_scale:g}, stamp_clock {self.stamp_clock}; {n.middleware})"
        )

    def _read_settings(self, s: params.Settings) -> None:
        """The settings the node's own methods read, as attributes (a judge reads its own table)."""
        self.problem_name, self.time_scale, self.stamp_clock = s.problem, s.time_scale, s.stamp_clock
        self.start_timeout, self.silence_timeout, self.wall_slack = s.start_timeout, s.silence_timeout, s.wall_slack
        self.run_invalid, self.reference = s.run_invalid, s.reference
        self.events_topic, self.crash_grace, self.tick_period = s.stack_events_topic, s.crash_grace, s.tick_period
        self.ours_error_codes: set[int] = s.get("ours_error_codes", set())  # Nav2's rules at the end of a run
        self.goal_time_budget: float = s.get("goal_time_budget", 0.0)
        try:
            self.known_failures = known_failures.load(s.known_failures) if s.known_failures else []
        except ValueError as exc:
            raise ConfigError(str(exc)) from None

    def _oracle(self, fields: tuple[str, ...]) -> Any:
        """The oracle's thresholds: ``oracle.<field>`` parameters over the full model's defaults."""
        defaults = sim_config(self.problem_name)
        table = [Param(f"oracle.{name}", type(getattr(defaults, name)), getattr(defaults, name),
                       f"oracle threshold {name}") for name in fields]
        values = params.declare(self.node.declare_parameter, table)
        options: dict[str, Any] = {name: values[f"oracle.{name}"] for name in fields
                                   if values[f"oracle.{name}"] != getattr(defaults, name)}
        options["run_invalid"] = bool(self.run_invalid)
        options["reference"] = self.reference
        return oracle_config(self.problem_name, options, self.settings.get("robot_profile", ""))

    # --- worker side ----------------------------------------------------------------------------
    def in_flight(self) -> int:
        """Scenarios held here, as heartbeats say: waiting, running, or judged but not yet answered
        (a driver sends a scenario again when every worker says it holds none)."""
        return len(self.queue) + (self.job is not None) + (self.finishing is not None)

    def publish(self, run_id: str, sid: int, outcome: Outcome) -> None:
        """A scenario's result, out and kept a while: a driver that did not hear it sends the scenario again."""
        self.answered[(run_id, sid)] = outcome
        while len(self.answered) > ANSWERS_KEPT:
            self.answered.popitem(last=False)
        self.endpoint.publish(run_id, sid, outcome)

    def accept(self, run_id: str, sid: int, scenario: Any, msg: Any) -> None:
        if any((j.run_id, j.scenario_id) == (run_id, sid) for j in [self.job, *self.queue] if j is not None):
            return  # a re-sent scenario still waiting here: its one result is coming
        if (run_id, sid) in self.answered:  # sent again: its result went out and was not heard; never run twice
            self.node.logger.info(f"scenario {sid} of run {run_id} came again: its result, once more")
            self.endpoint.publish(run_id, sid, self.answered[(run_id, sid)])
            return
        valid, reason = self.validity(scenario)
        if not valid and not self.run_invalid:
            outcome = Outcome.rejected(f"restriction broken: {reason}")
            outcome.metrics = {"outcome": "invalid", "valid": False, "reason": reason}
            self.publish(run_id, sid, outcome)
            return
        verdict = None
        if self.reference and not self.mode.certifies_itself:  # a judge with its own reference asks it itself
            verdict = reference.before(self.problem, scenario, self.oracle)
            if verdict is not None and not verdict.passed:  # never sent: no system could pass it
                outcome = reference.invalid_test(verdict)
                outcome.metrics = {**outcome.metrics, "valid": valid, "reason": reason}
                self.publish(run_id, sid, outcome)
                self.node.logger.info(f"scenario {sid}: invalid_test ({outcome.detail})")
                return
        self.queue.append(Job(run_id, sid, scenario, msg, reason, valid, before=verdict))
        self.idle()

    def idle(self) -> None:
        if self.job is None and self.queue:
            self.start(self.queue.popleft())

    def start(self, job: Job) -> None:
        """Take the next scenario: first wait until the system under test is on the graph."""
        self.job = job
        self.samples.clear()
        self.order.reset()
        self.pre_goal = None
        self._next_stream_check = 0.0
        self.mode.begin(job)
        job.started = time.monotonic()
        job.phase = "connecting"
        self._next_graph_check = 0.0
        self._fast = self.node.create_timer(self.tick_period, self.tick)

    def _missing_peers(self) -> list[str]:
        """What the system under test has not shown yet: subscribers to our inputs, its publisher."""
        missing = [f"nobody subscribes to {pub.topic}" for pub in self.mode.needs_subscribers()
                   if pub.subscription_count() < 1]
        for topic in [self.mode.sample_topic] + [self.topics[name] for name in self.order.streams]:
            if not self.node.publishers_info(topic):
                missing.append(f"nobody publishes {topic}")
        return missing + self.mode.missing()

    def setup(self, job: Job, now: float) -> None:
        """The judge puts the scenario on the stack's topics. A message we cannot turn into the
        contract is an error record; any other exception is a fault of ours: its traceback goes to
        the log, and the scenario still gets its error record (none is ever lost)."""
        try:
            self.mode.setup(job, now)
        except BAD_SCENARIO as exc:  # a scenario message we cannot turn into the contract
            self.finish(Outcome.rejected(f"{type(exc).__name__}: {exc}", kind="error"))
        except Exception as exc:  # noqa: BLE001 - a bug of ours: logged in full, the scenario on record
            self.node.logger.error(f"scenario {job.scenario_id}: the adapter failed to set it up\n"
                                   f"{traceback.format_exc()}")
            self.finish(Outcome.rejected(f"{type(exc).__name__} in the adapter: {exc} (a fault of ours, its "
                                         "traceback in the adapter's log); run it again", kind="error"))

    # --- samples and statuses -------------------------------------------------------------------
    def on_sample(self, msg: Any) -> None:
        """An odometry or temperature sample: kept from the run's start (the robot at its start pose)."""
        job = self.job
        if job is None or job.phase not in SAMPLE_PHASES:
            return
        sample = self.mode.sample_of(msg)  # raises on non-finite values: the sample is dropped and counted
        if job.phase == "settle":
            self.pre_goal = sample
        elif job.first is not None or self.samples or self.order.pending or self.mode.at_start(sample, job):
            self.samples.append(sample)

    def on_status(self, name: str, msg: Any) -> None:
        """A stamped status on the stall or collision topic: a heartbeat, or the stream's event (a
        WARN on the collision topic: a person walked into the robot, counted, not a failure)."""
        if self.job is not None:
            if self.job.phase in ("waiting", "running"):
                self.job.heard[name] = self.job.heard.get(name, 0) + 1
            if name == "collision" and conversions.status_note(msg) is not None:
                self.job.contacts_not_at_fault += 1
            stamp, problem = conversions.status_problem(msg)
            self.order.message(name, time.monotonic_ns() if self.stamp_clock == "receive" else stamp, problem)

    def on_stack_event(self, msg: Any) -> None:
        """A process of the run died or hung: the scenario running now ends. The stack's during the run:
        FAIL(sut_crashed), certified as any failure; ours, or the stack's before the run began: an error
        record (not the stack's failure: whoever restarts the part runs the scenario again)."""
        for process, part, what in conversions.stack_events_of(msg):
            job = self.job
            self.node.logger.warning(f"{process} ({part}) {what}" + (f" during scenario {job.scenario_id}" if job else ""))
            if self.nav2 is not None:  # a death of ours restarts Nav2 too (a new world is a new clock)
                self.nav2.forget_active()
            if job is None or job.phase == "queued":
                continue
            if part == "stack" and job.judge is not None and job.phase in ("waiting", "running"):
                job.judge.fail("sut_crashed", f"the stack crashed: {process} {what}, "
                                              f"{job.judge.elapsed:.1f} s into the run")
                outcome = job.judge.outcome()  # no objective before the route is known (a crash at once)
                outcome.objectives = {k: v for k, v in outcome.objectives.items() if math.isfinite(v)}
                self.finish(outcome)
            else:
                whose = "ours, not the stack's failure" if part == "ours" else "before the run began"
                self.finish(Outcome.rejected(f"{process} {what} ({whose}): run it again", kind="error"))

    def on_nav2_left_active(self, name: str, what: str) -> None:
        """A lifecycle node of Nav2 left the active state: its manager took the stack down (a bond not
        renewed within bond_timeout, as a node starved of CPU lets it lapse) or someone did. A run it
        interrupts ends as an error record, once a crash report had its grace to explain it instead."""
        job = self.job
        self.node.logger.warning(f"Nav2's {name} left the active state ({what})"
                                 + (f" during scenario {job.scenario_id}" if job is not None else ""))
        if job is not None and job.phase in ("settle", "waiting", "running") and not job.taken_down:
            job.taken_down = f"Nav2's {name} left the active state during the run ({what})"

    def _crash_grace(self, job: Job, now: float) -> bool:
        """Hold Nav2's failure a moment when someone reports the run's processes: a server killed
        mid-run makes Nav2 abort before the report of the kill arrives."""
        if self.crash_grace <= 0 or not self.events_topic or not self.node.publishers_info(self.events_topic):
            return False
        if job.grace_until is None:
            job.grace_until = now + self.crash_grace
        return now < job.grace_until

    # --- the turns ------------------------------------------------------------------------------
    def tick(self) -> None:
        job = self.job
        if job is None:
            return
        now = time.monotonic()
        if job.phase == "connecting":
            self._connect(job, now)
            return
        if job.taken_down:  # held while a crash report may still explain it, then an error record
            if not self._crash_grace(job, now):
                self.finish(Outcome.rejected(f"{job.taken_down}: the stack was taken down, not failed by the "
                                             "scenario; run it again", kind="error"))
            return
        if job.phase == "settle":
            self._settle(job, now)
            return
        if self.samples or self.order.pending:
            self._judge_samples(job, now)
            if job.judge.decided:
                self.finish(job.judge.outcome())
                return
        said = self.mode.step(job, RunView(now, self.order, bool(self.samples), lambda: self._crash_grace(job, now)))
        if said == HOLD:
            return
        if said == DECIDED:
            self.finish(job.judge.outcome())
            return
        if self.order.pending and now >= self._next_stream_check:
            self._close_deserted_streams(now)
        self._watch(job, now)
        if job.judge.decided:
            self.finish(job.judge.outcome())

    def _connect(self, job: Job, now: float) -> None:
        """Set the scenario up once the stack is on the graph; an error record at ``start_timeout``."""
        if now < self._next_graph_check:
            return
        self._next_graph_check = now + 0.05  # graph queries are not free: 20 per second at most
        missing = self._missing_peers()
        if not missing:
            self.setup(job, now)
        elif now - job.started > self.start_timeout:
            self.finish(Outcome.rejected(f"no {self.mode.samples_are} within {self.start_timeout:g} s: "
                                         f"{'; '.join(missing)}", kind="error"))

    def _settle(self, job: Job, now: float) -> None:
        """The goal goes out once the system shows the robot at the start (a quiet one: after
        settle_time; one still showing the last run: after start_timeout at most)."""
        ready = self.pre_goal is None or self.mode.at_start(self.pre_goal, job)
        if now >= job.settle_until and (ready or now >= job.settle_until + self.start_timeout):
            self.mode.send_goal(job)
            job.phase, job.go = "waiting", now
            if self.mode.at_start(self.pre_goal, job):  # the robot as the goal went out is sample 0
                self.samples.insert(0, self.pre_goal)

    def _watch(self, job: Job, now: float) -> None:
        """The watchdogs: no first sample, a silence, a run too slow for its time scale."""
        what = self.mode.samples_are
        if job.phase == "waiting" and now - job.go > self.start_timeout:
            job.judge.finish(f"no {what} within {self.start_timeout:g} s")
        elif job.phase == "running" and now - job.last_sample > self.silence_timeout:
            job.judge.finish(f"{what} stopped after {job.judge.elapsed:.1f} s (simulated) without a verdict"
                             + self._held_back())
        elif now - job.go > self.wall_slack * job.limit_sim / self.time_scale + self.start_timeout:
            job.judge.finish(f"too slow: {job.judge.elapsed:.1f} of {job.limit_sim:.0f} simulated s after "
                             f"{now - job.go:.1f} s wall (time_scale {self.time_scale:g})" + self._held_back())

    def _held_back(self) -> str:
        waiting = self.order.waiting_for()
        return (f"; {len(self.order.pending)} samples held back, waiting for "
                f"{', '.join(self.topics[name] for name in waiting)} to pass their stamps") if waiting else ""

    def _close_deserted_streams(self, now: float) -> None:
        """A status stream whose publisher left the graph holds no sample back any more."""
        self._next_stream_check = now + 0.5
        for name in self.order.waiting_for():
            if not self.node.publishers_info(self.topics[name]):
                self.order.close(name, f"nobody publishes {self.topics[name]}")

    def _judge_samples(self, job: Job, now: float) -> None:
        """The samples received, judged once every status stream has passed their stamps."""
        if self.samples:
            job.phase, job.last_sample = "running", now
            key = 1 if self.stamp_clock == "receive" else 0  # no stamps to trust: arrival is the only order
            for row in self.samples:
                self.order.sample(int(row[key]), row)
            self.samples.clear()
        if job.first is None:
            # with the stack's status, the run starts at the state it first acted on (sample 0)
            if "stall" in self.order.streams and not self.order.start_at_first("stall"):
                return
            row = self.order.pending[0][1]
            job.first, job.anchor = (int(row[0]), int(row[1])), row[1] / 1e9
        released = self.order.release()
        if not released:
            return
        batch, job.t_prev = timed(released, job.first, self.stamp_clock, self.time_scale, job.t_prev)
        if batch is not None:  # strictly increasing times only (drops duplicates, reordering)
            self.mode.feed(job, *batch)

    # --- the end --------------------------------------------------------------------------------
    def finish(self, outcome: Outcome) -> None:
        """The run's result, published: the oracle's verdict or an error, with the stack's word, the
        reference's certificate, hazards evidence, known failures and the run's own figures. The run
        stays held (``finishing``, in the heartbeats) until its result is out."""
        job = self.finishing = self.job
        self.job = None
        try:
            if self._fast is not None:
                self._fast.cancel()
                self._fast = None
            outcome = nav2_rules.with_stack_word(outcome, self.nav2, job)  # Nav2's own word beside our oracle's
            if self.topics.get("plan"):
                outcome = self.mode.with_plans(outcome)
            outcome = with_give_up(outcome, self.order.streams.get("stall"), self.topics.get("stall"))
            outcome = nav2_rules.ours_or_the_stacks(outcome, self.ours_error_codes)
            outcome = self.mode.with_timing(outcome)  # did the stack get its computer? a starved run is no verdict
            if self.reference and outcome.failed and not self.mode.certifies_itself:  # does the reference pass it?
                budget = nav2_rules.budget_spent(outcome.failure_kind, job.judge.elapsed, self.goal_time_budget)
                outcome = reference.certify(outcome, reference.after(self.problem, job.scenario, self.oracle, outcome,
                                                                     budget=budget) or job.before)
            hazards = self.problem_name == "robot" and getattr(self.problem, "hazards", False)
            if hazards:
                outcome = hazards_evidence(self.problem, job.scenario, outcome)
            if self.known_failures and outcome.failed:
                outcome = known_failures.mark(outcome, self.known_failures)
            wall = time.monotonic() - job.started
            outcome.elapsed_sec = wall
            outcome.metrics = {**outcome.metrics, "valid": job.valid, "reason": job.reason, "wall_s": wall,
                               "time_scale": self.time_scale, "stamp_clock": self.stamp_clock}
            if hazards:
                outcome.metrics["contacts_not_at_fault"] = job.contacts_not_at_fault
            if job.goal_sends > 1:
                outcome.metrics["goal_sends"] = job.goal_sends
            self.publish(job.run_id, job.scenario_id, outcome)
            self.node.logger.info(f"scenario {job.scenario_id}: {outcome.failure_kind} ({outcome.detail}) in {wall:.2f} s")
        finally:
            self.finishing = None
        self.idle()


def hazards_evidence(problem: Any, scenario: Any, outcome: Outcome) -> Outcome:
    """A failed hazards run: how far it ended from the nearest unmapped obstacle; a contact with a
    person: both speeds along the line of contact, as metrics."""
    if outcome.failed:
        where = outcome.failure_point or (None if outcome.trajectory is None or not len(outcome.trajectory)
                                          else tuple(outcome.trajectory[-1][:2]))
        outcome.metrics = {**outcome.metrics,
                           "unmapped_obstacle_m": known_failures.unmapped_obstacle_m(problem, scenario, where)}
    speeds = contact_speeds(outcome.detail)
    if speeds:
        outcome.metrics = {**outcome.metrics, **{f"contact_{k}": v for k, v in speeds.items()}}
    return outcome
