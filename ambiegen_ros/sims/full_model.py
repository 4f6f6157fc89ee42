"""Execute scenarios on the full-model simulators (the paper's RQ3 setting, ROS-free).

``full_model_executor(problem, **options)`` returns an executor whose ``execute(scenario, seed=0)``
gives an ``Outcome`` with the problem's failure oracle applied. In a run, the seed of scenario k is
``scenario_seed(run seed, k)``: the noise follows the run and the scenario, never the worker that
happens to execute it, so any number of workers gives the same outcomes. Options are fields of the
problem's simulator config (``RobotSimConfig``, ``CarSimConfig``, ``RoomSimConfig``); an unknown
option names the allowed ones, and a bad value is one ``ScenarioError`` naming the option, the value
and what is allowed (``--set cruise_speed=abc`` must not surface as a Python comparison error).
Scenarios that break a restriction of their problem are not simulated unless ``run_invalid=True``
(like the surrogate executor, they come back as ``invalid_scenario``, not failed);
``metrics["valid"]`` always says what the problem thinks.
"""
from __future__ import annotations

import dataclasses
import json
import math
import numbers
import time
import typing
from typing import Any, Callable

import numpy as np

from ..core.attributes import ScenarioError
from ..core.scenario import Scenario
from ..core.problem import Problem
from . import car, reference, robot, room
from .outcome import Outcome

SIMULATORS: dict[str, tuple[type, Callable[..., Outcome]]] = {
    "robot": (robot.RobotSimConfig, robot.simulate),
    "vehicle": (car.CarSimConfig, car.simulate),
    "thermostat": (room.RoomSimConfig, room.simulate),
}


def sim_config(problem_name: str, options: dict[str, Any] | None = None) -> Any:
    """The simulator config of a problem with ``options`` applied (unknown keys are named)."""
    if problem_name not in SIMULATORS:
        raise ScenarioError("problem", f"no full-model simulator for {problem_name!r}", "|".join(SIMULATORS))
    cls = SIMULATORS[problem_name][0]
    return _build(lambda checked: cls(**checked), check_options(problem_name, options))


def check_options(problem_name: str, options: dict[str, Any] | None) -> dict[str, Any]:
    """``options`` with each value checked against the type of its config field (ints made int).

    The configs' own ``__post_init__`` then checks ranges; a value of the wrong type must not reach
    it (``'abc' > 0`` would be a TypeError without the option's name).
    """
    cls = SIMULATORS[problem_name][0]
    fields = {f.name: f for f in dataclasses.fields(cls)}
    hints = typing.get_type_hints(cls)
    checked = {}
    for key, value in dict(options or {}).items():
        if key not in fields:
            raise ScenarioError(f"option.{key}", f"unknown {problem_name} simulator option", ", ".join(sorted(fields)))
        checked[key] = option_value(key, value, hints[key], fields[key].default)
    return checked


def option_value(key: str, value: Any, hint: Any, default: Any) -> Any:
    """One option value of a field typed ``hint``, or ``ScenarioError`` naming option, value and what is allowed."""
    where, shown = f"option.{key}", f"default {json.dumps(default)}"
    number = isinstance(value, numbers.Real) and not isinstance(value, bool)
    if hint is bool:
        if isinstance(value, bool):
            return value
        raise ScenarioError(where, f"expected true or false, got {value!r}", f"true|false; {shown}")
    if hint is int:
        if number and math.isfinite(value) and value == int(value):
            return int(value)
        raise ScenarioError(where, f"expected an integer, got {value!r}", f"integers; {shown}")
    if hint is float:
        if number and math.isfinite(value):
            return value
        raise ScenarioError(where, f"expected a number, got {value!r}", f"finite numbers; {shown}")
    if hint is str or hint == (str | None):
        if isinstance(value, str) or (value is None and hint != str):
            return value
        if isinstance(value, (bool, numbers.Real)):  # `--set planner=1` read as JSON: the text is meant
            return json.dumps(value)
        raise ScenarioError(where, f"expected text, got {value!r}", f"text; {shown}")
    return value


