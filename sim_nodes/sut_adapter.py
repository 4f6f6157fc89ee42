"""`sut_adapter`: an existing ROS stack as the system under test, judged by our oracles.

To the generator it is one more sim worker (heartbeats on ``/ambiegen/workers``, scenarios from
``/ambiegen/<problem>/scenarios``, one ``ambiegen_msgs/ScenarioResult`` per scenario on
``/ambiegen/results``). To the system under test it is a user with standard topics:

* ``robot``: the map on ``map_topic`` (``nav_msgs/OccupancyGrid``, reliable + transient local),
  the start on ``initialpose_topic`` (``geometry_msgs/PoseWithCovarianceStamped``; facing along
  the route, as the full model starts, unless ``start_heading:=scenario``), then the goal on
  ``goal_topic`` (``geometry_msgs/PoseStamped``) once ``settle_time`` has passed and the system
  shows the robot at the start (within ``start_tolerance`` m and ``start_yaw_tolerance`` rad;
  samples from before that, a world still showing the last run, are ignored). It watches
  ``odom_topic`` (``nav_msgs/Odometry``, poses in the map frame, or relative to the start pose
  with ``odom_frame:=start``), and optionally ``collision_topic`` (the world's collision report)
  and ``stall_topic`` (the stack gave up, and why: a ``stall``). Both are stamped statuses,
  ``diagnostic_msgs/DiagnosticArray``: a status at level ERROR is the event (its message the
  reason), every message a heartbeat up to its stamp. The verdict is decided in stamp order
  (``ambiegen_ros.sims.stamp_order``): a pose sample is judged only once each of these streams has
  passed its stamp or closed, so two events at one stamp resolve as in process (the world's
  collision, then contact, the stack's stall flag, goal, loitering, time limit), whatever the
  order in which the middleware delivers them.
  With ``plan_topic`` (``nav_msgs/Path``, the stack's global plan; Nav2: ``/plan``) the plans
  published after the goal are counted (``metrics["plans"]``, the last one's ``plan_length_m``),
  and a failure without any says so: a robot that never moves because its planner gave no path
  reads differently from one that could not follow its path.
  With ``goal_mode:=action`` the goal is Nav2's ``navigate_to_pose`` action
  (``sim_nodes.nav2_client``; on the DDS backend its services speak rmw_cyclonedds_cpp's wire
  format, so Nav2 must run on rmw_cyclonedds_cpp there): a scenario starts once the action server
  is up and every node of ``nav2_lifecycle_nodes`` is active; each new map clears both costmaps
  (``nav2_clear_costmaps``). **Nav2's own outcome is the verdict** (``early_verdicts:=false``,
  the default in this mode), so its recoveries (clear costmaps, spin, back up, wait, replan) get
  their turn: the goal succeeded = PASS; Nav2 aborted (or rejected) it = FAIL(nav2_aborted, with
  its error code and message); a collision in the world = FAIL(collision); no result by the time
  limit = FAIL(timeout). The time limit is max(``oracle.timeout`` 300 s, 2 x the clearance
  route / ``time_limit_speed`` + 60 s), ``time_limit_speed`` being the controller's top speed
  (the launch reads it from the params file). The paper's stall and loitering monitors still
  watch: what they would have said (their first verdict, or ``undecided``) is recorded in
  ``metrics["early_verdict"]``, ``early_detail`` and ``early_time``. With
  ``early_verdicts:=true`` they decide, as for a robot without recoveries, and a goal still
  running at their verdict is cancelled. Nav2's result is recorded beside the verdict either way
  (``nav2_status``, ``nav2_error_code``, ``nav2_error_msg``), with the recoveries Nav2 ran for it
  (``nav2_recoveries``, its feedback's count: costmap clearings, spins, waits, back-ups): a PASS
  that needed any is a near miss, and its detail says so. A failure that matches an entry of
  ``known_failures`` (a YAML file, ``ambiegen_ros.sims.known_failures``; the Nav2 launch passes
  ``config/nav2/known_failures.yaml``, NavFn's path cap) is recorded as FAIL(kind, known: name),
  ``metrics["known_failure"]``, and not counted among new distinct failures. A failed hazards run
  records how far it ended from the nearest unmapped box or post (``metrics["unmapped_obstacle_m"]``).
  Two rules keep our side's faults and the stack's own settings apart from its failures: an abort
  with an error code in ``ours_error_codes`` (the Nav2 launch: 107, the controller's costmap got no
  current data from our world in time, and 102 and 202, a transform of our world's too old) is an
  ``error`` record, to be run again; and a give-up at
  the stack's own time per goal (``goal_time_budget``: the launch reads a Timeout at the root of
  bt_navigator's tree) counts only when the reference reaches the goal within that time too.
  A bringup of Nav2 that gave up (its lifecycle manager stops at the first node that fails to
  activate; a costmap that waited for our world's first clock and TF is one such) is started again
  when ``nav2_lifecycle_manager`` names the manager (the Nav2 launch does, for the stacks it starts):
  the scenario waiting for it runs once the nodes are active.
  A lifecycle node of Nav2 leaving the active state during a run (its manager takes the whole stack
  down when a bond lapses, as a node starved of CPU lets it; seen on a loaded machine) ends the run as
  an ``error`` record, to be run again, unless a crash report explains it within ``crash_grace``; the
  next scenario waits until the nodes are active again.
* ``vehicle``: the road on ``road_topic`` (``nav_msgs/Path``, latched); watches ``odom_topic``
  (pose = centre of the car's bounding box).
* ``thermostat``: set points on ``setpoint_topic`` (``std_msgs/Float64``), each when its
  element starts (at ``time_scale``); for simulated rooms also the element's room model on
  ``room_model_topic`` (``std_msgs/UInt8``) and, first, the start temperature on
  ``initial_temperature_topic`` (``std_msgs/Float64``; empty names switch these off). Watches
  ``temperature_topic`` (``sensor_msgs/Temperature``).

Time: the first sample after the scenario started is t = 0. With ``stamp_clock:=sim`` (default)
header stamps count simulated seconds (a real system at time_scale 1, a simulator stamping with
its own clock); ``wall``: stamps are wall time of a system running ``time_scale`` times faster
(t = stamp difference x time_scale); ``receive``: stamps are ignored, arrival time x time_scale.
The problem (validity, the scenario's environment) follows ``config_file`` and ``profile``
(``replication`` | ``refined``; '' = the file's, else ``replication``), like the sim workers; a
run with another profile gets ``ERROR`` results instead of executions.
The verdict comes from ``ambiegen_ros.sims.oracles`` with the thresholds in ``oracle.<field>``
(defaults: the full-model simulators'). A failure counts only when the problem's reference passes
the same scenario (``ambiegen_ros.sims.reference``, parameter ``reference``, default true): a
scenario that breaks the static checks (robot: no route keeps the footprint plus a margin clear of
the walls; vehicle: the competition rules) is answered ``INVALID_TEST`` without being sent; a
failure on a scenario where the in-process reference (a cautious driver, an ideal controller)
fails too becomes ``INVALID_TEST``, with the system's kind in ``metrics["sut_failure_kind"]``. No first sample within ``start_timeout`` s, no sample for
``silence_timeout`` s, or the run taking longer than ``wall_slack`` x its simulated limit /
time_scale (+ start_timeout) wall seconds give an ``error`` result saying so.

What happens to the run's processes comes on ``stack_events_topic`` (``/ambiegen/stack_events``,
from whoever started them: ``ambiegen rerun``): a process of the stack that died or hung during the
run ends it as FAIL(sut_crashed), with the process and how (certified like any failure); one of ours
(the world, the recorder) ends it as an error record, to be run again. Nav2's own failure waits
``crash_grace`` s for such a report when someone publishes them (a server killed mid-run makes
Nav2 abort before the report of the kill arrives).

One scenario runs at a time; others queue (the heartbeat reports how many). Everything happens in
callbacks and timers; nothing blocks the executor.
"""
from __future__ import annotations

