"""A robot stack driven on its standard topics (``problem:=robot``, ``goal_mode:=topic``).

* **Setup.** The map goes out on ``map_topic`` (``nav_msgs/OccupancyGrid``, reliable + transient
  local; ``map_upsample`` k publishes each cell as k x k), the start on ``initialpose_topic``
  (``geometry_msgs/PoseWithCovarianceStamped``; facing along the route, as the full model starts,
  unless ``start_heading:=scenario``), and for hazards scenarios the world's unmapped obstacles and
  people on ``obstacles_topic`` (JSON, stamped like the map).
* **The goal** (``geometry_msgs/PoseStamped`` on ``goal_topic``) goes once ``settle_time`` has
  passed and the system shows the robot at the start (within ``start_tolerance`` m and
  ``start_yaw_tolerance`` rad; ``start_timeout`` at most). Samples from before that, a world still
  showing the last run, are ignored.
* **Samples.** ``odom_topic`` (``nav_msgs/Odometry``, poses in the map frame, or relative to the
  start pose with ``odom_frame:=start``). Optional ``collision_topic`` (the world's collision
  report) and ``stall_topic`` (the stack gave up, and why: a ``stall``) are stamped statuses
  (``diagnostic_msgs/DiagnosticArray``): a status at level ERROR is the event (its message the
  reason), every message a heartbeat up to its stamp. The verdict is decided in stamp order
  (``ambiegen_ros.sims.stamp_order``): a pose sample is judged only once each stream has passed
  its stamp or closed, so two events at one stamp resolve as in process (the world's collision,
  then contact, the stack's stall flag, goal, loitering, time limit), whatever the order in which
  the middleware delivers them. A WARN on the collision topic (a person walked into the robot) is
  counted, not a failure (``contacts_not_at_fault``).
* **The time limit** is max(``oracle.timeout``, 2 x the clearance route / ``time_limit_speed`` +
  60 s). ``early_verdicts`` (default true here) lets the paper's stall and loitering monitors decide.
* **The robot** is ``robot_profile``'s (the same name or path robot_world takes): the references
  keep its radius from the walls, a car's route must suit its turning radius, the judge measures its
  body ('' = the Pioneer). A bad profile stops the node with one line naming the field.
* **A goal lost on the wire goes again.** A reliable volatile message can miss a subscriber whose
  side of discovery is not complete (a stack part restarted a moment ago): with ``stall_topic`` or
  ``plan_topic`` set, a goal that no status and no plan answered within ``GOAL_RESEND_S`` wall
  seconds goes again, ``GOAL_RESENDS`` times at most (``metrics["goal_sends"]``); without either,
  nothing tells a lost goal from a slow stack, and it goes once.
* **Plans.** With ``plan_topic`` (``nav_msgs/Path``, the stack's global plan) the plans published
  after the goal are counted (``metrics["plans"]``, the last one's ``plan_length_m``), and a failure
  without any says so (``with_plans``). A stall the stack itself reported says so (``with_give_up``).
"""
from __future__ import annotations

import math
import time
from typing import Any

from ambiegen_ros.ros import conversions, topics
from ambiegen_ros.ros.qos import DEFAULT, LATCHED
from ambiegen_ros.sims import Outcome
from ambiegen_ros.sims.oracles import RobotJudge
from ambiegen_ros.sims.robot import polyline_length
from ambiegen_ros.sims.stamp_order import DECISION, STATE

from .judge import RunView, ScenarioJudge
from .params import Param
from .samples import to_map_frame

GOAL_RESEND_S = 10.0  # wall seconds a goal may go unanswered (no status, no plan) before it goes again
GOAL_RESENDS = 3  # ... at most this often

