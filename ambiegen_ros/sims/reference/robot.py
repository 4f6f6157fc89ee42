"""Robot reference: a route that keeps the robot's footprint plus a margin clear of every wall.

The replication profile's A* (``diagonal="always"``) steps between two wall cells that touch at a
corner and brushes wall corners at zero clearance: a route no robot can drive. A failure on such a
map says nothing about the robot, so the full model drives a route planned here instead, and a
map without one is an invalid test.

* *Required clearance*: the circumscribed radius of the pioneer2dx footprint about its rotation
  centre (``footprint_radius``: 0.26 m, the rear of its lid; computed from
  ``robot_world.PIONEER2DX``) plus ``clearance_margin`` (0.1 m): 0.36 m. A robot centre that far
  from every wall cannot touch one at any heading.
* *Clearance field*: the map (walls and everything outside it) is seen on a fine grid of
  ``route_resolution`` (0.1 m; rounded so that a whole number of fine cells fits a map cell). A
  fine cell is free when the Euclidean distance from its centre to the nearest wall cell's square
  is at least the required clearance. The distance is exact: a Euclidean distance transform on
  the half-fine lattice, which holds both the nearest wall corner and the foot of the
  perpendicular to the nearest wall edge of every fine-cell centre.
* *Route*: the shortest 8-connected path over free fine cells (a diagonal step needs both
  orthogonal neighbours free) from the start's to the goal's fine cell (``scipy.sparse.csgraph``),
  then pulled tight: from each vertex the farthest later one whose straight segment keeps the
  clearance, then every vertex dropped whose neighbours see each other (segments sampled every
  ``SEGMENT_STEP`` = 1 cm against the exact wall distance ``robot_world.clearances``, so a segment
  may come at most 5 mm nearer between samples).
  Two adjacent fine-cell centres are joined even when their short segment dips below the
  clearance (a corner passed between them: at most 7 mm at 0.1 m); ``route_min_clearance_m``
  records what the final route keeps, measured the same way.
* *Start and goal*: the problem's cell centres, joined to the route exactly. A free map cell's
  centre keeps half a cell (0.5 m) from the walls, more than the 0.36 m required, so with the
  default margin this never decides anything; with a margin above 0.24 m (or a finer map) a start
  or goal with less clearance than required has no clearance route: INVALID_TEST naming it, never
  a route that squeezes out of it.

``before`` answers ``clearance_route``: passed with the route as evidence (the simulator drives
it), or not passed, "no route keeps 0.36 m from the walls". On the paper's maps ``after`` has
nothing to add: on a map with a clearance route the robot's failure is its own (the route exists;
a robot that keeps it passes), so the route's existence is the whole reference. Hazards scenarios
(issue 48) check the route on the map the robot is given and in the true world (unmapped boxes
and posts kept clear too), and with walking people ``after`` drives the patient reference
(``robot_patient``).

*Robot profile* (issue 69): a config with a ``robot_profile`` (a ``sims.robot_profile``
``RobotProfile``, or a shipped name or path) asks for that robot's circumscribed radius instead
of the Pioneer's (the TurtleBot 3's 0.105 m passes gaps the Pioneer's 0.26 m does not); an
Ackermann profile's route must also be drivable by a car (``robot_car``: rounded to its minimum
turning radius, no turn on the spot at the start), else the scenario is an invalid test with the
reason; the patient reference drives the profile's body, no faster than its limits, a car along
the rounded path.

Speed (``bench/robot_route.py``, 20 sampled replication maps + an empty room, 500 x 500 fine
cells each): median 0.37 s, worst 0.48 s on the shared 2-core machine at load 6 (median 0.83 s
at load 8); the distance transform, the graph and Dijkstra take about a third each. A simulated
run takes seconds.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from ...problems.robot import grid_graph
from ..robot_world import PIONEER2DX, clearances, pad_grid
from . import ReferenceVerdict

SEGMENT_STEP = 0.01
"""Samples along a route segment whose wall distance is checked [m] (error at most half of it)."""
EPS = 1e-9  # distances equal to the required clearance count as enough (float rounding) [m]


def footprint_radius(footprint: np.ndarray = PIONEER2DX) -> float:
    """The body's circumscribed radius about its rotation centre (the footprint's origin) [m]."""
    pts = np.asarray(footprint, dtype=float)
    return float(np.hypot(pts[:, 0], pts[:, 1]).max())


def robot_profile(config: Any) -> Any:
    """The config's robot profile (a ``robot_profile.ProfiledConfig``'s ``RobotProfile``), or None
    for the Pioneer."""
    return getattr(config, "robot_profile", None) or None


def body_radius(config: Any) -> float:
    """The robot's circumscribed radius about its rotation centre: the profile's, else the Pioneer's [m]."""
    profile = robot_profile(config)
    return footprint_radius() if profile is None else profile.circumscribed_radius()


