"""One configuration's stack, started, watched and kept alive for as long as its runs last.

The session starts what a campaign starts (``launch_logic``: ``robot_world`` + the stack +
``sut_adapter``, or our ND stack) and a recorder, each as a process of its own, and sends the
scenarios from a node in this process (``SuiteDriver``, as the generator does). While a run is on,
it watches every process (``supervise.Watch``): one that exits, is killed or is stopped is an event
on ``/ambiegen/stack_events``, which the adapter turns into the run's end (the stack's:
FAIL(sut_crashed), certified as any failure; ours: an error record), and so does a stack that hung
while the run is on: a node of it not scheduled for ``hang_after`` s, or every sign of life it shows
on the graph (``/cmd_vel``, its navigator's action feedback and goal status) silent that long; a
robot held still by its own safety layer is no hang (docs/choices.md, "A held robot is not a hung
stack"). After the run the session restarts what died (the whole stack for a stack's process: a
fresh stack; the part alone for one of ours; the recorder into a new file, the old one recovered)
and says how long it took. Faults can be injected on a run's events (``faults``). Nothing here
decides verdicts: the adapter does.
"""
from __future__ import annotations

import json
import math
import os
import signal
import sys
import time
from pathlib import Path
from typing import Any, Callable

from ..ros.qos import Qos
from .configs import NAV2_STACKS, Prepared
from .faults import Injector
from .rows import utc_stamp
from .suite import Entry, Suite, problem_of
from .supervise import SCHEDULED_FLOOR_S, Death, Scheduling, Watch, core_shares, cpu_by_part

STOP_SIGNALS = (signal.SIGSTOP, signal.SIGTSTP, signal.SIGCONT)  # a hang, not a death

RESULT_SLACK_S = 60.0  # beyond the adapter's own guard, before the runner calls a scenario lost
MOVING_MPS = 0.05  # a run's robot moves once its odometry says this fast (injected faults wait for it)
NEAR_START_M = 1.0  # ... and puts it this near the run's start: the last run's robot, still driving to its
# goal when the next scenario goes out (a late odometry on a loaded machine), is not this run's
DISCOVERY_S = 2.0  # a new participant has heard the others on the domain by then (SPDP on one host)
GONE_TIMEOUT_S = 60.0  # a killed part's endpoints leave the graph within its lease (DDS: about 10 s)
# a stack's signs of life on the graph (``_hangs``): its commands, its navigator's feedback and goal states
SIGNS = ("/cmd_vel", "/navigate_to_pose/_action/feedback", "/navigate_to_pose/_action/status")
SIGN_QOS = Qos(reliable=False, transient_local=False, depth=10)  # best effort: matches any writer


def last_words(log: Path, width: int = 300) -> str:
    """The last non-empty line of a process's log (where a node says why it stopped)."""
    try:
        lines = [line.strip() for line in log.read_text(errors="replace").splitlines() if line.strip()]
    except OSError:
        return "(no log)"
    return lines[-1][:width] if lines else "(an empty log)"


class StackStopped(Exception):
    """The runs of a configuration stopped: the stack did not come up or back, or kept failing to answer."""


