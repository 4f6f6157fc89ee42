"""The judges the adapter knows: one per way of running a scenario. A new one is a line here."""
from __future__ import annotations

from ambiegen_ros.core.config import ConfigError

from .judge import ScenarioJudge
from .robot_nav2 import Nav2Robot
from .robot_planner import PlannerRobot
from .robot_topic import TopicRobot
from .thermostat import ThermostatRun
from .vehicle import VehicleRun

JUDGES: tuple[type[ScenarioJudge], ...] = (TopicRobot, Nav2Robot, PlannerRobot, VehicleRun, ThermostatRun)
PROBLEMS = tuple(dict.fromkeys(judge.problem for judge in JUDGES))  # robot, vehicle, thermostat
GOAL_MODES = tuple(judge.goal_mode for judge in JUDGES if judge.goal_mode)  # topic, action, plan


def judge_for(problem: str, goal_mode: str) -> type[ScenarioJudge]:
    """The judge of ``problem`` (robot: the one of ``goal_mode``)."""
    for judge in JUDGES:
        if judge.problem == problem and judge.goal_mode in ("", goal_mode):
            return judge
    raise ConfigError(f"problem: no judge for {problem!r} with goal_mode {goal_mode!r}")
