"""Surrogate execution: the case study's fast model plus a requirement oracle.

The oracles here are the simple readings of each problem's requirement available from its
surrogate (the full-model simulators bring richer ones):

* thermostat: RMSE to the schedule above ``requirement_rmse`` (1 degC) -> ``requirement``;
* vehicle: the surrogate car's centre deviates from the centre line it tracks by more than half
  a lane (``lane_width / 2``) -> ``out_of_lane``;
* robot: the surrogate (A*) has no failure notion; it reports the path length and never fails.

A scenario that breaks a restriction of its problem is reported as ``invalid_scenario``.
"""
from __future__ import annotations

import time
from typing import Any

import numpy as np

from ..core.scenario import Scenario
from ..core.problem import Problem
from .outcome import Outcome


class SurrogateExecutor:
    """Executes scenarios of one problem with its surrogate."""

    def __init__(self, problem: Problem):
        self.problem = problem

    def execute(self, scenario: Scenario) -> Outcome:
        return self.execute_batch([scenario])[0]

    def execute_batch(self, scenarios: list[Scenario]) -> list[Outcome]:
        """Execute several scenarios with one vectorised surrogate call (same outcomes as one by one)."""
        start = time.perf_counter()
        evaluation = self.problem.evaluate_scenarios(scenarios)
        outcomes = [self._outcome(scenario, evaluation.row(i)) for i, scenario in enumerate(scenarios)]
        share = (time.perf_counter() - start) / max(len(scenarios), 1)
        for outcome in outcomes:
            outcome.elapsed_sec = share
        return outcomes

    def _outcome(self, scenario: Scenario, row: dict) -> Outcome:
        problem = self.problem
        if not row["valid"]:
            outcome = Outcome.rejected(f"restriction broken: {row['reason']}")
            outcome.metrics = {"f1": 0.0}
            return outcome
        f1 = row["f1"]
        metrics = {k: v for k, v in row.items() if k not in ("valid", "reason")}
        failed, kind, detail = self._oracle(f1)
        outcome = Outcome(
            objectives={problem.name + "_f1": f1},
            failed=failed,
            failure_kind=kind,
            detail=detail,
            metrics=metrics,
            trajectory=self._trajectory(scenario),
        )
        return outcome

    def _oracle(self, f1: float) -> tuple[bool, str, str]:
        cfg: Any = self.problem.config
        name = self.problem.name
        if name == "thermostat":
            limit = float(cfg.requirement_rmse)
            if f1 > limit:
                return True, "requirement", f"RMSE {f1:.2f} degC > {limit:g} degC"
        elif name == "vehicle":
            limit = float(cfg.lane_width) / 2
            if f1 > limit:
                return True, "out_of_lane", f"max deviation {f1:.2f} m > half lane {limit:g} m"
        return False, "none", ""

    def _trajectory(self, scenario: Scenario) -> np.ndarray | None:
        if self.problem.name not in ("robot", "vehicle"):
            return None  # the thermostat has no trajectory: do not simulate it again
        env = self.problem.environment(scenario)
        if self.problem.name == "robot":
            return np.asarray(env.path_m, dtype=float).reshape(-1, 2) if env.path else None
        if self.problem.name == "vehicle":
            return np.asarray(env.path, dtype=float).reshape(-1, 2) if len(env.path) else None
        return None


def execute(problem: Problem, scenario: Scenario) -> Outcome:
    return SurrogateExecutor(problem).execute(scenario)
