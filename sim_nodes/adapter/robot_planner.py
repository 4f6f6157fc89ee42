"""Nav2's global planner as the system under test (``problem:=robot``, ``goal_mode:=plan``, issue 68).

No robot moves and no clock runs: a scenario is a map, a start and a goal, and the stack is
Nav2's ``planner_server`` (and ``smoother_server``) alone. Per scenario:

* **The map** goes out on ``map_topic`` as the robot judges publish it (``map_upsample``), stamped
  now (the stack runs on wall time, ``use_sim_time`` false).
* **The costmap shows this map** (``costmap_topic``: the ``OccupancyGrid`` a Nav2 costmap
  publishes, read with ``Costmap.from_costmap_grid``) when its size, resolution and origin are the
  published map's, its stamp is not older than the map's, and (``costmap_match:=lethal``, the
  default) its LETHAL cells are exactly the map's occupied cells: the static layer marks those and
  nothing else makes 254 on a stack without sensors, so a costmap still holding the last map never
  passes. Nav2's grid translation is exact at the values the oracles read (free, 253, 254,
  unknown), so the grid is enough; ``nav2_msgs/Costmap`` (``costmap_raw``) is not in our type store.
* **The question**: ``compute_path_to_pose`` (``ComputePathToPose``: the scenario's start and goal
  with ``use_start`` true, ``planner_id``); a scenario with vias (``problems.robot_hazards``, read
  from the scenario its ``meta.scenario_json`` holds: the message has map, start and goal only)
  asks ``compute_path_through_poses`` (``ComputePathThroughPoses``: goals the vias in order, then
  the goal); with ``smooth`` the path it returns goes to ``smooth_path`` (``SmoothPath``,
  ``check_for_collisions`` false: we check).
* **The verdict** (``plan_outcome``): ``judge_plan`` (``ambiegen_ros.sims.plans``) on the costmap
  read back, with the rules of ``planner_plugin`` (a ``rules.PROFILES`` entry, ``planner_rules``
  overriding its defaults). A path the oracles flag is FAIL(collision) for a path or a smoothed
  path through lethal space, FAIL(requirement) for every other oracle (ends, unknown space,
  reversal, turning radius, a failure where the reference planner has a certificate), the
  oracle's own kind first in the detail and in ``metrics["plan_oracle"]``, the certificate in
  ``metrics["certificate"]``. A refusal the reference proves right (no path, a goal off the map,
  a blocked start), or one it cannot decide, is INVALID_TEST. Planning over the plugin's own
  ``max_planning_time`` is ``metrics["plan_performance"]``, never a failure.
* **Its own watchdogs**: no matching costmap within ``costmap_timeout`` is an error record (ours:
  the map did not reach the costmap); no answer within ``answer_timeout`` is FAIL(sut_crashed,
  hung); a server that dies mid-run is FAIL(sut_crashed) by the node's crash reports.
* **TF.** With ``tf_frames`` (map,odom,base_link) the adapter publishes them as identity static
  transforms: the global costmap needs the robot's pose to activate and to update, and no world runs.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any, Optional

import numpy as np

from ambiegen_ros.core.config import ConfigError
from ambiegen_ros.ros import conversions
from ambiegen_ros.ros.qos import DEFAULT, LATCHED
from ambiegen_ros.sims import Outcome
from ambiegen_ros.sims.plans import rules as plan_rules
from ambiegen_ros.sims.plans.costmap import LETHAL, Costmap
from ambiegen_ros.sims.plans.oracles import judge_plan, yaw_from_quaternion
from ambiegen_ros.sims.plans.reference import ReferenceResult

from .judge import DECIDED, HOLD, RunView, ScenarioJudge
from .params import Param
from .robot_topic import ROBOT_ORACLE, ROBOT_PARAMS

PLAN_ACTION = "nav2_msgs/action/ComputePathToPose"
PLAN_THROUGH_ACTION = "nav2_msgs/action/ComputePathThroughPoses"
SMOOTH_ACTION = "nav2_msgs/action/SmoothPath"
GET_STATE = "lifecycle_msgs/srv/GetState"
SUCCEEDED = 4  # action_msgs/GoalStatus
COLLISION_KINDS = ("collision", "smoother_collision")  # FAIL(collision); every other oracle FAIL(requirement)
REFUSALS_RIGHT = ("correct_refusal", "goal_outside_map", "start_outside_map", "start_blocked", "undecided",
                  "kinematic_hint")  # an error answer that is no finding: INVALID_TEST


def parse_rules(text: str) -> dict[str, Any]:
    """``key=value,...`` overrides of a planner profile's defaults (numbers, true/false, words)."""
    out: dict[str, Any] = {}
    for item in filter(None, (part.strip() for part in text.split(","))):
        key, sep, raw = item.partition("=")
        if not sep or not key.strip():
            raise ValueError(item)
        raw = raw.strip()
        if raw.lower() in ("true", "false"):
            out[key.strip()] = raw.lower() == "true"
        else:
            try:
                out[key.strip()] = float(raw)
            except ValueError:
                out[key.strip()] = raw
    return out


