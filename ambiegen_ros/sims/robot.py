"""Full-model robot: a differential-drive base with a 2D laser navigating an obstacle map.

The paper executed its maps on a Pioneer 3-AT in Player/Stage (A* route simplified with
Ramer-Douglas-Peucker, nearness-diagram reactive navigation). This is a ROS-free stand-in, a
time-stepped simulation independent of the surrogate's path-length fitness:

* *Robot*: a disc of ``radius`` (unicycle kinematics, speed and turn-rate limits, acceleration
  limits), integrated with a fixed step ``dt``.
* *Laser*: ``beams`` rays over a ``fov_deg`` field of view, ``laser_range`` metres, cast exactly on
  the occupancy grid (a grid traversal vectorised over all rays), plus optional Gaussian noise
  from the run's seeded generator.
* *Global route*: A* (``problems.robot.astar``) on the grid inflated by the robot's radius, then
  Ramer-Douglas-Peucker with tolerance ``rdp_epsilon``; the kept vertices are the waypoints. No
  route (the robot does not fit any way to the goal) leaves the robot standing, so the stall oracle
  ends the run (metrics ``outcome = "no_route"``).
* *Local planner* (a gap choice in the spirit of the nearness diagram / VFH): for ``directions``
  candidate headings across the field of view it computes how far a disc of ``radius + margin``
  could travel along each heading before touching a laser return; headings free for
  ``min(lookahead, distance to the waypoint)`` are admissible, and it steers to the admissible one
  closest to the current waypoint, slowing with the free distance and the heading error and never
  faster than it could stop within the free distance (along the chosen and the current heading).
  When the margin leaves no heading admissible (typically entering a one-cell gap off-centre) it
  retries in a slow "squeeze" mode with ``squeeze_margin`` and ``squeeze_lookahead``; with still
  nothing admissible (or the waypoint behind the laser) it turns on the spot.

Oracle, checked after every step in this order: collision (the disc overlaps a wall cell),
success (centre within ``goal_tolerance`` of the goal cell's centre), stall or loiter (the robot
stays within ``stall_radius`` of one point for ``stall_time``: "stall" when it travelled less than
``stall_radius`` meanwhile, "loiter" when it moved about), timeout (``timeout`` simulated seconds).
Metrics: outcome, time, path length, minimum clearance (wall distance minus radius), route length.

Note on the defaults: at the paper's 0.3 m/s cruise speed a 300 s budget covers about 90 m, so
maps whose shortest route is much longer than that time out.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..core.attributes import ScenarioError
from ..problems.robot import astar, inflate
from .outcome import Outcome


@dataclass(frozen=True)
class RobotSimConfig:
    """Every number of the full-model robot (defaults: a Pioneer-class base, the paper's oracle)."""

    radius: float = 0.3  # footprint disc [m]
    cruise_speed: float = 0.3  # the paper's ND driver speed [m/s]
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
    # global route
    rdp_epsilon: float = 0.5  # Ramer-Douglas-Peucker tolerance [m]
    waypoint_tolerance: float = 0.4  # a waypoint counts as reached this close [m]
    # local planner
    margin: float = 0.05  # extra clearance the local planner keeps around the disc [m]
    lookahead: float = 1.0  # a heading must be free this far (or up to the waypoint) [m]
    directions: int = 91  # candidate headings across the field of view
    turn_gain: float = 1.5  # turn rate per radian of heading error [1/s]
    turn_in_place_deg: float = 60.0  # heading errors above this turn on the spot
    slow_distance: float = 0.6  # speed scales down when the chosen heading is free less than this [m]
    squeeze_margin: float = 0.01  # margin when the normal one leaves no way forward [m]
    squeeze_lookahead: float = 0.3  # [m]
    squeeze_speed: float = 0.1  # [m/s]
    # oracle
    goal_tolerance: float = 0.5  # [m]
    stall_radius: float = 0.5  # [m]
    stall_time: float = 10.0  # [s]
    timeout: float = 300.0  # simulated seconds
    clearance_cells: int = 3  # clearance is measured to walls within this many cells (capped beyond)
    run_invalid: bool = False  # also simulate scenarios the problem calls invalid

    def __post_init__(self):
        for name in ("radius", "cruise_speed", "max_speed", "max_turn_rate", "max_accel", "max_turn_accel",
                     "dt", "laser_range", "fov_deg", "lookahead", "turn_gain", "slow_distance",
                     "goal_tolerance", "stall_radius", "stall_time", "timeout", "waypoint_tolerance"):
            if not getattr(self, name) > 0:
                raise ScenarioError(f"option.{name}", "must be > 0")
        for name in ("laser_noise", "rdp_epsilon", "margin", "squeeze_margin", "squeeze_lookahead", "squeeze_speed"):
            if getattr(self, name) < 0:
                raise ScenarioError(f"option.{name}", "must be >= 0")
        if self.beams < 3 or self.directions < 3:
            raise ScenarioError("option.beams", "need at least 3 beams and 3 directions")
        if self.fov_deg > 360:
            raise ScenarioError("option.fov_deg", "at most 360")
        if self.cruise_speed > self.max_speed:
            raise ScenarioError("option.cruise_speed", "above max_speed", f"<= {self.max_speed}")


# --- geometry helpers ----------------------------------------------------------------------------
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


def cast_rays(grid: np.ndarray, resolution: float, x: float, y: float, angles: np.ndarray,
              max_range: float, padded: np.ndarray | None = None) -> np.ndarray:
    """Exact range to the first occupied cell along each ray (grid ``[y, x]``; outside = wall).

    A cell-by-cell traversal (Amanatides-Woo) advanced for all rays at once; returns ``max_range``
    where nothing is hit. ``padded`` (the grid with a ring of wall, see ``pad_grid``) can be passed
    to save building it on every call.
    """
    gp = pad_grid(grid) if padded is None else padded
    Wp = gp.shape[1]
    flat_grid = gp.reshape(-1)
    px, py = x / resolution, y / resolution
    dx, dy = np.cos(angles), np.sin(angles)
    fx, fy = math.floor(px), math.floor(py)
    pos_x, pos_y = dx > 0, dy > 0
    step_x = np.where(pos_x, 1, -1)
    step_y = np.where(pos_y, Wp, -Wp)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv_x = 1.0 / np.abs(dx)
        inv_y = 1.0 / np.abs(dy)
        t_x = np.where(pos_x, fx + 1 - px, px - fx) * inv_x
        t_y = np.where(pos_y, fy + 1 - py, py - fy) * inv_y
    t_x[~np.isfinite(t_x)] = np.inf
    t_y[~np.isfinite(t_y)] = np.inf
    cell = np.full(angles.shape, (fy + 1) * Wp + fx + 1, dtype=np.int64)
    limit = max_range / resolution
    out = np.full(angles.shape, limit)
    idx = np.arange(len(angles))
    for _ in range(int(2 * limit) + 4):
        along_x = t_x < t_y
        t = np.where(along_x, t_x, t_y)
        cell += np.where(along_x, step_x, step_y)
        np.add(t_x, inv_x, out=t_x, where=along_x)
        np.add(t_y, inv_y, out=t_y, where=~along_x)
        stop = flat_grid[cell] | (t >= limit)
        if stop.any():
            out[idx[stop]] = np.minimum(t[stop], limit)
            keep = ~stop
            if not keep.any():
                break
            idx, cell, t_x, t_y = idx[keep], cell[keep], t_x[keep], t_y[keep]
            inv_x, inv_y, step_x, step_y = inv_x[keep], inv_y[keep], step_x[keep], step_y[keep]
    return out * resolution


def pad_grid(grid: np.ndarray) -> np.ndarray:
    """The grid with a one-cell ring of wall, so rays never leave it."""
    grid = np.asarray(grid, dtype=bool)
    gp = np.ones((grid.shape[0] + 2, grid.shape[1] + 2), dtype=bool)
    gp[1:-1, 1:-1] = grid
    return gp


def wall_distance(grid: np.ndarray, resolution: float, x: float, y: float, cells: int) -> float:
    """Distance from (x, y) to the nearest occupied cell square within ``cells`` of it (else the cap)."""
    H, W = grid.shape
    cx, cy = int(math.floor(x / resolution)), int(math.floor(y / resolution))
    x0, x1 = max(cx - cells, 0), min(cx + cells + 1, W)
    y0, y1 = max(cy - cells, 0), min(cy + cells + 1, H)
    cap = cells * resolution
    if x0 >= x1 or y0 >= y1:
        return 0.0
    sub = grid[y0:y1, x0:x1]
    if not sub.any():
        return cap
    ys, xs = np.nonzero(sub)
    gx = np.maximum(np.abs(x - (xs + x0 + 0.5) * resolution) - 0.5 * resolution, 0.0)
    gy = np.maximum(np.abs(y - (ys + y0 + 0.5) * resolution) - 0.5 * resolution, 0.0)
    return float(min(np.min(np.hypot(gx, gy)), cap))


def _wrap(a):
    return (a + np.pi) % (2 * np.pi) - np.pi


def _clip(value: float, low: float, high: float) -> float:
    return low if value < low else high if value > high else value


# --- the simulation ------------------------------------------------------------------------------
def plan_route(grid: np.ndarray, resolution: float, start: tuple[int, int], goal: tuple[int, int],
               config: RobotSimConfig, diagonal: str = "both_free") -> tuple[np.ndarray, float]:
    """Waypoints (K, 2) in metres (RDP-simplified A* route for the robot's radius) and the route length."""
    planning = inflate(grid, config.radius, resolution)
    length, cells = astar(planning, start, goal, diagonal)
    if not cells:
        return np.zeros((0, 2)), math.inf
    pts = (np.asarray(cells, dtype=float) + 0.5) * resolution
    return rdp(pts, config.rdp_epsilon), length * resolution


def navigate(grid: np.ndarray, resolution: float, start: tuple[int, int], goal: tuple[int, int],
             config: RobotSimConfig | None = None, seed: int = 0, diagonal: str = "both_free") -> dict[str, Any]:
    """Drive from cell ``start`` to cell ``goal`` on occupancy ``grid`` ([y, x]); returns the record.

    Keys: outcome, failure_kind, detail, time, path_length, min_clearance, route_length, waypoints,
    failure_point, timeline (t, x, y, yaw, v arrays).
    """
    cfg = config or RobotSimConfig()
    grid = np.asarray(grid, dtype=bool)
    rng = np.random.default_rng(seed)
    waypoints, route_length = plan_route(grid, resolution, start, goal, cfg, diagonal)
    padded = pad_grid(grid)
    sx, sy = (start[0] + 0.5) * resolution, (start[1] + 0.5) * resolution
    gx, gy = (goal[0] + 0.5) * resolution, (goal[1] + 0.5) * resolution
    # Start facing the first waypoint past the start (else the goal), like a robot told its route.
    if len(waypoints) > 1:
        yaw = math.atan2(waypoints[1, 1] - sy, waypoints[1, 0] - sx)
    else:
        yaw = math.atan2(gy - sy, gx - sx)
    half_fov = math.radians(cfg.fov_deg) / 2
    beam_angles = np.linspace(-half_fov, half_fov, cfg.beams)
    dir_angles = np.linspace(-half_fov, half_fov, cfg.directions)
    cos_d, sin_d = np.cos(dir_angles)[:, None], np.sin(dir_angles)[:, None]
    modes = ((cfg.radius + cfg.margin, cfg.lookahead, cfg.cruise_speed),
             (cfg.radius + cfg.squeeze_margin, cfg.squeeze_lookahead, min(cfg.squeeze_speed, cfg.cruise_speed)))
    turn_in_place = math.radians(cfg.turn_in_place_deg)
    ahead = int(np.argmin(np.abs(dir_angles)))  # the candidate closest to straight ahead

    x, y, v, w = sx, sy, 0.0, 0.0
    n_max = int(math.ceil(cfg.timeout / cfg.dt))
    rec = np.zeros((n_max + 1, 5))  # t, x, y, yaw, v
    rec[0] = (0.0, x, y, yaw, 0.0)
    wp = 1
    path_length = 0.0
    clearance = wall_distance(grid, resolution, x, y, cfg.clearance_cells) - cfg.radius
    min_clearance = clearance
    anchor_x, anchor_y, anchor_t, anchor_path = x, y, 0.0, 0.0
    outcome, kind, detail = "timeout", "timeout", f"goal not reached within {cfg.timeout:g} s"
    failure_point = None
    k = 0
    if clearance < 0:
        outcome, kind, detail = "collision", "collision", "the robot starts inside a wall"
        failure_point = (x, y)
        n_max = 0
    for k in range(1, n_max + 1):
        t = k * cfg.dt
        # --- sense and decide ---
        v_cmd, w_cmd = 0.0, 0.0
        if len(waypoints):
            while (wp < len(waypoints) - 1
                   and math.hypot(waypoints[wp, 0] - x, waypoints[wp, 1] - y) < cfg.waypoint_tolerance):
                wp += 1
            tx, ty = waypoints[wp]
            dist = math.hypot(tx - x, ty - y)
            bearing = (math.atan2(ty - y, tx - x) - yaw + math.pi) % (2 * math.pi) - math.pi
            if abs(bearing) > half_fov:
                w_cmd = math.copysign(cfg.max_turn_rate, bearing)
            else:
                ranges = cast_rays(grid, resolution, x, y, beam_angles + yaw, cfg.laser_range, padded)
                if cfg.laser_noise > 0:
                    ranges = np.clip(ranges + rng.normal(0.0, cfg.laser_noise, ranges.shape), 0.0, cfg.laser_range)
                hits = ranges < cfg.laser_range
                ox = ranges[hits] * np.cos(beam_angles[hits])
                oy = ranges[hits] * np.sin(beam_angles[hits])
                forward = ox[None, :] * cos_d + oy[None, :] * sin_d
                lateral = oy[None, :] * cos_d - ox[None, :] * sin_d
                error = np.abs(_wrap(dir_angles - bearing))
                # Normal mode keeps the margin; when that leaves no way forward (e.g. entering a
                # one-cell gap off-centre) it squeezes: almost no margin, shorter horizon, slow.
                for reach, need, v_cap in modes:
                    blocking = (forward > 0) & (np.abs(lateral) < reach)
                    reach_at = forward - np.sqrt(np.maximum(reach * reach - lateral * lateral, 0.0))
                    free = np.where(blocking, reach_at, cfg.laser_range).min(axis=1, initial=cfg.laser_range)
                    admissible = free >= min(need, dist)
                    if admissible.any():
                        break
                if admissible.any():
                    j = int(np.argmin(np.where(admissible, error, np.inf)))
                    heading = float(dir_angles[j])
                    w_cmd = _clip(cfg.turn_gain * heading, -cfg.max_turn_rate, cfg.max_turn_rate)
                    if abs(heading) < turn_in_place:
                        scale = max(0.0, math.cos(heading)) * min(1.0, max(free[j], 0.0) / cfg.slow_distance)
                        # never faster than what can still stop before the free distance ends
                        # (along the chosen heading and the current one, which it keeps while turning)
                        room = max(min(free[j], free[ahead]), 0.0)
                        v_cmd = min(v_cap * scale, math.sqrt(2 * cfg.max_accel * room))
                        if wp == len(waypoints) - 1:  # ease into the goal
                            v_cmd = min(v_cmd, max(dist, 0.05))
                else:  # boxed in ahead: turn on the spot towards the waypoint side
                    w_cmd = math.copysign(cfg.max_turn_rate, bearing if bearing != 0 else 1.0)
        # --- act (acceleration limits, unicycle, midpoint heading) ---
        v_cmd = min(v_cmd, cfg.max_speed)
        v += _clip(v_cmd - v, -cfg.max_accel * cfg.dt, cfg.max_accel * cfg.dt)
        w += _clip(w_cmd - w, -cfg.max_turn_accel * cfg.dt, cfg.max_turn_accel * cfg.dt)
        mid = yaw + 0.5 * w * cfg.dt
        nx, ny = x + v * math.cos(mid) * cfg.dt, y + v * math.sin(mid) * cfg.dt
        path_length += math.hypot(nx - x, ny - y)
        x, y, yaw = nx, ny, (yaw + w * cfg.dt + math.pi) % (2 * math.pi) - math.pi
        rec[k] = (t, x, y, yaw, v)
        # --- oracle ---
        clearance = wall_distance(grid, resolution, x, y, cfg.clearance_cells) - cfg.radius
        min_clearance = min(min_clearance, clearance)
        if clearance < 0:
            outcome, kind = "collision", "collision"
            detail = f"footprint touches a wall at ({x:.2f}, {y:.2f}) after {t:.1f} s"
            failure_point = (x, y)
            break
        if math.hypot(gx - x, gy - y) <= cfg.goal_tolerance:
            outcome, kind, detail = "success", "none", f"goal reached in {t:.1f} s"
            break
        if math.hypot(x - anchor_x, y - anchor_y) > cfg.stall_radius:
            anchor_x, anchor_y, anchor_t, anchor_path = x, y, t, path_length
        elif t - anchor_t >= cfg.stall_time - 1e-9:
            moved = path_length - anchor_path
            if not len(waypoints):
                outcome, kind = "no_route", "stall"
                detail = f"no route for a robot of radius {cfg.radius:g} m: it never left the start"
            elif moved < cfg.stall_radius:
                outcome, kind = "stall", "stall"
                detail = f"stalled near ({x:.2f}, {y:.2f}) for {cfg.stall_time:g} s"
            else:
                outcome, kind = "loiter", "loiter"
                detail = (f"loitered within {cfg.stall_radius:g} m of ({anchor_x:.2f}, {anchor_y:.2f}) "
                          f"({moved:.1f} m driven)")
            failure_point = (x, y)
            break
    else:
        if outcome == "timeout":
            failure_point = (x, y)
    rec = rec[:k + 1]
    return {
        "outcome": outcome,
        "failure_kind": kind,
        "detail": detail,
        "time": float(rec[-1, 0]),
        "path_length": path_length,
        "min_clearance": float(min_clearance),
        "route_length": float(route_length) if math.isfinite(route_length) else None,
        "waypoints": waypoints,
        "failure_point": failure_point,
        "timeline": {"t": rec[:, 0], "x": rec[:, 1], "y": rec[:, 2], "yaw": rec[:, 3], "v": rec[:, 4]},
    }


def simulate(problem: Any, scenario: Any, config: RobotSimConfig | None = None, seed: int = 0) -> Outcome:
    """Execute one robot scenario on the full model and judge it with the paper's oracle."""
    cfg = config or RobotSimConfig()
    env = problem.environment(scenario)
    pc = problem.config
    run = navigate(env.grid, env.resolution, pc.start, pc.goal, cfg, seed=seed, diagonal=pc.diagonal)
    timeline = run["timeline"]
    metrics = {
        "outcome": run["outcome"],
        "time": run["time"],
        "path_length": run["path_length"],
        "min_clearance": run["min_clearance"],
        "route_length": run["route_length"],
        "surrogate_path_length": env.path_length if env.reachable else None,
        "waypoints": int(len(run["waypoints"])),
        "radius": cfg.radius,
        "distance_to_goal": float(math.hypot(timeline["x"][-1] - env.goal_m[0], timeline["y"][-1] - env.goal_m[1])),
        "seed": int(seed),
    }
    return Outcome(
        objectives={"robot_time": run["time"] if run["outcome"] == "success" else cfg.timeout},
        failed=run["failure_kind"] != "none",
        failure_kind=run["failure_kind"],
        detail=run["detail"],
        metrics=metrics,
        trajectory=np.column_stack([timeline["x"], timeline["y"]]),
        timeline=timeline,
        failure_point=run["failure_point"],
        elapsed_sec=0.0,
    )


__all__ = ["RobotSimConfig", "cast_rays", "navigate", "plan_route", "rdp", "simulate", "wall_distance"]
