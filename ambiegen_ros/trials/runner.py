"""Running trials: per configuration, start the stack, send each scenario, append each row.

The stack is what a campaign starts (``launch_logic``: ``robot_world`` + Nav2 + ``sut_adapter``,
or our ND stack), with the configuration's merged params file given to every node, and a
recorder writing one bag per configuration and invocation (``<bags>/<label>_<UTC time>/``, with
the nodes' logs and the params beside it). Scenarios go one at a time, each configuration's runs
round-robin (every scenario once, then again), so a run cut short leaves balanced counts, and the
next invocation runs only what is missing (``rows.TrialLog.done``).

The runner publishes the scenarios and takes the results as the generator does, on the same
topics, so the bag holds scenario, robot and verdict alike. A scenario that gets no answer in its
time gets a ``sim_timeout`` result, published and logged: nothing sent is lost. After
``max_errors`` errors of ours in a row (no answer, the adapter's error) the configuration stops
with one line naming the logs.
"""
from __future__ import annotations

import math
import os
import sys
import time
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Callable

from .configs import NAV2_STACKS, Prepared
from .rows import TrialLog, counted
from .suite import Entry, Suite, problem_of

RESULT_SLACK_S = 60.0  # beyond the adapter's own guard, before the runner calls a scenario lost


class StackStopped(Exception):
    """The runs of a configuration stopped: the stack did not come up, or kept failing to answer."""


@dataclass
class TrialSettings:
    stack: str  # nd | bringup | ours | external
    results: Path
    bags: Path
    repeat: int = 3
    time_scale: float = 1.0
    seed: int = 0
    domain_id: int | None = None
    known_failures: str | None = None
    fault_speed: float | None = None  # m/s: a contact with a person below it is not charged (None: the default)
    early_verdicts: bool = False
    map_upsample: int = 5
    start_timeout: float = 120.0  # s the adapter waits for the stack (external: for you to start it)
    ready_timeout: float = 300.0  # s for the stack's nodes to come up
    max_errors: int = 3
    extra_env: dict[str, str] = field(default_factory=dict)


def utc_stamp() -> str:
    return datetime.now(timezone.utc).strftime("%Y%m%dT%H%M%SZ")


def _number(value: Any) -> float | None:
    try:
        out = float(value)
    except (TypeError, ValueError):
        return None
    return out if math.isfinite(out) else None


def row_of(outcome: Any, entry: Entry, suite: Suite, prepared: Prepared, settings: TrialSettings, repeat: int,
           run_id: str, sid: int, bag: Path, wall: float, started_ns: int) -> dict:
    """One run as a row of the results file (see ``rows``)."""
    import numpy as np

    from ..core.runs import versions
    from ..sims.obstacles import contact_speeds

    m = outcome.metrics or {}
    traj = outcome.trajectory
    return {
        **prepared.record(), "stack": settings.stack, "time_scale": settings.time_scale, "seed": settings.seed,
        "scenario_name": entry.name, "key": entry.key, "repeat": repeat, "scenario": entry.scenario,
        "problem": suite.problem, "problem_config": suite.problem_config,
        "verdict": outcome.verdict, "failure_kind": outcome.failure_kind, "failed": bool(outcome.failed),
        "detail": outcome.detail, "known_failure": m.get("known_failure") or None,
        "time_s": _number(m.get("time")), "recoveries": _number(m.get("nav2_recoveries")),
        "nav2_status": m.get("nav2_status"), "nav2_error_code": _number(m.get("nav2_error_code")),
        "nav2_error_msg": m.get("nav2_error_msg"), "early_verdict": m.get("early_verdict"),
        "contact": contact_speeds(outcome.detail) if outcome.failed else None,
        "contacts_not_at_fault": _number(m.get("contacts_not_at_fault")),
        "reference_check": m.get("reference_check"),
        "failure_point": list(outcome.failure_point) if outcome.failure_point is not None else None,
        "trajectory_every_10": np.asarray(traj)[::10, :2].round(3).tolist() if traj is not None and len(traj) else None,
        "metrics": {str(k): v if isinstance(v, (str, int, float, bool)) or v is None else str(v) for k, v in m.items()},
        "wall_s": round(wall, 2), "run_id": run_id, "scenario_id": sid, "bag": str(bag),
        "wall_start_ns": started_ns, "wall_end_ns": time.time_ns(),
        "when": datetime.now(timezone.utc).isoformat(timespec="seconds"), "versions": versions(),
        "command": sys.argv,
    }


