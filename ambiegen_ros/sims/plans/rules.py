"""What each Nav2 global planner calls a blocked cell, a reached goal, a legal turn (jazzy).

One ``PlannerRules`` per planner configuration; the oracles and the reference planner read it, so
that a path is judged by the rule its planner promised to keep, never a stricter one.
Sources (navigation2, branch ``jazzy``):

* NavFn (``nav2_navfn_planner/src/navfn.cpp``, ``NavFn::setCostmap``): a cost >= 253
  (``COST_OBS_ROS``) becomes ``COST_OBS``, untraversable; 255 becomes traversable
  (``COST_OBS - 1``) only with ``allow_unknown`` (Jazzy default true). ``NavFn::setupNavFn`` sets
  the outer ring of cells to ``COST_OBS``. ``navfn_planner.cpp``: ``makePlan`` clears the start
  cell (``clearRobotCell``); ``tolerance`` (default 0.5 m) searches a *square* of +-tolerance
  around the goal in steps of the resolution for the reachable point nearest the goal, and the
  path ends exactly there (``smoothApproachToGoal``); ``GoalOccupied`` only when tolerance == 0
  and the goal cell is 254. NavFn's own ``worldToMap`` rounds (``std::round``), not floors, and
  its ``mapToWorld`` adds no half cell: its poses sit on cell corners of the costmap.
* Smac 2D (``nav2_smac_planner/src/collision_checker.cpp``, ``GridCollisionChecker::inCollision(
  index, traverse_unknown)``; ``node_2d.cpp``, ``Node2D::isNodeValid``): blocked when the cell's
  cost >= 253, except 255 under ``allow_unknown`` (default true); the footprint is never used and
  ``cost_travel_multiplier`` only weighs the cost, never decides a collision. ``tolerance``
  (default 0.125 m) is Euclidean, in cells, from the node to the goal (``a_star.cpp``,
  ``_best_heuristic_node`` against ``getToleranceHeuristic``; ``Node2D::getHeuristicCost``);
  a path is returned from the nearest node within it when the goal is not reached.
  ``smac_planner_2d.cpp``: ``StartOccupied`` when the start is blocked, ``PlannerTimedOut`` past
  ``max_iterations``; ``max_planning_time`` default 2.0 s.
* Smac Hybrid-A* and Lattice (``GridCollisionChecker::inCollision(x, y, angle, traverse_unknown)``):
  with a round robot (``footprint_is_radius_``) the centre cell's cost >= 253 blocks; with a
  polygon footprint the centre cell at 253 or 254 blocks, and so does a footprint whose outline
  cells (``FootprintCollisionChecker::footprintCost``: each vertex's cell and the Bresenham line
  between them, ``nav2_util::LineIterator``) reach 254. Defaults: ``tolerance`` 0.25,
  ``minimum_turning_radius`` 0.4 (Hybrid), ``motion_model_for_search`` DUBIN (forward only;
  REEDS_SHEPP reverses), ``max_planning_time`` 5.0; Lattice: the turning radius of its
  primitives file (default ``5cm_resolution/0.5m_turning_radius/ackermann``), reversing only with
  ``allow_reverse_expansion`` (default false).
* Theta* (``nav2_theta_star_planner/include/.../theta_star.hpp``, ``ThetaStar::isSafe``): a cell
  is safe when its cost <= 252, or 255 with ``allow_unknown`` (default true); no goal tolerance
  (``theta_star_planner.cpp``: ``GoalOccupied`` when the goal cell is 254).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Optional

import numpy as np

from .costmap import INSCRIBED, JAZZY


@dataclass(frozen=True)
class PlannerRules:
    """One planner's collision, goal and motion rules (the ``planner_server`` parameters that matter)."""

    name: str
    blocked_from: int = INSCRIBED  # a centre cell at or above this cost is blocked (255: see allow_unknown)
    allow_unknown: bool = True
    border_blocked: bool = False  # NavFn: the map's outer ring is an obstacle
    start_cleared: bool = False  # NavFn plans out of a blocked start cell; Smac refuses (StartOccupied)
    tolerance: float = 0.0  # metres
    tolerance_metric: str = "euclidean"  # "euclidean" (Smac) or "square" (NavFn: +-tolerance on each axis)
    robot_radius: float = JAZZY.robot_radius
    footprint: Optional[np.ndarray] = field(default=None, compare=False)  # (N, 2) polygon; None: round robot
    min_turning_radius: Optional[float] = None  # metres; None: no turning limit (2D planners)
    reversing: bool = True  # may the path drive backwards (only checked when min_turning_radius is set)
    max_planning_time: Optional[float] = None  # seconds; over it is a performance note, never a failure

    def traversable(self, cost: np.ndarray) -> np.ndarray:
        """Cells a path's centre may occupy under this planner's rule (boolean, same shape)."""
        cost = np.asarray(cost)
        ok = cost < self.blocked_from
        if self.allow_unknown:
            ok |= cost == 255
        if self.border_blocked and ok.size:
            ok = ok.copy()
            ok[0, :] = ok[-1, :] = False
            ok[:, 0] = ok[:, -1] = False
        return ok


