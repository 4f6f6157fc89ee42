"""What failed: the signature of a certified failure, so that distinct failures count causes, not genomes.

Two genomes that differ in one attribute can fail in the same bend; two that share most attributes
can fail in different places. An engineer counts the second pair twice and the first once. A
signature is ``(problem, kind, place)``; two signatures are the *same failure* when:

* **robot**: the same kind and failure points (``Outcome.failure_point``, x/y in m) at most
  ``radius`` apart (default 2 m). A failure without a point only matches one without a point.
* **vehicle**: the same kind and the same *failing bend*, by its shape, wherever it lies on its
  road (``failing_bend``): the bend of largest curvature in the ``BEND_LOOKBACK`` metres of road
  before the place where the car left the lane (``metrics["oob_arc_length"]``, where the oracle
  fired; else ``departure_arc_length``, its first lane touch, which can lie bends earlier). Its
  shape is its direction (a left and a right bend are never the same), its sharpest curvature
  (within ``curvature_tolerance``, default 0.01 1/m: R 20 m and R 25 m are the same), how far it
  turns (within ``radius`` degrees, default 30) and how the car came into it (``ENTRIES``: after a
  long straight, a short one, an opposite bend, a bend the same way). Where along its road the
  bend lies does not matter: two roads are compared by shape, as the SBFT tool competition
  compares failing road segments.
* **thermostat**: the same kind and the same *kind of schedule element* where the worst error
  fell (``failure_point[0]``, hours), wherever it lies in its day: the set-point step into it
  (direction up/down/none, and its size within ``radius`` degC, default 1), its room model and its
  duration band (``DURATION_BANDS``: up to 2 h, up to 3 h, longer). An element's index means
  nothing across two schedules: a failure one element later in a shifted day is the same failure.

A run's distinct failures are counted greedily in execution order (``DistinctFailures``): a failure
is distinct when it is not the same as any earlier failure of the run. ROS-free.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

DEFAULT_RADIUS = {"robot": 2.0, "vehicle": 30.0, "thermostat": 1.0}
DURATION_BANDS = (120.0, 180.0)  # min: an element up to 2 h, up to 3 h, or longer (thermostat)
CURVATURE_TOLERANCE = 0.01  # 1/m (vehicle)
BEND_CURVATURE = 0.01  # 1/m: sharper than R 100 m is a bend (vehicle)
BEND_LOOKBACK = 40.0  # m of road before the place the car left the lane searched for the bend that threw it out
LONG_STRAIGHT = 60.0  # m: a brisk car reaches most of its 70 km/h on a straight this long
ENTRIES = ("after a long straight", "after a short straight", "after an opposite bend", "after a bend the same way")


@dataclass(frozen=True)
class FailureSignature:
    """What failed and where: ``place`` is robot (x, y) m; vehicle (arc length m where the car left the lane,
    direction -1/0/+1, sharpest curvature 1/m, turn deg, entry index into ``ENTRIES``); thermostat
    (element index, set-point direction -1/0/+1, step size degC, room model, duration band index);
    None when the outcome has no place."""

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
            arc, direction, kappa, turn, entry = self.place
            if not direction:
                return f"{self.kind} on a straight, out of the lane at {arc:.0f} m along the road"
            bend = "left" if direction > 0 else "right"
            return (f"{self.kind} in a {bend} bend (R {1 / kappa:.0f} m, turning {turn:.0f} deg) "
                    f"{ENTRIES[int(entry)]}, out of the lane at {arc:.0f} m along the road")
        index, direction, size, model, band = self.place
        step = {1: f"a {size:g} degC step up", -1: f"a {size:g} degC step down", 0: "no step"}[int(direction)]
        length = ("up to 2 h", "2-3 h", "over 3 h")[int(band)]
        return f"{self.kind} in an element after {step}, room model {int(model)}, {length} (element {int(index)})"


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


def failing_bend(road: np.ndarray, arc: float, lookback: float = BEND_LOOKBACK) -> tuple[float, float, float, int]:
    """The bend that threw the car out at ``arc`` (m along ``road``): (direction -1/0/+1, sharpest
    |curvature| 1/m, turn deg, entry index into ``ENTRIES``); direction 0 when no node of the
    ``lookback`` metres before ``arc`` is sharper than ``BEND_CURVATURE`` (a departure on a straight)."""
    road = np.asarray(road, dtype=float)
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(road, axis=0).T))])
    kappa = signed_curvature(road)
    window = np.flatnonzero((s >= arc - lookback) & (s <= arc))
    if not len(window):
        window = np.array([int(np.argmin(np.abs(s - arc)))])
    peak = int(window[np.argmax(np.abs(kappa[window]))])
    if abs(kappa[peak]) < BEND_CURVATURE:
        return 0, 0.0, 0.0, 0
    sign = np.sign(kappa[peak])
    inside = sign * kappa >= BEND_CURVATURE / 2  # the bend: the run of nodes turning this way around the peak
    lo, hi = peak, peak
    while lo > 0 and inside[lo - 1]:
        lo -= 1
    while hi < len(road) - 1 and inside[hi + 1]:
        hi += 1
    ds = np.gradient(s)
    turn = float(np.degrees(np.sum(np.abs(kappa[lo:hi + 1]) * ds[lo:hi + 1])))
    before = np.flatnonzero(np.abs(kappa[:lo]) >= BEND_CURVATURE)
    lead = s[lo] - (s[before[-1]] if len(before) else 0.0)
    if len(before) and lead < LONG_STRAIGHT / 2:
        entry = 2 if np.sign(kappa[before[-1]]) != sign else 3
    else:
        entry = 0 if lead >= LONG_STRAIGHT else 1
    return int(sign), float(abs(kappa[peak])), turn, entry


def _vehicle_place(problem, scenario, outcome) -> tuple[float, ...] | None:
    from .car import road_of

    m = outcome.metrics or {}
    arc = m.get("oob_arc_length")
    arc = m.get("departure_arc_length") if arc is None else arc
    if arc is None:
        return None
    road, _, _ = road_of(problem, scenario)
    return (float(arc), *(float(v) for v in failing_bend(road, float(arc))))


def _thermostat_place(problem, scenario, outcome) -> tuple[float, ...] | None:
    from .room import schedule_of

    if outcome.failure_point is None:
        return None
    setpoints, durations, models = schedule_of(problem, scenario)
    ends = np.cumsum(durations) / 60.0
    index = min(int(np.searchsorted(ends, float(outcome.failure_point[0]), side="right")), len(setpoints) - 1)
    step = setpoints[index] - setpoints[index - 1] if index > 0 else 0.0
    band = int(np.searchsorted(DURATION_BANDS, durations[index], side="left"))
    return (float(index), float(np.sign(step)), abs(float(step)), float(models[index]), float(band))


def signature(problem, scenario, outcome, radius: float | None = None) -> FailureSignature | None:
    """The signature of a failed outcome (None when it did not fail: passes and invalid tests have none)."""
    if not outcome.failed:
        return None
    radius = DEFAULT_RADIUS[problem.name] if radius is None else float(radius)
    if problem.name == "robot":
        place = None if outcome.failure_point is None else tuple(float(v) for v in outcome.failure_point[:2])
    elif problem.name == "vehicle":
        place = _vehicle_place(problem, scenario, outcome)
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
    if len(a.place) != len(b.place):  # written by another version of this module
        return False
    if a.problem == "vehicle":
        (_, dir_a, k_a, turn_a, entry_a), (_, dir_b, k_b, turn_b, entry_b) = a.place, b.place
        if dir_a != dir_b or entry_a != entry_b:
            return False
        return dir_a == 0 or (abs(k_a - k_b) <= curvature_tolerance and abs(turn_a - turn_b) <= radius)
    (_, dir_a, size_a, model_a, band_a), (_, dir_b, size_b, model_b, band_b) = a.place, b.place
    return dir_a == dir_b and model_a == model_b and band_a == band_b and abs(size_a - size_b) <= radius


def predicted_signature(problem, scenario, metrics: dict[str, Any]) -> FailureSignature | None:
    """The signature of the failure the surrogate predicts (its evaluation's ``metrics`` of this
    scenario), or None when it predicts no place. The "certified" objectives say where: the vehicle's
    brisk driver left the lane at ``failure_arc``; the thermostat's worst error fell at ``failure_hour``."""
    from .outcome import Outcome

    if problem.name == "vehicle" and np.isfinite(metrics.get("failure_arc", np.nan)):
        guess = Outcome(objectives={}, failed=True, failure_kind="out_of_lane",
                        metrics={"oob_arc_length": float(metrics["failure_arc"])})
    elif problem.name == "thermostat" and np.isfinite(metrics.get("failure_hour", np.nan)):
        guess = Outcome(objectives={}, failed=True, failure_kind="requirement",
                        failure_point=(float(metrics["failure_hour"]), 0.0))
    else:
        return None
    return signature(problem, scenario, guess)


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


__all__ = ["BEND_CURVATURE", "CURVATURE_TOLERANCE", "DEFAULT_RADIUS", "DURATION_BANDS", "ENTRIES", "DistinctFailures",
           "FailureSignature", "failing_bend", "predicted_signature", "same_failure", "signature", "signed_curvature"]
