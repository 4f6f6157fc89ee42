"""Case studies behind one interface (``core.problem.Problem``); register a new one in ``_CLASSES``.

Light on purpose: naming the problems (``PROBLEM_NAMES``) imports nothing heavy, and a case
study's module (numba kernels, shapely) loads only when that problem is built.
"""
from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING, Any

from ..core.names import DEFAULT_PROFILE, PROFILES

if TYPE_CHECKING:
    from ..core.problem import Problem

PROBLEM_NAMES = ("thermostat", "robot", "vehicle")


_CLASSES = {"thermostat": (".thermostat", "ThermostatProblem"), "robot": (".robot", "RobotProblem"),
            "vehicle": (".vehicle", "VehicleProblem")}
"""name -> (module, class): a new case study is one line here (and its name in PROBLEM_NAMES)."""


def problem_class(name: str) -> type[Problem]:
    """The case study's class; only its own module is imported."""
    if name not in PROBLEM_NAMES:
        from ..core.attributes import ScenarioError

        raise ScenarioError("problem", f"unknown problem {name!r}", "|".join(PROBLEM_NAMES))
    module, cls = _CLASSES[name]
    return getattr(import_module(module, __name__), cls)


def get_problem(name: str, config: Any = None, **overrides: Any) -> Problem:
    """Instantiate a case study by name, with an optional config (dict or Config) and overrides."""
    return problem_class(name)(config, **overrides)


__all__ = ["DEFAULT_PROFILE", "PROBLEM_NAMES", "PROFILES", "get_problem", "problem_class"]