def planner_rules(plugin: str, overrides: dict[str, Any]) -> plan_rules.PlannerRules:
    """The rules of ``plugin`` (``rules.PROFILES``) with ``overrides``; a bad key is one ConfigError line."""
    try:
        return plan_rules.PROFILES[plugin](**overrides)
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"planner_rules: {exc}") from None


PLANNER_PARAMS = tuple(p for p in ROBOT_PARAMS if p.name in ("settle_time", "map_upsample", "map_topic",
                                                              "robot_profile")) + (
    Param("planner_plugin", str, "navfn", "goal_mode plan: the planner under test, whose rules judge its paths "
                                          "(ambiegen_ros/sims/plans/rules.py; docs/planner_oracles.md)",
          allowed=tuple(plan_rules.PROFILES)),
    Param("planner_rules", str, "", "goal_mode plan: the plugin's parameters where the user's params differ from "
                                    "Jazzy's, key=value comma separated (tolerance=0.25,allow_unknown=false; "
                                    "'' = Jazzy's defaults)", parse=parse_rules, parse_text="key=value,..."),
    Param("planner_id", str, "", "goal_mode plan: ComputePathToPose's planner_id (the planner_server's plugin "
                                 "name, e.g. GridBased; '' = its only one)"),
    Param("plan_action", str, "compute_path_to_pose", "goal_mode plan: the planner_server's action"),
    Param("plan_through_action", str, "compute_path_through_poses", "goal_mode plan: the planner_server's action for "
                                                                    "a scenario with vias (asked when the config's "
                                                                    "max_vias > 0: goals the vias, then the goal)"),
    Param("smooth", bool, False, "goal_mode plan: send each path to smooth_action too and check that the smoothed "
                                 "path collides nowhere its input did not"),
    Param("smooth_action", str, "smooth_path", "goal_mode plan: the smoother_server's action"),
    Param("smoother_id", str, "", "goal_mode plan: SmoothPath's smoother_id ('' = the server's only one)"),
    Param("costmap_topic", str, "/global_costmap/costmap", "goal_mode plan: nav_msgs/OccupancyGrid in: the planner's "
                                                           "global costmap as Nav2 publishes it"),
    Param("costmap_match", str, "lethal", "goal_mode plan: when the costmap shows the scenario's map: lethal = size, "
                                          "resolution, origin, a stamp not before the map's and its lethal cells the "
                                          "map's occupied ones; stamp = all but the cells", allowed=("lethal", "stamp")),
    Param("costmap_timeout", float, 20.0, "goal_mode plan: seconds for the costmap to show the map (else an error "
                                          "record)", minimum=0, above=True),
    Param("answer_timeout", float, 60.0, "goal_mode plan: seconds for each server's answer (else FAIL(sut_crashed): "
                                         "hung)", minimum=0, above=True),
    Param("plan_lifecycle_nodes", str, "planner_server", "goal_mode plan: nodes that must be active first "
                                                         "(smoother_server is added with smooth)"),
    Param("tf_frames", str, "map,odom,base_link", "goal_mode plan: frames the adapter chains with identity static "
                                                  "transforms on /tf_static, for the costmap's robot pose ('' = none: "
                                                  "someone else publishes them)"),
)