ROBOT_PARAMS = (
    Param("settle_time", float, 0.3, "seconds between map + initial pose and the goal"),
    Param("start_heading", str, "route", "robot: initial pose facing along its route (as the full model starts) | "
                                         "as the scenario message says", allowed=("route", "scenario")),
    Param("early_verdicts", bool, lambda v: v["goal_mode"] != "action",
          "robot: the paper's stall and loitering monitors (and its goal tolerance) decide, and Nav2 is cancelled "
          "at their verdict (default with goal_mode topic); false (default with goal_mode action): the stack's own "
          "result decides (Nav2: succeeded = PASS, aborted = nav2_aborted), besides a collision and the time limit, "
          "and the early verdict is recorded beside it", default_text="true with goal_mode topic, false with action"),
    Param("time_limit_speed", float, 0.0, "robot: top speed [m/s] of the time limit max(timeout, 2 x route / speed "
                                          "+ 60 s) (the stack's, e.g. Nav2's controller max speed; 0 = the oracle's "
                                          "cruise_speed, 0.3)"),
    Param("start_tolerance", float, 0.5, "robot: a run starts with the first pose sample this close to the start pose "
                                         "[m]; earlier ones (a world still showing the last run) are ignored"),
    Param("start_yaw_tolerance", float, 0.1, "robot: ... and heading this close to the start pose's [rad] "
                                             "(< 0: any heading)"),
    Param("map_upsample", int, 1, "robot: publish each map cell as k x k cells (the same walls at the resolution a "
                                  "stack's costmaps expect; Nav2: 10 = 0.1 m)", minimum=1),
    Param("map_topic", str, "/map", "nav_msgs/OccupancyGrid out, reliable + transient local"),
    Param("initialpose_topic", str, "/initialpose", "geometry_msgs/PoseWithCovarianceStamped out: the start"),
    Param("goal_topic", str, "/goal_pose", "geometry_msgs/PoseStamped out: the goal (goal_mode topic)"),
    Param("odom_topic", str, "/odom", "nav_msgs/Odometry in: the robot's pose and speed"),
    Param("collision_topic", str, "", "optional diagnostic_msgs/DiagnosticArray from the world, level ERROR = a "
                                      "collision, stamped ('' = none)"),
    Param("stall_topic", str, "", "optional diagnostic_msgs/DiagnosticArray from the stack every cycle, level ERROR "
                                  "= it gave up, message = why ('' = none)"),
    Param("plan_topic", str, "", "optional nav_msgs/Path: the stack's global plan, counted after the goal "
                                 "(Nav2: /plan; '' = none)"),
    Param("robot_profile", str, "", "robot: the robot judged, a shipped profile's name (turtlebot4, ...) or a profile "
                                    "file (docs/robot_profiles.md), as robot_world's: the references' clearance, a "
                                    "car's turning radius and the judge's body are its ('' = Stage's pioneer2dx)"),
    Param("obstacles_topic", str, topics.WORLD_OBSTACLES, "std_msgs/String out (JSON), stamped like the map: what "
                                                          "the world holds besides the map, for robot_world (hazards "
                                                          "scenarios; '' = none)"),
)
ROBOT_ORACLE = ("radius", "goal_tolerance", "stall_radius", "stall_time", "timeout", "clearance_cells",
                "contact_fault_speed")


