"""Executing scenarios and judging them with failure oracles (ROS-free).

``execute(problem, scenario)`` returns an ``Outcome``. Until the full-model simulators exist the
executor is the case study's surrogate with a simple requirement oracle per problem
(``SurrogateExecutor``); sim nodes only call this module.
"""
from .outcome import FAILURE_KINDS, Outcome
from .surrogate import SurrogateExecutor, execute

__all__ = ["FAILURE_KINDS", "Outcome", "SurrogateExecutor", "execute"]
