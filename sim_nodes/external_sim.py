"""`external_sim`: our full-model simulators as someone else's stack would run them.

It speaks only standard ROS topics (no ``ambiegen_msgs`` type), so it stands in for a Nav2 robot,
a driving stack or a thermostat when proving ``sut_adapter`` end to end:

* ``robot``: ``map_topic`` (``nav_msgs/OccupancyGrid``, latched), ``initialpose_topic``
  (``geometry_msgs/PoseWithCovarianceStamped``), ``goal_topic`` (``geometry_msgs/PoseStamped``)
  in; ``odom_topic`` (``nav_msgs/Odometry``, map frame) out. A goal starts a run: the whole run is
  computed at once with ``sims.robot.navigate`` (blocking this node for up to a few seconds) and
  then streamed at ``time_scale``. The initial heading is the simulator's own (towards its
  route); the start pose's orientation is ignored. A new map or initial pose aborts the stream.
* ``vehicle``: ``road_topic`` (``nav_msgs/Path``, latched) in; ``odom_topic`` out (pose = the
  centre of the car's bounding box). A road starts a run (``sims.car.drive``), streamed likewise.
* ``thermostat``: ``setpoint_topic`` (``std_msgs/Float64``) in, ``temperature_topic``
  (``sensor_msgs/Temperature``: the true room temperature) out. The room is stepped live
  (``SteppedRoom``: ``sims.room.heat`` one step at a time) at ``time_scale``, with whatever set
  point has arrived. Two optional inputs a simulated room understands, empty names to ignore:
  ``initial_temperature_topic`` (``std_msgs/Float64``: reset the room to this temperature and
  start a new run) and ``room_model_topic`` (``std_msgs/UInt8``: room model 1..7 from now on;
  default the ``room_model`` parameter). A run lasts at most ``max_duration`` simulated seconds.

The problem's numbers (room models, lane width, A* rule) come from ``config_file`` and
``profile`` (``replication`` | ``refined``; '' = the file's, else ``replication``).

Clock: message stamps are this system's simulated clock, which starts at the wall time a run
starts and then advances ``time_scale`` times faster than the wall clock (samples are published
when the wall clock reaches them). Simulator numbers are parameters ``sim.<field>`` (every field
of ``RobotSimConfig`` / ``CarSimConfig`` / ``RoomSimConfig``).
"""
from __future__ import annotations

import math
import sys
from typing import Any

import numpy as np

from ambiegen_ros.core.config import ConfigError
from ambiegen_ros.ros import conversions
from ambiegen_ros.ros.qos import DEFAULT, LATCHED, STREAM, Qos
from ambiegen_ros.ros.transport import create_node
from ambiegen_ros.sims import car, robot
from ambiegen_ros.sims.full_model import SIMULATORS
from ambiegen_ros.sims.room import SteppedRoom, room_of
from ambiegen_ros.nodes import run_node
from sim_nodes.worker import load_problem, sim_options

PROBLEMS = ("robot", "vehicle", "thermostat")


class _Stream:
    """A precomputed run published as the wall clock reaches each sample's simulated time."""

    def __init__(self, columns: dict[str, np.ndarray], start_ns: int, every: int):
        self.cols = columns
        self.start_ns = start_ns
        n = len(columns["t"])
        idx = np.arange(0, n, max(1, every))
        if n and idx[-1] != n - 1:
            idx = np.append(idx, n - 1)  # the last sample (where the run ended) always goes out
        self.idx = idx
        self.next = 0

    def due(self, now_ns: int, time_scale: float) -> np.ndarray:
        sim_now = (now_ns - self.start_ns) / 1e9 * time_scale
        t = self.cols["t"][self.idx]
        end = int(np.searchsorted(t, sim_now + 1e-12, side="right"))
        out = self.idx[self.next:end]
        self.next = max(self.next, end)
        return out

    @property
    def done(self) -> bool:
        return self.next >= len(self.idx)