class TopicRobot(ScenarioJudge):
    """A robot stack that takes its goal on a topic; the oracle decides (or the stack's stall report)."""

    problem, goal_mode = "robot", "topic"
    PARAMS = ROBOT_PARAMS
    ORACLE_FIELDS = ROBOT_ORACLE
    STREAMS = (("collision", STATE), ("stall", DECISION))  # the world's collision at its stamp; the stack's
    KEYS = ("map", "initialpose", "goal", "odom", "collision", "stall", "plan", "obstacles")  # decision after

    def __init__(self, node: Any, settings: Any, oracle: Any, problem: Any):
        super().__init__(node, settings, oracle, problem)
        self.topics = {key: settings[f"{key}_topic"] for key in self.KEYS}
        self.plans, self.last_plan = 0, None  # the stack's plans since the goal went out, the last one

    def wire(self, host: Any) -> None:
        n, t = self.node, self.topics
        self.pub_obstacles = n.create_publisher("std_msgs/msg/String", t["obstacles"], LATCHED) if t["obstacles"] else None
        self.pub_map = n.create_publisher("nav_msgs/msg/OccupancyGrid", t["map"], LATCHED)
        self.pub_initialpose = n.create_publisher("geometry_msgs/msg/PoseWithCovarianceStamped", t["initialpose"],
                                                  DEFAULT)
        self.pub_goal = n.create_publisher("geometry_msgs/msg/PoseStamped", t["goal"], DEFAULT)
        super().wire(host)
        if t["plan"]:
            n.create_subscription("nav_msgs/msg/Path", t["plan"], self.on_plan, DEFAULT)

    def needs_subscribers(self) -> list[Any]:
        return [self.pub_initialpose, self.pub_goal]

    def begin(self, job: Any) -> None:
        self.plans, self.last_plan = 0, None

    def on_plan(self, msg: Any) -> None:
        job = self._job()
        if job is not None and job.phase in ("waiting", "running"):
            self.plans, self.last_plan = self.plans + 1, msg  # measured once, when the run ends

    # --- setup ----------------------------------------------------------------------------------
    def setup(self, job: Any, now: float) -> None:
        make, stamp, msg = self.node.new_message, self.node.now_ns(), job.msg
        info = msg.map.info
        origin = (float(info.origin.position.x), float(info.origin.position.y))
        goal = msg.goal.pose.position
        job.judge = RobotJudge(conversions.grid_from_message(msg.map), float(info.resolution),
                               (float(goal.x), float(goal.y)), self.oracle, origin,
                               diagonal=self.problem.config.diagonal, speed=self.settings.time_limit_speed or None,
                               early_verdicts=self.settings.early_verdicts)
        job.limit_sim = self.oracle.timeout  # the floor; the route's own limit once the start is seen
        start = self._start(job, make, stamp)
        self._publish_map(msg.map, make, stamp)
        head = conversions.header(make, stamp, self.settings.frame_id)
        self.pub_initialpose.publish(make("geometry_msgs/msg/PoseWithCovarianceStamped", header=head,
                                          pose=make("geometry_msgs/msg/PoseWithCovariance", pose=start)))
        self.prepare_stack()
        job.phase, job.settle_until = "settle", now + self.settings.settle_time

    def _start(self, job: Any, make: Any, stamp: int) -> Any:
        """The start pose (job.start_pose), facing the route's first leg unless ``start_heading:=scenario``
        or a hazards scenario; the world's unmapped obstacles published on the way."""
        s = job.msg.start.pose
        job.start_pose = (float(s.position.x), float(s.position.y), conversions.yaw_of(s.orientation))
        hazards = bool(getattr(self.problem, "hazards", False))
        if self.pub_obstacles is not None:  # the world's unmapped obstacles and people, stamped like the map
            unmapped = self.problem.environment(job.scenario).unmapped if hazards else {}
            self.pub_obstacles.publish(conversions.obstacles_message(make, stamp, unmapped or {}))
        if self.settings.start_heading == "route" and not hazards:  # as the full model starts
            route = job.judge.start(job.start_pose[0], job.start_pose[1])
            if len(route) > 1:
                heading = math.atan2(route[1, 1] - route[0, 1], route[1, 0] - route[0, 0])
                job.start_pose = (job.start_pose[0], job.start_pose[1], heading)
                s = conversions.pose(make, *job.start_pose)
        return s

    def _publish_map(self, grid: Any, make: Any, stamp: int) -> None:
        frame, k = self.settings.frame_id, self.settings.map_upsample
        if k > 1:
            self.pub_map.publish(conversions.upsampled_grid(make, grid, k, stamp, frame))
        else:
            self.pub_map.publish(make("nav_msgs/msg/OccupancyGrid", header=conversions.header(make, stamp, frame),
                                      info=grid.info, data=grid.data))

    def prepare_stack(self) -> None:
        """The stack's own preparation for a new map (Nav2: its costmaps cleared)."""

    def send_goal(self, job: Any) -> None:
        self.pub_goal.publish(self.goal_message(job))
        job.goal_sends, job.goal_sent = job.goal_sends + 1, time.monotonic()

    def step(self, job: Any, view: RunView) -> str | None:
        """A goal the stack never answered (no status on ``stall_topic``, no plan) goes again."""
        if job.goal_sends and job.goal_sends <= GOAL_RESENDS and view.now - job.goal_sent > GOAL_RESEND_S \
                and self.unanswered(job):
            self.node.logger.warning(f"scenario {job.scenario_id}: no sign the stack took the goal in "
                                     f"{GOAL_RESEND_S:g} s (no status on {self.topics['stall'] or '-'}, no plan on "
                                     f"{self.topics['plan'] or '-'}): it goes again")
            self.send_goal(job)
        return None

    def unanswered(self, job: Any) -> bool:
        """Nothing of the stack's since the goal went out (False when nothing could tell: neither a
        status nor a plan topic)."""
        if not self.topics["stall"] and not self.topics["plan"]:
            return False
        return not job.heard.get("stall") and not self.plans

    def goal_message(self, job: Any) -> Any:
        make = self.node.new_message
        return make("geometry_msgs/msg/PoseStamped",
                    header=conversions.header(make, self.node.now_ns(), self.settings.frame_id),
                    pose=job.msg.goal.pose)

    # --- samples --------------------------------------------------------------------------------
    def at_start(self, sample: tuple | None, job: Any) -> bool:
        """Is this pose sample the robot at the scenario's start (within ``start_tolerance``)?"""
        if sample is None:
            return False
        s = self.settings
        x, y, yaw = sample[2], sample[3], sample[4]
        if s.odom_frame == "map":
            x, y, yaw = x - job.start_pose[0], y - job.start_pose[1], yaw - job.start_pose[2]
        turned = abs((yaw + math.pi) % (2 * math.pi) - math.pi)
        return math.hypot(x, y) <= s.start_tolerance and not turned > s.start_yaw_tolerance >= 0

    def feed(self, job: Any, t: Any, values: Any, events: list[dict]) -> None:
        x, y, yaw, v = values.T
        if self.settings.odom_frame == "start":
            x, y, yaw = to_map_frame(x, y, yaw, job.start_pose)
        collision = self.topics["collision"]
        job.judge.add(t, x, y, yaw, stall=[e.get("stall") for e in events],
                      collision=[f"reported on {collision}: {e['collision']}" if "collision" in e else None
                                 for e in events])
        if math.isfinite(job.judge.time_limit):
            job.limit_sim = max(job.limit_sim, job.judge.time_limit)

    # --- what it adds to the record -------------------------------------------------------------
    def with_plans(self, outcome: Outcome) -> Outcome:
        """The plans counted since the goal, the last one's length; a failure without any says so."""
        length = None if self.last_plan is None else polyline_length(conversions.path_points(self.last_plan))
        outcome.metrics = {**outcome.metrics, "plans": self.plans, "plan_length_m": length}
        if outcome.failed and not self.plans:
            outcome.detail = f"{outcome.detail}; no plan on {self.topics['plan']} since the goal"
        return outcome


def with_give_up(outcome: Outcome, gave_up: Any, stall_topic: str | None) -> Outcome:
    """A stall verdict whose cause is the one the stack reported on ``stall_topic`` says so."""
    if outcome.failure_kind == "stall" and gave_up is not None and gave_up.event is not None \
            and outcome.metrics.get("stall_cause") == gave_up.event[1]:
        outcome.detail = f"{outcome.detail} (the system under test gave up, on {stall_topic})"
    return outcome