class SuiteDriver:
    """Publishes scenarios as the generator does and takes every result; answers a lost one with a
    published ``sim_timeout`` result, so the log accounts for every scenario it sent."""

    def __init__(self, node: Any, problem: Any):
        from ..ros import conversions, topics
        from ..ros.qos import LATCHED, STREAM

        self.node, self.problem, self.conv, self.topics = node, problem, conversions, topics
        self.pub = node.create_publisher(topics.SCENARIO_TYPES[problem.name], topics.scenarios(problem.name), STREAM)
        self.pub_results = node.create_publisher(topics.RESULT_TYPE, topics.RESULTS, STREAM)
        self.pub_config = node.create_publisher(topics.RUN_CONFIG_TYPE, topics.RUN_CONFIG, LATCHED)
        self.results: dict[tuple[str, int], Any] = {}
        self.workers: dict[tuple[str, int], str] = {}
        node.create_subscription(topics.RESULT_TYPE, topics.RESULTS, self.on_result, STREAM)

    def on_result(self, msg: Any) -> None:
        key = (msg.run_id, int(msg.scenario_id))
        self.results.setdefault(key, self.conv.outcome_from_message(msg))
        self.workers.setdefault(key, msg.worker)

    def announce(self, run_id: str, config: dict) -> None:
        """The run's configuration on ``/ambiegen/run_config`` (latched): the bag says what ran."""
        from .. import __version__

        self.pub_config.publish(self.conv.run_config_message(self.node.new_message, self.node.now_ns(), run_id, config,
                                                             __version__))

    def wait_matched(self, count: int, timeout: float) -> bool:
        return self.node.spin_until(lambda: self.pub.subscription_count() >= count, timeout)

    def send(self, run_id: str, sid: int, scenario: Any, seed: int = 0) -> None:
        meta = self.conv.ScenarioMeta(run_id, sid, seed=seed)
        self.pub.publish(self.conv.scenario_message(self.node.new_message, self.node.now_ns(), self.problem, scenario,
                                                    meta))

    def wait(self, run_id: str, sid: int, timeout: float, stop: Callable[[], bool] = lambda: False) -> Any:
        self.node.spin_until(lambda: (run_id, sid) in self.results or stop(), timeout)
        return self.results.get((run_id, sid))

    def lost(self, run_id: str, sid: int, detail: str) -> Any:
        """Record a scenario that got no answer: a ``sim_timeout`` result, published (and so logged)."""
        from ..sims.outcome import Outcome

        outcome = Outcome.rejected(detail, kind="sim_timeout")
        self.pub_results.publish(self.conv.result_message(self.node.new_message, self.node.now_ns(), run_id, sid,
                                                          self.problem.name, "ambiegen_trials", outcome))
        self.results[(run_id, sid)] = outcome
        return outcome


def stack_nodes(settings: TrialSettings, prepared: Prepared, problem_file: Path, bag: Path, tag: str) -> list:
    """The node set of one configuration: recorder, world, stack, adapter (``launch_logic.NodeSpec``)."""
    from ..campaign import STACK_TOPICS
    from ..launch_logic import NAV2_TOPICS, NodeSpec, nav2_stack, nd_stack

    files = [str(prepared.path)] if prepared.path else []
    nav2 = settings.stack in NAV2_STACKS
    recorder = NodeSpec("recorder", "recorder", {"output": str(bag),
                                                 "extra_topics": ",".join(NAV2_TOPICS if nav2 else STACK_TOPICS)})
    if nav2:
        start = 600.0 if settings.stack == "external" else settings.start_timeout
        nodes = nav2_stack("", settings.stack, prepared.params, prepared.path, settings.seed, tag, settings.time_scale,
                           settings.map_upsample, start, settings.early_verdicts, prepared.speed, str(problem_file), "")
        if settings.known_failures:
            nodes[-1].parameters["known_failures"] = settings.known_failures
    else:
        nodes = nd_stack(settings.seed, tag, None, str(problem_file))
    for node in nodes:
        if node.package == "ambiegen_ros":
            node.params_files = files + [f for f in node.params_files if f not in files]
        if node.executable == "robot_world" and settings.fault_speed is not None:
            node.parameters["sim.contact_fault_speed"] = settings.fault_speed
        if node.executable == "sut_adapter":
            node.parameters["min_result_subscribers"] = 2  # the runner and the recorder
            if settings.fault_speed is not None:
                node.parameters["oracle.contact_fault_speed"] = settings.fault_speed
    return [recorder, *nodes]


