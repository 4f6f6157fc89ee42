"""Reference checks: a failure counts only when a reference passes the same scenario (ROS-free).

A scenario that no reasonable system could pass is an invalid test, not a failure of the system
under test. Each problem has a reference, in its own module, with two hooks:

* ``before(problem, scenario, config) -> ReferenceVerdict``: static checks before the system
  under test runs (robot: a route that keeps the footprint plus a margin clear of every wall;
  vehicle: the competition rules). Not passed: the verdict is INVALID_TEST and nothing runs.
  Its ``evidence`` goes to the simulator as keyword arguments (the robot drives that route).
* ``after(problem, scenario, config, outcome, seed) -> ReferenceVerdict``: called only when the
  system under test failed; does a reference system pass the same scenario (vehicle: a cautious
  driver; thermostat: an ideal controller)? Not passed: INVALID_TEST.

``certify`` turns a failed outcome into INVALID_TEST when the reference did not pass, keeping
what the system under test did in ``metrics["sut_failure_kind"]``. Every simulator config has
``reference: bool = True``; false gives the old, unchecked verdicts.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from importlib import import_module
from typing import Any

from ..outcome import Outcome


@dataclass
class ReferenceVerdict:
    """What a reference check found: passed or not, which check decided, and why (one line)."""

    passed: bool
    check: str  # "clearance_route" | "competition_rules" | "reference_driver" | "ideal_controller"
    reason: str = ""  # why not passed, one line a user reads ("no route keeps 0.39 m from the walls")
    metrics: dict[str, Any] = field(default_factory=dict)  # numbers for the record (prefixed "reference_")
    evidence: dict[str, Any] = field(default_factory=dict)  # keyword arguments for the simulator

    def as_dict(self) -> dict[str, Any]:
        return {"check": self.check, "passed": bool(self.passed), "reason": self.reason}


_MODULES = {"robot": ".robot", "vehicle": ".vehicle", "thermostat": ".thermostat"}


def _module(problem_name: str):
    return import_module(_MODULES[problem_name], __name__)


def before(problem: Any, scenario: Any, config: Any) -> ReferenceVerdict | None:
    """The problem's static reference check (None when its reference has none)."""
    hook = getattr(_module(problem.name), "before", None)
    return hook(problem, scenario, config) if hook is not None else None


def after(problem: Any, scenario: Any, config: Any, outcome: Outcome, seed: int = 0,
          budget: float | None = None) -> ReferenceVerdict | None:
    """The problem's reference run on a scenario the system under test failed (None: none needed).
    ``budget`` (s, robot only): the system gave up at its own time limit per goal; the reference
    gets the same time."""
    hook = getattr(_module(problem.name), "after", None)
    if hook is None:
        return None
    return hook(problem, scenario, config, outcome, seed, budget=budget) if budget else \
        hook(problem, scenario, config, outcome, seed)


def invalid_test(verdict: ReferenceVerdict, outcome: Outcome | None = None) -> Outcome:
    """The INVALID_TEST outcome of a scenario whose reference did not pass (never a failure).

    With ``outcome`` (the system under test ran), its evidence stays: metrics, trajectory,
    timeline, and the kind it would have been judged in ``metrics["sut_failure_kind"]``.
    """
    metrics = {} if outcome is None else dict(outcome.metrics)
    if outcome is not None:
        metrics["sut_failure_kind"] = outcome.failure_kind
        metrics["sut_detail"] = outcome.detail
    metrics.update({f"reference_{k}": v for k, v in verdict.metrics.items()})
    metrics["outcome"] = "invalid_test"
    metrics["reference_check"] = verdict.check
    return Outcome(
        objectives={} if outcome is None else dict(outcome.objectives),
        failed=False,
        failure_kind="invalid_test",
        detail=verdict.reason,
        metrics=metrics,
        trajectory=None if outcome is None else outcome.trajectory,
        timeline=None if outcome is None else outcome.timeline,
        failure_point=None if outcome is None else outcome.failure_point,
        reference=verdict.as_dict(),
    )


def certify(outcome: Outcome, verdict: ReferenceVerdict | None) -> Outcome:
    """``outcome`` with the reference's word: a failure stays one only when the reference passed."""
    if verdict is None:
        return outcome
    if outcome.failed and not verdict.passed:
        return invalid_test(verdict, outcome)
    outcome.reference = verdict.as_dict()
    outcome.metrics = {**outcome.metrics, **{f"reference_{k}": v for k, v in verdict.metrics.items()},
                       "reference_check": verdict.check}
    return outcome


__all__ = ["ReferenceVerdict", "after", "before", "certify", "invalid_test"]
