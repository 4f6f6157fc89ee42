"""The robot case study's numbers: ``RobotConfig`` (every field, checked, with the profile's
defaults) and the constants that name its rules, objectives and engines.

At the bottom of the package, so that the grids, the planners and the problem share one
definition of each rule and nothing here imports them.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

from ...core.attributes import ScenarioError
from ...core.problem import DEFAULT_PROFILE, check_profile

HORIZONTAL, VERTICAL = 0, 1
DIAGONAL_RULES = ("both_free", "one_free", "always")
INFLATION_RULES = ("overlap", "centre")  # how the robot radius blocks cells (see ``inflation_footprint``)
INFLATION_RULE = {"refined": "overlap", "replication": "centre"}
OBJECTIVES = ("route", "narrow", "threat", "block")  # what F1 measures (``RobotConfig.objective``; threat, block: hazards only)
HAZARD_OBJECTIVES = ("threat", "block")  # F1 from ``robot_hazards.features`` of that name
SCENARIO_KINDS = ("walls", "hazards")  # ``RobotConfig.scenario``: the paper's map, or issue 48's hazards
LOOP_OBJECTIVES = ("time", "pace", "time_share")  # what F1 of an execution measures in the loop (``RobotConfig.loop_objective``)
ENGINES = ("auto", "numba", "numpy")  # batch planner: numba when importable, else scipy
NO_PATH = "no path from start to goal"


# Defaults of the fields that differ by profile (``None`` in a Config resolves to these).
PROFILE_DEFAULTS = {
    "replication": {"keep_out": 0, "free_band": 3, "diagonal": "always"},
    "refined": {"keep_out": 1, "free_band": 0, "diagonal": "both_free"},
}


@dataclass(frozen=True)
class RobotConfig:
    """Every number of the robot case study; ``None`` fields take the profile's default."""

    alpha: float = 120.0  # MO constraint: a map is 'risky' when its path is longer [m]
    map_size: int = 50  # cells per side, border included (attribute domains assume 50)
    resolution: float = 1.0  # metres per cell; genome values are cells (= m at 1.0)
    start: tuple[int, int] = (1, 1)  # (x, y) cell
    goal: tuple[int, int] = (48, 48)  # (x, y) cell
    robot_radius: float = 0.5  # m; see ``inflate``
    keep_out: int | None = None  # Chebyshev radius (cells) around start/goal never walled (R2)
    free_band: int | None = None  # interior cells along the top and right borders never walled
    type_p_stay: float = 0.5  # Markov chain over wall type: P(next type = this type)
    sampling: str = "markov"  # "markov" (type by the chain) | "uniform"
    diagonal: str | None = None  # diagonal step needs: both_free | one_free | always
    engine: str = "auto"  # batch planner: "auto" (numba if importable) | "numba" | "numpy" (scipy)
    route_cap: float = 0.0  # m; > 0: F1 folds back above it (see ``fold_above``); 0 = off
    objective: str = "route"  # F1: "route" = the A* route length (the paper's) | "narrow" = ``narrow_route_metres``
    narrow_clearance: float = 2.0  # m from a wall cell's centre below which a route cell is narrow ("narrow")
    # in the loop, F1 of an execution: "time" = the time to the goal (the time limit on a failure;
    # the paper's full model) | "pace" = seconds per metre of the clearance route (a failure: the time
    # limit's, above any pass): how hard the stack found the map, whatever its length (``loop_f1``) |
    # "time_share" = the time over the time limit (1 on a failure): measured, and it climbs route length
    loop_objective: str = "time"
    profile: str = DEFAULT_PROFILE  # replication | refined (see the package docstring)
    # scenario kind (issue 48): "walls" = the paper's map; "hazards" = walls plus the start and goal
    # poses, unmapped boxes and posts and walking people (``problems.robot_hazards``; refined only)
    scenario: str = "walls"
    start_area: tuple | None = None  # hazards: ((x0, y0), (x1, y1)) cells the start lies in; None = start +- 2
    goal_area: tuple | None = None  # hazards: the goal's area; None = goal +- 2 cells
    max_hazards: int = 6  # hazards: boxes, posts and people per scenario, at most
    # hazards: vias a planner is asked to pass through, in order (Nav2's ComputePathThroughPoses), at
    # least and at most; 0..0 (the default) = none, and every config without them samples as before
    min_vias: int = 0
    max_vias: int = 0
    via_area: tuple | None = None  # hazards: the vias' area; None = the room inside its border
    box_side: tuple = (0.3, 1.0)  # hazards: a box's side [m], min and max
    post_diameter: tuple = (0.05, 0.2)  # hazards: a thin post's diameter [m]
    person_radius: tuple = (0.2, 0.35)  # hazards: a person's radius [m]
    person_reach: float = 3.0  # hazards: a person walks this far on each side of its point on the route [m]
    clear_of_ends: float = 0.6  # hazards: obstacles and standing people keep this far from start and goal [m]
    # hazards: walls may cover the start and goal areas (a planner's scenarios: starts and goals anywhere,
    # walls anywhere; one on a wall is a refusal the reference proves right); false: those areas stay free
    walls_over_ends: bool = False
    # threat: the robot's pace along the route when it times a person's meeting [m/s]; the stack's
    # own pace makes the timing match what it meets (MPPI's measured median: 0.39 m/s)
    threat_speed: float = 0.5

    def __post_init__(self):
        check_profile(self.profile)
        for name, default in PROFILE_DEFAULTS[self.profile].items():
            if getattr(self, name) is None:
                object.__setattr__(self, name, default)
        if self.sampling not in ("markov", "uniform"):
            raise ScenarioError("config.sampling", f"unknown sampling {self.sampling!r}", "markov|uniform")
        if self.diagonal not in DIAGONAL_RULES:
            raise ScenarioError("config.diagonal", f"unknown rule {self.diagonal!r}", "|".join(DIAGONAL_RULES))
        if self.engine not in ENGINES:
            raise ScenarioError("config.engine", f"unknown engine {self.engine!r}", "|".join(ENGINES))
        if not self.resolution > 0:
            raise ScenarioError("config.resolution", "must be positive")
        if self.robot_radius < 0:
            raise ScenarioError("config.robot_radius", "must be >= 0")
        if self.objective not in OBJECTIVES:
            raise ScenarioError("config.objective", f"unknown objective {self.objective!r}", "|".join(OBJECTIVES))
        if self.loop_objective not in LOOP_OBJECTIVES:
            raise ScenarioError("config.loop_objective", f"unknown objective {self.loop_objective!r}",
                                "|".join(LOOP_OBJECTIVES))
        if not self.narrow_clearance > 0:
            raise ScenarioError("config.narrow_clearance", "must be positive")
        if not self.route_cap >= 0:
            raise ScenarioError("config.route_cap", "must be >= 0 (0 = off)")
        if self.keep_out < 0:
            raise ScenarioError("config.keep_out", "must be >= 0")
        if not 0 <= self.free_band <= self.map_size - 3:
            raise ScenarioError("config.free_band", "must leave interior cells for walls", f"0..{self.map_size - 3}")
        if not 0.0 <= self.type_p_stay <= 1.0:
            raise ScenarioError("config.type_p_stay", "must be a probability", "[0, 1]")
        if self.scenario not in SCENARIO_KINDS:
            raise ScenarioError("config.scenario", f"unknown scenario kind {self.scenario!r}", "|".join(SCENARIO_KINDS))
        if self.scenario == "hazards":
            self._check_hazards()
        elif self.objective in HAZARD_OBJECTIVES:
            raise ScenarioError("config.objective", f"{self.objective} scores hazards", "scenario: hazards")
        # YAML/JSON give lists; keep the dataclass hashable and the cells integral.
        object.__setattr__(self, "start", tuple(int(v) for v in self.start))
        object.__setattr__(self, "goal", tuple(int(v) for v in self.goal))
        for name in ("start", "goal"):
            x, y = getattr(self, name)
            if not (0 < x < self.map_size - 1 and 0 < y < self.map_size - 1):
                raise ScenarioError(f"config.{name}", f"({x}, {y}) is not an interior cell",
                                    f"1..{self.map_size - 2}")

    def _check_hazards(self) -> None:
        if self.profile != "refined":
            raise ScenarioError("config.scenario", "hazards scenarios need the refined profile", "profile: refined")
        if not 0 <= int(self.max_hazards) <= 20:
            raise ScenarioError("config.max_hazards", f"{self.max_hazards}", "0..20")
        if not 0 <= int(self.min_vias) <= int(self.max_vias) <= 10:
            raise ScenarioError("config.max_vias", f"min_vias {self.min_vias}, max_vias {self.max_vias}",
                                "0 <= min_vias <= max_vias <= 10")
        object.__setattr__(self, "min_vias", int(self.min_vias))
        object.__setattr__(self, "max_vias", int(self.max_vias))
        for name in ("start_area", "goal_area", "via_area"):
            value = getattr(self, name)
            if value is None:
                continue
            try:
                (x0, y0), (x1, y1) = value
                cells = tuple(tuple(int(v) for v in c) for c in value)
            except (TypeError, ValueError):
                raise ScenarioError(f"config.{name}", f"expected [[x0, y0], [x1, y1]], got {value!r}") from None
            (x0, y0), (x1, y1) = cells
            if not (1 <= x0 <= x1 <= 48 and 1 <= y0 <= y1 <= 48):
                raise ScenarioError(f"config.{name}", f"{cells} is not a box of interior cells", "1 <= x0 <= x1 <= 48")
            object.__setattr__(self, name, cells)
        for name in ("box_side", "post_diameter", "person_radius"):
            lo_hi = tuple(float(v) for v in getattr(self, name))
            if len(lo_hi) != 2 or not 0 < lo_hi[0] <= lo_hi[1]:
                raise ScenarioError(f"config.{name}", f"{getattr(self, name)!r}", "[min, max] with 0 < min <= max")
            object.__setattr__(self, name, lo_hi)
        for name in ("person_reach", "clear_of_ends", "threat_speed"):
            if not getattr(self, name) > 0:
                raise ScenarioError(f"config.{name}", "must be > 0")

    def for_profile(self, profile: str) -> "RobotConfig":
        """This config under another profile: fields still at this profile's default follow the new one.

        (``dataclasses.replace(config, profile=...)`` alone would keep the old profile's resolved
        values, e.g. a refined config with corner-cutting A*.)
        """
        follow: dict[str, Any] = {name: None for name, default in PROFILE_DEFAULTS[self.profile].items()
                  if getattr(self, name) == default}
        return dataclasses.replace(self, profile=check_profile(profile), **follow)
