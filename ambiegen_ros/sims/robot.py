"""Full-model robot: a Stage pioneer2dx with a 2D laser following the A* route through an obstacle map.

The paper (RQ3) drove its maps in Player/Stage: a pioneer2dx with a SICK laser, Player's ``nd``
(Nearness Diagram) driver steering towards the RDP-simplified A* waypoints, and the monitors of
Arnold and Alexander (2013) judging the run. This is a ROS-free, time-stepped stand-in, independent
of the surrogate's path-length fitness. The world (body, contact with walls, laser) is
``sims.robot_world``; this module is the robot's run: its route, its local planner and the
monitors that judge it.

* *Route* (``plan_route``): with ``reference`` (default), the clearance route of
  ``sims.reference.robot``: the shortest route that keeps the footprint's circumscribed radius
  (0.26 m) plus ``clearance_margin`` (0.1 m) from every wall, planned on a ``route_resolution``
  (0.1 m) grid and pulled tight, in every profile; a map without one is an INVALID_TEST before
  anything runs (``sims.full_model``), and the executor hands the route it checked to
  ``simulate(route=...)``. With ``reference=false``, the old route: A* (``problems.robot.astar``) on
  the grid inflated by ``radius``, with the problem's diagonal rule (the route its surrogate
  scored; ``route_diagonal`` overrides it: the replication profile's rule ``always`` also steps
  diagonally between two wall cells that touch at a corner, a gap no robot passes), simplified by
  Ramer-Douglas-Peucker (``rdp_epsilon``). The surrogate keeps its A* either way (RQ1/RQ2).
  A controller sends the waypoints one by one and moves on within ``waypoint_tolerance`` of the
  current one, like the paper's waypoint follower. No route leaves the robot standing
  (``outcome = "no_route"``).
* *Local planner* (``planner``): ``"nd"`` (default) is the Nearness Diagram method with Player's
  ``nd`` driver around it and the paper's ``player.cfg`` numbers (``sims.nearness_diagram``):
  0.3 m/s and 30 deg/s at most, 0.1 m/s and 10 deg/s at least, its own goal tolerance 0.1 m
  (``nd_goal_tolerance``), avoid_dist 0.4 m, safety_dist 0, stuck after 5 s without 0.15 m or
  10 deg, the last two laser scans. It gives up (its stall flag) on an emergency stop, with no
  navigable region or when stuck. ``"gap"`` is the earlier planner (a disc of ``radius + margin``
  choosing the free heading closest to the waypoint, with a slow squeeze mode); it never gives up
  by itself.

Oracle (``RobotMonitors``, the paper's monitors), checked on every pose in this order:

* *stall*: the body touches a wall (Stage's stall: blocked, it cannot move), or the robot's
  stall flag is up (the ND driver gave up), or the loitering rule below fires on a robot that did
  not move at all (no route: it never starts). ``metrics["stall_cause"]`` says which: contact |
  emergency_stop | no_region | no_progress | no_motion | stationary | no_route;
* *success*: within ``goal_tolerance`` (0.5 m, ``GOAL_TOLERANCE``) of the goal (the route's last
  waypoint): the paper's pipeline judged arrival at its waypoints within 0.5 m, the last one
  included. The run ends there, so the ND driver's own 0.1 m never decides a verdict;
* *loiter*: once the run covers ``stall_time`` (the loitering window, 10 s), the robot lies
  within ``stall_radius`` (0.5 m) of the mean position of the window's poses;
* *timeout*: the time limit, ``max(timeout, timeout_route_factor x route length / cruise_speed
  + timeout_margin)`` = max(300 s, 2 x route / 0.3 m/s + 60 s): a long route alone never fails.
  (The paper stopped a run after 300 s of wall clock on a simulation about 8x faster than real
  time; a fixed limit is ``timeout_route_factor = timeout_margin = 0``.)

With ``early_verdicts=False`` (a stack with its own recoveries, e.g. Nav2 behind
``sut_adapter``), stall, success and loitering do not end the run: the first of them is recorded
as the *early verdict* (``metrics["early_verdict"]``, ``early_detail``, ``early_time``) and only
a collision (the world's report, or the body touching a wall) and the time limit decide; the
stack's own result decides the rest (``oracles.RobotJudge.stack_result``). Every run records its
early verdict either way, so the two can be compared.

Unsafe proximity (body within ``proximity`` = 0.2 m of a wall) and waypoint arrivals (within
``waypoint_tolerance``) are recorded (``unsafe_proximity_events``/``_s``, ``waypoints_reached``),
not failures: the paper's verdict counted stalls and loitering only (its proximity monitor watched
pairs of robots). Metrics: outcome, time, time limit, path length, minimum clearance (body to
wall), route length, distance to the goal and the goal tolerance it was judged with.

Speed: a run of a 50 m map takes 1.5-2.5 s, about 150x real time (ND itself, numpy, is most of a
step; the world's loops are compiled).
"""
from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..core.attributes import ScenarioError
from ..problems.robot import DIAGONAL_RULES, astar, inflate
from .nearness_diagram import NDDriver, NDParams, NearnessDiagram
from .outcome import Outcome
from .reference.robot import route_for
from .robot_world import (ENGINES, PIONEER2DX, PIONEER2DX_LENGTH, PIONEER2DX_ORIGIN_X, PIONEER2DX_WIDTH, WORLD_FIELDS,
                          RobotWorld, WallGeometry, _clip, cast_rays, clearances, pad_grid, pioneer2dx_footprint,
                          wall_distance)