import math
import sys
import time
from collections import deque
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ambiegen_ros.core.config import ConfigError
from ambiegen_ros.ros import conversions, topics
from ambiegen_ros.ros.qos import DEFAULT, LATCHED, STREAM, Qos
from ambiegen_ros.sims import Outcome, known_failures, reference
from ambiegen_ros.sims.full_model import FullModelExecutor, sim_config
from ambiegen_ros.sims.oracles import CarJudge, RobotJudge, ThermostatJudge, warm_up_judge
from ambiegen_ros.sims.obstacles import contact_speeds
from ambiegen_ros.sims.robot import polyline_length
from ambiegen_ros.sims.stamp_order import DECISION, STATE, StampOrder
from ambiegen_ros.nodes import run_node
from sim_nodes.worker import WorkerEndpoint, load_problem, worker_node

ORACLE_FIELDS = {
    "robot": ("radius", "goal_tolerance", "stall_radius", "stall_time", "timeout", "clearance_cells",
              "contact_fault_speed"),
    "vehicle": ("length", "width", "rear_overhang", "lane_width", "oob_tolerance", "stall_distance",
                "stall_time", "goal_distance", "timeout_base", "timeout_speed"),
    "thermostat": ("requirement_rmse", "band"),
}
STAMP_CLOCKS = ("sim", "wall", "receive")
ODOM_FRAMES = ("map", "start")
GOAL_MODES = ("topic", "action")
START_HEADINGS = ("route", "scenario")
NAV2_NOT_READY_S = 1.0  # simulated s judged: Nav2 refusing its goal sooner gets it once more


def near_miss(recoveries: int) -> str:
    """What a PASS detail adds when Nav2 got there only through its recovery branch."""
    return f" (a near miss: after {recoveries} recover{'y' if recoveries == 1 else 'ies'})" if recoveries else ""


def ours_not_the_stack(outcome: Outcome) -> Outcome:
    """A Nav2 abort whose error code says our side failed it (``ours_error_codes``): an error record,
    to be run again, with what Nav2 said kept in its detail and metrics."""
    code = outcome.metrics.get("nav2_error_code")
    return Outcome(objectives=dict(outcome.objectives), failed=False, failure_kind="error",
                   detail=f"{outcome.detail}: error {code} is ours (ours_error_codes), not the stack's failure; "
                          "run it again",
                   metrics={**outcome.metrics, "sut_failure_kind": outcome.failure_kind},
                   trajectory=outcome.trajectory, timeline=outcome.timeline, failure_point=outcome.failure_point)


def budget_spent(kind: str, elapsed: float, budget: float) -> float | None:
    """The stack's own time per goal (``goal_time_budget``) when it gave up at it, within 10 % (the
    world's clock may lag the tree's wall clock on a loaded machine): the time the reference gets
    too. None otherwise."""
    if budget > 0 and kind == "nav2_aborted" and elapsed >= 0.9 * budget:
        return budget
    return None


def nav2_answer(result: dict, elapsed: float) -> str:
    """Nav2's result in words: '<status> its goal after <t> s (error <code>[: <message>])'."""
    message = f": {result['error_msg']}" if result["error_msg"] else ""
    return f"{result['status']} its goal after {elapsed:.1f} s (error {result['error_code']}{message})"


def to_map_frame(x: np.ndarray, y: np.ndarray, yaw: np.ndarray, start: tuple[float, float, float]):
    """Poses relative to the start pose (an odometry frame that begins where the robot was
    spawned) -> map frame."""
    sx, sy, syaw = start
    c, s = math.cos(syaw), math.sin(syaw)
    return sx + c * x - s * y, sy + s * x + c * y, (yaw + syaw + math.pi) % (2 * math.pi) - math.pi


