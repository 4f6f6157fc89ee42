"""Known failures: limits of a system under test its engineers already know, declared in YAML.

A failure that matches one is still recorded, as FAIL(kind, known: name), but a campaign or a
report does not count it among new distinct failures: a Nav2 engineer wants the maps where their
stack fails for a reason they do not know yet. An entry names the limit, a reference (an issue
URL), and the facts a failure must show to be it:

* ``kinds``: the failure kinds it shows as (e.g. ``nav2_aborted``, ``stall``, ``timeout``);
* ``no_plan: true``: the stack published no plan after the goal (``metrics["plans"] == 0``);
* ``route_over_map_side: f``: the clearance route is longer than ``f`` x the map's longer side
  (``metrics["route_length_m"]``, ``metrics["map_side_m"]``, from the robot oracle);
* ``nav2_error_codes``: Nav2's error code is one of these (``metrics["nav2_error_code"]``);
* ``unmapped_obstacle_within: d``: a box or post that is not in the map lies within ``d`` m of
  where the run failed (``metrics["unmapped_obstacle_m"]``, hazards scenarios: ``sut_adapter``).

Every condition given must hold. ``config/nav2/known_failures.yaml`` ships NavFn's path cap.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .outcome import Outcome

FIELDS = ("name", "reference", "what", "kinds", "no_plan", "route_over_map_side", "nav2_error_codes",
          "unmapped_obstacle_within", "boundary")


@dataclass(frozen=True)
class KnownFailure:
    name: str
    reference: str
    what: str = ""
    kinds: tuple[str, ...] = ()
    no_plan: bool = False
    route_over_map_side: float | None = None
    boundary: str = ""  # where it was measured to start, for the reader
    nav2_error_codes: tuple[int, ...] = ()
    unmapped_obstacle_within: float | None = None

    def matches(self, outcome: Outcome) -> bool:
        m = outcome.metrics or {}
        kind = m.get("sut_failure_kind", outcome.failure_kind)
        if not outcome.failed or (self.kinds and kind not in self.kinds):
            return False
        plans = m.get("plans")
        if self.no_plan and (plans is None or int(plans) != 0):  # a count, or its text in a logged result
            return False
        if self.route_over_map_side is not None:
            route, side = m.get("route_length_m"), m.get("map_side_m")
            if route in (None, "None") or not side or float(route) <= self.route_over_map_side * float(side):
                return False
        if self.nav2_error_codes and _number(m.get("nav2_error_code")) not in self.nav2_error_codes:
            return False
        if self.unmapped_obstacle_within is not None:
            near = _number(m.get("unmapped_obstacle_m"), float)
            if near is None or near > self.unmapped_obstacle_within:
                return False
        return True


def _number(value: Any, kind: type = int) -> Any:
    """A metric as a number (a logged result holds its text), or None."""
    try:
        return kind(float(value)) if kind is int else kind(value)
    except (TypeError, ValueError):
        return None


def unmapped_obstacle_m(problem: Any, scenario: Any, point: Any) -> float | None:
    """How far ``point`` (where a hazards run failed) lies from the scenario's nearest unmapped box
    or post: the evidence ``unmapped_obstacle_within`` reads. None for other scenarios or no point."""
    from .obstacles import Obstacles

    if point is None or not getattr(problem, "hazards", False):
        return None
    unmapped = Obstacles.from_dict(problem.environment(scenario).unmapped or {})
    return unmapped.nearest_static_m((float(point[0]), float(point[1])))


def load(path: str | Path) -> list[KnownFailure]:
    """The entries of a known-failures YAML file (a list); ``ValueError`` naming the bad one."""
    import yaml

    try:
        data = yaml.safe_load(Path(path).read_text()) or []
    except (OSError, yaml.YAMLError) as exc:
        raise ValueError(f"known_failures: cannot read {path}: {exc}") from None
    if not isinstance(data, list):
        raise ValueError(f"known_failures: {path} must hold a list of entries")
    out = []
    for i, entry in enumerate(data):
        if not isinstance(entry, dict) or not entry.get("name") or not entry.get("reference"):
            raise ValueError(f"known_failures: entry {i} of {path} needs a name and a reference")
        unknown = sorted(set(entry) - set(FIELDS))
        if unknown:
            raise ValueError(f"known_failures: entry {entry['name']!r}: unknown field(s) {', '.join(unknown)} "
                             f"(allowed: {', '.join(FIELDS)})")
        ratio, near = entry.get("route_over_map_side"), entry.get("unmapped_obstacle_within")
        out.append(KnownFailure(str(entry["name"]), str(entry["reference"]), str(entry.get("what", "")),
                                tuple(str(k) for k in entry.get("kinds") or ()), bool(entry.get("no_plan", False)),
                                None if ratio is None else float(ratio), str(entry.get("boundary", "")),
                                tuple(int(c) for c in entry.get("nav2_error_codes") or ()),
                                None if near is None else float(near)))
    return out


def mark(outcome: Outcome, entries: list[KnownFailure]) -> Outcome:
    """``outcome`` with the first known failure it matches named in its metrics and detail."""
    known = next((k for k in entries if k.matches(outcome)), None)
    if known is not None:
        outcome.metrics = {**outcome.metrics, "known_failure": known.name, "known_failure_reference": known.reference}
        outcome.detail = f"{outcome.detail} (known: {known.name}, {known.reference})"
    return outcome


def is_known(outcome: Any) -> bool:
    return bool((getattr(outcome, "metrics", None) or {}).get("known_failure"))


__all__ = ["KnownFailure", "is_known", "load", "mark", "unmapped_obstacle_m"]