PLANNERS = ("nd", "gap")
STALL_CAUSES = ("contact", "emergency_stop", "no_region", "no_progress", "no_motion", "stationary", "no_route",
                "reported")

GOAL_TOLERANCE = 0.5
"""Success: the monitors end the run as passed once the robot's centre is this close to the goal
[m]. The paper's pipeline (Arnold and Alexander's monitors) judged arrival at every waypoint, the
goal (the route's last waypoint) included, within 0.5 m."""
WAYPOINT_TOLERANCE = 0.5
"""Route following: the controller sends the next waypoint once the robot is this close to the
current one, and the monitors count an arrival [m] (the paper's arrival tolerance)."""
ND_GOAL_TOLERANCE = 0.1
"""The ND driver's own ``goal_tol`` (Player's ``nd``, the paper's player.cfg) [m]: where it stops
for the waypoint it was sent. It steers; it never decides a verdict (``GOAL_TOLERANCE`` does)."""


@dataclass(frozen=True)
class RobotSimConfig:
    """Every number of the full-model robot (defaults: Stage's pioneer2dx, the paper's player.cfg
    and monitors)."""

    planner: str = "nd"  # nd | gap
    radius: float = 0.3  # the gap planner's disc; the old route's A* inflation (reference=false) [m]
    cruise_speed: float = 0.3  # top speed of either planner (ND's max_speed) and of the time limit [m/s]
    max_speed: float = 0.8  # hard limit of the base [m/s]
    max_turn_rate: float = 1.0  # [rad/s]
    max_accel: float = 0.5  # [m/s^2]
    max_turn_accel: float = 2.0  # [rad/s^2]
    dt: float = 0.1  # simulation and control step [s]
    # laser
    laser_range: float = 10.0  # [m]
    fov_deg: float = 180.0  # field of view, centred on the heading
    beams: int = 181
    laser_noise: float = 0.01  # standard deviation of range noise [m]; 0 = exact
    # route
    reference: bool = True  # check each scenario with the problem's reference; false = the old, unchecked verdicts
    clearance_margin: float = 0.1  # the clearance route keeps the footprint's radius + this from every wall [m]
    route_resolution: float = 0.1  # fine grid of the clearance route [m]
    route_diagonal: str | None = None  # old route (reference=false): A* diagonal rule; None = the problem's
    rdp_epsilon: float = 0.5  # old route: Ramer-Douglas-Peucker tolerance [m]
    waypoint_tolerance: float = WAYPOINT_TOLERANCE  # the controller moves on this close to a waypoint [m]
    # nearness diagram (Player's nd driver, the paper's player.cfg)
    nd_turn_rate_deg: float = 30.0  # max_speed[1] [deg/s]
    nd_min_speed: float = 0.1  # min_speed[0] [m/s]
    nd_min_turn_rate_deg: float = 10.0  # min_speed[1] [deg/s]
    nd_goal_tolerance: float = ND_GOAL_TOLERANCE  # goal_tol[0]: the ND driver stops this close [m]
    avoid_dist: float = 0.4  # [m]
    safety_dist: float = 0.0  # [m]
    stuck_time: float = 5.0  # translate_stuck_time [s]
    stuck_distance: float = 0.15  # translate_stuck_dist [m]
    stuck_angle_deg: float = 10.0  # translate_stuck_angle [deg]
    laser_buffer: int = 2  # scans merged per cycle
    nd_sectors: int = 180
    # gap planner
    margin: float = 0.05  # extra clearance the gap planner keeps around its disc [m]
    lookahead: float = 1.0  # a heading must be free this far (or up to the waypoint) [m]
    directions: int = 91  # candidate headings across the field of view
    turn_gain: float = 1.5  # turn rate per radian of heading error [1/s]
    turn_in_place_deg: float = 60.0  # heading errors above this turn on the spot
    slow_distance: float = 0.6  # speed scales down when the chosen heading is free less than this [m]
    squeeze_margin: float = 0.01  # margin when the normal one leaves no way forward [m]
    squeeze_lookahead: float = 0.3  # [m]
    squeeze_speed: float = 0.1  # [m/s]
    # monitors
    goal_tolerance: float = GOAL_TOLERANCE  # success: the monitors pass a run this close to the goal [m]
    stall_radius: float = 0.5  # loitering radius [m]
    stall_time: float = 10.0  # loitering window [s]
    proximity: float = 0.2  # unsafe proximity (recorded) [m]
    timeout: float = 300.0  # the time limit is at least this [s]
    timeout_route_factor: float = 2.0  # ... and at least this x route length / cruise_speed ...
    timeout_margin: float = 60.0  # ... + this [s]
    clearance_cells: int = 3  # clearance is measured to walls within this many cells (capped beyond)
    # a contact with a person is the robot's only when it moves towards them faster than this [m/s]
    contact_fault_speed: float = 0.01
    run_invalid: bool = False  # also simulate scenarios the problem calls invalid
    engine: str = "auto"  # laser and body clearance: numba (compiled, same numbers) | numpy | auto

    def __post_init__(self):
        if self.planner not in PLANNERS:
            raise ScenarioError("option.planner", f"unknown planner {self.planner!r}", "|".join(PLANNERS))
        for name in ("radius", "cruise_speed", "max_speed", "max_turn_rate", "max_accel", "max_turn_accel",
                     "dt", "laser_range", "fov_deg", "lookahead", "turn_gain", "slow_distance",
                     "goal_tolerance", "stall_radius", "stall_time", "timeout", "waypoint_tolerance",
                     "nd_turn_rate_deg", "nd_goal_tolerance", "avoid_dist", "stuck_time", "stuck_distance",
                     "stuck_angle_deg", "route_resolution"):
            if not getattr(self, name) > 0:
                raise ScenarioError(f"option.{name}", "must be > 0")
        for name in ("laser_noise", "rdp_epsilon", "margin", "squeeze_margin", "squeeze_lookahead", "squeeze_speed",
                     "nd_min_speed", "nd_min_turn_rate_deg", "safety_dist", "proximity", "timeout_route_factor",
                     "timeout_margin", "clearance_margin", "contact_fault_speed"):
            if getattr(self, name) < 0:
                raise ScenarioError(f"option.{name}", "must be >= 0")
        if self.beams < 3 or self.directions < 3:
            raise ScenarioError("option.beams", "need at least 3 beams and 3 directions")
        if self.fov_deg > 360:
            raise ScenarioError("option.fov_deg", "at most 360")
        if self.cruise_speed > self.max_speed:
            raise ScenarioError("option.cruise_speed", "above max_speed", f"<= {self.max_speed}")
        if self.nd_min_speed > self.cruise_speed or self.nd_min_turn_rate_deg > self.nd_turn_rate_deg:
            raise ScenarioError("option.nd_min_speed", "minimum speeds above the maximum ones")
        if self.engine not in ENGINES:
            raise ScenarioError("option.engine", f"unknown engine {self.engine!r}", "|".join(ENGINES))
        if self.route_diagonal is not None and self.route_diagonal not in DIAGONAL_RULES:
            raise ScenarioError("option.route_diagonal", f"unknown rule {self.route_diagonal!r}",
                                "|".join(DIAGONAL_RULES))
        if self.laser_buffer < 1:
            raise ScenarioError("option.laser_buffer", "must be >= 1")
        if self.nd_sectors < 8 or self.nd_sectors % 4:
            raise ScenarioError("option.nd_sectors", "a multiple of 4, at least 8")

    def time_limit(self, route_length: float | None, speed: float | None = None) -> float:
        """max(timeout, timeout_route_factor x route / speed + timeout_margin) [s]; ``speed`` is the
        robot's top speed (default ``cruise_speed``; a stack's own, e.g. Nav2's controller's)."""
        if route_length is None or not math.isfinite(route_length):
            return float(self.timeout)
        return float(max(self.timeout, self.timeout_route_factor * route_length / (speed or self.cruise_speed)
                         + self.timeout_margin))



