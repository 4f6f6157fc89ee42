"""A FAKE of Nav2's planner_server (not Nav2): what the planner judge (``goal_mode:=plan``) needs of one.

``fake_nav2_dds.py`` plays ``planner_server`` with this role when ``FAKE_NAV2_PLANNER`` is set
(``straight`` or ``refuse``), as ``--stack planner`` starts it through the fake ``ros2``; run alone
(``python fake_planner_dds.py MODE``) it is a node named planner_server. It is no planner:

* ``/map`` in (reliable, transient local), ``/global_costmap/costmap`` out: the map's occupied cells
  as 100 and the cells within ``INFLATE_CELLS`` of one as 99 (a crude inflation: a square, not
  Nav2's brushfire), stamped when made, latched like Nav2's;
* ``compute_path_to_pose``: ``straight`` answers a straight line of poses from the goal's start to
  its goal, whatever lies between (so a wall between them is the oracle's FAIL(collision));
  ``refuse`` answers NO_VALID_PATH (208) to every goal (so a reachable goal is a missed path);
  ``crash_blocked`` answers as ``straight`` unless the line crosses an occupied cell, and then dies
  by SIGSEGV, as a planner that segfaults on a map would (the same map crashes it again);
* ``compute_path_through_poses`` as Jazzy's planner_server joins its legs
  (``PlannerServer::computePlanThroughPoses``): leg i from the last pose of the path so far to goal
  i, each later leg's first pose dropped, each leg as above (a straight line); ``short`` ends every
  leg 0.2 m before its goal on the line (inside NavFn's 0.5 m tolerance) and starts the next one
  there, as a planner with a goal tolerance may; ``skip_vias`` answers one line from the start to
  the last goal, as a planner that ignored the vias would (a bug for the oracle to find); ``refuse``
  answers NO_VALID_PATH (308);
* the status and feedback topics are offered (an action server is up only with them) but stay silent:
  the adapter reads only SendGoal and GetResult.
"""
from __future__ import annotations

import os
import signal
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
for extra in (REPO, REPO / "test" / "ros"):
    if str(extra) not in sys.path:
        sys.path.insert(0, str(extra))

from ambiegen_ros.ros import conversions, interfaces  # noqa: E402
from ambiegen_ros.ros.qos import LATCHED  # noqa: E402
from ambiegen_ros.ros.transport.dds_services import FEEDBACK_QOS, STATUS_QOS  # noqa: E402
from test_dds_services import FakeService  # noqa: E402  (rmw_cyclonedds_cpp's service side)

PLAN = "nav2_msgs/action/ComputePathToPose"
THROUGH = "nav2_msgs/action/ComputePathThroughPoses"
CANCEL = "action_msgs/srv/CancelGoal"
INFLATE_CELLS = 2
NO_VALID_PATH, SUCCEEDED, ABORTED = 208, 4, 6
NO_VALID_PATH_THROUGH = 308
SHORT_M = 0.2  # ``short``: each leg ends this far before its goal


def inflated(occupied: np.ndarray, cells: int = INFLATE_CELLS) -> np.ndarray:
    """OccupancyGrid values of a costmap: 100 on occupied cells, 99 within ``cells`` (a square) of one."""
    near = occupied.copy()
    h, w = occupied.shape
    for dy in range(-cells, cells + 1):
        for dx in range(-cells, cells + 1):
            shifted = np.zeros_like(occupied)
            shifted[max(dy, 0):h + min(dy, 0), max(dx, 0):w + min(dx, 0)] = \
                occupied[max(-dy, 0):h + min(-dy, 0), max(-dx, 0):w + min(-dx, 0)]
            near |= shifted
    return np.where(occupied, 100, np.where(near, 99, 0)).astype(np.int8)


class FakeAction:
    """One action server's goal, result and cancel services (and its silent topics): ``plan(goal)``
    gives (status, result fields) for each goal, its result kept until it is asked for."""

    def __init__(self, node, action: str, name: str, plan):
        self.reg, self.action, self.plan = node._registry, action, plan
        interfaces.ensure(self.reg, action)
        interfaces.ensure(self.reg, CANCEL)
        base = f"/{name}/_action/"
        self.result_service = FakeService(node, action + "_GetResult", base + "get_result", self.on_result)
        self.services = [FakeService(node, action + "_SendGoal", base + "send_goal", self.on_goal), self.result_service,
                         FakeService(node, CANCEL, base + "cancel_goal", lambda r, t: self.reg.new(CANCEL + "_Response"))]
        self.offered = [node.create_publisher(action + "_FeedbackMessage", base + "feedback", FEEDBACK_QOS),
                        node.create_publisher("action_msgs/msg/GoalStatusArray", base + "status", STATUS_QOS)]
        self.results: dict[bytes, object] = {}
        self.waiting: dict[bytes, object] = {}

    def on_goal(self, request, _token):
        status, fields = self.plan(request.goal)
        key = bytes(bytearray(request.goal_id.uuid))
        self.results[key] = self.reg.new(self.action + "_GetResult_Response", status=status,
                                         result=self.reg.new(self.action + "_Result", **fields))
        return self.reg.new(self.action + "_SendGoal_Response", accepted=True)

    def on_result(self, request, token):
        key = bytes(bytearray(request.goal_id.uuid))
        if key in self.results:
            return self.results.pop(key)
        self.waiting[key] = token
        return None

    def poll(self) -> None:
        for key in [k for k in self.waiting if k in self.results]:
            self.result_service.respond(self.waiting.pop(key), self.results.pop(key))