def sample_times(stamp_ns: np.ndarray, recv_ns: np.ndarray, first: tuple[int, int], clock: str,
                 time_scale: float) -> np.ndarray:
    """Simulated seconds since the first sample, from header stamps or arrival times."""
    if clock == "sim":
        return (np.asarray(stamp_ns, dtype=np.int64) - first[0]) / 1e9
    if clock == "wall":
        return (np.asarray(stamp_ns, dtype=np.int64) - first[0]) / 1e9 * time_scale
    return (np.asarray(recv_ns, dtype=np.int64) - first[1]) / 1e9 * time_scale


@dataclass
class Job:
    run_id: str
    scenario_id: int
    scenario: Any
    msg: Any
    reason: str | None = None
    valid: bool = True
    judge: Any = None
    phase: str = "queued"  # queued -> settle -> waiting -> running
    started: float = 0.0  # monotonic, job start
    go: float = 0.0  # monotonic, when the run was started on the system under test
    anchor: float | None = None  # monotonic arrival of sample 0 (= simulated time 0)
    settle_until: float = 0.0
    last_sample: float = 0.0
    first: tuple[int, int] | None = None  # (stamp ns, receive ns) of sample 0
    t_prev: float = -math.inf
    limit_sim: float = 0.0  # simulated seconds the oracle needs at most
    schedule: list[tuple[float, float, int]] = field(default_factory=list)  # (start s, set point, model)
    next_element: int = 0
    start_pose: tuple[float, float, float] = (0.0, 0.0, 0.0)
    nav2_first_abort: str = ""  # Nav2 refused the first goal at once: what it said (the goal went again)
    nav2_refused_ns: int = 0  # the node's ROS time (sim time under /clock) of that refusal
    nav2_resend_wait_s: float | None = None  # ROS-clock s from that refusal to the goal's going again
    contacts_not_at_fault: int = 0  # people who walked into the robot (the world's WARNs): recorded, not failures
    before: Any = None  # the reference's static check (passed), the word on a failure without a reference run
    grace_until: float | None = None  # monotonic: Nav2 failed; a crash reported by then explains it
    taken_down: str = ""  # a Nav2 lifecycle node left the active state during the run: what happened

    @property
    def nav2_resend_due(self) -> bool:
        """Nav2 refused the first goal and it has not gone again yet."""
        return bool(self.nav2_first_abort) and self.nav2_resend_wait_s is None