def required_clearance(config: Any) -> float:
    """Footprint radius (``body_radius``) + the config's ``clearance_margin`` [m]."""
    return body_radius(config) + float(config.clearance_margin)


def fine_size(resolution: float, route_resolution: float) -> float:
    """``route_resolution`` rounded so that a whole number of fine cells fits one map cell."""
    return resolution / max(1, round(resolution / route_resolution))


@dataclass
class ClearanceRoute:
    """A route keeping ``required`` metres from every wall; ``waypoints`` empty when none exists."""

    waypoints: np.ndarray  # (K, 2) metres, start and goal included
    length: float  # polyline length [m]; inf without a route
    required: float  # the clearance asked for [m]
    min_clearance: float | None  # the least wall distance along the route (1 cm samples) [m]
    reason: str  # why there is no route ("" with one)
    fine: float  # fine cell size used [m]

    @property
    def found(self) -> bool:
        return len(self.waypoints) > 0


def clearance_field(grid: np.ndarray, resolution: float, fine: float) -> np.ndarray:
    """Exact distance from each fine-cell centre to the nearest wall square (outside = wall), ``[y, x]``.

    ``fine`` must divide ``resolution``. The nearest point of a union of cell squares to a centre
    at odd multiples of fine / 2 is a wall corner or the foot of a perpendicular on a wall edge;
    both lie on the lattice of fine / 2 steps, so a distance transform over that lattice is exact.
    """
    from scipy.ndimage import distance_transform_edt

    grid = np.asarray(grid, dtype=bool)
    H, W = grid.shape
    n = int(round(2 * resolution / fine))  # half-fine steps per map cell
    padded = pad_grid(grid)  # padded index = grid index + 1

    def cells(count: int) -> tuple[np.ndarray, np.ndarray]:
        k = np.arange(count * n + 1)
        inner = k // n + 1  # the cell whose square holds the sample (its lower edge included)
        return inner, np.where(k % n == 0, inner - 1, inner)  # on a cell edge: the neighbour too

    ya, yb = cells(H)
    xa, xb = cells(W)
    rows = padded[ya] | padded[yb]
    wall = rows[:, xa] | rows[:, xb]
    dist = distance_transform_edt(~wall, sampling=fine / 2)
    return dist[1::2, 1::2]


def _wall_distance(grid: np.ndarray, resolution: float, points: np.ndarray, required: float,
                   extra: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None) -> np.ndarray:
    """Exact distance of points to the walls (outside = wall), capped beyond ``required`` + a cell;
    with ``extra`` (x, y -> distances: obstacles not on the grid) the nearer of the two."""
    cells = int(math.ceil(required / resolution)) + 1
    out = clearances(pad_grid(grid), resolution, points[:, 0], points[:, 1], cells, origin=(-resolution, -resolution))
    return out if extra is None else np.minimum(out, extra(points[:, 0], points[:, 1]))