class SuiteDriver:
    """Publishes scenarios as the generator does and takes every result; answers a lost one with a
    published result of its own (``sim_timeout``, or ``error`` naming a part of ours that died), so
    the log accounts for every scenario it sent.

    A scenario can be lost on the wire: a reliable volatile reader that has not finished its side of
    discovery drops what a writer already matched to it sends. While a result is awaited, a
    scenario that every worker's heartbeat, taken ``RESEND_AFTER_S`` after it went out, shows idle
    goes again (``RESENDS`` times at most); the adapter answers one it has run from its record, and
    never runs a scenario twice."""

    RESEND_AFTER_S = 3.0
    RESENDS = 3

    def __init__(self, node: Any, problem: Any):
        from ..ros import conversions, topics
        from ..ros.qos import DEFAULT, LATCHED, STREAM

        self.node, self.problem, self.conv, self.topics = node, problem, conversions, topics
        self.pub = node.create_publisher(topics.SCENARIO_TYPES[problem.name], topics.scenarios(problem.name), STREAM)
        self.pub_results = node.create_publisher(topics.RESULT_TYPE, topics.RESULTS, STREAM)
        self.pub_config = node.create_publisher(topics.RUN_CONFIG_TYPE, topics.RUN_CONFIG, LATCHED)
        self.results: dict[tuple[str, int], Any] = {}
        self.workers: dict[tuple[str, int], str] = {}
        self.sent: dict[tuple[str, int], list] = {}  # awaited: [message, monotonic time sent, times sent]
        self.beats: dict[str, tuple[float, bool]] = {}  # worker -> (monotonic time heard, idle)
        self.resent = 0
        node.create_subscription(topics.RESULT_TYPE, topics.RESULTS, self.on_result, STREAM)
        node.create_subscription(topics.WORKERS_TYPE, topics.WORKERS, self.on_beat, DEFAULT)

    def on_result(self, msg: Any) -> None:
        key = (msg.run_id, int(msg.scenario_id))
        self.results.setdefault(key, self.conv.outcome_from_message(msg))
        self.workers.setdefault(key, msg.worker)
        self.sent.pop(key, None)

    def on_beat(self, msg: Any) -> None:
        if msg.hardware_id == self.problem.name:
            self.beats[msg.name] = (time.monotonic(), msg.message == "idle")

    def announce(self, run_id: str, config: dict) -> None:
        """The run's configuration on ``/ambiegen/run_config`` (latched): the bag says what ran."""
        from .. import __version__

        self.pub_config.publish(self.conv.run_config_message(self.node.new_message, self.node.now_ns(), run_id, config,
                                                             __version__))

    def wait_matched(self, count: int, timeout: float, stop: Callable[[], bool] = lambda: False) -> bool:
        return self.node.spin_until(lambda: self.pub.subscription_count() >= count or stop(), timeout) \
            and self.pub.subscription_count() >= count

    def send(self, run_id: str, sid: int, scenario: Any, seed: int = 0) -> None:
        meta = self.conv.ScenarioMeta(run_id, sid, seed=seed)
        msg = self.conv.scenario_message(self.node.new_message, self.node.now_ns(), self.problem, scenario, meta)
        self.sent[(run_id, sid)] = [msg, time.monotonic(), 1]
        self.pub.publish(msg)

    def resend_lost(self) -> bool:
        """Send again what every worker, heard since, shows it does not hold (always False: a
        ``spin_until`` condition that acts)."""
        now = time.monotonic()
        for key, entry in list(self.sent.items()):
            msg, at, times = entry
            heard = [idle for t, idle in self.beats.values() if t > at + self.RESEND_AFTER_S]
            if times <= self.RESENDS and heard and all(heard) and now - at > self.RESEND_AFTER_S:
                self.node.logger.warning(f"scenario {key[1]} of run {key[0]}: no result, and no worker holds it "
                                         f"{now - at:.1f} s after it went out: sent again")
                entry[1], entry[2] = now, times + 1
                self.resent += 1
                self.pub.publish(msg)
        return False

    def wait(self, run_id: str, sid: int, timeout: float, stop: Callable[[], bool] = lambda: False) -> Any:
        self.node.spin_until(lambda: self.resend_lost() or (run_id, sid) in self.results or stop(), timeout)
        return self.results.get((run_id, sid))

    def lost(self, run_id: str, sid: int, detail: str, kind: str = "sim_timeout") -> Any:
        """Record a scenario that got no answer: a result of ours, published (and so logged)."""
        from ..sims.outcome import Outcome

        outcome = Outcome.rejected(detail, kind=kind)
        self.pub_results.publish(self.conv.result_message(self.node.new_message, self.node.now_ns(), run_id, sid,
                                                          self.problem.name, "ambiegen_trials", outcome))
        self.results[(run_id, sid)] = outcome
        self.sent.pop((run_id, sid), None)
        return outcome


def lean_parts(settings: Any) -> tuple[str, ...]:
    """Our parts that run on ``settings.our_transport`` (dds: no rclpy executor, whose Python wait
    set cost each part hundreds of microseconds a message; docs/speed.md): the world, the recorder
    and the adapter, which speaks rmw_cyclonedds_cpp's services to Nav2's action."""
    if not settings.our_transport:
        return ()
    return ("robot_world", "recorder", "sut_adapter")


def cell_metres(problem_file: Path) -> float:
    """The scenario's cell size: ``problem_config.resolution`` of the session's problem file (1 m
    when it says none, or there is none)."""
    import yaml

    try:
        config = yaml.safe_load(problem_file.read_text()) or {}
    except OSError:
        return 1.0
    return float((config.get("problem_config") or {}).get("resolution", 1.0))


