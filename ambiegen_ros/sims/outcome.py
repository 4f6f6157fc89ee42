"""The result of executing one scenario, independent of how it is transported."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

# Same codes as ambiegen_msgs/ScenarioResult's constants (checked by a test).
FAILURE_KINDS = {
    "none": 0,
    "collision": 1,
    "stall": 2,
    "timeout": 3,
    "out_of_lane": 4,
    "requirement": 5,
    "invalid_scenario": 6,
    "error": 7,
    "sim_timeout": 8,
    "loiter": 9,
    "invalid_test": 10,
    "nav2_aborted": 11,
    "sut_crashed": 12,
}
# Kinds that say the system under test failed (``Outcome.failed``); every other kind says nothing
# about it: ``none`` passed, ``invalid_test`` is a scenario no reference passes (never a failure).
SUT_FAILURES = ("collision", "stall", "timeout", "out_of_lane", "requirement", "loiter", "nav2_aborted", "sut_crashed")
FAILURE_NAMES = {code: name for name, code in FAILURE_KINDS.items()}
NAV2_RECOVERIES = "nav2_recoveries"  # metric: recovery actions Nav2 ran for the goal (its action feedback's count)


def near_miss(kind: str, recoveries: Any) -> bool:
    """A PASS that needed the stack's recoveries (``recoveries`` as recorded, text or number; None = not recorded)."""
    return kind == "none" and int(recoveries or 0) > 0


@dataclass
class Outcome:
    """What an execution produced: objectives (larger = closer to failing), verdict, evidence."""

    objectives: dict[str, float]
    failed: bool
    failure_kind: str = "none"
    detail: str = ""
    metrics: dict[str, Any] = field(default_factory=dict)
    trajectory: np.ndarray | None = None  # (K, 2) x/y in metres, or None
    elapsed_sec: float = 0.0
    # Optional evidence from the full-model simulators (``sims.full_model``): time-stamped samples
    # (robot/car: t, x, y, yaw, v; thermostat: t, temperature, measured, setpoint, heater; t in s)
    # for publishing as nav_msgs/Odometry or sensor_msgs/Temperature, and where the run failed
    # (x, y in metres; thermostat: hour, temperature of the largest error) for the plots.
    timeline: dict[str, np.ndarray] | None = None
    failure_point: tuple[float, float] | None = None
    # The reference check (``sims.reference``): {"check", "passed", "reason"}; None = not checked.
    reference: dict[str, Any] | None = None

    def __post_init__(self) -> None:
        if self.failure_kind not in FAILURE_KINDS:
            raise ValueError(f"failure_kind: unknown {self.failure_kind!r} (allowed: {', '.join(FAILURE_KINDS)})")

    @property
    def f1(self) -> float:
        """The first objective: what the in-the-loop search maximises."""
        return float(next(iter(self.objectives.values()), 0.0))

    @property
    def verdict(self) -> str:
        """PASS, FAIL(kind), INVALID_TEST(reason), or the kind in capitals (INVALID_SCENARIO, ERROR, ...)."""
        if self.failure_kind == "none":
            return "PASS"
        if self.failed:
            return f"FAIL({self.failure_kind})"
        if self.failure_kind == "invalid_test":
            return f"INVALID_TEST({self.detail})"
        return self.failure_kind.upper()

    @classmethod
    def rejected(cls, detail: str, kind: str = "invalid_scenario") -> "Outcome":
        return cls(objectives={}, failed=False, failure_kind=kind, detail=detail)