# --- the route -----------------------------------------------------------------------------------
def rdp(points: np.ndarray, epsilon: float) -> np.ndarray:
    """Ramer-Douglas-Peucker: keep the vertices that deviate more than ``epsilon`` from the chord."""
    points = np.asarray(points, dtype=float)
    if len(points) < 3:
        return points.copy()
    keep = np.zeros(len(points), dtype=bool)
    keep[0] = keep[-1] = True
    stack = [(0, len(points) - 1)]
    while stack:
        lo, hi = stack.pop()
        if hi - lo < 2:
            continue
        a, b = points[lo], points[hi]
        mid = points[lo + 1:hi]
        ab = b - a
        norm = math.hypot(ab[0], ab[1])
        if norm == 0:
            dist = np.hypot(*(mid - a).T)
        else:
            dist = np.abs(ab[0] * (mid[:, 1] - a[1]) - ab[1] * (mid[:, 0] - a[0])) / norm
        k = int(np.argmax(dist))
        if dist[k] > epsilon:
            idx = lo + 1 + k
            keep[idx] = True
            stack.append((lo, idx))
            stack.append((idx, hi))
    return points[keep]


# --- the paper's monitors ------------------------------------------------------------------------
class RobotMonitors:
    """Stall, route completion, loitering and time limit on a stream of poses (see the module
    docstring), plus the recorded unsafe-proximity and waypoint-arrival events. ``update`` takes
    one pose with its body clearance and the robot's stall flag (the cause, or None); it returns
    True once decided (``kind``, ``outcome``, ``detail``, ``failure_point``, ``stall_cause``).

    When the loitering rule fires on a robot that did not move at all during the window, it is a
    stall ("stationary"; "no_route" when ``no_route``): what an observer without the stall flag
    sees of a robot that gave up or never started."""

    def __init__(self, config: RobotSimConfig, goal_xy: tuple[float, float], time_limit: float,
                 waypoints: np.ndarray | None = None, no_route: bool = False, early_verdicts: bool = True):
        self.cfg = config
        self.no_route = no_route
        self.early_verdicts = early_verdicts
        self.early: dict[str, Any] | None = None  # the first verdict of stall / success / loitering
        self.goal = (float(goal_xy[0]), float(goal_xy[1]))
        self.time_limit = float(time_limit)
        self.waypoints = np.zeros((0, 2)) if waypoints is None else np.asarray(waypoints, dtype=float)
        self.kind: str | None = None
        self.outcome = ""
        self.detail = ""
        self.failure_point: tuple[float, float] | None = None
        self.stall_cause: str | None = None
        self.t0: float | None = None
        self.t = 0.0
        self.path_length = 0.0
        self.min_clearance = math.inf
        self.proximity_events = 0
        self.proximity_time = 0.0
        self.waypoints_reached = 0
        self.arrivals: list[float] = []
        self._near = False
        self._prev: tuple[float, float, float] | None = None
        self._window: deque = deque()  # (t, x, y) of the loitering window
        self._sum = [0.0, 0.0]
        self._window_path = 0.0  # distance driven between the window's poses

    @property
    def decided(self) -> bool:
        return self.kind is not None

    def _decide(self, kind: str, outcome: str, detail: str, x: float, y: float) -> None:
        self.kind, self.outcome, self.detail = kind, outcome, detail
        self.failure_point = None if kind == "none" else (x, y)

    def update(self, t: float, x: float, y: float, clearance: float, stall_cause: str | None = None,
               collision: str | None = None) -> bool:
        """One pose; ``collision``: a collision the world reported at it (the report's source), which
        outranks everything the monitors see at the same pose."""
        if self.decided:
            return True
        cfg = self.cfg
        first = self._prev is None
        if self._prev is None:
            self.t0 = t
        else:
            px, py, pt = self._prev
            self.path_length += math.hypot(x - px, y - py)
            if self._near:
                self.proximity_time += t - pt
        self._prev = (x, y, t)
        self.t = t - (self.t0 if self.t0 is not None else t)
        self.min_clearance = min(self.min_clearance, clearance)
        near = clearance < cfg.proximity
        self.proximity_events += int(near and not self._near)
        self._near = near
        while (self.waypoints_reached < len(self.waypoints) and math.hypot(
                *(self.waypoints[self.waypoints_reached] - (x, y))) < cfg.waypoint_tolerance):
            self.waypoints_reached += 1
            self.arrivals.append(self.t)
        # loitering window: the poses of the last stall_time seconds, this one included
        if self._window:
            self._window_path += math.hypot(x - self._window[-1][1], y - self._window[-1][2])
        self._window.append((t, x, y))
        self._sum[0] += x
        self._sum[1] += y
        while t - self._window[0][0] > cfg.stall_time + 1e-9:
            _, ox, oy = self._window.popleft()
            self._sum[0] -= ox
            self._sum[1] -= oy
            self._window_path -= math.hypot(self._window[0][1] - ox, self._window[0][2] - oy)

        if collision:
            self._decide("collision", "collision", f"collision at ({x:.2f}, {y:.2f}) after {self.t:.1f} s ({collision})",
                         x, y)
        elif clearance <= 0.0:
            self.stall_cause = "contact"
            touch = f"the body touches a wall at ({x:.2f}, {y:.2f}) after {self.t:.1f} s"
            if self.early_verdicts:
                self._decide("stall", "stall", f"{touch} and cannot move", x, y)
            else:  # no recovery undoes a touch: the collision the world reports
                self._decide("collision", "collision", touch, x, y)
        elif first and stall_cause is None:
            return False
        elif (early := self._early_rules(x, y, stall_cause)) is not None:
            kind, outcome, detail, cause = early
            if self.early is None:
                self.early = {"kind": kind, "detail": detail, "time": self.t}
            if self.early_verdicts:
                self.stall_cause = cause
                self._decide(kind, outcome, detail, x, y)
        if not self.decided and self.t >= self.time_limit - 1e-9:
            self._decide("timeout", "timeout", f"goal not reached within {self.time_limit:.0f} s", x, y)
        return self.decided

    def _early_rules(self, x: float, y: float, stall_cause: str | None) -> tuple[str, str, str, str | None] | None:
        """The stall flag, route completion and loitering at this pose, in that order: (kind,
        outcome, detail, stall cause) of the first that fires, else None."""
        cfg = self.cfg
        if stall_cause is not None:
            return ("stall", "no_route" if stall_cause == "no_route" else "stall",
                    f"stalled at ({x:.2f}, {y:.2f}) after {self.t:.1f} s: {stall_cause.replace('_', ' ')}", stall_cause)
        if (to_goal := math.hypot(self.goal[0] - x, self.goal[1] - y)) <= cfg.goal_tolerance:
            return ("none", "success", f"goal reached in {self.t:.1f} s ({to_goal:.2f} m from it; "
                    f"goal tolerance {cfg.goal_tolerance:g} m)", None)
        if self.t >= cfg.stall_time - 1e-9:
            n = len(self._window)
            cx, cy = self._sum[0] / n, self._sum[1] / n
            if math.hypot(x - cx, y - cy) < cfg.stall_radius and self._window_path < 1e-6:
                cause = "no_route" if self.no_route else "stationary"
                return ("stall", "no_route" if self.no_route else "stall",
                        f"stalled at ({x:.2f}, {y:.2f}): no motion for {cfg.stall_time:g} s (after {self.t:.1f} s)"
                        + ("; no route" if self.no_route else ""), cause)
            if math.hypot(x - cx, y - cy) < cfg.stall_radius:
                return ("loiter", "loiter", f"loitering within {cfg.stall_radius:g} m of ({cx:.2f}, {cy:.2f}) "
                        f"for {cfg.stall_time:g} s (after {self.t:.1f} s)", None)
        return None

    def early_verdict(self) -> dict[str, Any]:
        """What the early monitors said: their first verdict; else the collision or the time limit
        that both kinds of verdict share; else ``undecided`` (the stack decided first)."""
        e = self.early
        if e is None and self.kind in ("collision", "timeout"):
            e = {"kind": self.kind, "detail": self.detail, "time": self.t}
        elif e is None:
            e = {"kind": "undecided", "detail": f"no early verdict in {self.t:.1f} s", "time": None}
        return {"early_verdict": e["kind"], "early_detail": e["detail"], "early_time": e["time"]}

    def metrics(self) -> dict[str, Any]:
        return {
            "outcome": self.outcome or "undecided",
            "time": self.t,
            "time_limit": self.time_limit,
            "path_length": self.path_length,
            "min_clearance": float(self.min_clearance) if math.isfinite(self.min_clearance) else None,
            "stall_cause": self.stall_cause,
            "unsafe_proximity_events": self.proximity_events,
            "unsafe_proximity_s": self.proximity_time,
            "waypoints_reached": self.waypoints_reached,
            "goal_tolerance": self.cfg.goal_tolerance,
            "early_verdicts": self.early_verdicts,
            **self.early_verdict(),
        }