class ExternalSim:
    def __init__(self, argv: list[str] | None = None, node=None):
        self.node = node or create_node("external_sim", argv=argv)
        n = self.node
        p = n.declare_parameter
        self.problem_name = p("problem", "robot", "robot | vehicle | thermostat")
        if self.problem_name not in PROBLEMS:
            raise ConfigError(f"problem: unknown {self.problem_name!r} (allowed: {'|'.join(PROBLEMS)})")
        self.problem = load_problem(n, self.problem_name)  # config_file (thermostat: room models) + profile
        self.time_scale = float(p("time_scale", 1.0, "simulated seconds per wall second"))
        if not self.time_scale > 0:
            raise ConfigError("time_scale: must be > 0")
        self.seed = p("seed", 0, "seed of every run (laser / sensor noise)")
        self.every = max(1, p("publish_every", 1, "publish every k-th simulator step (the last always)"))
        self.frame_id = p("frame_id", "map", "frame of published poses")
        self.child_frame_id = p("child_frame_id", "base_link", "odometry child frame")
        tick = p("tick_period", 0.002, "seconds between publishing turns")
        self.cfg = sim_options(n, SIMULATORS[self.problem_name][0])
        self.stream: _Stream | None = None
        self.runs = 0
        make = n.new_message
        self._make = make
        if self.problem_name == "robot":
            self.map: tuple[np.ndarray, float, float, float] | None = None
            self.start: tuple[float, float] | None = None
            self.goal: tuple[float, float] | None = None
            self.diagonal = p("diagonal", self.problem.config.diagonal, "A* diagonal rule of the route planner")
            n.create_subscription("nav_msgs/msg/OccupancyGrid", p("map_topic", "/map"), self.on_map, LATCHED)
            n.create_subscription("geometry_msgs/msg/PoseWithCovarianceStamped",
                                  p("initialpose_topic", "/initialpose"), self.on_initialpose, DEFAULT)
            n.create_subscription("geometry_msgs/msg/PoseStamped", p("goal_topic", "/goal_pose"), self.on_goal, DEFAULT)
        elif self.problem_name == "vehicle":
            self.lane_width = float(p("lane_width", float(self.problem.config.lane_width), "lane width [m]"))
            n.create_subscription("nav_msgs/msg/Path", p("road_topic", "/road"), self.on_road, LATCHED)
        else:
            self.room_model = int(p("room_model", 1, "room model while none arrives on room_model_topic"))
            self.initial_temperature = float(p("initial_temperature", float("nan"),
                                               "start temperature without a reset message (NaN = first set point)"))
            self.max_duration = float(p("max_duration", 86400.0, "a run stops after this many simulated seconds"))
            self.setpoint: float | None = None
            self.room: SteppedRoom | None = None
            self.room_start_ns = 0
            n.create_subscription("std_msgs/msg/Float64", p("setpoint_topic", "/thermostat/setpoint"), self.on_setpoint, DEFAULT)
            reset_topic = p("initial_temperature_topic", "/thermostat/initial_temperature", "'' = none")
            model_topic = p("room_model_topic", "/thermostat/room_model", "'' = none")
            if reset_topic:
                n.create_subscription("std_msgs/msg/Float64", reset_topic, self.on_reset, DEFAULT)
            if model_topic:
                n.create_subscription("std_msgs/msg/UInt8", model_topic, self.on_room_model, DEFAULT)
        out_topic = p("temperature_topic" if self.problem_name == "thermostat" else "odom_topic",
                      "/thermostat/temperature" if self.problem_name == "thermostat" else "/odom")
        out_type = "sensor_msgs/msg/Temperature" if self.problem_name == "thermostat" else "nav_msgs/msg/Odometry"
        reliable = p("reliable", True, "publish reliably (false: best effort)")
        self.pub = n.create_publisher(out_type, out_topic, Qos(reliable=reliable, transient_local=False, depth=STREAM.depth))
        n.create_timer(tick, self.tick)
        n.logger.info(f"external {self.problem_name} simulator at {self.time_scale:g}x real time, seed {self.seed}")

    # --- robot ------------------------------------------------------------------------------
    def on_map(self, msg: Any) -> None:
        info = msg.info
        self.map = (conversions.grid_from_message(msg), float(info.resolution),
                    float(info.origin.position.x), float(info.origin.position.y))
        self.node.logger.debug(f"map {info.width}x{info.height} at {info.resolution:g} m")
        self._abort()

    def on_initialpose(self, msg: Any) -> None:
        pos = msg.pose.pose.position
        self.start = tuple(conversions.require_finite((pos.x, pos.y), "pose.pose.position").tolist())
        self.node.logger.debug(f"initial pose {self.start}")
        self._abort()

    def on_goal(self, msg: Any) -> None:
        pos = msg.pose.position
        self.goal = tuple(conversions.require_finite((pos.x, pos.y), "pose.position").tolist())
        self.node.logger.debug(f"goal {self.goal}")
        self._abort()

    def _robot_run(self) -> None:
        grid, res, ox, oy = self.map
        cell = lambda p: (int(math.floor((p[0] - ox) / res)), int(math.floor((p[1] - oy) / res)))  # noqa: E731
        start, goal = cell(self.start), cell(self.goal)
        self.goal = None
        H, W = grid.shape
        if not all(0 <= c[0] < W and 0 <= c[1] < H for c in (start, goal)):
            self.node.logger.warning(f"start {start} or goal {goal} outside the {W}x{H} map; not moving")
            return
        run = robot.navigate(grid, res, start, goal, self.cfg, seed=self.seed, diagonal=self.diagonal)
        tl = run["timeline"]
        cols = {"t": tl["t"], "x": tl["x"] + ox, "y": tl["y"] + oy, "yaw": tl["yaw"], "v": tl["v"]}
        self._start_stream(cols, f"robot run: {run['outcome']} after {run['time']:.1f} s")

    # --- car --------------------------------------------------------------------------------
    def on_road(self, msg: Any) -> None:
        self._abort()
        pts = conversions.require_finite(conversions.path_points(msg), "poses")
        if len(pts) < 2:
            self.node.logger.warning("road with fewer than 2 points; not driving")
            return
        run = car.drive(pts, self.lane_width, self.cfg, seed=self.seed)
        tl = run["timeline"]
        self._start_stream({k: tl[k] for k in ("t", "x", "y", "yaw", "v")},
                           f"car run: {run['outcome']} after {run['time']:.1f} s")

    # --- thermostat ---------------------------------------------------------------------------
    def on_setpoint(self, msg: Any) -> None:
        self.setpoint = float(conversions.require_finite(msg.data, "data"))
        self.node.logger.debug(f"set point {self.setpoint:g} degC")
        if self.room is None:  # no reset message so far: the first set point starts the room
            start = self.initial_temperature if math.isfinite(self.initial_temperature) else self.setpoint
            self._reset_room(start)
        elif self.room.t >= self.max_duration:  # a finished run goes on from where it stopped
            self._reset_room(self.room.T)

    def on_reset(self, msg: Any) -> None:
        self._reset_room(float(conversions.require_finite(msg.data, "data")))

    def on_room_model(self, msg: Any) -> None:
        model = int(msg.data)
        if 1 <= model <= len(self.problem.config.room_conditions):
            self.room_model = model
        else:
            self.node.logger.warning(f"room model {model} unknown (1..{len(self.problem.config.room_conditions)}); ignored")

    def _reset_room(self, temperature: float) -> None:
        self.room = SteppedRoom(self.cfg, room_of(self.problem), temperature, self.seed)
        self.room_started = False
        self.runs += 1
        self.node.logger.debug(f"room reset to {temperature:g} degC (run {self.runs})")

    def _room_tick(self, now: int) -> None:
        room = self.room
        if room is None or room.t >= self.max_duration:
            return
        if not self.room_started:  # the run's clock starts once there is a set point to follow
            if self.setpoint is None:
                return
            self.room_started, self.room_start_ns = True, now
            self._publish_temperature(now, room.T)
        target = math.floor((now - self.room_start_ns) / 1e9 * self.time_scale / self.cfg.dt + 1e-9)
        while room.k < target and room.t < self.max_duration:
            T = room.step(self.setpoint, self.room_model)
            self._publish_temperature(self.room_start_ns + int(round(room.t * 1e9)), T)

    def _publish_temperature(self, stamp_ns: int, value: float) -> None:
        make = self._make
        noise = self.cfg.sensor_noise
        self.pub.publish(make("sensor_msgs/msg/Temperature", header=conversions.header(make, stamp_ns, self.frame_id),
                              temperature=float(value), variance=float(noise * noise)))

    # --- streaming ----------------------------------------------------------------------------
    def _start_stream(self, cols: dict[str, np.ndarray], what: str) -> None:
        self.runs += 1
        self.stream = _Stream(cols, self.node.now_ns(), self.every)
        self.node.logger.info(f"{what} (run {self.runs}; streaming {len(self.stream.idx)} samples)")

    def _abort(self) -> None:
        if self.stream is not None and not self.stream.done:
            self.node.logger.info("new input: the current run is abandoned")
        self.stream = None

    def tick(self) -> None:
        now = self.node.now_ns()
        if self.problem_name == "thermostat":
            self._room_tick(now)
            return
        if self.problem_name == "robot" and self.goal is not None and self.map is not None and self.start is not None:
            self._robot_run()  # blocks while it computes; the run's clock starts afterwards
            now = self.node.now_ns()
        if self.stream is None:
            return
        s = self.stream
        make = self._make
        for i in s.due(now, self.time_scale):
            stamp = s.start_ns + int(round(float(s.cols["t"][i]) * 1e9))
            self.pub.publish(conversions.odometry(make, stamp, s.cols["x"][i], s.cols["y"][i], float(s.cols["yaw"][i]),
                                                  s.cols["v"][i], frame_id=self.frame_id,
                                                  child_frame_id=self.child_frame_id))
        if s.done:
            self.stream = None


def main(argv: list[str] | None = None) -> int:
    return run_node("external_sim", lambda: ExternalSim(argv), doc=__doc__)


if __name__ == "__main__":
    sys.exit(main())
