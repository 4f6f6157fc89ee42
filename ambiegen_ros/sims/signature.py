"""What failed: the signature of a certified failure, so that distinct failures count causes, not genomes.

Two genomes that differ in one attribute can fail in the same bend; two that share most attributes
can fail in different places. An engineer counts the second pair twice and the first once. A
signature is ``(problem, kind, place)``; two signatures are the *same failure* when:

* **robot**: the same kind and failure points (``Outcome.failure_point``, x/y in m) at most
  ``radius`` apart (default 2 m). A failure without a point only matches one without a point.
* **vehicle**: the same kind, the places where the car left the lane (``metrics
  ["departure_arc_length"]``, the first lane touch; else ``oob_arc_length``; metres along the road's
  centre line) at most ``radius`` apart (default 10 m), and the stretch's signed curvature (the
  curvature of largest magnitude over the ``radius`` metres of road before that place, i.e. the bend
  that threw the car out; > 0 = left bend) within ``curvature_tolerance`` (default 0.01 1/m: a 20 m
  and a 25 m bend are the same, a left and a right bend never are).
* **thermostat**: the same kind, the same schedule element (the element containing the hour of
  the worst error, ``failure_point[0]``; indices at most ``radius`` apart, default 0) and the same
  direction of the set-point change into that element (up, down or none).

A run's distinct failures are counted greedily in execution order (``DistinctFailures``): a failure
is distinct when it is not the same as any earlier failure of the run. ROS-free.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

DEFAULT_RADIUS = {"robot": 2.0, "vehicle": 10.0, "thermostat": 0.0}
CURVATURE_TOLERANCE = 0.01  # 1/m (vehicle)


@dataclass(frozen=True)
class FailureSignature:
    """What failed and where: ``place`` is robot (x, y) m; vehicle (arc length m, signed curvature
    1/m); thermostat (element index, set-point direction -1/0/+1); None when the outcome has no place."""

    problem: str
    kind: str
    place: tuple[float, ...] | None

    def to_dict(self) -> dict[str, Any]:
        return {"problem": self.problem, "kind": self.kind,
                "place": None if self.place is None else [round(float(v), 6) for v in self.place]}

    def describe(self) -> str:
        """One line a reader understands."""
        if self.place is None:
            return f"{self.kind} (no place)"
        if self.problem == "robot":
            return f"{self.kind} at ({self.place[0]:.1f}, {self.place[1]:.1f}) m"
        if self.problem == "vehicle":
            bend = "left" if self.place[1] > 0 else "right" if self.place[1] < 0 else "straight"
            radius = f"R {1 / abs(self.place[1]):.0f} m" if self.place[1] else "no curvature"
            return f"{self.kind}, first lane touch at {self.place[0]:.0f} m along the road, {bend} bend ({radius})"
        direction = {1: "step up", -1: "step down", 0: "no step"}[int(self.place[1])]
        return f"{self.kind} in schedule element {int(self.place[0])} ({direction})"


def signed_curvature(points: np.ndarray) -> np.ndarray:
    """Signed curvature at each node of a polyline (circle through neighbours; > 0 turns left)."""
    p = np.asarray(points, dtype=float)
    out = np.zeros(len(p))
    if len(p) < 3:
        return out
    a, b, c = p[:-2], p[1:-1], p[2:]
    cross = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    prod = np.hypot(*(b - a).T) * np.hypot(*(c - b).T) * np.hypot(*(c - a).T)
    out[1:-1] = 2 * cross / np.maximum(prod, 1e-12)
    out[0], out[-1] = out[1], out[-2]
    return out


def stretch_curvature(road: np.ndarray, arc: float, length: float) -> float:
    """The signed curvature of largest magnitude over the ``length`` metres of road before ``arc``."""
    road = np.asarray(road, dtype=float)
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(road, axis=0).T))])
    kappa = signed_curvature(road)
    inside = (s >= arc - max(length, 1e-9)) & (s <= arc)
    if not inside.any():
        inside[int(np.argmin(np.abs(s - arc)))] = True
    k = kappa[inside]
    return float(k[int(np.argmax(np.abs(k)))])


def _vehicle_place(problem, scenario, outcome, radius: float) -> tuple[float, ...] | None:
    from .car import road_of

    m = outcome.metrics or {}
    arc = m.get("departure_arc_length")
    arc = m.get("oob_arc_length") if arc is None else arc
    if arc is None:
        return None
    road, _, _ = road_of(problem, scenario)
    return (float(arc), stretch_curvature(road, float(arc), radius))


def _thermostat_place(problem, scenario, outcome) -> tuple[float, ...] | None:
    from .room import schedule_of

    if outcome.failure_point is None:
        return None
    setpoints, durations, _ = schedule_of(problem, scenario)
    ends = np.cumsum(durations) / 60.0
    index = min(int(np.searchsorted(ends, float(outcome.failure_point[0]), side="right")), len(setpoints) - 1)
    step = setpoints[index] - setpoints[index - 1] if index > 0 else 0.0
    return (float(index), float(np.sign(step)))


def signature(problem, scenario, outcome, radius: float | None = None) -> FailureSignature | None:
    """The signature of a failed outcome (None when it did not fail: passes and invalid tests have none)."""
    if not outcome.failed:
        return None
    radius = DEFAULT_RADIUS[problem.name] if radius is None else float(radius)
    if problem.name == "robot":
        place = None if outcome.failure_point is None else tuple(float(v) for v in outcome.failure_point[:2])
    elif problem.name == "vehicle":
        place = _vehicle_place(problem, scenario, outcome, radius)
    elif problem.name == "thermostat":
        place = _thermostat_place(problem, scenario, outcome)
    else:
        raise ValueError(f"no failure signature for problem {problem.name!r}")
    return FailureSignature(problem.name, outcome.failure_kind, place)


def same_failure(a: FailureSignature, b: FailureSignature, radius: float | None = None,
                 curvature_tolerance: float = CURVATURE_TOLERANCE) -> bool:
    """Are two signatures the same failure (see the module docstring)?"""
    if a.problem != b.problem or a.kind != b.kind:
        return False
    if a.place is None or b.place is None:
        return a.place is None and b.place is None
    radius = DEFAULT_RADIUS[a.problem] if radius is None else float(radius)
    if a.problem == "robot":
        return bool(np.hypot(a.place[0] - b.place[0], a.place[1] - b.place[1]) <= radius)
    if a.problem == "vehicle":
        return abs(a.place[0] - b.place[0]) <= radius and abs(a.place[1] - b.place[1]) <= curvature_tolerance
    return abs(a.place[0] - b.place[0]) <= radius and a.place[1] == b.place[1]


class DistinctFailures:
    """A run's failure signatures; ``add`` says whether a failure is new (not the same as any earlier one)."""

    def __init__(self, radius: float | None = None, curvature_tolerance: float = CURVATURE_TOLERANCE):
        self.radius, self.curvature_tolerance = radius, curvature_tolerance
        self.seen: list[FailureSignature] = []
        self.distinct: list[FailureSignature] = []

    def add(self, sig: FailureSignature) -> bool:
        new = not any(same_failure(sig, old, self.radius, self.curvature_tolerance) for old in self.seen)
        self.seen.append(sig)
        if new:
            self.distinct.append(sig)
        return new

    def __len__(self) -> int:
        return len(self.distinct)


__all__ = ["CURVATURE_TOLERANCE", "DEFAULT_RADIUS", "DistinctFailures", "FailureSignature", "same_failure",
           "signature", "signed_curvature", "stretch_curvature"]