def _wrap(a):
    return (a + np.pi) % (2 * np.pi) - np.pi


# --- local planners ------------------------------------------------------------------------------
class GapPlanner:
    """The earlier local planner: for ``directions`` candidate headings across the field of view,
    how far a disc of ``radius + margin`` could travel before touching a laser return; headings
    free for ``min(lookahead, distance to the waypoint)`` are admissible, and it steers to the one
    closest to the waypoint, slowing with the free distance and the heading error and never faster
    than it could stop within the free distance. With no admissible heading it retries in a slow
    squeeze mode (``squeeze_margin``, ``squeeze_lookahead``); still none, or the waypoint behind the
    laser: it turns on the spot."""

    def __init__(self, cfg: RobotSimConfig, beam_angles: np.ndarray):
        self.cfg = cfg
        self.beam_angles = beam_angles
        self.half_fov = math.radians(cfg.fov_deg) / 2
        self.dir_angles = np.linspace(-self.half_fov, self.half_fov, cfg.directions)
        self.cos_d, self.sin_d = np.cos(self.dir_angles)[:, None], np.sin(self.dir_angles)[:, None]
        self.modes = ((cfg.radius + cfg.margin, cfg.lookahead, cfg.cruise_speed),
                      (cfg.radius + cfg.squeeze_margin, cfg.squeeze_lookahead,
                       min(cfg.squeeze_speed, cfg.cruise_speed)))
        self.turn_in_place = math.radians(cfg.turn_in_place_deg)
        self.ahead = int(np.argmin(np.abs(self.dir_angles)))

    def command(self, bearing: float, dist: float, final: bool, ranges: np.ndarray) -> tuple[float, float]:
        cfg = self.cfg
        if abs(bearing) > self.half_fov:
            return 0.0, math.copysign(cfg.max_turn_rate, bearing)
        hits = ranges < cfg.laser_range
        ox = ranges[hits] * np.cos(self.beam_angles[hits])
        oy = ranges[hits] * np.sin(self.beam_angles[hits])
        forward = ox[None, :] * self.cos_d + oy[None, :] * self.sin_d
        lateral = oy[None, :] * self.cos_d - ox[None, :] * self.sin_d
        error = np.abs(_wrap(self.dir_angles - bearing))
        for reach, need, v_cap in self.modes:
            blocking = (forward > 0) & (np.abs(lateral) < reach)
            reach_at = forward - np.sqrt(np.maximum(reach * reach - lateral * lateral, 0.0))
            free = np.where(blocking, reach_at, cfg.laser_range).min(axis=1, initial=cfg.laser_range)
            admissible = free >= min(need, dist)
            if admissible.any():
                break
        if not admissible.any():  # boxed in ahead: turn on the spot towards the waypoint side
            return 0.0, math.copysign(cfg.max_turn_rate, bearing if bearing != 0 else 1.0)
        j = int(np.argmin(np.where(admissible, error, np.inf)))
        heading = float(self.dir_angles[j])
        w_cmd = _clip(cfg.turn_gain * heading, -cfg.max_turn_rate, cfg.max_turn_rate)
        v_cmd = 0.0
        if abs(heading) < self.turn_in_place:
            scale = max(0.0, math.cos(heading)) * min(1.0, max(free[j], 0.0) / cfg.slow_distance)
            room = max(min(free[j], free[self.ahead]), 0.0)  # it keeps the current heading while turning
            v_cmd = min(v_cap * scale, math.sqrt(2 * cfg.max_accel * room))
            if final:  # ease into the goal
                v_cmd = min(v_cmd, max(dist, 0.05))
        return v_cmd, w_cmd