def navfn(tolerance: float = 0.5, allow_unknown: bool = True, robot_radius: float = JAZZY.robot_radius) -> PlannerRules:
    """``nav2_navfn_planner::NavfnPlanner`` (Dijkstra or A*: the same rule)."""
    return PlannerRules("navfn", INSCRIBED, allow_unknown, border_blocked=True, start_cleared=True,
                        tolerance=tolerance, tolerance_metric="square", robot_radius=robot_radius)


def smac_2d(tolerance: float = 0.125, allow_unknown: bool = True, robot_radius: float = JAZZY.robot_radius,
            max_planning_time: float = 2.0) -> PlannerRules:
    """``nav2_smac_planner::SmacPlanner2D``: centre cell, always (no footprint)."""
    return PlannerRules("smac_2d", INSCRIBED, allow_unknown, tolerance=tolerance, robot_radius=robot_radius,
                        max_planning_time=max_planning_time)


def theta_star(allow_unknown: bool = True, robot_radius: float = JAZZY.robot_radius) -> PlannerRules:
    """``nav2_theta_star_planner::ThetaStarPlanner``: cost <= 252 is safe, no goal tolerance."""
    return PlannerRules("theta_star", INSCRIBED, allow_unknown, tolerance=0.0, robot_radius=robot_radius)


def smac_hybrid(motion_model: str = "DUBIN", minimum_turning_radius: float = 0.4, tolerance: float = 0.25,
                allow_unknown: bool = True, footprint: Optional[np.ndarray] = None,
                robot_radius: float = JAZZY.robot_radius, max_planning_time: float = 5.0) -> PlannerRules:
    """``nav2_smac_planner::SmacPlannerHybrid``; DUBIN drives forward only, REEDS_SHEPP reverses too."""
    model = motion_model.upper()
    if model not in ("DUBIN", "REEDS_SHEPP"):
        raise ValueError(f"motion_model_for_search {motion_model!r}: Hybrid-A* takes DUBIN or REEDS_SHEPP")
    return _kinematic("smac_hybrid", minimum_turning_radius, model == "REEDS_SHEPP", tolerance, allow_unknown,
                      footprint, robot_radius, max_planning_time)


def smac_lattice(minimum_turning_radius: float = 0.5, allow_reverse_expansion: bool = False,
                 tolerance: float = 0.25, allow_unknown: bool = True, footprint: Optional[np.ndarray] = None,
                 robot_radius: float = JAZZY.robot_radius, max_planning_time: float = 5.0,
                 motion_model: str = "ackermann") -> PlannerRules:
    """``nav2_smac_planner::SmacPlannerLattice``; the radius and motion model are the primitives file's
    ``lattice_metadata`` (``turning_radius``, ``motion_model``). Only an ``ackermann`` set promises the
    radius: ``diff`` sets rotate in place and ``omni`` sets move sideways, so for them the kinematic
    oracles are off and only the collision and endpoint oracles judge."""
    model = str(motion_model).lower()
    if model not in ("ackermann", "diff", "omni"):
        raise ValueError(f"motion_model {motion_model!r}: a lattice file's is ackermann, diff or omni")
    rules = _kinematic("smac_lattice", minimum_turning_radius, allow_reverse_expansion, tolerance, allow_unknown,
                       footprint, robot_radius, max_planning_time)
    return rules if model == "ackermann" else replace(rules, min_turning_radius=None)


def _kinematic(name: str, radius: float, reversing: bool, tolerance: float, allow_unknown: bool,
               footprint: Optional[np.ndarray], robot_radius: float, max_time: float) -> PlannerRules:
    """Hybrid and Lattice share the collision checker: the centre cell blocks at 253 either way."""
    poly = None if footprint is None else np.asarray(footprint, dtype=float)
    return PlannerRules(name, INSCRIBED, allow_unknown, tolerance=tolerance,
                        robot_radius=robot_radius, footprint=poly, min_turning_radius=radius,
                        reversing=reversing, max_planning_time=max_time)


PROFILES = {"navfn": navfn, "smac_2d": smac_2d, "theta_star": theta_star, "smac_hybrid": smac_hybrid,
            "smac_lattice": smac_lattice}