@dataclass
class PlanAnswer:
    """What the servers said: the planner's status, error and path, the smoother's if asked."""

    status: int = 0
    error_code: int = 0
    error_msg: str = ""
    path: Optional[np.ndarray] = None  # (N, 3) x, y, yaw
    planning_time: Optional[float] = None  # the planner's own figure [s]
    answer_s: float = 0.0  # wall seconds from the goal to the result
    smoothed: Optional[np.ndarray] = None
    smooth_error: str = ""

    @property
    def error(self) -> Optional[str]:
        """The planner's failure as the oracles read it (None: a path came back)."""
        if self.status == SUCCEEDED and self.error_code == 0 and self.path is not None and len(self.path):
            return None
        what = f"error {self.error_code}" + (f" {self.error_msg}" if self.error_msg else "")
        return what if self.status == SUCCEEDED or self.error_code else f"status {self.status}, {what}"


def poses_of(msg_path: Any) -> np.ndarray:
    """A ``nav_msgs/Path`` as (N, 3) x, y, yaw."""
    rows = [(p.pose.position.x, p.pose.position.y,
             yaw_from_quaternion(p.pose.orientation.x, p.pose.orientation.y, p.pose.orientation.z,
                                 p.pose.orientation.w)) for p in msg_path.poses]
    return np.asarray(rows, dtype=float).reshape(-1, 3)


def clearance(costmap: Costmap, path: np.ndarray) -> float:
    """The path's least distance [m] from a lethal cell's centre (inf: none): the search's objective."""
    lethal = np.argwhere(costmap.cost == LETHAL)
    if not len(lethal) or path is None or not len(path):
        return math.inf
    centres = np.column_stack([costmap.origin_x + (lethal[:, 1] + 0.5) * costmap.resolution,
                               costmap.origin_y + (lethal[:, 0] + 0.5) * costmap.resolution])
    from scipy.spatial import cKDTree

    return float(cKDTree(centres).query(path[:, :2])[0].min())


def plan_outcome(costmap: Costmap, rules: plan_rules.PlannerRules, start: tuple, goal: tuple,
                 answer: PlanAnswer, vias: tuple = ()) -> Outcome:
    """The verdict on one answer (module docstring): a finding, an INVALID_TEST or a PASS, with
    metrics; ``vias``: the poses it was asked through (ComputePathThroughPoses), in order."""
    error = answer.error
    judgement = judge_plan(costmap, rules, start, goal, path=None if error else answer.path, error=error,
                           planning_time=answer.planning_time,
                           smoothed=answer.smoothed if not error else None, vias=vias)
    v = judgement.verdict
    # a path that held is as close as its judged poses came: those leaving a colliding start are not judged
    near = clearance(costmap, answer.path[judgement.judged_from:]) if not error else math.inf
    metrics: dict[str, Any] = {
        "plan_oracle": v.kind, "plan_failures": [f.kind for f in judgement.failures], "planner": rules.name,
        "plan_error_code": answer.error_code, "plan_error_msg": answer.error_msg,
        "planning_time_s": answer.planning_time, "plan_answer_s": round(answer.answer_s, 4),
        "plan_poses": 0 if answer.path is None else len(answer.path),
        "plan_clearance_m": None if math.isinf(near) else round(near, 4),
        "costmap": [costmap.size_x, costmap.size_y, costmap.resolution, costmap.origin_x, costmap.origin_y],
    }
    if vias:
        metrics["plan_vias"] = [[round(float(v), 4) for v in via] for via in vias]
    if answer.smooth_error:
        metrics["smooth_error"] = answer.smooth_error
    if answer.smoothed is not None and not error:  # the smoother answered: its path, as the input's figures
        metrics["smoothed_poses"] = len(answer.smoothed)
        smoothed_near = clearance(costmap, answer.smoothed) if len(answer.smoothed) else math.inf
        metrics["smoothed_clearance_m"] = None if math.isinf(smoothed_near) else round(smoothed_near, 4)
    performance = next((n for n in judgement.notes if n.kind == "performance"), None)
    if performance is not None:
        metrics["plan_performance"] = performance.detail
    if isinstance(v.evidence, ReferenceResult):
        metrics["certificate" if v.evidence.found else "reference"] = v.evidence.to_dict()
    objectives = {"plan_closeness": -near if math.isfinite(near) else -1e3}
    trajectory = None if answer.path is None or not len(answer.path) else answer.path[:, :2].copy()
    if judgement.failed:
        kind = "collision" if v.kind in COLLISION_KINDS else "sut_crashed" if v.kind == "sut_crashed" else "requirement"
        where = None if v.cell is None else costmap.map_to_world(*v.cell)
        return Outcome(objectives, True, kind, f"{v.kind}: {v.detail}", metrics=metrics, trajectory=trajectory,
                       failure_point=where)
    if error is not None:  # a refusal that is no finding (REFUSALS_RIGHT)
        return Outcome(objectives, False, "invalid_test", f"{v.kind}: {v.detail}", metrics=metrics)
    return Outcome(objectives, False, "none", f"{rules.name}'s path holds ({v.detail})", metrics=metrics,
                   trajectory=trajectory)


