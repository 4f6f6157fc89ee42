"""Can a car-like robot drive the clearance route? (issue 69: an Ackermann reference, kept simple)

A car cannot turn in place, so the clearance route's polyline, with its sharp corners, is no
car's path. This check drives it the simplest way a car can and says whether that works:

* *Start*: from the start pose, the car turns on its ``min_turning_radius`` circle towards the
  first waypoint until it faces it (a Dubins curve-then-straight). A first waypoint inside that
  circle cannot be reached so: it would need a turn on the spot or a manoeuvre backwards.
* *Corners*: each corner of the route is rounded by an arc of exactly the minimum turning radius,
  tangent to both legs. The arc needs ``r tan(theta / 2)`` of straight leg on each side of a
  corner turning by ``theta``: two corners that need more than the leg between them, or a hairpin
  (theta near 180 degrees), cannot be driven so.
* *Clearance*: the rounded path, sampled every ``SEGMENT_STEP``, must keep the body's
  circumscribed radius (not the margin: the margin is slack for the controller) from every wall,
  and with ``extra`` from every unmapped box and post; rounding a corner moves the path towards
  its inner wall.

Not covered, so a "no" here can be wrong in the car's favour (an invalid test a car could have
driven): other routes than the shortest clearance route, wider arcs than the minimum, reversing
and multi-point turns (Reeds-Shepp), a final heading at the goal (it is not asked for), and
steering rate limits (the curvature jumps at each arc's ends). A "yes" is a real path: every
turn within the minimum radius, clear of the walls by the body's radius.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..robot_world import clearances, pad_grid

SEGMENT_STEP = 0.01  # [m] between the points of a rounded path (``reference.robot``'s sampling step)
EPS = 1e-9  # a clearance equal to the body's radius is enough (float rounding) [m]


def polyline_clearance(grid: np.ndarray, resolution: float, points: np.ndarray, required: float,
                       extra: Callable | None = None) -> float:
    """The least wall (and ``extra`` obstacle) distance over dense points, exact up to ``required``
    + a cell (as ``reference.robot.polyline_clearance``, whose module imports this one)."""
    cells = int(math.ceil(required / resolution)) + 1
    out = clearances(pad_grid(grid), resolution, points[:, 0], points[:, 1], cells, origin=(-resolution, -resolution))
    return float((out if extra is None else np.minimum(out, extra(points[:, 0], points[:, 1]))).min())


@dataclass
class CarPath:
    """The rounded route: points every ``SEGMENT_STEP`` (empty when the car cannot drive it)."""

    points: np.ndarray  # (N, 2) [m]
    reason: str  # why not ("" when it can)
    min_clearance: float | None = None  # [m]

    @property
    def found(self) -> bool:
        return len(self.points) > 0


def _arc(centre: np.ndarray, r: float, a0: float, sweep: float) -> np.ndarray:
    """Points on a circle from angle ``a0`` through ``sweep`` radians (signed), every ``SEGMENT_STEP``."""
    n = max(1, int(math.ceil(abs(sweep) * r / SEGMENT_STEP)))
    a = a0 + np.linspace(0.0, sweep, n + 1)
    return np.column_stack([centre[0] + r * np.cos(a), centre[1] + r * np.sin(a)])


def _line(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    n = max(1, int(math.ceil(float(np.hypot(*(b - a))) / SEGMENT_STEP)))
    return a + np.linspace(0.0, 1.0, n + 1)[:, None] * (b - a)


def start_turn(start: np.ndarray, yaw: float, target: np.ndarray, r: float) -> tuple[np.ndarray, np.ndarray, str]:
    """The arc from the start pose that leaves the car facing ``target``: (arc points, its end, reason)."""
    heading = np.array([math.cos(yaw), math.sin(yaw)])
    to = target - start
    cross = heading[0] * to[1] - heading[1] * to[0]
    if abs(cross) <= 1e-9 * max(1.0, float(np.hypot(*to))) and float(heading @ to) > 0:
        return start[None], start, ""  # already facing it
    side = 1.0 if cross >= 0 else -1.0  # 1: turn left (counterclockwise)
    centre = start + side * r * np.array([-heading[1], heading[0]])
    d = float(np.hypot(*(target - centre)))
    if d <= r + 1e-9:
        return np.zeros((0, 2)), start, (f"the first waypoint ({target[0]:.2f}, {target[1]:.2f}) lies inside the car's "
                                         f"{r:.2f} m turning circle from the start heading: it would need to turn on "
                                         f"the spot or back up")
    alpha = math.atan2(target[1] - centre[1], target[0] - centre[0])
    beta = math.acos(r / d)
    a0 = math.atan2(start[1] - centre[1], start[0] - centre[0])
    a_end = alpha - side * beta  # the tangent point whose direction of travel points at the target
    sweep = side * ((side * (a_end - a0)) % (2 * math.pi))
    pts = _arc(centre, r, a0, sweep)
    return pts, pts[-1], ""


def car_path(route: np.ndarray, start_yaw: float, r: float) -> CarPath:
    """The route rounded for a car of minimum turning radius ``r`` (module docstring), unchecked
    against the walls; empty with the reason when the car cannot drive it so."""
    route = np.asarray(route, dtype=float)
    if len(route) > 1:  # a repeated point (a start on a fine cell's centre) is no leg
        route = route[np.concatenate([[True], np.hypot(*np.diff(route, axis=0).T) > 1e-12])]
    if len(route) < 2:
        return CarPath(route.copy(), "")
    arc, tangent, reason = start_turn(route[0], start_yaw, route[1], r)
    if reason:
        return CarPath(np.zeros((0, 2)), reason)
    legs = np.concatenate([tangent[None], route[1:]])
    vec = np.diff(legs, axis=0)
    length = np.hypot(vec[:, 0], vec[:, 1])
    u = vec / np.maximum(length, 1e-12)[:, None]
    turn = np.zeros(len(legs))  # the turning angle at each vertex (0 at the ends)
    for k in range(1, len(legs) - 1):
        turn[k] = math.atan2(u[k - 1, 0] * u[k, 1] - u[k - 1, 1] * u[k, 0], float(u[k - 1] @ u[k]))
    need = r * np.tan(np.abs(turn) / 2)
    for k in range(len(vec)):
        if need[k] + need[k + 1] > length[k] + 1e-9:
            at = k + 1 if need[k + 1] >= need[k] else k
            return CarPath(np.zeros((0, 2)), f"the turn of {math.degrees(abs(turn[at])):.0f} deg at ({legs[at, 0]:.2f}, "
                                             f"{legs[at, 1]:.2f}) needs {need[at]:.2f} m of straight on each side for "
                                             f"a car's {r:.2f} m minimum turning radius; the leg there is "
                                             f"{length[k]:.2f} m")
    parts = [arc]
    for k in range(len(vec)):
        a = legs[k] + u[k] * need[k]
        b = legs[k + 1] - u[k] * need[k + 1]
        parts.append(_line(a, b))
        if k + 1 < len(legs) - 1 and need[k + 1] > 0:
            side = math.copysign(1.0, turn[k + 1])
            centre = b + side * r * np.array([-u[k, 1], u[k, 0]])
            a0 = math.atan2(b[1] - centre[1], b[0] - centre[0])
            parts.append(_arc(centre, r, a0, turn[k + 1]))
    return CarPath(np.concatenate(parts), "")


def car_check(grid: np.ndarray, resolution: float, route: np.ndarray, start_yaw: float, r: float, body_radius: float,
              extra: Callable | None = None) -> CarPath:
    """``car_path`` and its clearance: the rounded path keeps ``body_radius`` from the walls (and
    what ``extra`` measures), or it is refused with the least clearance it keeps."""
    path = car_path(route, start_yaw, r)
    if not path.found:
        return path
    clearance = polyline_clearance(grid, resolution, path.points, body_radius, extra)
    if clearance < body_radius - EPS:
        return CarPath(np.zeros((0, 2)), f"rounded to the car's {r:.2f} m minimum turning radius, the clearance route "
                                         f"comes within {clearance:.2f} m of a wall, less than the body's "
                                         f"{body_radius:.2f} m radius", clearance)
    return CarPath(path.points, "", clearance)


def poses_along(points: np.ndarray, speed: float, dt: float) -> np.ndarray:
    """Poses (N, 3) every ``dt`` along a dense path at ``speed``, heading along the path."""
    seg = np.diff(points, axis=0)
    s = np.concatenate([[0.0], np.cumsum(np.hypot(seg[:, 0], seg[:, 1]))])
    at = np.append(np.arange(0.0, s[-1], speed * dt), s[-1])
    x, y = np.interp(at, s, points[:, 0]), np.interp(at, s, points[:, 1])
    k = np.clip(np.searchsorted(s, at, side="right") - 1, 0, len(seg) - 1)
    yaw = np.arctan2(seg[k, 1], seg[k, 0]) if len(seg) else np.zeros(len(at))
    return np.column_stack([x, y, yaw])


__all__ = ["CarPath", "car_check", "car_path", "polyline_clearance", "poses_along", "start_turn"]
