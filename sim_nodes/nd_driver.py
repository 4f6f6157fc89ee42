"""`nd_driver`: the full model's robot (route + Nearness Diagram) as a navigation stack on Nav2's topics.

A thin node over ``ambiegen_ros.sims.robot.RouteFollower``, the controller the in-process full
model drives with. To a world (``robot_world``, Stage, Gazebo) it is what Nav2 is: it takes
``scan_topic`` (``sensor_msgs/LaserScan``), ``odom_topic`` (``nav_msgs/Odometry``, map-frame
poses), ``map_topic`` (``nav_msgs/OccupancyGrid``, latched) and a goal on ``goal_topic``
(``geometry_msgs/PoseStamped``, Nav2's ``/goal_pose``), and publishes ``cmd_vel_topic``
(``geometry_msgs/Twist``, or ``TwistStamped`` with ``cmd_vel_stamped:=true``).

* *Planner*: on a goal, the route the full model drives (``sims.robot.plan_route``: the clearance
  route, keeping the footprint's radius + ``sim.clearance_margin`` from every wall) from the
  robot's cell to the goal's, published on ``plan_topic`` (``nav_msgs/Path``).
* *Controller*: one command per scan, computed from the scan and the odometry of the same stamp
  (or the first newer one): waypoints one at a time to Player's ``nd`` driver with the paper's
  numbers (``sim.<field>``: every ``RobotSimConfig`` field).
* *Start*: after an initial pose (``initialpose_topic``), a goal is planned from the first scan
  no older than the first odometry that shows the robot there (within ``start_tolerance`` and
  ``start_yaw_tolerance``), so
  that a scan from before the teleport, still on its way, never starts a run (``robot_world``
  spends a step on every teleport, so the stamps tell them apart).
* *Status*: with every command, a status on ``stall_topic`` (``diagnostic_msgs/DiagnosticArray``,
  '' = none) stamped with the scan it answers: OK, or, once the ND driver gives up (emergency stop,
  no navigable region, stuck) or no route exists, ERROR with the reason, the robot's stall flag;
  it then commands zero until the next goal. The OK ones are heartbeats: a judge that orders the
  streams by stamp (``sut_adapter``) knows from them that the stack has not given up so far.

A new map drops the goal: nothing is commanded until the next one. Topics are not ordered among
themselves, so a goal stamped after the map (or the initial pose) that arrives before it stays.
With ``paired_start:=true`` (as ``robot_world``'s, for ``sut_adapter``, which stamps each run's map
and initial pose alike) a run is planned only on the map stamped like its initial pose: on a loaded
machine the map may arrive after the pose, the goal and the world's first scans, and planning on the
last run's map would then steer this run by it.
"""
from __future__ import annotations

import math
import sys
from typing import Any

import numpy as np

from ambiegen_ros.ros import conversions
from ambiegen_ros.ros.qos import DEFAULT, LATCHED, Qos
from ambiegen_ros.ros.transport import create_node
from ambiegen_ros.sims.robot import RobotSimConfig, RouteFollower, plan_route
from ambiegen_ros.nodes import run_node
from sim_nodes.worker import sim_options

SENSOR_IN = Qos(reliable=False, transient_local=False, depth=10)  # matches reliable and best-effort sensors
PLAN = Qos(reliable=True, transient_local=True, depth=1)