class StackSession:
    """One configuration's processes and the in-process driver, for as long as its runs last."""

    def __init__(self, settings: TrialSettings, suite: Suite, prepared: Prepared, say: Callable[[str], None]):
        import yaml

        from ..campaign import ProcessGroup, discovery_scope, node_argv
        from ..ros.transport import create_node

        self.settings, self.suite, self.prepared, self.say = settings, suite, prepared, say
        self.dir = Path(settings.bags) / f"{prepared.config.label}_{utc_stamp()}"
        self.dir.mkdir(parents=True, exist_ok=False)
        self.bag = self.dir / "trials.mcap"
        problem_file = self.dir / "problem.yaml"
        problem_file.write_text(yaml.safe_dump({"problem": suite.problem, "problem_config": suite.problem_config}))
        self.run_id = f"trials-{prepared.config.label}-{self.dir.name[-16:]}"
        env = dict(os.environ, PYTHONUNBUFFERED="1", **settings.extra_env)
        if settings.domain_id is not None:
            env["ROS_DOMAIN_ID"] = str(settings.domain_id)
        env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = discovery_scope(None, env)
        self.env = env
        self.group = ProcessGroup(self.dir / "logs", env)
        for node in stack_nodes(settings, prepared, problem_file, self.bag, self.run_id[-6:]):
            self.group.start_argv(node.name, node_argv(node))
        if settings.stack == "bringup":
            self.group.start_argv("nav2", ["ros2", "launch", "nav2_bringup", "navigation_launch.py", "use_sim_time:=true",
                                           "autostart:=true", "use_composition:=False",
                                           f"params_file:={prepared.path}"])
        elif settings.stack == "external":
            say(f"start your Nav2 now, in ROS domain {env.get('ROS_DOMAIN_ID', '0')}: ros2 launch nav2_bringup "
                f"navigation_launch.py use_sim_time:=true params_file:={prepared.path}")
        for key in ("ROS_DOMAIN_ID", "ROS_AUTOMATIC_DISCOVERY_RANGE"):  # the driver joins the same graph
            if key in env:
                os.environ[key] = env[key]
        self.node = create_node("ambiegen_trials", argv=[])
        self.problem = problem_of(suite)
        self.driver = SuiteDriver(self.node, self.problem)
        self.driver.announce(self.run_id, {"trials": prepared.record(), "stack": settings.stack,
                                           "problem": suite.problem, "problem_config": suite.problem_config,
                                           "suite": suite.sources, "repeat": settings.repeat,
                                           "seed": settings.seed, "time_scale": settings.time_scale,
                                           "command": sys.argv})
        self.sid = 0

    def ready(self) -> bool:
        """The adapter and the recorder take scenarios (a bound, not a wait: it ends once they match)."""
        return self.driver.wait_matched(2, self.settings.ready_timeout)

    def died(self) -> str | None:
        """A node of ours or the stack's launch that has exited, named, else None."""
        for name, proc in self.group.procs.items():
            if proc.poll() is not None:
                return f"{name} exited with {proc.returncode} (log: {self.dir / 'logs' / (name + '.log')})"
        return None

    def limit(self, entry: Entry) -> float:
        """Wall seconds the runner waits for an answer: twice the oracle's time limit for the route at
        the stack's speed, over the time scale, plus the adapter's start and our slack."""
        from ..sims.robot import RobotSimConfig

        scenario = self.problem.parse(entry.scenario)
        route = float(self.problem.evaluate_scenarios([scenario]).metrics["path_length"][0])
        route = route if math.isfinite(route) and route > 0 else 100.0
        k = self.settings.time_scale if self.settings.stack in NAV2_STACKS else 1.0
        start = 600.0 if self.settings.stack == "external" else self.settings.start_timeout
        return 2 * RobotSimConfig().time_limit(route, self.prepared.speed) / k + start + RESULT_SLACK_S

    def run(self, entry: Entry) -> tuple[Any, int, float, int]:
        """(outcome, scenario id, wall seconds, wall start ns) of one run; a lost one is recorded as such."""
        sid, self.sid = self.sid, self.sid + 1
        scenario = self.problem.parse(entry.scenario)
        t0, w0 = time.monotonic(), time.time_ns()
        self.driver.send(self.run_id, sid, scenario, self.settings.seed)
        limit = self.limit(entry)
        outcome = self.driver.wait(self.run_id, sid, limit, stop=lambda: self.died() is not None)
        if outcome is None:
            why = self.died() or f"no answer within {limit:.0f} s"
            outcome = self.driver.lost(self.run_id, sid, f"the runner got no result: {why}")
            self.node.spin_until(lambda: False, 0.5)  # the recorder takes it
        return outcome, sid, time.monotonic() - t0, w0

    def close(self) -> None:
        self.node.spin_until(lambda: False, 0.3)  # the last result reaches the recorder
        try:
            self.node.shutdown()
        finally:
            order = [n for n in self.group.procs if n != "recorder"] + ["recorder"]
            self.group.stop(order, timeout=30.0)