def nd_driver(cfg: RobotSimConfig) -> NDDriver:
    """Player's nd driver with the config's numbers on the pioneer2dx's rectangle."""
    params = NDParams.player(PIONEER2DX_LENGTH, PIONEER2DX_WIDTH, PIONEER2DX_ORIGIN_X, avoid_dist=cfg.avoid_dist,
                             safety_dist=cfg.safety_dist, max_speed=cfg.cruise_speed,
                             max_turn_rate=math.radians(cfg.nd_turn_rate_deg), sectors=cfg.nd_sectors, period=cfg.dt)
    return NDDriver(NearnessDiagram(params), goal_tolerance=cfg.nd_goal_tolerance, min_speed=cfg.nd_min_speed,
                    min_turn_rate=math.radians(cfg.nd_min_turn_rate_deg), stuck_time=cfg.stuck_time,
                    stuck_distance=cfg.stuck_distance, stuck_angle=math.radians(cfg.stuck_angle_deg),
                    laser_buffer=cfg.laser_buffer)


class RouteFollower:
    """The robot's controller: the route's waypoints, one at a time, to the local planner.

    It moves on to the next waypoint within ``waypoint_tolerance`` of the current one (the
    paper's waypoint follower) and asks the planner (``cfg.planner``: Player's ND driver, or the
    gap planner) for a velocity command on each laser scan. ``drive`` runs it in process; the
    ``nd_driver`` node runs the same one behind ROS topics, so both steer alike.
    """

    def __init__(self, cfg: RobotSimConfig, waypoints: np.ndarray, beam_angles: np.ndarray,
                 pose: tuple[float, float, float], t: float = 0.0):
        self.cfg = cfg
        self.waypoints = np.asarray(waypoints, dtype=float).reshape(-1, 2)
        self.beam_angles = np.asarray(beam_angles, dtype=float)
        self.driver = nd_driver(cfg) if cfg.planner == "nd" else None
        self.gap = GapPlanner(cfg, self.beam_angles) if cfg.planner == "gap" else None
        self.wp = min(1, len(self.waypoints) - 1)
        if self.driver is not None and len(self.waypoints):
            self.driver.set_goal(self.waypoints[self.wp], t, pose)

    @property
    def has_route(self) -> bool:
        return bool(len(self.waypoints))

    def advance(self, t: float, pose: tuple[float, float, float]) -> None:
        """Move on past every waypoint the robot is already within ``waypoint_tolerance`` of."""
        wps, x, y = self.waypoints, pose[0], pose[1]
        while self.wp < len(wps) - 1 and math.hypot(wps[self.wp, 0] - x, wps[self.wp, 1] - y) < self.cfg.waypoint_tolerance:
            self.wp += 1
            if self.driver is not None:
                self.driver.set_goal(wps[self.wp], t, pose)

    def command(self, t: float, pose: tuple[float, float, float], v_now: float, w_now: float,
                ranges: np.ndarray, hits: np.ndarray) -> tuple[float, float, str | None]:
        """The velocity command for one scan at ``pose`` (ranges along ``beam_angles``; ``hits``: the
        beams that hit a wall), and why the robot gave up (its stall flag), if it did."""
        x, y, yaw = pose
        if self.driver is not None:
            angles = self.beam_angles[hits] + yaw
            self.driver.add_scan(np.column_stack([x + ranges[hits] * np.cos(angles), y + ranges[hits] * np.sin(angles)]))
            v_cmd, w_cmd = self.driver.command(t, pose, v_now, w_now)
            return v_cmd, w_cmd, self.driver.gave_up
        if self.gap is not None:
            tx, ty = self.waypoints[self.wp]
            bearing = (math.atan2(ty - y, tx - x) - yaw + math.pi) % (2 * math.pi) - math.pi
            v_cmd, w_cmd = self.gap.command(bearing, math.hypot(tx - x, ty - y), self.wp == len(self.waypoints) - 1,
                                            ranges)
            return v_cmd, w_cmd, None
        return 0.0, 0.0, None