def _samples(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    steps = max(1, int(math.ceil(math.hypot(b[0] - a[0], b[1] - a[1]) / SEGMENT_STEP)))
    s = np.linspace(0.0, 1.0, steps + 1)[:, None]
    return a + s * (b - a)


def polyline_clearance(grid: np.ndarray, resolution: float, waypoints: np.ndarray, required: float,
                       extra: Callable | None = None) -> float:
    """The least wall (and ``extra`` obstacle) distance along a polyline, sampled every ``SEGMENT_STEP``."""
    pts = np.concatenate([_samples(a, b) for a, b in zip(waypoints[:-1], waypoints[1:])]) if len(waypoints) > 1 \
        else np.asarray(waypoints, dtype=float)
    return float(_wall_distance(grid, resolution, pts, required, extra).min())


def _pull_tight(grid: np.ndarray, resolution: float, pts: np.ndarray, required: float,
                extra: Callable | None = None) -> np.ndarray:
    """From each kept vertex, the farthest later one reachable by a segment keeping ``required``
    (galloping then bisecting; every accepted segment is checked, only adjacent points pass
    unchecked), then any vertex whose neighbours see each other dropped."""

    def clear(i: int, j: int) -> bool:
        return bool(_wall_distance(grid, resolution, _samples(pts[i], pts[j]), required, extra).min() >= required - EPS)

    keep, i, last = [0], 0, len(pts) - 1
    while i < last:
        best, step, blocked = i + 1, 2, None
        while best < last:
            j = min(i + step, last)
            if clear(i, j):
                best, step = j, step * 2
            else:
                blocked = j
                break
        if blocked is not None:
            lo, hi = best, blocked
            while hi - lo > 1:
                mid = (lo + hi) // 2
                lo, hi = (mid, hi) if clear(i, mid) else (lo, mid)
            best = lo
        keep.append(best)
        i = best
    changed = True
    while changed:  # the greedy pass can stop short of a corner (a chord along a wall dips by mm): drop
        changed = False  # every vertex whose neighbours see each other
        k = 1
        while k < len(keep) - 1:
            if clear(keep[k - 1], keep[k + 1]):
                del keep[k]
                changed = True
            else:
                k += 1
    return pts[keep]


def plan_clearance_route(grid: np.ndarray, resolution: float, start_xy: tuple[float, float],
                         goal_xy: tuple[float, float], required: float, route_resolution: float = 0.1,
                         extra: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None) -> ClearanceRoute:
    """The shortest route from ``start_xy`` to ``goal_xy`` keeping ``required`` m from every wall
    (module docstring) and, with ``extra`` (x, y -> distance), from the obstacles it measures."""
    from scipy.sparse.csgraph import dijkstra

    grid = np.asarray(grid, dtype=bool)
    fine = fine_size(resolution, route_resolution)
    none = lambda reason: ClearanceRoute(np.zeros((0, 2)), math.inf, required, None, reason, fine)  # noqa: E731
    ends = np.array([start_xy, goal_xy], dtype=float)
    own = _wall_distance(grid, resolution, ends, required, extra)
    what = "the walls" if extra is None else "the walls and obstacles"
    for name, xy, d in zip(("start", "goal"), ends, own):
        if d < required - EPS:
            return none(f"the {name} ({xy[0]:.2f}, {xy[1]:.2f}) keeps only {d:.2f} m from {what}, "
                        f"less than the {required:.2f} m required")
    field = clearance_field(grid, resolution, fine)
    if extra is not None:
        fy, fx = np.mgrid[0:field.shape[0], 0:field.shape[1]]
        field = np.minimum(field, extra(((fx + 0.5) * fine).ravel(), ((fy + 0.5) * fine).ravel()).reshape(field.shape))
    free = field >= required - EPS
    Hf, Wf = free.shape
    nodes = []
    for xy in ends:  # the fine cell holding the point, else its nearest free neighbour
        i, j = int(math.floor(xy[0] / fine)), int(math.floor(xy[1] / fine))
        near = [(jj, ii) for jj in range(j - 1, j + 2) for ii in range(i - 1, i + 2)
                if 0 <= jj < Hf and 0 <= ii < Wf and free[jj, ii]]
        near.sort(key=lambda c: (c != (j, i), math.hypot((c[1] + 0.5) * fine - xy[0], (c[0] + 0.5) * fine - xy[1])))
        if not near:
            return none(f"no route keeps {required:.2f} m from {what}")
        nodes.append(near[0][0] * Wf + near[0][1])
    dist, pred = dijkstra(grid_graph(~free[None], "both_free"), indices=nodes[0], return_predecessors=True)
    if not np.isfinite(dist[nodes[1]]):
        return none(f"no route keeps {required:.2f} m from {what}")
    chain = [nodes[1]]
    while chain[-1] != nodes[0]:
        chain.append(int(pred[chain[-1]]))
    chain = np.asarray(chain[::-1])
    centres = np.column_stack([(chain % Wf + 0.5) * fine, (chain // Wf + 0.5) * fine])
    pts = np.concatenate([ends[:1], centres, ends[1:]])
    waypoints = _pull_tight(grid, resolution, pts, required, extra)
    length = float(np.hypot(*np.diff(waypoints, axis=0).T).sum())
    return ClearanceRoute(waypoints, length, required,
                          polyline_clearance(grid, resolution, waypoints, required, extra), "", fine)


def route_for(grid: np.ndarray, resolution: float, start: tuple[int, int], goal: tuple[int, int],
              config: Any, extra: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None) -> ClearanceRoute:
    """The clearance route between two cells' centres with the config's margin and resolution (and
    clear of what ``extra`` measures, as ``plan_clearance_route``)."""
    centre = lambda c: ((c[0] + 0.5) * resolution, (c[1] + 0.5) * resolution)  # noqa: E731
    return plan_clearance_route(grid, resolution, centre(start), centre(goal), required_clearance(config),
                                config.route_resolution, extra)


def before(problem: Any, scenario: Any, config: Any) -> ReferenceVerdict:
    """Passed when a clearance route joins the scenario's start and goal; it is the route driven.

    Hazards scenarios (issue 48): the route must exist on the map the robot is given (what it
    plans on) and in the true world, whose unmapped boxes and posts it also keeps clear of (what
    the reference drives)."""
    env = problem.environment(scenario)
    route = route_for(env.grid, env.resolution, env.start, env.goal, config)
    metrics = {
        "route_length_m": route.length if route.found else None,
        "clearance_m": route.required,
        "footprint_radius_m": body_radius(config),
        "clearance_margin_m": float(config.clearance_margin),
        "route_min_clearance_m": route.min_clearance,
        "route_resolution_m": route.fine,
        "route_waypoints": int(len(route.waypoints)),
    }
    evidence = {"route": route.waypoints} if route.found else {}
    car = _car_reason(env, route, config, metrics)
    if car:
        return ReferenceVerdict(False, "clearance_route", car, metrics)
    if not getattr(problem, "hazards", False):
        return ReferenceVerdict(route.found, "clearance_route", route.reason, metrics, evidence)
    if not route.found:
        return ReferenceVerdict(False, "clearance_route", f"on the map the robot is given: {route.reason}", metrics)
    true = true_route(problem, scenario, env, config)
    metrics["true_route_length_m"] = true.length if true.found else None
    if not true.found:
        return ReferenceVerdict(False, "clearance_route", f"in the world, unmapped obstacles included: {true.reason}",
                                metrics)
    car = _car_reason(env, true, config, {}, _static_extra(env))
    if car:
        return ReferenceVerdict(False, "clearance_route", f"in the world, unmapped obstacles included: {car}", metrics)
    return ReferenceVerdict(True, "clearance_route", "", metrics, evidence)


def _static_extra(env: Any) -> Callable | None:
    """The distance to a hazards world's unmapped boxes and posts (None without any)."""
    from ..obstacles import Obstacles

    obstacles = Obstacles.from_dict(env.unmapped) if getattr(env, "unmapped", None) else Obstacles()
    return obstacles.static_distance if len(obstacles.posts) or len(obstacles.boxes) else None


def _car_reason(env: Any, route: ClearanceRoute, config: Any, metrics: dict, extra: Callable | None = None) -> str:
    """Why a car-like profile cannot drive the found route ('' when it can, or for any other robot)."""
    profile = robot_profile(config)
    if profile is None or profile.drive != "ackermann" or not route.found:
        return ""
    from .robot_car import car_check

    path = car_check(env.grid, env.resolution, route.waypoints, env.start_yaw or 0.0, profile.min_turning_radius,
                     profile.circumscribed_radius(), extra)
    metrics["min_turning_radius_m"] = profile.min_turning_radius
    return "" if path.found else f"no car-like robot drives it: {path.reason}"


_TRUE_ROUTES: dict = {}  # the last few true-world routes (``before`` and ``after`` ask for the same)


def true_route(problem: Any, scenario: Any, env: Any, config: Any) -> ClearanceRoute:
    """The clearance route of a hazards scenario's true world: walls and unmapped boxes and posts."""
    from ..obstacles import Obstacles

    key = (scenario.to_json(indent=None), required_clearance(config), float(config.route_resolution))
    if key not in _TRUE_ROUTES:
        obstacles = Obstacles.from_dict(env.unmapped) if env.unmapped else Obstacles()
        static = len(obstacles.posts) or len(obstacles.boxes)
        if len(_TRUE_ROUTES) >= 8:
            _TRUE_ROUTES.pop(next(iter(_TRUE_ROUTES)))
        _TRUE_ROUTES[key] = route_for(env.grid, env.resolution, env.start, env.goal, config,
                                      obstacles.static_distance if static else None)
    return _TRUE_ROUTES[key]


def after(problem: Any, scenario: Any, config: Any, outcome: Any, seed: int = 0,
          budget: float | None = None) -> ReferenceVerdict | None:
    """Hazards scenarios with people: does the patient reference (``robot_patient``), knowing every
    person's path, reach the goal along the true route? Without people (and on the paper's maps)
    the route's existence is the whole reference: None keeps ``before``'s word.

    ``budget`` (s): the system under test gave up at its own time limit per goal (a behaviour
    tree's Timeout), shorter than the scenario's. The reference then has that much time too, people
    or not: a route longer than the stack allows itself is the stack's setting, not its failure."""
    from ..obstacles import Obstacles
    from .robot_patient import patient_run

    if not getattr(problem, "hazards", False) and budget is None:
        return None
    env = problem.environment(scenario)
    obstacles = Obstacles.from_dict(env.unmapped) if env.unmapped else Obstacles()
    if not obstacles.people and budget is None:
        return None
    true = true_route(problem, scenario, env, config)
    if not true.found:
        return ReferenceVerdict(False, "patient_robot", f"in the world, unmapped obstacles included: {true.reason}")
    limit = float(budget) if budget else (outcome.metrics or {}).get("time_limit") or config.time_limit(true.length)
    run = _patient(true, obstacles.people, env, config, float(limit))
    metrics = {"patient_time_s": run.time, "patient_waited_s": run.waited,
               "patient_contacts_not_at_fault": run.contacts_not_at_fault, "true_route_length_m": true.length}
    reason = run.reason
    if budget:
        metrics["time_budget_s"] = float(budget)
        if not run.passed:
            reason = (f"the patient reference robot does not reach the goal within the stack's own {budget:.0f} s "
                      f"per goal either (the route is {true.length:.0f} m): a setting of the stack, not a failure")
    return ReferenceVerdict(run.passed, "patient_robot", reason, metrics)


def _patient(route: ClearanceRoute, people: tuple, env: Any, config: Any, limit: float) -> Any:
    """The patient reference on the config's robot: the Pioneer as before, or the profile's body no
    faster than its limits (a car along its rounded path, which ``before`` found drivable)."""
    from .robot_patient import patient_run

    profile = robot_profile(config)
    if profile is None:
        return patient_run(route.waypoints, people, env.start_yaw or 0.0, env.goal_yaw, config, limit)
    import dataclasses

    speed = min(float(config.cruise_speed), profile.max_speed[0])
    turn = min(float(config.nd_turn_rate_deg), math.degrees(profile.max_speed[2]))
    cfg = dataclasses.replace(config, cruise_speed=speed, nd_turn_rate_deg=turn)
    plan = None
    if profile.drive == "ackermann":
        from .robot_car import car_check, poses_along

        path = car_check(env.grid, env.resolution, route.waypoints, env.start_yaw or 0.0, profile.min_turning_radius,
                         profile.circumscribed_radius(), _static_extra(env))
        plan = poses_along(path.points, speed, float(config.dt))
    return patient_run(route.waypoints, people, env.start_yaw or 0.0, env.goal_yaw, cfg, limit, profile.footprint(),
                       plan=plan)


__all__ = ["ClearanceRoute", "SEGMENT_STEP", "after", "before", "true_route", "clearance_field", "fine_size", "footprint_radius",
           "plan_clearance_route", "polyline_clearance", "required_clearance", "robot_profile", "route_for",
           "body_radius"]