def costmap_shows(grid_msg: Any, published: Any, occupied: np.ndarray, mode: str) -> tuple[bool, str]:
    """Does the costmap ``grid_msg`` show the map ``published`` (its occupied cells ``occupied``)? And if
    not, why (for the error record at ``costmap_timeout``)."""
    a, b = grid_msg.info, published.info
    if (int(a.width), int(a.height)) != (int(b.width), int(b.height)):
        return False, f"{a.width} x {a.height} cells, the map {b.width} x {b.height}"
    if abs(float(a.resolution) - float(b.resolution)) > 1e-6:
        return False, f"resolution {a.resolution:g}, the map's {b.resolution:g}"
    if max(abs(float(a.origin.position.x) - float(b.origin.position.x)),
           abs(float(a.origin.position.y) - float(b.origin.position.y))) > 1e-6:
        return False, "another origin"
    if conversions.stamp_ns(grid_msg.header) < conversions.stamp_ns(published.header):
        return False, "stamped before the map"
    if mode == "lethal":
        lethal = np.asarray(grid_msg.data, dtype=np.int16).reshape(occupied.shape) == 100
        if not np.array_equal(lethal, occupied):
            return False, f"{int((lethal != occupied).sum())} cells lethal where the map is not occupied or back"
    return True, ""


def costmap_of(grid_msg: Any) -> Costmap:
    info = grid_msg.info
    return Costmap.from_costmap_grid(grid_msg.data, int(info.width), int(info.height), float(info.resolution),
                                     float(info.origin.position.x), float(info.origin.position.y))


class PlanRun:
    """The run's oracle as the node holds it (``job.judge``): decided once the answer is judged."""

    def __init__(self) -> None:
        self.started = time.monotonic()
        self.decided, self._outcome = False, None

    @property
    def elapsed(self) -> float:
        return time.monotonic() - self.started

    def decide(self, outcome: Outcome) -> None:
        if not self.decided:
            self.decided, self._outcome = True, outcome

    def fail(self, kind: str, detail: str) -> None:
        """A failure the node found (a crash report during the run)."""
        self.decide(Outcome({}, True, kind, detail))

    def finish(self, reason: str) -> None:
        """A node's watchdog: an error record."""
        self.decide(Outcome.rejected(reason, kind="error"))

    def outcome(self) -> Outcome:
        return self._outcome if self._outcome is not None else Outcome.rejected("no verdict", kind="error")