class NDDriverNode:
    def __init__(self, argv: list[str] | None = None, node=None):
        self.node = node or create_node("nd_driver", argv=argv)
        n = self.node
        p = n.declare_parameter
        topic = {name: p(f"{name}_topic", default, desc) for name, default, desc in (
            ("map", "/map", "nav_msgs/OccupancyGrid in"), ("scan", "/scan", "sensor_msgs/LaserScan in"),
            ("odom", "/odom", "nav_msgs/Odometry in (map-frame poses)"), ("goal", "/goal_pose", "PoseStamped in"),
            ("initialpose", "/initialpose", "PoseWithCovarianceStamped in: where the next run starts ('' = none)"),
            ("cmd_vel", "/cmd_vel", "velocity commands out"), ("plan", "/plan", "nav_msgs/Path out ('' = none)"),
            ("stall", "/nd_driver/stall", "diagnostic_msgs/DiagnosticArray out with every command: OK, or ERROR "
                                          "and why the robot gave up ('' = none)"))}
        self.stamped = bool(p("cmd_vel_stamped", False, "publish geometry_msgs/TwistStamped"))
        self.start_tolerance = float(p("start_tolerance", 0.5, "after an initial pose, a goal is planned from a pose "
                                                               "this close to it [m] (older odometry is ignored)"))
        self.start_yaw_tolerance = float(p("start_yaw_tolerance", 0.1, "... and heading this close to it [rad] "
                                                                       "(< 0: any heading)"))
        self.paired = bool(p("paired_start", False, "plan a run only on the map stamped like its initial pose "
                                                    "(sut_adapter stamps them alike; false: the latest map)"))
        self.cfg = sim_options(n, RobotSimConfig)
        self._make = n.new_message
        self.pub_cmd = n.create_publisher("geometry_msgs/msg/TwistStamped" if self.stamped else "geometry_msgs/msg/Twist",
                                          topic["cmd_vel"], DEFAULT)
        self.pub_plan = n.create_publisher("nav_msgs/msg/Path", topic["plan"], PLAN) if topic["plan"] else None
        self.pub_stall = (n.create_publisher("diagnostic_msgs/msg/DiagnosticArray", topic["stall"], DEFAULT)
                          if topic["stall"] else None)
        n.create_subscription("nav_msgs/msg/OccupancyGrid", topic["map"], self.on_map, LATCHED)
        n.create_subscription("sensor_msgs/msg/LaserScan", topic["scan"], self.on_scan, SENSOR_IN)
        n.create_subscription("nav_msgs/msg/Odometry", topic["odom"], self.on_odom, SENSOR_IN)
        n.create_subscription("geometry_msgs/msg/PoseStamped", topic["goal"], self.on_goal, DEFAULT)
        if topic["initialpose"]:
            n.create_subscription("geometry_msgs/msg/PoseWithCovarianceStamped", topic["initialpose"],
                                  self.on_initialpose, DEFAULT)
        self.map: tuple[np.ndarray, float, tuple[float, float]] | None = None
        self.map_stamp = self.pose_stamp = -1
        self.goal: tuple[float, float] | None = None
        self.goal_stamp = -1
        self.follower: RouteFollower | None = None
        self.scan: tuple[int, np.ndarray, np.ndarray, np.ndarray] | None = None  # stamp, angles, ranges, hits
        self.odom: tuple[int, tuple[float, float, float], float, float] | None = None  # stamp, pose, v, w
        self.answered = -1  # stamp of the last scan answered
        self.stamp0 = 0  # stamp of the scan the current goal started from
        self.gave_up: str | None = None  # why, once the ND driver gave up on the current goal
        self.expected_start: tuple[float, float, float] | None = None  # the last initial pose, until a plan starts there
        self.start_stamp: int | None = None  # the first odometry showing the robot there: older scans are stale
        n.logger.info(f"nd driver: {topic['scan']} + {topic['odom']} + {topic['goal']} -> {topic['cmd_vel']}"
                      f" ({self.cfg.planner} planner)")

    # --- inputs ---------------------------------------------------------------------------------
    def on_map(self, msg: Any) -> None:
        info = msg.info
        self.map = (conversions.grid_from_message(msg), float(info.resolution),
                    (float(info.origin.position.x), float(info.origin.position.y)))
        self.map_stamp = conversions.stamp_ns(msg.header)
        if self.goal_stamp <= self.map_stamp:  # a new scenario: wait for its goal (one
            self.goal, self.follower = None, None  # stamped after this map arrived first and stays)
        self._answer()  # paired_start: the scan that waited for this map

    def on_initialpose(self, msg: Any) -> None:
        """A new run starts here: drop the goal; the next plan starts from odometry that shows it
        (scans and odometry from before the teleport may still be on their way). Topics are not
        ordered among themselves: a goal stamped after this pose arrived first and stays."""
        x, y = conversions.require_finite((msg.pose.pose.position.x, msg.pose.pose.position.y), "pose.pose.position")
        self.expected_start, self.start_stamp = (float(x), float(y), conversions.yaw_of(msg.pose.pose.orientation)), None
        self.pose_stamp = conversions.stamp_ns(msg.header)
        if self.goal_stamp <= self.pose_stamp:  # a goal stamped later is this run's: keep it
            self.goal, self.follower = None, None

    def on_goal(self, msg: Any) -> None:
        x, y = conversions.require_finite((msg.pose.position.x, msg.pose.position.y), "pose.position")
        self.goal, self.follower, self.gave_up = (float(x), float(y)), None, None
        self.goal_stamp = conversions.stamp_ns(msg.header)
        self._answer()

    def on_scan(self, msg: Any) -> None:
        angles, ranges, hits = conversions.scan_beams(msg)
        self.scan = (conversions.stamp_ns(msg.header), angles, ranges, hits)
        self._answer()

    def on_odom(self, msg: Any) -> None:
        pose, twist = msg.pose.pose, msg.twist.twist
        x, y, v, w = conversions.require_finite((pose.position.x, pose.position.y, twist.linear.x, twist.angular.z),
                                                "odometry pose / twist")
        self.odom = (conversions.stamp_ns(msg.header), (float(x), float(y), conversions.yaw_of(pose.orientation)),
                     float(v), float(w))
        start, yaw = self.expected_start, self.odom[1][2]
        if start is not None and self.start_stamp is None and math.hypot(x - start[0], y - start[1]) <= self.start_tolerance:
            turned = abs((yaw - start[2] + math.pi) % (2 * math.pi) - math.pi)
            if not turned > self.start_yaw_tolerance >= 0:
                self.start_stamp = self.odom[0]
        self._answer()

    # --- the controller -------------------------------------------------------------------------
    def _answer(self) -> None:
        """One command per scan, once the odometry of its stamp (or a newer one) is here."""
        if self.goal is None or self.map is None or self.scan is None or self.odom is None:
            return
        stamp, angles, ranges, hits = self.scan
        if stamp <= self.answered or self.odom[0] < stamp:
            return
        _, pose, v_now, w_now = self.odom
        if self.follower is None:
            if self.expected_start is not None and (self.start_stamp is None or stamp < self.start_stamp):
                return  # a scan from before the teleport: wait for one of the robot at its start
            if self.paired and self.map_stamp != self.pose_stamp:
                return  # this run's map is still on its way
            self.expected_start = None
            self._plan(stamp, angles, pose)
        follower = self.follower
        assert follower is not None
        t = self._time(stamp)
        follower.advance(t, pose)
        v = w = 0.0
        stall = "no_route" if not follower.has_route else None
        if follower.has_route:
            v, w, stall = follower.command(t, pose, v_now, w_now, ranges, hits)
        self.answered = stamp
        self._publish_command(v, w)
        if stall is not None and self.gave_up is None:
            self.gave_up = stall
            self.node.logger.info(f"gave up: {stall}")
        if self.pub_stall is not None:  # stamped with the scan it answers: a decision on what it saw then
            self.pub_stall.publish(conversions.status_report(self._make, stamp, self.node.name, self.gave_up or "",
                                                             "base_link"))

    def _time(self, stamp: int) -> float:
        """Seconds since the goal's first scan, plus one control period: the command for a scan
        drives the next period (the in-process run labels it with the end of that period). Whole
        periods are counted exactly as the in-process run counts them (k x dt)."""
        dt = self.cfg.dt
        t = (stamp - self.stamp0) / 1e9
        k = round(t / dt)
        return (k + 1) * dt if abs(t - k * dt) < 1e-6 else t + dt

    def _plan(self, stamp: int, angles: np.ndarray, pose: tuple[float, float, float]) -> None:
        grid, res, (ox, oy) = self.map
        goal = self.goal
        cell = lambda px, py: (int(math.floor((px - ox) / res)), int(math.floor((py - oy) / res)))  # noqa: E731
        waypoints, length = plan_route(grid, res, cell(pose[0], pose[1]), cell(*goal), self.cfg)
        waypoints = waypoints + (ox, oy) if len(waypoints) else waypoints
        self.stamp0 = stamp
        self.follower = RouteFollower(self.cfg, waypoints, angles, pose, t=0.0)
        if self.pub_plan is not None:
            self.pub_plan.publish(conversions.path(self._make, stamp, waypoints))
        route = f"{length:.1f} m, {len(waypoints)} waypoints" if len(waypoints) else "no route"
        self.node.logger.info(f"goal ({goal[0]:.2f}, {goal[1]:.2f}) from ({pose[0]:.2f}, {pose[1]:.2f}): {route}")

    def _publish_command(self, v: float, w: float) -> None:
        make = self._make
        twist = make("geometry_msgs/msg/Twist", linear=make("geometry_msgs/msg/Vector3", x=float(v), y=0.0, z=0.0),
                     angular=make("geometry_msgs/msg/Vector3", x=0.0, y=0.0, z=float(w)))
        if self.stamped:
            twist = make("geometry_msgs/msg/TwistStamped", header=conversions.header(make, self.answered, "base_link"),
                         twist=twist)
        self.pub_cmd.publish(twist)


def main(argv: list[str] | None = None) -> int:
    return run_node("nd_driver", lambda: NDDriverNode(argv), doc=__doc__)


if __name__ == "__main__":
    sys.exit(main())