# --- the simulation ------------------------------------------------------------------------------
def plan_route(grid: np.ndarray, resolution: float, start: tuple[int, int], goal: tuple[int, int],
               config: RobotSimConfig, diagonal: str = "both_free") -> tuple[np.ndarray, float]:
    """The route the robot drives between two cells: waypoints (K, 2) in metres and its length.

    With ``config.reference`` the clearance route (``sims.reference.robot``; its polyline length);
    else the old one, A* for ``config.radius`` with the ``diagonal`` rule, RDP-simplified (the A*
    length). No route: no waypoints, length inf.
    """
    if config.reference:
        route = route_for(grid, resolution, start, goal, config)
        return route.waypoints, route.length
    planning = inflate(grid, config.radius, resolution)
    length, cells = astar(planning, start, goal, diagonal)
    if not cells:
        return np.zeros((0, 2)), math.inf
    pts = (np.asarray(cells, dtype=float) + 0.5) * resolution
    return rdp(pts, config.rdp_epsilon), length * resolution


def polyline_length(points: np.ndarray) -> float:
    """Length in metres of a polyline of (K, 2) points (0 for fewer than two)."""
    return float(np.hypot(*np.diff(np.asarray(points, dtype=float).reshape(-1, 2), axis=0).T).sum())


def navigate(grid: np.ndarray, resolution: float, start: tuple[int, int], goal: tuple[int, int],
             config: RobotSimConfig | None = None, seed: int = 0, diagonal: str = "both_free",
             route: np.ndarray | None = None, obstacles: Any = None, heading: float | None = None) -> dict[str, Any]:
    """Drive from cell ``start`` to cell ``goal`` on occupancy ``grid`` ([y, x]) along ``route``
    ((K, 2) metres, from the start's centre; default ``plan_route``'s, with the problem's
    ``diagonal`` rule for the old route); returns ``drive``'s record. ``obstacles`` and
    ``heading``: see ``drive``."""
    cfg = config or RobotSimConfig()
    if route is None:
        waypoints, route_length = plan_route(np.asarray(grid, dtype=bool), resolution, start, goal, cfg, diagonal)
    else:
        waypoints = np.asarray(route, dtype=float).reshape(-1, 2)
        route_length = polyline_length(waypoints) if len(waypoints) else math.inf
    start_xy = ((start[0] + 0.5) * resolution, (start[1] + 0.5) * resolution)
    goal_xy = ((goal[0] + 0.5) * resolution, (goal[1] + 0.5) * resolution)
    run = drive(grid, resolution, start_xy, goal_xy, waypoints, cfg, seed, cfg.time_limit(route_length), heading,
                obstacles)
    run["route_length"] = float(route_length) if math.isfinite(route_length) else None
    return run