class PlannerRobot(ScenarioJudge):
    """Nav2's planner_server (and smoother_server) asked directly; our oracles judge the answer."""

    problem, goal_mode = "robot", "plan"
    PARAMS = PLANNER_PARAMS
    ORACLE_FIELDS = ROBOT_ORACLE
    SAMPLE_KEY = "costmap"  # the node waits until someone publishes it; no sample is ever fed
    SAMPLE_TYPE = "nav_msgs/msg/OccupancyGrid"
    samples_are = "costmap"
    certifies_itself = True  # the reference planner certifies a failure here, not the robot problem's reference

    def __init__(self, node: Any, settings: Any, oracle: Any, problem: Any):
        super().__init__(node, settings, oracle, problem)
        self.topics = {"map": settings.map_topic, "costmap": settings.costmap_topic}
        self.rules = planner_rules(settings.planner_plugin, settings.planner_rules)
        names = [n.strip().strip("/") for n in settings.plan_lifecycle_nodes.split(",") if n.strip()]
        if settings.smooth and "smoother_server" not in names:
            names.append("smoother_server")
        self.lifecycle_nodes, self.active, self._asking = names, set(), set()
        self.grid: Any = None  # the newest costmap message
        # scenarios may hold vias: ask (and wait for) the through-poses action too
        self.through_poses = bool(getattr(getattr(problem, "config", None), "max_vias", 0))
        self.plan_through: Any = None
        self.reset()

    def reset(self) -> None:
        self.vias: tuple = ()  # this scenario's vias, (x, y, yaw) in order
        self.state, self.since, self.published, self.occupied = "idle", 0.0, None, None
        self.answer, self.costmap, self.why_not, self.grid_seen = PlanAnswer(), None, "no costmap yet", None

    def wire(self, host: Any) -> None:
        n, s = self.node, self.settings
        self._job = lambda: host.job
        self.pub_map = n.create_publisher("nav_msgs/msg/OccupancyGrid", s.map_topic, LATCHED)
        n.create_subscription(self.SAMPLE_TYPE, s.costmap_topic, self.on_costmap, LATCHED)
        self.plan = n.create_action_client(PLAN_ACTION, s.plan_action)
        if self.through_poses:
            self.plan_through = n.create_action_client(PLAN_THROUGH_ACTION, s.plan_through_action)
        self.smoother = n.create_action_client(SMOOTH_ACTION, s.smooth_action) if s.smooth else None
        self._states = {name: n.create_client(GET_STATE, f"/{name}/get_state") for name in self.lifecycle_nodes}
        frames = [f.strip() for f in s.tf_frames.split(",") if f.strip()]
        if len(frames) > 1:
            pub = n.create_publisher("tf2_msgs/msg/TFMessage", "/tf_static", LATCHED)
            make, stamp = n.new_message, n.now_ns()
            pub.publish(make("tf2_msgs/msg/TFMessage", transforms=[
                conversions.transform(make, stamp, a, b) for a, b in zip(frames, frames[1:])]))
            self.pub_tf = pub  # kept: a latched publisher must live for late subscribers

    def on_costmap(self, msg: Any) -> None:
        self.grid = msg

    def needs_subscribers(self) -> list[Any]:
        return [self.pub_map]

    def missing(self) -> list[str]:
        """The servers' actions, and each lifecycle node active (asked over get_state until it is)."""
        out = [] if self.plan.server_is_ready() else [f"the planner's {self.settings.plan_action} action is not up"]
        if self.plan_through is not None and not self.plan_through.server_is_ready():
            out.append(f"the planner's {self.settings.plan_through_action} action is not up")
        if self.smoother is not None and not self.smoother.server_is_ready():
            out.append(f"the smoother's {self.settings.smooth_action} action is not up")
        for name, client in self._states.items():
            if name in self.active:
                continue
            out.append(f"Nav2 node {name} is not active")
            if name in self._asking or not client.service_is_ready():
                continue
            self._asking.add(name)

            def done(future, name=name):
                self._asking.discard(name)
                response = future.result()
                if response is not None and response.current_state.label == "active":
                    self.active.add(name)

            client.call_async(client.new_request()).add_done_callback(done)
        return out

    def begin(self, job: Any) -> None:
        self.reset()

    def setup(self, job: Any, now: float) -> None:
        """The map out (stamped now), the run's oracle made; the question waits for the costmap."""
        make, stamp, msg, k = self.node.new_message, self.node.now_ns(), job.msg, self.settings.map_upsample
        frame = self.settings.frame_id
        if k > 1:
            grid = conversions.upsampled_grid(make, msg.map, k, stamp, frame)
        else:
            grid = make("nav_msgs/msg/OccupancyGrid", header=conversions.header(make, stamp, frame),
                        info=msg.map.info, data=msg.map.data)
        info = grid.info
        self.occupied = np.asarray(grid.data, dtype=np.int16).reshape(int(info.height), int(info.width)) >= 100
        self.published = grid
        s, g = job.msg.start.pose, job.msg.goal.pose
        job.start_pose = (float(s.position.x), float(s.position.y), conversions.yaw_of(s.orientation))
        self.goal_pose = (float(g.position.x), float(g.position.y), conversions.yaw_of(g.orientation))
        self.vias = tuple(self.problem.via_poses(job.scenario)) if self.through_poses else ()
        job.judge = PlanRun()
        job.limit_sim = self.settings.costmap_timeout + 2 * self.settings.answer_timeout
        self.pub_map.publish(grid)
        job.phase, job.settle_until = "settle", now + self.settings.settle_time

    def send_goal(self, job: Any) -> None:
        self.state, self.since = "costmap", time.monotonic()

    def step(self, job: Any, view: RunView) -> str | None:
        """Costmap, then the planner, then (``smooth``) the smoother, then the verdict; each with its timeout."""
        now = view.now
        if job.judge.decided:
            return DECIDED
        if self.state == "costmap":
            self._await_costmap(job, now)
        elif self.state in ("planning", "smoothing"):
            if now - self.since > self.settings.answer_timeout:
                server = "planner_server" if self.state == "planning" else "smoother_server"
                job.judge.fail("sut_crashed", f"{server} hung: no answer within {self.settings.answer_timeout:g} s")
        elif self.state == "judge":
            job.judge.decide(plan_outcome(self.costmap, self.rules, job.start_pose, self.goal_pose, self.answer,
                                          self.vias))
        return DECIDED if job.judge.decided else HOLD

    def _await_costmap(self, job: Any, now: float) -> None:
        grid = self.grid
        if grid is not None and grid is not self.grid_seen:
            self.grid_seen = grid
            ok, self.why_not = costmap_shows(grid, self.published, self.occupied, self.settings.costmap_match)
            if ok:
                self.costmap = costmap_of(grid)
                self._ask_planner(job)
                return
        if now - self.since > self.settings.costmap_timeout:
            job.judge.finish(f"the global costmap on {self.settings.costmap_topic} did not show the scenario's map "
                             f"within {self.settings.costmap_timeout:g} s (last: {self.why_not}): ours, run it again")

    def _ask_planner(self, job: Any) -> None:
        """ComputePathToPose, or with vias ComputePathThroughPoses (goals: the vias in order, then the goal)."""
        make, stamp, frame = self.node.new_message, self.node.now_ns(), self.settings.frame_id
        start = conversions.pose_stamped(make, stamp, *job.start_pose)
        start.header.frame_id = frame
        if self.vias:
            goals = [conversions.pose_stamped(make, stamp, *pose) for pose in (*self.vias, self.goal_pose)]
            for goal in goals:
                goal.header.frame_id = frame
            client, request = self.plan_through, self.plan_through.new_goal(
                goals=goals, start=start, planner_id=self.settings.planner_id, use_start=True)
        else:
            goal = conversions.pose_stamped(make, stamp, *self.goal_pose)
            goal.header.frame_id = frame
            client, request = self.plan, self.plan.new_goal(goal=goal, start=start,
                                                            planner_id=self.settings.planner_id, use_start=True)
        self.state, self.since = "planning", time.monotonic()
        self._send(client, request, job.judge, self._on_plan)

    def _send(self, client: Any, request: Any, run: PlanRun, then: Any) -> None:
        """Send a goal; ``then(wrapped result)`` unless the scenario is over (``run`` no longer the job's)."""
        def on_response(future):
            handle = future.result()
            if self._current() is not run:
                return
            if handle is None or not handle.accepted:
                then(None)
                return
            handle.get_result_async().add_done_callback(lambda f: self._current() is run and then(f.result()))

        client.send_goal_async(request).add_done_callback(on_response)

    def _current(self) -> Any:
        job = self._job()
        return None if job is None else job.judge

    def _on_plan(self, wrapped: Any) -> None:
        a = self.answer
        a.answer_s = time.monotonic() - self.since
        if wrapped is None:
            a.status, a.error_msg = 0, "goal rejected"
        else:
            result = wrapped.result
            a.status, a.error_code, a.error_msg = int(wrapped.status), int(result.error_code), str(result.error_msg)
            a.path = poses_of(result.path)
            t = result.planning_time
            a.planning_time = float(t.sec) + float(t.nanosec) / 1e9 or None
        if self.smoother is not None and a.error is None:
            make = self.node.new_message
            request = self.smoother.new_goal(path=wrapped.result.path, smoother_id=self.settings.smoother_id,
                                             max_smoothing_duration=make("builtin_interfaces/msg/Duration", sec=1),
                                             check_for_collisions=False)
            self.state, self.since = "smoothing", time.monotonic()
            self._send(self.smoother, request, self._current(), self._on_smoothed)
            return
        self.state = "judge"

    def _on_smoothed(self, wrapped: Any) -> None:
        if wrapped is None or int(wrapped.status) != SUCCEEDED or int(wrapped.result.error_code):
            code = "rejected" if wrapped is None else f"error {int(wrapped.result.error_code)} {wrapped.result.error_msg}"
            self.answer.smooth_error = f"the smoother answered {code}"
        else:
            self.answer.smoothed = poses_of(wrapped.result.path)
        self.state = "judge"

    def feed(self, job: Any, t: Any, values: Any, events: list[dict]) -> None:
        """No samples here: the costmap is read in ``on_costmap``."""