class SutAdapter:
    def __init__(self, argv: list[str] | None = None, node=None):
        self.node, default_id = (node, None) if node is not None else worker_node("sut_adapter", argv)
        n = self.node
        p = n.declare_parameter
        self.problem_name = p("problem", "robot", "robot | vehicle | thermostat")
        if self.problem_name not in ORACLE_FIELDS:
            raise ConfigError(f"problem: unknown {self.problem_name!r} (allowed: {'|'.join(ORACLE_FIELDS)})")
        self.frame_id = p("frame_id", "map", "frame of the published map, poses and road")
        self.time_scale = float(p("time_scale", 1.0, "simulated seconds per wall second of the system under test"))
        self.stamp_clock = p("stamp_clock", "sim", "sim | wall | receive: how sample times are read")
        self.odom_frame = p("odom_frame", "map", "map | start: frame of odometry poses (robot)")
        self.settle_time = float(p("settle_time", 0.3, "seconds between map + initial pose and the goal"))
        self.start_timeout = float(p("start_timeout", 10.0, "seconds to wait for the first sample"))
        self.silence_timeout = float(p("silence_timeout", 10.0, "seconds without a sample that end a run"))
        self.wall_slack = float(p("wall_slack", 2.0, "a run may take this times its simulated limit / time_scale"))
        self.run_invalid = p("run_invalid", False, "also run scenarios the problem calls invalid")
        self.reference = bool(p("reference", True, "a failure counts only when the problem's reference passes the "
                                                   "scenario (false: the old, unchecked verdicts)"))
        self.goal_mode = p("goal_mode", "topic", "topic | action (Nav2 navigate_to_pose)")
        self.start_heading = p("start_heading", "route", "robot: initial pose facing along its route (as the full "
                                                          "model starts) | as the scenario message says")
        self.action_name = p("action_name", "navigate_to_pose", "Nav2 action for goal_mode action")
        self.early_verdicts = bool(p("early_verdicts", self.goal_mode != "action",
                                     "robot: the paper's stall and loitering monitors (and its goal tolerance) "
                                     "decide, and Nav2 is cancelled at their verdict (default with goal_mode "
                                     "topic); false (default with goal_mode action): the stack's own result decides "
                                     "(Nav2: succeeded = PASS, aborted = nav2_aborted), besides a collision and the "
                                     "time limit, and the early verdict is recorded beside it"))
        known = p("known_failures", "", "YAML of known failures (ambiegen_ros/sims/known_failures.py): a failure "
                                        "matching one is recorded as FAIL(kind, known: name) ('' = none)")
        try:
            self.known_failures = known_failures.load(known) if known else []
        except ValueError as exc:
            raise ConfigError(str(exc)) from None
        self.goal_time_budget = float(p("goal_time_budget", 0.0, "robot, goal_mode action: the stack's own time limit "
                                                             "per goal [simulated s] (a behaviour tree's Timeout; the "
                                                             "Nav2 launch reads it from the tree). An abort at that "
                                                             "limit is a failure only when the reference reaches the "
                                                             "goal within it too (0 = none)"))
        ours = p("ours_error_codes", "", "goal_mode action: Nav2 error codes that say our side failed the stack, "
                                         "comma separated: an abort with one is an error record, run again, not the "
                                         "stack's failure (the Nav2 launch passes 102,107,202: a transform of our "
                                         "world's too old, its data late to the controller's costmap; '' = none)")
        try:
            self.ours_error_codes = {int(c) for c in str(ours).replace(" ", "").split(",") if c}
        except ValueError:
            raise ConfigError(f"ours_error_codes: comma separated integers, not {ours!r}") from None
        self.time_limit_speed = float(p("time_limit_speed", 0.0, "robot: top speed [m/s] of the time limit max("
                                                                 "timeout, 2 x route / speed + 60 s) (the stack's, "
                                                                 "e.g. Nav2's controller max speed; 0 = the oracle's "
                                                                 "cruise_speed, 0.3)"))
        nav2_nodes = p("nav2_lifecycle_nodes", "planner_server,controller_server,bt_navigator",
                       "goal_mode action: Nav2 nodes that must be active before a scenario starts")
        nav2_manager = p("nav2_lifecycle_manager", "", "goal_mode action: Nav2's lifecycle manager (e.g. "
                                                      "lifecycle_manager_navigation): when its bringup gave up "
                                                      "(nodes inactive for nav2_restart_after s and it says it is "
                                                      "not active), ask it to clean up and start again ('' = never; "
                                                      "the Nav2 launch sets it for the stacks it starts)")
        nav2_restarts = int(p("nav2_restarts", 3, "goal_mode action: restarts of a failed bringup, at most"))
        nav2_restart_after = float(p("nav2_restart_after", 20.0, "goal_mode action: seconds lifecycle nodes stay "
                                                                 "inactive before the manager is asked"))
        nav2_clear = p("nav2_clear_costmaps", "/global_costmap/clear_entirely_global_costmap,"
                                              "/local_costmap/clear_entirely_local_costmap",
                       "goal_mode action: costmap clearing services called with every new map ('' = none)")
        self.events_topic = p("stack_events_topic", topics.STACK_EVENTS,
                              "diagnostic_msgs/DiagnosticArray in: what happened to the run's processes, from "
                              "whoever started them (ambiegen rerun); during a run, one of the stack's = "
                              "FAIL(sut_crashed), one of ours = an error record ('' = none)")
        self.crash_grace = float(p("crash_grace", 2.0, "wall seconds a failure of the stack's own (Nav2 aborted) "
                                                       "waits for a crash report that explains it, when someone "
                                                       "publishes them (0 = no wait)"))
        self.start_tolerance = float(p("start_tolerance", 0.5, "robot: a run starts with the first pose sample this "
                                                                "close to the start pose [m]; earlier ones (a world "
                                                                "still showing the last run) are ignored"))
        self.start_yaw_tolerance = float(p("start_yaw_tolerance", 0.1, "robot: ... and heading this close to the start "
                                                                       "pose's [rad] (< 0: any heading)"))
        self.map_upsample = int(p("map_upsample", 1, "robot: publish each map cell as k x k cells (the same walls at "
                                                      "the resolution a stack's costmaps expect; Nav2: 10 = 0.1 m)"))
        if self.map_upsample < 1:
            raise ConfigError("map_upsample: must be >= 1")
        self.tick_period = float(p("tick_period", 0.002, "seconds between adapter turns while a scenario runs"))
        odom_reliable = p("odom_reliable", True, "subscribe to samples reliably (false: best effort)")
        for name, allowed, value in (("stamp_clock", STAMP_CLOCKS, self.stamp_clock),
                                     ("odom_frame", ODOM_FRAMES, self.odom_frame),
                                     ("goal_mode", GOAL_MODES, self.goal_mode),
                                     ("start_heading", START_HEADINGS, self.start_heading)):
            if value not in allowed:
                raise ConfigError(f"{name}: unknown {value!r} (allowed: {'|'.join(allowed)})")
        if not self.time_scale > 0:
            raise ConfigError("time_scale: must be > 0")

        defaults = sim_config(self.problem_name)
        options = {}
        for name in ORACLE_FIELDS[self.problem_name]:
            value = p(f"oracle.{name}", getattr(defaults, name), f"oracle threshold {name}")
            if value != getattr(defaults, name):
                options[name] = value
        options["run_invalid"] = bool(self.run_invalid)
        options["reference"] = self.reference
        self.oracle = sim_config(self.problem_name, options)
        self.problem = load_problem(n, self.problem_name)  # config_file + profile
        self.validity = FullModelExecutor(self.problem, config=self.oracle).validity

        # reliable samples are kept all: an adapter busy for a moment buffers them instead of losing
        # the oldest, which a judge by stamps would read as a robot standing still
        sample_qos = Qos(reliable=odom_reliable, transient_local=False, depth=STREAM.depth, keep_all=odom_reliable)
        self.topics: dict[str, str] = {}
        if self.problem_name == "robot":
            self.topics = {
                "map": p("map_topic", "/map"), "initialpose": p("initialpose_topic", "/initialpose"),
                "goal": p("goal_topic", "/goal_pose"), "odom": p("odom_topic", "/odom"),
                "collision": p("collision_topic", "", "optional diagnostic_msgs/DiagnosticArray from the world, "
                                                      "level ERROR = a collision, stamped ('' = none)"),
                "stall": p("stall_topic", "", "optional diagnostic_msgs/DiagnosticArray from the stack every cycle, "
                                              "level ERROR = it gave up, message = why ('' = none)"),
                "plan": p("plan_topic", "", "optional nav_msgs/Path: the stack's global plan, counted after the goal "
                                            "(Nav2: /plan; '' = none)"),
                "obstacles": p("obstacles_topic", topics.WORLD_OBSTACLES,
                               "std_msgs/String out (JSON), stamped like the map: what the world holds besides the "
                               "map, for robot_world (hazards scenarios; '' = none)"),
            }
            self.pub_obstacles = (n.create_publisher("std_msgs/msg/String", self.topics["obstacles"], LATCHED)
                                  if self.topics["obstacles"] else None)
            self.pub_map = n.create_publisher("nav_msgs/msg/OccupancyGrid", self.topics["map"], LATCHED)
            self.pub_initialpose = n.create_publisher("geometry_msgs/msg/PoseWithCovarianceStamped",
                                                      self.topics["initialpose"], DEFAULT)
            self.pub_goal = n.create_publisher("geometry_msgs/msg/PoseStamped", self.topics["goal"], DEFAULT)
            n.create_subscription("nav_msgs/msg/Odometry", self.topics["odom"], self.on_odom, sample_qos)
            if self.topics["plan"]:
                n.create_subscription("nav_msgs/msg/Path", self.topics["plan"], self.on_plan, DEFAULT)
        elif self.problem_name == "vehicle":
            self.topics = {"road": p("road_topic", "/road"), "odom": p("odom_topic", "/odom")}
            self.pub_road = n.create_publisher("nav_msgs/msg/Path", self.topics["road"], LATCHED)
            n.create_subscription("nav_msgs/msg/Odometry", self.topics["odom"], self.on_odom, sample_qos)
        else:
            self.topics = {
                "setpoint": p("setpoint_topic", "/thermostat/setpoint"),
                "temperature": p("temperature_topic", "/thermostat/temperature"),
                "room_model": p("room_model_topic", "/thermostat/room_model", "'' = do not publish"),
                "initial_temperature": p("initial_temperature_topic", "/thermostat/initial_temperature",
                                         "'' = do not publish"),
            }
            self.pub_setpoint = n.create_publisher("std_msgs/msg/Float64", self.topics["setpoint"], DEFAULT)
            self.pub_model = (n.create_publisher("std_msgs/msg/UInt8", self.topics["room_model"], DEFAULT)
                              if self.topics["room_model"] else None)
            self.pub_reset = (n.create_publisher("std_msgs/msg/Float64", self.topics["initial_temperature"], DEFAULT)
                              if self.topics["initial_temperature"] else None)
            n.create_subscription("sensor_msgs/msg/Temperature", self.topics["temperature"], self.on_temperature,
                                  sample_qos)
        if self.events_topic:
            n.create_subscription(topics.STACK_EVENTS_TYPE, self.events_topic, self.on_stack_event, STREAM)
        self.queue: deque[Job] = deque()
        self.job: Job | None = None
        self.samples: list[tuple] = []
        # the world's collision applies at its stamp; the stack's decision from the next sample on
        self.order = StampOrder([(name, how) for name, how in (("collision", STATE), ("stall", DECISION))
                                 if self.topics.get(name)])
        for name in self.order.streams:  # every status kept: each one moves its stream's watermark
            n.create_subscription("diagnostic_msgs/msg/DiagnosticArray", self.topics[name],
                                  lambda msg, name=name: self.on_status(name, msg), sample_qos)
        self.nav2_stamp: int | None = None  # Nav2's result has no stamp: the newest sample's when it came
        self.plans, self.last_plan = 0, None  # the stack's plans since the goal went out, the last one
        self.pre_goal: tuple | None = None  # the last sample before the goal went out
        self._fast = None
        self.nav2 = None
        if self.goal_mode == "action":  # either backend: the DDS one speaks rmw_cyclonedds_cpp's services
            from sim_nodes.nav2_client import Nav2Client

            self.nav2 = Nav2Client(n, self.action_name, nav2_nodes.split(","), nav2_clear.split(","), n.logger,
                                   manager=nav2_manager, restarts=nav2_restarts, restart_after=nav2_restart_after)
            self.nav2.watch_transitions(DEFAULT, self.on_nav2_left_active)
        self.endpoint = WorkerEndpoint(n, self.problem, self.accept,
                                       lambda: len(self.queue) + (self.job is not None), default_id)
        self.worker_id = self.endpoint.worker_id
        self.publish = self.endpoint.publish
        warm_up_judge(self.problem_name, self.oracle)  # not mid-run: see its docstring
        # the next scenario starts as the last one ends or as it arrives (finish, accept); this
        # timer only catches what those miss, so it need not wake the node 50 times a second
        n.create_timer(float(p("idle_period", 0.2, "seconds between checks for a waiting scenario while none runs")),
                       self.idle)
        n.logger.info(
            f"{self.worker_id}: {self.problem_name} scenarios -> {', '.join(f'{k}={v}' for k, v in self.topics.items() if v)}"
            f" (time_scale {self.time_scale:g}, stamp_clock {self.stamp_clock}; {n.middleware})"
        )

    # --- worker side ----------------------------------------------------------------------------
    def accept(self, run_id: str, sid: int, scenario: Any, msg: Any) -> None:
        if any((j.run_id, j.scenario_id) == (run_id, sid) for j in [self.job, *self.queue] if j is not None):
            return  # a re-sent scenario still waiting here: its one result is coming
        valid, reason = self.validity(scenario)
        if not valid and not self.run_invalid:
            outcome = Outcome.rejected(f"restriction broken: {reason}")
            outcome.metrics = {"outcome": "invalid", "valid": False, "reason": reason}
            self.publish(run_id, sid, outcome)
            return
        verdict = None
        if self.reference:
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
        self.pre_goal, self.nav2_stamp = None, None
        self._next_stream_check = 0.0
        self.plans, self.last_plan = 0, None
        job.started = time.monotonic()
        job.phase = "connecting"
        self._next_graph_check = 0.0
        self._fast = self.node.create_timer(self.tick_period, self.tick)

    def _missing_peers(self) -> list[str]:
        """What the system under test has not shown yet: subscribers to our inputs, its publisher."""
        if self.problem_name == "robot":
            pubs = [self.pub_initialpose] + ([self.pub_goal] if self.goal_mode == "topic" else [])
            out_topic = self.topics["odom"]
        elif self.problem_name == "vehicle":
            pubs, out_topic = [self.pub_road], self.topics["odom"]
        else:
            pubs, out_topic = [self.pub_setpoint], self.topics["temperature"]
        missing = [f"nobody subscribes to {pub.topic}" for pub in pubs if pub.subscription_count() < 1]
        for topic in [out_topic] + [self.topics[name] for name in self.order.streams]:
            if not self.node.publishers_info(topic):
                missing.append(f"nobody publishes {topic}")
        if self.nav2 is not None:
            missing += self.nav2.missing()
        return missing

    def setup(self, job: Job, now: float) -> None:
        """Put the scenario on the standard topics (the goal follows after ``settle_time``)."""
        make, stamp = self.node.new_message, self.node.now_ns()
        head = conversions.header(make, stamp, self.frame_id)
        msg = job.msg
        try:
            if self.problem_name == "robot":
                grid = conversions.grid_from_message(msg.map)
                info = msg.map.info
                origin = (float(info.origin.position.x), float(info.origin.position.y))
                goal = msg.goal.pose.position
                job.judge = RobotJudge(grid, float(info.resolution), (float(goal.x), float(goal.y)), self.oracle, origin,
                                       diagonal=self.problem.config.diagonal, speed=self.time_limit_speed or None,
                                       early_verdicts=self.early_verdicts)
                job.limit_sim = self.oracle.timeout  # the floor; the route's own limit once the start is seen
                s = msg.start.pose
                job.start_pose = (float(s.position.x), float(s.position.y), conversions.yaw_of(s.orientation))
                hazards = bool(getattr(self.problem, "hazards", False))
                if self.pub_obstacles is not None:  # the world's unmapped obstacles and people, stamped like the map
                    unmapped = self.problem.environment(job.scenario).unmapped if hazards else {}
                    self.pub_obstacles.publish(conversions.obstacles_message(make, stamp, unmapped or {}))
                if self.start_heading == "route" and not hazards:  # facing the route's first leg, as the full model starts
                    route = job.judge.start(job.start_pose[0], job.start_pose[1])
                    if len(route) > 1:
                        heading = math.atan2(route[1, 1] - route[0, 1], route[1, 0] - route[0, 0])
                        job.start_pose = (job.start_pose[0], job.start_pose[1], heading)
                        s = conversions.pose(make, *job.start_pose)
                if self.map_upsample > 1:
                    self.pub_map.publish(conversions.upsampled_grid(make, msg.map, self.map_upsample, stamp,
                                                                    self.frame_id))
                else:
                    self.pub_map.publish(make("nav_msgs/msg/OccupancyGrid", header=head, info=info, data=msg.map.data))
                self.pub_initialpose.publish(make("geometry_msgs/msg/PoseWithCovarianceStamped", header=head,
                                                  pose=make("geometry_msgs/msg/PoseWithCovariance", pose=s)))
                if self.nav2 is not None:  # the last scenario's walls out of both costmaps
                    self.nav2.clear_costmaps()
                job.phase, job.settle_until = "settle", now + self.settle_time
            elif self.problem_name == "vehicle":
                road = conversions.path_points(msg.road)
                job.judge = CarJudge(road, float(msg.lane_width), self.oracle)
                job.limit_sim = job.judge.time_limit
                self.pub_road.publish(make("nav_msgs/msg/Path", header=head, poses=list(msg.road.poses)))
                job.phase, job.go = "waiting", now
            else:
                setpoints = [float(v) for v in np.asarray(msg.setpoints, dtype=float)]
                durations = [float(v) for v in np.asarray(msg.durations_min, dtype=float)]
                models = [int(v) for v in np.asarray(msg.room_models)]
                job.judge = ThermostatJudge(setpoints, durations, self.oracle)
                job.limit_sim = job.judge.total
                starts = np.concatenate([[0.0], np.cumsum(np.asarray(durations) * 60.0)[:-1]])
                job.schedule = list(zip(starts.tolist(), setpoints, models))
                self._publish_element(job.schedule[0])
                if self.pub_reset is not None:
                    self.pub_reset.publish(make("std_msgs/msg/Float64", data=float(msg.initial_temperature)))
                job.next_element = 1
                job.phase, job.go = "waiting", now
        except Exception as exc:  # a scenario message we cannot turn into the contract
            self.finish(Outcome.rejected(f"{type(exc).__name__}: {exc}", kind="error"))

    def _publish_element(self, element: tuple[float, float, int]) -> None:
        make = self.node.new_message
        _, setpoint, model = element
        if self.pub_model is not None:
            self.pub_model.publish(make("std_msgs/msg/UInt8", data=int(model)))
        self.pub_setpoint.publish(make("std_msgs/msg/Float64", data=float(setpoint)))

    def _send_goal(self, job: Job) -> None:
        make = self.node.new_message
        goal = make("geometry_msgs/msg/PoseStamped", header=conversions.header(make, self.node.now_ns(), self.frame_id),
                    pose=job.msg.goal.pose)
        if self.nav2 is not None:
            self.nav2.send(goal)
        else:
            self.pub_goal.publish(goal)

    # --- samples --------------------------------------------------------------------------------
    def on_odom(self, msg: Any) -> None:
        job = self.job
        if job is None or job.phase not in ("settle", "waiting", "running"):
            return
        pose = msg.pose.pose
        o = pose.orientation
        conversions.require_finite((pose.position.x, pose.position.y, o.x, o.y, o.z, o.w, msg.twist.twist.linear.x),
                                   "odometry pose / twist")  # raises: the sample is dropped and counted
        sample = (conversions.stamp_ns(msg.header), time.monotonic_ns(), float(pose.position.x),
                  float(pose.position.y), conversions.yaw_of(pose.orientation), float(msg.twist.twist.linear.x))
        if job.phase == "settle":
            self.pre_goal = sample
        elif job.first is not None or self.samples or self.order.pending or self._at_start(sample, job):
            self.samples.append(sample)

    def on_temperature(self, msg: Any) -> None:
        job = self.job
        if job is None or job.phase not in ("waiting", "running"):
            return
        temperature = float(conversions.require_finite(msg.temperature, "temperature"))
        self.samples.append((conversions.stamp_ns(msg.header), time.monotonic_ns(), temperature))

    def on_status(self, name: str, msg: Any) -> None:
        """A stamped status on the stall or collision topic: a heartbeat, or the stream's event (a
        WARN on the collision topic: a person walked into the robot, counted, not a failure)."""
        if self.job is not None:
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

    def on_plan(self, msg: Any) -> None:
        if self.job is not None and self.job.phase in ("waiting", "running"):
            self.plans, self.last_plan = self.plans + 1, msg  # measured once, when the run ends

    def tick(self) -> None:
        job = self.job
        if job is None:
            return
        now = time.monotonic()
        what = "temperature readings" if self.problem_name == "thermostat" else "odometry"
        if job.phase == "connecting":
            if now < self._next_graph_check:
                return
            self._next_graph_check = now + 0.05  # graph queries are not free: 20 per second at most
            missing = self._missing_peers()
            if not missing:
                self.setup(job, now)
            elif now - job.started > self.start_timeout:
                self.finish(Outcome.rejected(f"no {what} within {self.start_timeout:g} s: {'; '.join(missing)}",
                                             kind="error"))
            return
        if job.taken_down:  # held while a crash report may still explain it, then an error record
            if not self._crash_grace(job, now):
                self.finish(Outcome.rejected(f"{job.taken_down}: the stack was taken down, not failed by the "
                                             "scenario; run it again", kind="error"))
            return
        if job.phase == "settle":
            # the goal goes out once the system shows the robot at the start (a quiet one: after
            # settle_time; one still showing the last run: after start_timeout at most)
            ready = self.pre_goal is None or self._at_start(self.pre_goal, job)
            if now >= job.settle_until and (ready or now >= job.settle_until + self.start_timeout):
                self._send_goal(job)
                job.phase, job.go = "waiting", now
                if self._at_start(self.pre_goal, job):  # the robot as the goal went out is sample 0
                    self.samples.insert(0, self.pre_goal)
            return
        if self.samples or self.order.pending:
            self._judge_samples(job, now)
            if job.judge.decided:
                self.finish(job.judge.outcome())
                return
        # Set point changes follow the system's clock, which starts with its first reading.
        while (job.anchor is not None and job.next_element < len(job.schedule)
               and now >= job.anchor + job.schedule[job.next_element][0] / self.time_scale):
            self._publish_element(job.schedule[job.next_element])
            job.next_element += 1
        r = None if self.nav2 is None else self.nav2.result
        if job.nav2_resend_due:
            r = None  # the refusal on record is not the verdict
            # the world's clock has run on, in the robot's odometry or in ROS time (a stack whose
            # odometry starts with the goal): an event of the simulation, not a wall-clock wait
            waited_s = (self.node.now_ns() - job.nav2_refused_ns) / 1e9
            if job.judge.elapsed >= NAV2_NOT_READY_S or waited_s >= NAV2_NOT_READY_S:
                job.nav2_resend_wait_s = waited_s
                self._send_goal(job)
        elif r is not None and r["status"] != "succeeded" and not job.nav2_first_abort and \
                job.judge.elapsed < NAV2_NOT_READY_S:
            # Nav2 refused the goal before the robot could move: after a world reset its controller
            # may still see the robot where it was ("Resulting plan has 0 poses", 103). Once more, when
            # the world's clock has run NAV2_NOT_READY_S simulated seconds: sent again at once, the
            # goal met the same stale view 0.1 s later (docs/choices.md). A real failure repeats and
            # is the verdict (the first answer is recorded)
            job.nav2_first_abort = nav2_answer(r, job.judge.elapsed)
            job.nav2_refused_ns = self.node.now_ns()
            self.node.logger.warning(f"Nav2 {job.nav2_first_abort} at the start; sending the goal once more "
                                     f"when the world's clock has run {NAV2_NOT_READY_S:g} s")
            return
        if r is not None and r["status"] != "succeeded" and self._crash_grace(job, now):
            return
        if r is not None and (r["status"] != "succeeded" or not self.early_verdicts):
            # Nav2's result carries no stamp: it counts at the newest pose received before it, once
            # every sample up to there is judged (an earlier verdict from them stands)
            if self.nav2_stamp is None:
                self.nav2_stamp = self.order.newest if self.order.newest is not None else -1
            if self.order.watermark >= self.nav2_stamp and not self.samples:
                if r["status"] == "succeeded":
                    job.judge.stack_result(True, "none", f"Nav2 reached the goal after {job.judge.elapsed:.1f} s"
                                                           + near_miss(self.nav2.recoveries))
                else:
                    job.judge.stack_result(False, "nav2_aborted", f"Nav2 {nav2_answer(r, job.judge.elapsed)}")
                self.finish(job.judge.outcome())
                return
        if self.order.pending and now >= self._next_stream_check:
            self._close_deserted_streams(now)
        if job.phase == "waiting" and now - job.go > self.start_timeout:
            job.judge.finish(f"no {what} within {self.start_timeout:g} s")
        elif job.phase == "running" and now - job.last_sample > self.silence_timeout:
            job.judge.finish(f"{what} stopped after {job.judge.elapsed:.1f} s (simulated) without a verdict"
                             + self._held_back())
        elif now - job.go > self.wall_slack * job.limit_sim / self.time_scale + self.start_timeout:
            job.judge.finish(f"too slow: {job.judge.elapsed:.1f} of {job.limit_sim:.0f} simulated s after "
                             f"{now - job.go:.1f} s wall (time_scale {self.time_scale:g})" + self._held_back())
        if job.judge.decided:
            self.finish(job.judge.outcome())

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

    def _at_start(self, sample: tuple | None, job: Job) -> bool:
        """Is this pose sample the robot at the scenario's start (within ``start_tolerance``)?
        Every sample of a road or a room is."""
        if sample is None:
            return False
        if self.problem_name != "robot":
            return True
        x, y, yaw = sample[2], sample[3], sample[4]
        if self.odom_frame == "map":
            x, y, yaw = x - job.start_pose[0], y - job.start_pose[1], yaw - job.start_pose[2]
        turned = abs((yaw + math.pi) % (2 * math.pi) - math.pi)
        return math.hypot(x, y) <= self.start_tolerance and not turned > self.start_yaw_tolerance >= 0

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
        rows = np.array([row for _, row, _ in released], dtype=object)
        events = [what for _, _, what in released]
        stamps = rows[:, 0].astype(np.int64)
        recv = rows[:, 1].astype(np.int64)
        t = sample_times(stamps, recv, job.first, self.stamp_clock, self.time_scale)
        keep = np.zeros(len(t), dtype=bool)  # strictly increasing times only (drops duplicates, reordering)
        last = job.t_prev
        for i, ti in enumerate(t):
            if ti > last:
                keep[i], last = True, ti
        job.t_prev = last
        if not keep.any():
            return
        vals = rows[keep, 2:].astype(float)
        t = t[keep]
        events = [e for e, k in zip(events, keep) if k]
        if self.problem_name == "thermostat":
            job.judge.add(t, vals[:, 0])
            return
        x, y, yaw, v = vals.T
        if self.odom_frame == "start":
            x, y, yaw = to_map_frame(x, y, yaw, job.start_pose)
        if self.problem_name == "robot":
            collision = self.topics["collision"]
            job.judge.add(t, x, y, yaw, stall=[e.get("stall") for e in events],
                          collision=[f"reported on {collision}: {e['collision']}" if "collision" in e else None
                                     for e in events])
            if math.isfinite(job.judge.time_limit):
                job.limit_sim = max(job.limit_sim, job.judge.time_limit)
        else:
            job.judge.add(t, x, y, yaw, v)

    def finish(self, outcome: Outcome) -> None:
        job = self.job
        self.job = None
        if self._fast is not None:
            self._fast.cancel()
            self._fast = None
        if self.nav2 is not None:  # Nav2's own word beside our oracle's
            r = self.nav2.result or {"status": "running (cancelled: the oracle decided first)" if self.nav2.handle
                                     else "no goal", "error_code": 0, "error_msg": ""}
            outcome.metrics = {**outcome.metrics, "nav2_status": r["status"], "nav2_error_code": r["error_code"],
                               "nav2_error_msg": r["error_msg"], "nav2_first_abort": job.nav2_first_abort,
                               "nav2_resend_wait_s": job.nav2_resend_wait_s,
                               "nav2_recoveries": self.nav2.recoveries}
            self.nav2.cancel()
        if self.topics.get("plan"):
            length = None if self.last_plan is None else polyline_length(conversions.path_points(self.last_plan))
            outcome.metrics = {**outcome.metrics, "plans": self.plans, "plan_length_m": length}
            if outcome.failed and not self.plans:
                outcome.detail = f"{outcome.detail}; no plan on {self.topics['plan']} since the goal"
        gave_up = self.order.streams.get("stall")
        if outcome.failure_kind == "stall" and gave_up is not None and gave_up.event is not None \
                and outcome.metrics.get("stall_cause") == gave_up.event[1]:
            outcome.detail = f"{outcome.detail} (the system under test gave up, on {self.topics['stall']})"
        if outcome.failure_kind == "nav2_aborted" and outcome.metrics.get("nav2_error_code") in self.ours_error_codes:
            outcome = ours_not_the_stack(outcome)
        if self.reference and outcome.failed:  # does the in-process reference pass the same scenario?
            budget = budget_spent(outcome.failure_kind, job.judge.elapsed, self.goal_time_budget)
            outcome = reference.certify(outcome, reference.after(self.problem, job.scenario, self.oracle, outcome,
                                                                 budget=budget) or job.before)
        hazards = self.problem_name == "robot" and getattr(self.problem, "hazards", False)
        if hazards and outcome.failed:  # evidence for a known failure: an unmapped obstacle where it failed
            where = outcome.failure_point or (None if outcome.trajectory is None or not len(outcome.trajectory)
                                              else tuple(outcome.trajectory[-1][:2]))
            outcome.metrics = {**outcome.metrics,
                               "unmapped_obstacle_m": known_failures.unmapped_obstacle_m(self.problem, job.scenario, where)}
        speeds = contact_speeds(outcome.detail) if hazards else None
        if speeds:  # a contact with a person: both speeds along the line of contact, as metrics
            outcome.metrics = {**outcome.metrics, **{f"contact_{k}": v for k, v in speeds.items()}}
        if self.known_failures and outcome.failed:
            outcome = known_failures.mark(outcome, self.known_failures)
        wall = time.monotonic() - job.started
        outcome.elapsed_sec = wall
        outcome.metrics = {**outcome.metrics, "valid": job.valid, "reason": job.reason, "wall_s": wall,
                           "time_scale": self.time_scale, "stamp_clock": self.stamp_clock}
        if hazards:
            outcome.metrics["contacts_not_at_fault"] = job.contacts_not_at_fault
        self.publish(job.run_id, job.scenario_id, outcome)
        self.node.logger.info(f"scenario {job.scenario_id}: {outcome.failure_kind} ({outcome.detail}) in {wall:.2f} s")
        self.idle()


def main(argv: list[str] | None = None) -> int:
    return run_node("sut_adapter", lambda: SutAdapter(argv), lambda a: a.endpoint.stop(), doc=__doc__)


if __name__ == "__main__":
    sys.exit(main())