def drive(grid: np.ndarray, resolution: float, start_xy: tuple[float, float], goal_xy: tuple[float, float],
          waypoints: np.ndarray, config: RobotSimConfig | None = None, seed: int = 0,
          time_limit: float | None = None, heading: float | None = None, obstacles: Any = None) -> dict[str, Any]:
    """Drive the robot from ``start_xy`` (facing ``heading``; default ``waypoints[1]``, else the
    goal) through ``waypoints`` ((K, 2) metres, ``waypoints[0]`` = the start; none = no route) to
    ``goal_xy``, judged by the monitors; ``time_limit`` defaults to the config's for the waypoints'
    polyline. ``obstacles`` (``sims.obstacles.Obstacles``): in the world, not on ``grid``; driving
    into a person is a ``collision``, a person walking into the robot is counted
    (``contacts_not_at_fault``), not a failure.

    Keys: outcome, failure_kind, detail, time, time_limit, path_length, min_clearance, route_length,
    waypoints, waypoints_reached, stall_cause, unsafe_proximity_events, unsafe_proximity_s,
    failure_point, timeline (t, x, y, yaw, v, stall arrays; stall = the robot's stall flag, 0/1).
    """
    cfg = config or RobotSimConfig()
    grid = np.asarray(grid, dtype=bool)
    waypoints = np.asarray(waypoints, dtype=float).reshape(-1, 2)
    polyline = polyline_length(waypoints) if len(waypoints) else math.inf
    time_limit = cfg.time_limit(polyline) if time_limit is None else float(time_limit)
    sx, sy = float(start_xy[0]), float(start_xy[1])
    gx, gy = float(goal_xy[0]), float(goal_xy[1])
    if heading is None:
        ahead = waypoints[1] if len(waypoints) > 1 else (gx, gy)
        heading = math.atan2(ahead[1] - sy, ahead[0] - sx)
    world = RobotWorld(grid, resolution, cfg, (sx, sy, heading), np.random.default_rng(seed), obstacles=obstacles)
    follower = RouteFollower(cfg, waypoints, world.beam_angles, world.pose)
    monitors = RobotMonitors(cfg, (gx, gy), time_limit, waypoints[1:], no_route=not len(waypoints))

    x, y, yaw = world.pose
    n_max = int(math.ceil(time_limit / cfg.dt - 1e-9))
    rec = np.zeros((n_max + 1, 6))  # t, x, y, yaw, v, stall
    rec[0] = (0.0, x, y, yaw, 0.0, 0.0)
    k = 0
    monitors.update(0.0, x, y, world.clearance())
    while not monitors.decided and k < n_max:
        k += 1
        t = k * cfg.dt
        # --- sense and decide ---
        follower.advance(t, world.pose)
        if not follower.has_route:  # no route: nothing to drive to; the robot stands where it is
            rec[k] = (t, world.x, world.y, world.yaw, 0.0, 0.0)
            monitors.update(t, world.x, world.y, world.clearance())
            continue
        ranges, hits = world.scan()
        v_cmd, w_cmd, stall_cause = follower.command(t, world.pose, world.v, world.w, ranges, hits)
        # --- act: the world moves the body; a wall stops it ---
        clearance = world.step(v_cmd, w_cmd)
        rec[k] = (t, world.x, world.y, world.yaw, world.v, float(stall_cause is not None))
        monitors.update(t, world.x, world.y, clearance, stall_cause, collision=world.person_contact)
    rec = rec[:k + 1]
    m = monitors.metrics()
    detail = monitors.detail
    if follower.driver is not None and m["stall_cause"] in ("emergency_stop", "no_region", "no_progress", "no_motion"):
        detail += " (the ND driver gave up)"
    return {
        **m,
        "contacts_not_at_fault": world.contacts_not_at_fault,
        "failure_kind": monitors.kind,
        "detail": detail,
        "route_length": polyline if math.isfinite(polyline) else None,
        "waypoints": waypoints,
        "failure_point": monitors.failure_point,
        "timeline": {"t": rec[:, 0], "x": rec[:, 1], "y": rec[:, 2], "yaw": rec[:, 3], "v": rec[:, 4],
                     "stall": rec[:, 5]},
    }


