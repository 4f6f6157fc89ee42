"""The ROS wire's number formats, applied to an in-process robot run (an emulation, for tests and
``bench/nd_stack.py``): what ``nd_driver`` sees of ``robot_world`` over ROS, in process."""
from __future__ import annotations

import math
from contextlib import contextmanager

import numpy as np


@contextmanager
def wire_emulation():
    """In-process runs see what ``nd_driver`` sees over ROS: float32 ranges, beam angles spread
    between float32 ends, the heading through a quaternion (a patch of the classes, undone on exit)."""
    from ambiegen_ros.sims import robot, robot_world

    scan, init, command = robot_world.RobotWorld.scan, robot.RouteFollower.__init__, robot.RouteFollower.command

    def scan32(self):
        ranges, hits = scan(self)
        return np.asarray(ranges, dtype=np.float32).astype(float), hits

    def init32(self, cfg, waypoints, beam_angles, pose, t=0.0):
        ends = np.asarray(beam_angles, dtype=np.float32)[[0, -1]].astype(float)
        init(self, cfg, waypoints, np.linspace(ends[0], ends[1], len(beam_angles)), pose, t)

    def command_q(self, t, pose, v, w, ranges, hits):
        qz, qw = math.sin(pose[2] / 2), math.cos(pose[2] / 2)
        return command(self, t, (pose[0], pose[1], math.atan2(2.0 * qw * qz, 1.0 - 2.0 * qz * qz)), v, w, ranges, hits)

    robot_world.RobotWorld.scan, robot.RouteFollower.__init__, robot.RouteFollower.command = scan32, init32, command_q
    try:
        yield
    finally:
        robot_world.RobotWorld.scan, robot.RouteFollower.__init__, robot.RouteFollower.command = scan, init, command