def planner_upsample(params: dict, settings: Any, cell_m: float = 1.0) -> int:
    """Map cells per scenario cell (``cell_m`` metres) for a planner stack: the map at the global
    costmap's own ``resolution`` (Jazzy's 0.05 m: 20 per 1 m cell, 5 per 0.25 m cell), as a real map
    server gives it; without one, ``settings.map_upsample``."""
    costmap = (((params.get("global_costmap") or {}).get("global_costmap") or {}).get("ros__parameters")) or {}
    try:
        k = round(float(cell_m) / float(costmap["resolution"]))
    except (KeyError, TypeError, ValueError, ZeroDivisionError):
        return settings.map_upsample
    return k if k >= 1 else settings.map_upsample


def stack_nodes(settings: Any, prepared: Prepared, problem_file: Path, bag: Path, tag: str) -> list:
    """The node set of one configuration: recorder, world, stack, adapter (``launch_logic.NodeSpec``)."""
    from ..campaign import STACK_TOPICS
    from ..launch_logic import NAV2_TOPICS, PLANNER_TOPICS, NodeSpec, nav2_stack, nd_stack, planner_stack
    from ..ros import topics

    files = [str(prepared.path)] if prepared.path else []
    nav2 = settings.stack in NAV2_STACKS
    planner = settings.stack == "planner"  # Nav2's planner_server alone, asked by the adapter (issue 68)
    recorded = (PLANNER_TOPICS if planner else NAV2_TOPICS if nav2 else STACK_TOPICS) + (topics.STACK_EVENTS,)
    recorder = NodeSpec("recorder", "recorder", {"output": str(bag), "extra_topics": ",".join(recorded)})
    if planner:
        try:
            nodes = planner_stack(prepared.params, prepared.path, tag, planner_upsample(prepared.params, settings, cell_metres(problem_file)),
                                  settings.start_timeout, str(problem_file), "")
        except ValueError as exc:
            from ..core.errors import BadInput

            raise BadInput(f"--params {prepared.config.label}: {exc}") from None
    elif nav2:
        start = settings.start_timeout  # the user's, or the stack's default (``TrialSettings``)
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
        if node.executable in ("robot_world", "sut_adapter") and getattr(settings, "robot", ""):
            node.parameters["robot_profile"] = settings.robot  # the world drives it, the adapter judges it
        if node.executable == "sut_adapter":
            node.parameters["min_result_subscribers"] = 2  # the runner and the recorder
            if settings.fault_speed is not None:
                node.parameters["oracle.contact_fault_speed"] = settings.fault_speed
    return [recorder, *nodes]