def simulate(problem: Any, scenario: Any, config: RobotSimConfig | None = None, seed: int = 0,
             route: np.ndarray | None = None) -> Outcome:
    """Execute one robot scenario on the full model and judge it with the paper's monitors.

    ``route`` ((K, 2) metres): the route to drive, as the reference check planned it (the
    clearance route); default ``plan_route``'s for the config.
    """
    cfg = config or RobotSimConfig()
    env = problem.environment(scenario)
    pc = problem.config
    obstacles = None
    if env.unmapped:
        from .obstacles import Obstacles

        obstacles = Obstacles.from_dict(env.unmapped)
    run = navigate(env.grid, env.resolution, env.start, env.goal, cfg, seed=seed,
                   diagonal=cfg.route_diagonal or pc.diagonal, route=route, obstacles=obstacles,
                   heading=env.start_yaw)
    timeline = run["timeline"]
    metrics = {
        "outcome": run["outcome"],
        "time": run["time"],
        "time_limit": run["time_limit"],
        "path_length": run["path_length"],
        "min_clearance": run["min_clearance"],
        "route_length": run["route_length"],
        "route": "clearance" if cfg.reference else "astar",
        "surrogate_path_length": env.path_length if env.reachable else None,
        "waypoints": int(len(run["waypoints"])),
        "waypoints_reached": run["waypoints_reached"],
        "planner": cfg.planner,
        "stall_cause": run["stall_cause"],
        "unsafe_proximity_events": run["unsafe_proximity_events"],
        "unsafe_proximity_s": run["unsafe_proximity_s"],
        "radius": cfg.radius,
        "distance_to_goal": float(math.hypot(timeline["x"][-1] - env.goal_m[0], timeline["y"][-1] - env.goal_m[1])),
        "goal_tolerance": cfg.goal_tolerance,
        "contacts_not_at_fault": run["contacts_not_at_fault"],
        "seed": int(seed),
    }
    return Outcome(
        objectives={"robot_time": run["time"] if run["outcome"] == "success" else run["time_limit"]},
        failed=run["failure_kind"] != "none",
        failure_kind=run["failure_kind"],
        detail=run["detail"],
        metrics=metrics,
        trajectory=np.column_stack([timeline["x"], timeline["y"]]),
        timeline=timeline,
        failure_point=run["failure_point"],
        elapsed_sec=0.0,
    )


# The world's names stay importable from here (``sims.robot.WallGeometry``, ``cast_rays``, ...).
__all__ = ["ENGINES", "GOAL_TOLERANCE", "ND_GOAL_TOLERANCE", "PIONEER2DX", "PIONEER2DX_LENGTH", "PIONEER2DX_ORIGIN_X",
           "PIONEER2DX_WIDTH", "PLANNERS", "STALL_CAUSES", "WAYPOINT_TOLERANCE", "WORLD_FIELDS", "GapPlanner",
           "RobotMonitors", "RobotSimConfig", "RobotWorld", "RouteFollower", "WallGeometry", "cast_rays", "clearances",
           "drive", "nd_driver", "navigate", "pad_grid", "pioneer2dx_footprint", "plan_route", "polyline_length", "rdp",
           "simulate", "wall_distance"]
