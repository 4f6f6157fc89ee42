"""A driving stack (``problem:=vehicle``): the road out, the car's odometry in.

The road goes out on ``road_topic`` (``nav_msgs/Path``, latched) and starts the run; the stack
answers on ``odom_topic`` (``nav_msgs/Odometry``, the pose being the centre of the car's bounding
box). ``CarJudge`` decides: out of lane beyond ``oracle.oob_tolerance``, a stall, the goal within
``oracle.goal_distance`` of the road's end, or the time limit (``timeout_base`` + length /
``timeout_speed``).
"""
from __future__ import annotations

from typing import Any

from ambiegen_ros.ros import conversions
from ambiegen_ros.ros.qos import LATCHED
from ambiegen_ros.sims.oracles import CarJudge

from .judge import ScenarioJudge
from .params import Param
from .samples import to_map_frame

VEHICLE_PARAMS = (
    Param("road_topic", str, "/road", "nav_msgs/Path out, latched: the road"),
    Param("odom_topic", str, "/odom", "nav_msgs/Odometry in: the centre of the car's bounding box"),
)


class VehicleRun(ScenarioJudge):
    """The road published once; the car's odometry judged by ``CarJudge``."""

    problem = "vehicle"
    PARAMS = VEHICLE_PARAMS
    ORACLE_FIELDS = ("length", "width", "rear_overhang", "lane_width", "oob_tolerance", "stall_distance",
                     "stall_time", "goal_distance", "timeout_base", "timeout_speed")

    def __init__(self, node: Any, settings: Any, oracle: Any, problem: Any):
        super().__init__(node, settings, oracle, problem)
        self.topics = {"road": settings.road_topic, "odom": settings.odom_topic}

    def wire(self, host: Any) -> None:
        self.pub_road = self.node.create_publisher("nav_msgs/msg/Path", self.topics["road"], LATCHED)
        super().wire(host)

    def needs_subscribers(self) -> list[Any]:
        return [self.pub_road]

    def setup(self, job: Any, now: float) -> None:
        make, msg = self.node.new_message, job.msg
        head = conversions.header(make, self.node.now_ns(), self.settings.frame_id)
        job.judge = CarJudge(conversions.path_points(msg.road), float(msg.lane_width), self.oracle)
        job.limit_sim = job.judge.time_limit
        self.pub_road.publish(make("nav_msgs/msg/Path", header=head, poses=list(msg.road.poses)))
        job.phase, job.go = "waiting", now

    def feed(self, job: Any, t: Any, values: Any, events: list[dict]) -> None:
        x, y, yaw, v = values.T
        if self.settings.odom_frame == "start":
            x, y, yaw = to_map_frame(x, y, yaw, job.start_pose)
        job.judge.add(t, x, y, yaw, v)