def _build(make: Callable[[dict[str, Any]], Any], checked: dict[str, Any]) -> Any:
    """``make(checked)`` with the config's range errors naming the value that broke them."""
    try:
        return make(checked)
    except ScenarioError as exc:
        key = exc.field.split(".", 1)[-1]
        if exc.field.startswith("option.") and key in checked:
            value = checked[key]
            if isinstance(value, str) and repr(value) in exc.message:  # "unknown planner 'magic'" names it
                raise
            raise ScenarioError(exc.field, f"value {value!r}: {exc.message}", exc.allowed) from None
        given = ", ".join(f"{k}={v!r}" for k, v in checked.items())
        raise ScenarioError(exc.field, exc.message + (f" (with {given})" if given else ""), exc.allowed) from None
    except TypeError as exc:  # a last resort: still one line naming the options, never a traceback
        raise ScenarioError("option", f"{exc} (options: {', '.join(map(str, checked))})") from None


class FullModelExecutor:
    """Executes scenarios of one problem on its full-model simulator."""

    def __init__(self, problem: Problem, config: Any = None, **options: Any):
        self.problem = problem
        if config is None:
            config = sim_config(problem.name, options)
        elif options:
            base = config
            config = _build(lambda checked: dataclasses.replace(base, **checked), check_options(problem.name, options))
        self.config = config
        self._simulate = SIMULATORS[problem.name][1]

    def validity(self, scenario: Scenario) -> tuple[bool, str | None]:
        """What the problem's restrictions say about the scenario."""
        row = self.problem.codec.to_row(scenario)
        G, lengths = self.problem.codec.split(row)
        if not bool(self.problem.codec.in_domain(G, lengths)[0]):
            return False, "genome outside the attribute domains"
        if self.problem.name == "vehicle":  # the road checks only (no surrogate drive)
            _, valid, reason = car.road_of(self.problem, scenario)
            return valid, reason
        ev = self.problem.evaluate(G, lengths)
        return bool(ev.valid[0]), ev.reasons[0]

    def execute(self, scenario: Scenario | dict, seed: int = 0) -> Outcome:
        start = time.perf_counter()
        if isinstance(scenario, dict):
            scenario = self.problem.parse(scenario)
        valid, reason = self.validity(scenario)
        if not valid and not self.config.run_invalid:
            outcome = Outcome.rejected(f"restriction broken: {reason}")
            outcome.metrics = {"outcome": "invalid", "valid": False, "reason": reason}
        else:
            outcome = self._checked_run(scenario, int(seed))
            outcome.metrics = {**outcome.metrics, "valid": valid, "reason": reason}
        outcome.elapsed_sec = time.perf_counter() - start
        return outcome

    def _checked_run(self, scenario: Scenario, seed: int) -> Outcome:
        """Simulate, with the problem's reference checks around it (``sims.reference``)."""
        if not getattr(self.config, "reference", True):
            return self._simulate(self.problem, scenario, self.config, seed=seed)
        first = reference.before(self.problem, scenario, self.config)
        if first is not None and not first.passed:
            return reference.invalid_test(first)
        outcome = self._simulate(self.problem, scenario, self.config, seed=seed,
                                 **(first.evidence if first is not None else {}))
        if outcome.failed:  # a problem without a reference run (robot) keeps its static check's word
            return reference.certify(outcome, reference.after(self.problem, scenario, self.config, outcome, seed)
                                     or first)
        return reference.certify(outcome, first)

    def config_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self.config)


def scenario_seed(run_seed: int, scenario_id: int) -> int:
    """The simulator seed of one scenario of a run: distinct streams for distinct (run, scenario)
    pairs (``run_seed + scenario_id`` would give run 3's scenario 5 the noise of run 5's scenario 3)."""
    state = np.random.SeedSequence([int(run_seed), int(scenario_id)]).generate_state(2, np.uint32)
    return int(state[0]) << 32 | int(state[1])


def full_model_executor(problem: Problem, **options: Any) -> FullModelExecutor:
    """The full-model executor of ``problem``; ``options`` override simulator config fields."""
    return FullModelExecutor(problem, **options)


def execute(problem: Problem, scenario: Scenario, seed: int = 0, **options: Any) -> Outcome:
    return FullModelExecutor(problem, **options).execute(scenario, seed=seed)


def timeline_lists(outcome: Outcome) -> dict[str, list[float]] | None:
    """The outcome's timeline as plain lists (for JSON)."""
    if outcome.timeline is None:
        return None
    return {k: np.asarray(v, dtype=float).tolist() for k, v in outcome.timeline.items()}


__all__ = ["FullModelExecutor", "SIMULATORS", "check_options", "execute", "full_model_executor", "option_value",
           "scenario_seed", "sim_config", "timeline_lists"]