class PathPlanner:
    """planner_server's costmap and its two actions, as the module docstring says."""

    def __init__(self, node, mode: str = "straight"):
        self.node, self.reg, self.mode = node, node._registry, mode
        self.actions = [FakeAction(node, PLAN, "compute_path_to_pose", self.to_pose),
                        FakeAction(node, THROUGH, "compute_path_through_poses", self.through_poses)]
        self.services = [s for a in self.actions for s in a.services]
        self.costmap = node.create_publisher("nav_msgs/msg/OccupancyGrid", "/global_costmap/costmap", LATCHED)
        node.create_subscription("nav_msgs/msg/OccupancyGrid", "/map", self.on_map, LATCHED)
        self.maps = 0
        self.occupied, self.info = None, None

    def on_map(self, msg) -> None:
        info = msg.info
        occupied = np.asarray(msg.data, dtype=np.int16).reshape(int(info.height), int(info.width)) >= 100
        make = self.node.new_message
        self.maps += 1
        self.occupied, self.info = occupied, info
        self.costmap.publish(make("nav_msgs/msg/OccupancyGrid", header=conversions.header(make, self.node.now_ns()),
                                  info=info, data=inflated(occupied).reshape(-1)))
        print(f"costmap {self.maps}: {info.width} x {info.height}", flush=True)

    def to_pose(self, goal):
        g, s = goal.goal.pose.position, goal.start.pose.position
        print(f"plan {self.mode}: ({s.x:.2f}, {s.y:.2f}) -> ({g.x:.2f}, {g.y:.2f})", flush=True)
        if self.mode == "refuse":
            return ABORTED, {"error_code": NO_VALID_PATH, "error_msg": "fake: no valid path"}
        return SUCCEEDED, {"path": conversions.path(self.node.new_message, self.node.now_ns(),
                                                    self.leg((s.x, s.y), (g.x, g.y)))}

    def through_poses(self, goal):
        """Jazzy's joining: leg i from the path's last pose so far, each later leg's first pose dropped."""
        s, ends = goal.start.pose.position, [(p.pose.position.x, p.pose.position.y) for p in goal.goals]
        print(f"plan through {self.mode}: ({s.x:.2f}, {s.y:.2f}) -> " + " -> ".join(f"({x:.2f}, {y:.2f})"
                                                                                  for x, y in ends), flush=True)
        if self.mode == "refuse":
            return ABORTED, {"error_code": NO_VALID_PATH_THROUGH, "error_msg": "fake: no valid path"}
        if self.mode == "skip_vias":
            ends = ends[-1:]
        points = np.array([[s.x, s.y]])
        for k, end in enumerate(ends):
            leg = self.leg(tuple(points[-1]), end)
            if self.mode == "short" and len(leg) > 2:
                keep = np.hypot(*(leg - np.asarray(end)).T) >= SHORT_M
                leg = leg[keep] if keep.sum() >= 2 else leg
            points = np.vstack([points, leg[1:]]) if k else leg
        return SUCCEEDED, {"path": conversions.path(self.node.new_message, self.node.now_ns(), points)}

    def leg(self, a, b) -> np.ndarray:
        """A straight line of poses every 5 cm (``crash_blocked``: a SIGSEGV if it crosses a wall)."""
        n = max(2, int(np.hypot(b[0] - a[0], b[1] - a[1]) / 0.05) + 1)
        points = np.linspace(a, b, n)
        if self.mode == "crash_blocked" and self.blocked(points):
            print("crash_blocked: the line crosses a wall: SIGSEGV", flush=True)
            os.kill(os.getpid(), signal.SIGSEGV)
        return points

    def blocked(self, points: np.ndarray) -> bool:
        """Does the line cross an occupied cell of the last map?"""
        if self.occupied is None:
            return False
        res, o = float(self.info.resolution), self.info.origin.position
        cols = ((points[:, 0] - o.x) / res).astype(int).clip(0, self.occupied.shape[1] - 1)
        rows = ((points[:, 1] - o.y) / res).astype(int).clip(0, self.occupied.shape[0] - 1)
        return bool(self.occupied[rows, cols].any())

    def poll(self, now: float) -> None:
        for action in self.actions:
            action.poll()


def main() -> int:
    """Alone: a node named planner_server that also says it is active."""
    from ambiegen_ros.ros import transport

    node = transport.create_node("planner_server", argv=[], backend="dds")
    interfaces.ensure(node._registry, "lifecycle_msgs/srv/GetState")
    role = PathPlanner(node, sys.argv[1] if len(sys.argv) > 1 else os.environ.get("FAKE_NAV2_PLANNER", "straight"))
    state = node._registry.new("lifecycle_msgs/msg/State", id=3, label="active")
    services = role.services + [FakeService(node, "lifecycle_msgs/srv/GetState", "/planner_server/get_state",
                                            lambda r, t: node._registry.new("lifecycle_msgs/srv/GetState_Response",
                                                                            current_state=state))]
    print("planner_server ready (a fake)", flush=True)
    try:
        while True:
            node.spin_once(0.02)
            for service in services:
                service.poll()
            role.poll(time.monotonic())
    except KeyboardInterrupt:
        pass
    node.shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
