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
}
FAILURE_NAMES = {code: name for name, code in FAILURE_KINDS.items()}


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

    def __post_init__(self) -> None:
        if self.failure_kind not in FAILURE_KINDS:
            raise ValueError(f"failure_kind: unknown {self.failure_kind!r} (allowed: {', '.join(FAILURE_KINDS)})")

    @property
    def f1(self) -> float:
        """The first objective: what the in-the-loop search maximises."""
        return float(next(iter(self.objectives.values()), 0.0))

    @classmethod
    def rejected(cls, detail: str, kind: str = "invalid_scenario") -> "Outcome":
        return cls(objectives={}, failed=False, failure_kind=kind, detail=detail)
