"""Case studies behind one interface (``base.Problem``); register a new one in ``PROBLEMS``."""
from __future__ import annotations

from typing import Any

from ..core.attributes import ScenarioError
from .base import DEFAULT_PROFILE, PROFILES, Budget, Evaluation, Problem


def _registry() -> dict[str, type[Problem]]:
    from .robot import RobotProblem
    from .thermostat import ThermostatProblem
    from .vehicle import VehicleProblem

    return {cls.name: cls for cls in (ThermostatProblem, RobotProblem, VehicleProblem)}


PROBLEM_NAMES = ("thermostat", "robot", "vehicle")


def problem_class(name: str) -> type[Problem]:
    registry = _registry()
    if name not in registry:
        raise ScenarioError("problem", f"unknown problem {name!r}", "|".join(registry))
    return registry[name]


def get_problem(name: str, config: Any = None, **overrides: Any) -> Problem:
    """Instantiate a case study by name, with an optional config (dict or Config) and overrides."""
    return problem_class(name)(config, **overrides)


__all__ = ["Budget", "DEFAULT_PROFILE", "Evaluation", "Problem", "PROBLEM_NAMES", "PROFILES", "get_problem", "problem_class"]