class StackSession:
    """One configuration's processes and the in-process driver, for as long as its runs last."""

    def __init__(self, settings: Any, suite: Suite, prepared: Prepared, say: Callable[[str], None],
                 injector: Injector | None = None):
        """Start it all. A failure part way stops what had started (processes, the driver's node)
        before the error goes on: a caller that got no session has nothing to close."""
        try:
            self._open(settings, suite, prepared, say, injector)
        except BaseException:
            self._abandon()
            raise

    def __enter__(self) -> StackSession:
        return self

    def __exit__(self, *_exc: Any) -> None:
        self.close()

    def _abandon(self) -> None:
        """What a constructor that failed had started: the node shut down, every process stopped."""
        node, group = getattr(self, "node", None), getattr(self, "group", None)
        try:
            if node is not None:
                node.shutdown()
        finally:
            if group is not None:
                group.stop(timeout=30.0)

    def _open(self, settings: Any, suite: Suite, prepared: Prepared, say: Callable[[str], None],
              injector: Injector | None) -> None:
        import yaml

        from ..campaign import ProcessGroup, discovery_scope, node_argv
        from ..ros import topics
        from ..ros.qos import STREAM
        from ..ros.transport import ENV_VAR, create_node

        self.settings, self.suite, self.prepared, self.say = settings, suite, prepared, say
        self.injector = injector or Injector([], say)
        self.dir = Path(settings.bags) / f"{prepared.config.label}_{utc_stamp()}"
        self.dir.mkdir(parents=True, exist_ok=False)
        self.bag = self.dir / "trials.mcap"
        self.bags = [self.bag]
        problem_file = self.dir / "problem.yaml"
        problem_file.write_text(yaml.safe_dump({"problem": suite.problem, "problem_config": suite.problem_config}))
        self.run_id = f"trials-{prepared.config.label}-{self.dir.name[-16:]}"
        env = dict(os.environ, PYTHONUNBUFFERED="1", **settings.extra_env)
        if settings.domain_id is not None:
            env["ROS_DOMAIN_ID"] = str(settings.domain_id)
        env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = discovery_scope(None, env)
        self.group = ProcessGroup(self.dir / "logs", env, {name: {ENV_VAR: settings.our_transport}
                                                           for name in lean_parts(settings)})
        self.argv: dict[str, list[str]] = {}
        self.nodes = stack_nodes(settings, prepared, problem_file, self.bag, self.run_id[-6:])
        for node in self.nodes:
            self.argv[node.name] = node_argv(node)
        if settings.stack == "bringup":
            self.argv["nav2"] = ["ros2", "launch", "nav2_bringup", "navigation_launch.py", "use_sim_time:=true",
                                 "autostart:=true", "use_composition:=False", f"params_file:={prepared.path}"]
        if settings.stack == "external":
            say(f"start your Nav2 now, in ROS domain {env.get('ROS_DOMAIN_ID', '0')}: ros2 launch nav2_bringup "
                f"navigation_launch.py use_sim_time:=true params_file:={prepared.path}")
        self.stack_parts = [n for n in self.argv if n not in ("recorder", "robot_world", "sut_adapter")]
        self.watch = Watch(self.group)
        for key in ("ROS_DOMAIN_ID", "ROS_AUTOMATIC_DISCOVERY_RANGE"):  # the driver joins the same graph
            if key in env:
                os.environ[key] = env[key]
        self.node = create_node("ambiegen_trials", argv=[])
        self.problem = problem_of(suite)
        self.driver = SuiteDriver(self.node, self.problem)
        self._clean_graph(env.get("ROS_DOMAIN_ID", "0"))
        for name, argv in self.argv.items():
            self.group.start_argv(name, argv)
        self.pub_events = self.node.create_publisher(topics.STACK_EVENTS_TYPE, topics.STACK_EVENTS, STREAM)
        if self.injector.faults:  # when a run's robot moves: only injected faults wait for it (50 Hz of odometry)
            self.node.create_subscription("nav_msgs/msg/Odometry", "/odom", self._on_odom, STREAM)
        self.alive_at = time.monotonic()  # the stack's last sign of life on the graph (``_watch_signs``)
        self.signs: dict[str, Any] = {}  # topic -> our subscription to it
        self.unreadable: set[str] = set()  # offered signs of a type this node cannot read
        self.scheduling = Scheduling()
        self.driver.announce(self.run_id, {"trials": prepared.record(), "stack": settings.stack,
                                           "problem": suite.problem, "problem_config": suite.problem_config,
                                           "suite": suite.sources, "repeat": settings.repeat,
                                           "seed": settings.seed, "time_scale": settings.time_scale,
                                           "command": sys.argv})
        self.sid = 0
        self.in_flight = False
        self.moved_at: float | None = None
        self.run_start: tuple[float, float] | None = None  # the run's start (m), where its robot moves from
        self.run_no = 0
        self.deaths: list[Death] = []  # of the run in flight
        self.signalled: list = []  # faults injected during the run in flight (their deaths belong to it)
        self._next_pulse = 0.0
        self.hung_said = False
        self.unlogged: list[tuple[int, Any]] = []  # results no recorder heard (it was dead): logged again
        self.cpu: dict[str, float | None] = {}  # the last run's cores: ours (world, adapter, recorder), the stack's

    # --- watching -------------------------------------------------------------------------------
    def _on_odom(self, msg: Any) -> None:
        if self.in_flight and self.moved_at is None and abs(float(msg.twist.twist.linear.x)) > MOVING_MPS:
            at = msg.pose.pose.position
            if self.run_start is None or math.dist((float(at.x), float(at.y)), self.run_start) <= NEAR_START_M:
                self.moved_at = time.monotonic()

    def _on_sign(self, _data: Any, _receive_ns: int = 0) -> None:
        self.alive_at = time.monotonic()

    def _watch_signs(self) -> None:
        """Subscribe to each sign of life (``SIGNS``) once the stack offers it, by the type offered,
        undecoded: any sample is enough."""
        for topic in SIGNS:
            if topic in self.signs:
                continue
            offered = self.node.publishers_info(topic)
            if not offered or topic in self.unreadable:
                continue
            try:
                if self._can_read(offered[0].typename):
                    self.signs[topic] = self.node.create_subscription(offered[0].typename, topic, self._on_sign,
                                                                      SIGN_QOS, raw=True)
                    continue
            except Exception as exc:  # noqa: BLE001 - a type this node cannot load: a sign it cannot read
                self.say(f"[{self.prepared.config.label}] {topic} ({offered[0].typename}) not read as a sign of "
                         f"life: {exc}")
            self.unreadable.add(topic)

    def _can_read(self, typename: str) -> bool:
        """The DDS backend knows an action's wire types from ``ros.interfaces`` once told (rclpy knows
        what is installed); a type known to neither is no sign we can read."""
        registry = getattr(self.node, "_registry", None)
        if registry is None or registry.has(typename):
            return True
        from ..ros import interfaces

        action = typename.rsplit("_", 1)[0]
        if action in interfaces.ACTIONS:
            interfaces.ensure(registry, action)
            return True
        return False

    def _hangs(self, now: float) -> list[Death]:
        """The stack hung: a node of it not scheduled for ``hang_after`` s, whatever the topics say;
        or, once it showed a sign of life in this run, every sign it shows silent that long (a robot
        held still by a collision monitor, whose commands stop, is no hang while its navigator's
        feedback goes on; a stack silent before its first sign, as Nav2 is until its goal, has not
        started: the adapter's start timeout guards that)."""
        after = self.settings.hang_after
        if after <= 0:
            return []
        out = self.scheduling.poll(self.group, self.sent_at, max(after, SCHEDULED_FLOOR_S), now)
        quiet = now - max(self.alive_at, self.sent_at)
        if self.signs and self.alive_at > self.sent_at and not self.hung_said and quiet > after:
            self.hung_said = True
            out.append(Death("the stack", "stack", f"went silent (hung: nothing on {', '.join(sorted(self.signs))} for "
                                                   f"{quiet:.0f} s)", "signs of life"))
        return out

    def event(self, death: Death) -> None:
        """Say it, log it (``events.jsonl`` beside the bag), publish it for the adapter and the bag."""
        from ..ros import conversions

        self.say(f"[{self.prepared.config.label}] {death.part}: {death.words()}"
                 + (f" (run {self.run_no})" if self.in_flight else ""))
        self.pub_events.publish(conversions.stack_event(self.node.new_message, self.node.now_ns(), death.process,
                                                        death.part, death.what))
        self.log_event({"event": "death", "process": death.process, "part": death.part, "what": death.what,
                        "group": death.group, "run": self.run_no if self.in_flight else None})

    def log_event(self, record: dict) -> None:
        with open(self.dir / "events.jsonl", "a") as fh:
            fh.write(json.dumps({"when": time.time(), **record}) + "\n")

    def pulse(self) -> None:
        """Five times a second while waiting: deaths and hangs, and the injected faults due."""
        now = time.monotonic()
        if now < self._next_pulse:
            return
        self._next_pulse = now + 0.2
        self._take_deaths()
        if self.in_flight:
            self.signalled += self.injector.tick(self.group, self.run_no, self.moved_at)
            self._watch_signs()
            for death in self._hangs(now):
                self.event(death)
                self.deaths.append(death)

    def _clean_graph(self, domain: str) -> None:
        """Nothing else on the domain takes scenarios before our adapter and recorder start: a scenario
        would reach the other one, not ours. The remains of a killed session leave with their lease
        (about 10 s, waited for); a live session stays, and then the command stops with one line."""
        taken = self.driver.pub.subscription_count
        self.node.spin_until(lambda: taken() > 0, DISCOVERY_S)  # what is there shows up by then
        if taken() == 0:
            return
        self.say(f"[{self.prepared.config.label}] waiting for {taken()} reader(s) of scenarios on ROS domain {domain} "
                 f"to leave (another session's adapter or recorder, or what remains of a killed one)")
        if self.node.spin_until(lambda: taken() == 0, GONE_TIMEOUT_S):
            return
        self._interrupted()
        readers = taken()  # counted before the node goes: its writer goes with it
        self.node.shutdown()
        raise StackStopped(f"[{self.prepared.config.label}] {readers} reader(s) of another session take scenarios "
                           f"on ROS domain {domain} (an adapter or recorder still running?): stop it, or give this "
                           f"command its own --domain-id")

    # --- the runs ---------------------------------------------------------------------------------
    def ready(self) -> bool:
        """The adapter and the recorder take scenarios (a bound, not a wait: it ends once they match).
        A process that dies meanwhile stops the configuration at once, with its last words (a node
        that refuses its parameters says why in one line; waiting out the bound would hide it)."""
        dead: list[Death] = []

        def died() -> bool:
            dead.extend(self.watch.poll())
            return bool(dead)

        if self.driver.wait_matched(2, self.settings.ready_timeout, stop=died):
            return True
        self._interrupted()
        if not dead:
            return False
        for death in dead:
            self.event(death)
        first = dead[0]
        raise StackStopped(f"[{self.prepared.config.label}] {first.words()} while the stack came up: "
                           f"{last_words(self.dir / 'logs' / f'{first.group}.log')!r} (logs: {self.dir / 'logs'})")

    def limit(self, entry: Entry) -> float:
        """Wall seconds the runner waits for an answer: twice the oracle's time limit for the route at
        the stack's speed, over the time scale, plus the adapter's start and our slack."""
        from ..sims.robot import RobotSimConfig

        scenario = self.problem.parse(entry.scenario)
        route = float(self.problem.evaluate_scenarios([scenario]).metrics["path_length"][0])
        route = route if math.isfinite(route) and route > 0 else 100.0
        k = self.settings.time_scale if self.settings.stack in NAV2_STACKS else 1.0
        start = self.settings.start_timeout  # the user's, or the stack's default (``TrialSettings``)
        return 2 * RobotSimConfig().time_limit(route, self.prepared.speed) / k + start + RESULT_SLACK_S

    def _interrupted(self) -> None:
        """A Ctrl-C (or SIGTERM) stops the node's spinning: the wait that ended is no lost run, and no
        stack that failed to come up; the command stops (the runs made so far are in the results)."""
        if not self.node.ok():
            raise KeyboardInterrupt

    def _start_of(self, scenario: Any) -> tuple[float, float] | None:
        """The robot's start (m) in a robot scenario, for the faults' trigger (None: no such start)."""
        try:
            start = self.problem.environment(scenario).start_m
        except (AttributeError, ValueError):
            return None
        return (float(start[0]), float(start[1])) if start is not None else None

    def _adapter_gone(self) -> bool:
        return any(d.process == "sut_adapter" for d in self.deaths)

    def run(self, entry: Entry, run_no: int) -> tuple[Any, int, float, int, list[Death]]:
        """(outcome, scenario id, wall seconds, wall start ns, deaths during it) of one run. A run whose
        adapter or recorder died is an error record of ours (the adapter's own answer, if any, is not
        what the log holds); a lost one is recorded as such."""
        sid, self.sid = self.sid, self.sid + 1
        scenario = self.problem.parse(entry.scenario)
        self.run_no, self.deaths, self.moved_at, self.hung_said = run_no, [], None, False
        self.run_start = self._start_of(scenario) if self.injector.faults else None
        self.signalled = []
        t0, w0 = time.monotonic(), time.time_ns()
        self.sent_at = t0
        self.in_flight = True
        self.driver.send(self.run_id, sid, scenario, self.settings.seed)
        limit = self.limit(entry)

        def done() -> bool:
            self.pulse()
            return self._adapter_gone()

        cpu0 = cpu_by_part(self.group)
        try:
            outcome = self.driver.wait(self.run_id, sid, limit, stop=done)
            self._interrupted()
            self.cpu = core_shares(cpu0, cpu_by_part(self.group), time.monotonic() - t0)
            self._see_signalled_deaths()
            ours = [d for d in self.deaths if d.part == "ours"]
            if outcome is None:
                if ours:
                    outcome = self.driver.lost(self.run_id, sid, f"{ours[0].words()} (ours, not the stack's failure): "
                                                                 "run it again", kind="error")
                else:
                    outcome = self.driver.lost(self.run_id, sid, f"the runner got no result in {limit:.0f} s")
            elif any(d.process == "recorder" for d in ours) and outcome.failure_kind != "error":
                from ..sims.outcome import Outcome

                verdict = outcome.verdict
                outcome = Outcome.rejected(f"the recorder died during the run (its log lacks part of it; the stack "
                                           f"said {verdict}): run it again", kind="error")
            if any(d.process == "recorder" for d in ours):
                self.unlogged.append((sid, outcome))  # logged by the next recorder, once it is up
            # no pause for the recorder: it takes the result as we do, and flushes it within
            # ``recorder.VITAL_FLUSH_S``; a fault injected later finds it on file
        finally:
            self.in_flight = False
            self.driver.sent.pop((self.run_id, sid), None)  # answered, lost or interrupted: never sent again
        return outcome, sid, time.monotonic() - t0, w0, list(self.deaths)

    def _take_deaths(self) -> None:
        """What the watch saw die or hang since it last looked: said, logged, and the run's if one is on."""
        for death in self.watch.poll():
            self.event(death)
            if self.in_flight:
                self.deaths.append(death)

    def _see_signalled_deaths(self, bound_s: float = 5.0) -> None:
        """A process we killed during the run, whose answer came first: its death belongs to this
        run, so wait (bounded) until the watch has seen it, and take any death the last pulse missed."""
        lethal = [f for f in self.signalled if f.pid is not None and f.signal not in STOP_SIGNALS]
        deadline = time.monotonic() + bound_s
        while True:
            self._take_deaths()
            seen = {d.group for d in self.deaths} | {d.process for d in self.deaths}
            if all(f.target in seen for f in lethal) or time.monotonic() >= deadline:
                return
            self.node.spin_until(lambda: False, 0.05)

    # --- recovery ---------------------------------------------------------------------------------
    def between_runs(self) -> list[dict]:
        """What died while no run was on, said and restarted before the next run goes out."""
        deaths = self.watch.poll()
        for death in deaths:
            self.event(death)
        return self.recover(deaths) if deaths else []

    def recover(self, deaths: list[Death]) -> list[dict]:
        """Restart what died or hung: the whole stack for a stack's part, the part alone for ours.
        Returns a record per restart (what, why, seconds it took until the part showed up again)."""
        from ..nodes.recorder import CANNOT_WRITE

        later = self.watch.poll()
        for death in later:
            self.event(death)
        deaths = deaths + later
        if any(d.process == "recorder" and d.code == CANNOT_WRITE for d in deaths):
            raise StackStopped(f"the recorder cannot write {self.bags[-1]} (disk full?); the log holds everything up "
                               f"to its last flush (ambiegen recover {self.bags[-1]}). Free room, then the same "
                               "command resumes")
        groups: dict[str, Death] = {}
        for death in deaths:
            name = death.group if death.group in self.argv else ("nav2" if "nav2" in self.argv else death.group)
            if death.part == "stack":
                for part in self.stack_parts:
                    groups.setdefault(part, death)
            elif name in self.argv:
                groups.setdefault(name, death)
        if "robot_world" in groups:  # a new world's clock starts again at 0: the stack must start with it
            for part in self.stack_parts:
                groups.setdefault(part, groups["robot_world"])
        order = sorted(groups, key=lambda n: (n != "robot_world", n in self.stack_parts))  # world, ours, stack
        ours = [[name] for name in order if name not in self.stack_parts]
        stack = [name for name in order if name in self.stack_parts]  # one unit: killed, then started, together
        return [record for names in ours + ([stack] if stack else []) for record in self.restart(names, groups)]

    def restart(self, names: list[str], why: dict[str, Death]) -> list[dict]:
        """Kill ``names``' process groups for good and start them again, together (the parts of one
        stack: a lifecycle manager and the servers it activates come back as one); wait until they
        show up. A record per part."""
        t0 = time.monotonic()
        unit = names[0] if len(names) == 1 else "stack"
        before = self._endpoints(unit)  # the dead parts': their successors' are the ones not among them
        for name in names:
            proc = self.group.procs.get(name)
            if proc is not None:
                for sig in (signal.SIGCONT, signal.SIGKILL):  # a stopped process too
                    try:
                        os.killpg(proc.pid, sig)
                    except (ProcessLookupError, PermissionError):
                        pass
                proc.wait()
        # the dead part's endpoints leave the graph at the end of its lease: only then is its
        # successor told apart from it (a scenario sent before would miss a new adapter or recorder)
        self.node.spin_until(lambda: self._gone(unit, before), GONE_TIMEOUT_S)
        if "recorder" in names:
            self.recover_bag(self.bags[-1])
            self.bags.append(self.dir / f"trials.{len(self.bags)}.mcap")
            self.argv["recorder"] = [a.replace(f"output:={self.bags[-2]}", f"output:={self.bags[-1]}")
                                     for a in self.argv["recorder"]]
        started = {name: self.group.start_argv(name, list(self.argv[name])) for name in names}
        for name in names:
            self.watch.forget(name)
        # a successor that exits at once (a params file gone, a broken install) will not come back:
        # stop now with its last words rather than wait out the bound
        exited = lambda: [n for n, p in started.items() if p.poll() is not None]  # noqa: E731
        ok = self.node.spin_until(lambda: self._shows_up(unit, before) or bool(exited()),
                                  self.settings.ready_timeout) and not exited()
        self._interrupted()
        took = time.monotonic() - t0
        if ok and "recorder" in names:  # what the dead recorder did not hear: its own death, the run's result
            self.relog(why["recorder"])
        records = []
        for name in names:
            record = {"event": "restart", "process": name, "why": why[name].words(), "took_s": round(took, 2),
                      "ok": ok}
            self.log_event(record)
            records.append(record)
        self.say(f"[{self.prepared.config.label}] restarted {', '.join(names)} ({why[names[0]].words()}) in "
                 f"{took:.1f} s" + ("" if ok else " but it did not show up"))
        if not ok:
            after = f"after {why[names[0]].words()} (logs: {self.dir / 'logs'})"
            if exited():
                name = exited()[0]
                raise StackStopped(f"{name} did not come back: it exited with status {started[name].returncode} "
                                   f"{took:.0f} s after its restart, saying "
                                   f"{last_words(self.dir / 'logs' / f'{name}.log')!r}, {after}")
            raise StackStopped(f"{', '.join(names)} did not come back within {self.settings.ready_timeout:.0f} s "
                               f"{after}")
        return records

    def relog(self, why: Death) -> None:
        """After a recorder restart: its death and the results it missed, into the new bag."""
        from ..ros import conversions

        self.node.spin_until(lambda: False, 1.5)  # its readers match ours (it subscribes as it discovers)
        self.pub_events.publish(conversions.stack_event(self.node.new_message, self.node.now_ns(), why.process,
                                                        why.part, f"{why.what} (restarted into {self.bags[-1].name})"))
        for sid, outcome in self.unlogged:
            self.driver.pub_results.publish(conversions.result_message(
                self.node.new_message, self.node.now_ns(), self.run_id, sid, self.problem.name, "ambiegen_trials",
                outcome))
        self.unlogged.clear()
        self.node.spin_until(lambda: False, 0.3)

    def _signs(self, name: str) -> tuple[str, ...]:
        """The topics a part publishes that tell it is on the graph: the world /odom; the stack
        (``name`` a part of it or "stack") /cmd_vel, Nav2's also its navigate_to_pose server's
        status, the planner stack its compute_path_to_pose server's status."""
        if name == "robot_world":
            return ("/odom",)
        if self.settings.stack == "planner":
            return ("/compute_path_to_pose/_action/status",)
        if name == "nav2" or self.settings.stack in NAV2_STACKS:
            return ("/cmd_vel", "/navigate_to_pose/_action/status")
        return ("/cmd_vel",)

    def _endpoints(self, name: str) -> set[bytes]:
        """The global ids of the publishers on ``name``'s signs (``_signs``) now."""
        if name in ("sut_adapter", "recorder"):
            return set()
        return {ep.gid for topic in self._signs(name) for ep in self.node.publishers_info(topic)}

    def _gone(self, name: str, before: set[bytes]) -> bool:
        """The dead parts' endpoints are off the graph: none of those seen before the kill is left
        (the whole unit was killed; each participant leaves at the end of its own lease, a frozen
        one's earlier than the rest). The adapter and the recorder: the driver's scenarios have no
        reader but its own."""
        if name in ("sut_adapter", "recorder"):
            return self.driver.pub.subscription_count() <= 1
        return not (before & self._endpoints(name))

    def _shows_up(self, name: str, before: set[bytes] = frozenset()) -> bool:
        """The restarted part is on the graph: a publisher on each of its signs that was not there
        before the kill; the adapter and the recorder take scenarios."""
        if name in ("sut_adapter", "recorder"):
            return self.driver.pub.subscription_count() >= 2
        return all({ep.gid for ep in self.node.publishers_info(topic)} - before for topic in self._signs(name))

    def recover_bag(self, path: Path) -> Path | None:
        """A bag cut short (its recorder killed) rebuilt beside it (``ambiegen recover``); None when it
        is whole or absent."""
        from mcap.reader import make_reader

        from ..ros.mcap_log import recover

        if not path.exists():
            return None
        try:
            with open(path, "rb") as fh:
                if make_reader(fh).get_summary() is not None:
                    return None
        except Exception:  # noqa: BLE001 - a file cut short fails in many ways; recover decides
            pass
        out = path.with_suffix(".recovered.mcap")
        stats = recover(path, out)
        self.log_event({"event": "recovered", "bag": str(path), "into": str(out), **stats})
        self.say(f"[{self.prepared.config.label}] the recorder's bag cut short, rebuilt: {out}")
        return out

    def close(self) -> None:
        self.node.spin_until(lambda: False, 0.3)  # the last result reaches the recorder
        try:
            self.node.shutdown()
        finally:
            order = [n for n in self.group.procs if n != "recorder"] + ["recorder"]
            self.group.stop(order, timeout=30.0)


__all__ = ["SuiteDriver", "StackSession", "StackStopped", "stack_nodes"]