def run_trials(suite: Suite, prepared: list[Prepared], settings: TrialSettings,
               say: Callable[[str], None] = print) -> dict[str, int]:
    """Every configuration's missing runs, appended to the results file as they finish. Returns the
    runs made per label. ``KeyboardInterrupt`` stops the stack and is raised again."""
    log = TrialLog(settings.results)
    for p in prepared:
        log.check_label(p.config.label, p.digest)
    plans = []
    for p in prepared:
        done = log.done(p.config.label)
        todo = [(r, e) for r in range(1, settings.repeat + 1) for e in suite.entries if done[e.key] < r]
        plans.append((p, todo))
    total = sum(len(t) for _, t in plans)
    say(f"{len(suite.entries)} scenarios x {settings.repeat} runs x {len(prepared)} configuration"
        f"{'s' * (len(prepared) != 1)}: {total} runs to make"
        + (f" ({sum(len(suite.entries) * settings.repeat for _ in prepared) - total} already in {settings.results})"
           if total < len(suite.entries) * settings.repeat * len(prepared) else ""))
    made: dict[str, int] = {}
    count, t_start = 0, time.monotonic()
    for p, todo in plans:
        if not todo:
            continue
        label = p.config.label
        session = StackSession(settings, suite, p, say)
        say(f"[{label}] stack {settings.stack}, params {p.path or '(defaults)'}; bag {session.bag}")
        errors = 0
        try:
            if not session.ready():
                raise StackStopped(f"[{label}] the stack's nodes did not come up in {settings.ready_timeout:.0f} s "
                               f"(logs: {session.dir / 'logs'})")
            done = log.done(label)
            for _, entry in todo:
                repeat = done[entry.key] + 1
                outcome, sid, wall, w0 = session.run(entry)
                row = row_of(outcome, entry, suite, p, settings, repeat, session.run_id, sid, session.bag, wall, w0)
                log.append(row)
                count += 1
                made[label] = made.get(label, 0) + 1
                if counted(row):
                    done[entry.key] += 1
                    errors = 0
                else:
                    errors += 1
                eta = (time.monotonic() - t_start) / count * (total - count)
                say(f"[{count}/{total}] {label} {entry.name} run {repeat}/{settings.repeat}: {outcome.verdict[:90]}"
                    + (f" ({outcome.detail[:120]})" if outcome.failed or not counted(row) else "")
                    + f"  {wall:.0f} s" + (f", about {eta / 60:.0f} min left" if count < total else ""))
                if errors >= settings.max_errors:
                    raise StackStopped(f"[{label}] {errors} errors in a row, the last: {outcome.detail[:200]} "
                                   f"(logs: {session.dir / 'logs'}); rerun the same command to resume")
        finally:
            session.close()
    return made


__all__ = ["StackSession", "StackStopped", "SuiteDriver", "TrialSettings", "row_of", "run_trials", "stack_nodes"]
