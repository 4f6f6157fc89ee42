"""A thermostat (``problem:=thermostat``): set points out on their schedule, temperatures in.

Each element's set point goes out on ``setpoint_topic`` (``std_msgs/Float64``) when the element
starts, at ``time_scale``: the first at setup, the others when the system's clock, which starts
with its first reading, reaches the element's start (wall seconds = start / ``time_scale`` after
that reading's arrival). For simulated rooms the element's room model goes out too on
``room_model_topic`` (``std_msgs/UInt8``) and, first, the start temperature on
``initial_temperature_topic`` (``std_msgs/Float64``); empty names switch these off. Readings come
on ``temperature_topic`` (``sensor_msgs/Temperature``); ``ThermostatJudge`` decides by the RMSE
against the schedule (``oracle.requirement_rmse``).
"""
from __future__ import annotations

import time
from typing import Any

import numpy as np

from ambiegen_ros.ros import conversions
from ambiegen_ros.ros.qos import DEFAULT
from ambiegen_ros.sims.oracles import ThermostatJudge

from .judge import RunView, ScenarioJudge
from .params import Param

THERMOSTAT_PARAMS = (
    Param("setpoint_topic", str, "/thermostat/setpoint", "std_msgs/Float64 out: each element's set point"),
    Param("temperature_topic", str, "/thermostat/temperature", "sensor_msgs/Temperature in: the room's readings"),
    Param("room_model_topic", str, "/thermostat/room_model", "'' = do not publish"),
    Param("initial_temperature_topic", str, "/thermostat/initial_temperature", "'' = do not publish"),
)


class ThermostatRun(ScenarioJudge):
    """Set points on the schedule; the readings judged by ``ThermostatJudge``."""

    problem = "thermostat"
    PARAMS = THERMOSTAT_PARAMS
    ORACLE_FIELDS = ("requirement_rmse", "band")
    SAMPLE_KEY, SAMPLE_TYPE = "temperature", "sensor_msgs/msg/Temperature"
    samples_are = "temperature readings"

    def __init__(self, node: Any, settings: Any, oracle: Any, problem: Any):
        super().__init__(node, settings, oracle, problem)
        self.topics = {key: settings[f"{key}_topic"]
                       for key in ("setpoint", "temperature", "room_model", "initial_temperature")}

    def wire(self, host: Any) -> None:
        n, t = self.node, self.topics
        self.pub_setpoint = n.create_publisher("std_msgs/msg/Float64", t["setpoint"], DEFAULT)
        self.pub_model = n.create_publisher("std_msgs/msg/UInt8", t["room_model"], DEFAULT) if t["room_model"] else None
        self.pub_reset = (n.create_publisher("std_msgs/msg/Float64", t["initial_temperature"], DEFAULT)
                          if t["initial_temperature"] else None)
        super().wire(host)

    def needs_subscribers(self) -> list[Any]:
        return [self.pub_setpoint]

    def sample_of(self, msg: Any) -> tuple:
        temperature = float(conversions.require_finite(msg.temperature, "temperature"))
        return conversions.stamp_ns(msg.header), time.monotonic_ns(), temperature

    def setup(self, job: Any, now: float) -> None:
        msg = job.msg
        setpoints = [float(v) for v in np.asarray(msg.setpoints, dtype=float)]
        durations = [float(v) for v in np.asarray(msg.durations_min, dtype=float)]
        models = [int(v) for v in np.asarray(msg.room_models)]
        job.judge = ThermostatJudge(setpoints, durations, self.oracle)
        job.limit_sim = job.judge.total
        starts = np.concatenate([[0.0], np.cumsum(np.asarray(durations) * 60.0)[:-1]])
        job.schedule = list(zip(starts.tolist(), setpoints, models))
        self.publish_element(job.schedule[0])
        if self.pub_reset is not None:
            self.pub_reset.publish(self.node.new_message("std_msgs/msg/Float64", data=float(msg.initial_temperature)))
        job.next_element = 1
        job.phase, job.go = "waiting", now

    def publish_element(self, element: tuple[float, float, int]) -> None:
        make = self.node.new_message
        _, setpoint, model = element
        if self.pub_model is not None:
            self.pub_model.publish(make("std_msgs/msg/UInt8", data=int(model)))
        self.pub_setpoint.publish(make("std_msgs/msg/Float64", data=float(setpoint)))

    def feed(self, job: Any, t: Any, values: Any, events: list[dict]) -> None:
        job.judge.add(t, values[:, 0])

    def step(self, job: Any, view: RunView) -> str | None:
        """Set point changes follow the system's clock, which starts with its first reading."""
        while (job.anchor is not None and job.next_element < len(job.schedule)
               and view.now >= job.anchor + job.schedule[job.next_element][0] / self.settings.time_scale):
            self.publish_element(job.schedule[job.next_element])
            job.next_element += 1
        return None
