"""Full-model robot: a Stage pioneer2dx with a 2D laser following the A* route through an obstacle map.

The paper (RQ3) drove its maps in Player/Stage: a pioneer2dx with a SICK laser, Player's ``nd``
(Nearness Diagram) driver steering towards the RDP-simplified A* waypoints, and the monitors of
Arnold and Alexander (2013) judging the run. This is a ROS-free, time-stepped stand-in, independent
of the surrogate's path-length fitness:

* *Body*: Stage's pioneer2dx footprint (the convex hull of its blocks, 0.44 x 0.38 m, rotation
  centre 4 cm ahead of the centre of area), unicycle kinematics with speed, turn-rate and
  acceleration limits, integrated with a fixed step ``dt``. As in Stage, the body cannot enter a
  wall: a step that would make it touch one ends at the contact and the robot is blocked there.
* *Laser*: ``beams`` rays over ``fov_deg``, ``laser_range`` metres, cast exactly on the occupancy
  grid (all rays at once), plus optional Gaussian noise on the returns from the run's seeded
  generator; a beam that hits nothing reads the maximum range, which is no obstacle.
* *Route*: A* (``problems.robot.astar``) on the grid inflated by ``radius``, with the problem's
  diagonal rule (the route its surrogate scored; ``route_diagonal`` overrides it: the replication
  profile's rule ``always`` also steps diagonally between two wall cells that touch at a corner,
  a gap no robot passes), simplified by Ramer-Douglas-Peucker (``rdp_epsilon``); a controller
  sends the waypoints one by one and moves on within ``waypoint_tolerance`` of the current one,
  like the paper's waypoint follower. No route leaves the robot standing (``outcome = "no_route"``).
* *Local planner* (``planner``): ``"nd"`` (default) is the Nearness Diagram method with Player's
  ``nd`` driver around it and the paper's ``player.cfg`` numbers (``sims.nearness_diagram``):
  0.3 m/s and 30 deg/s at most, 0.1 m/s and 10 deg/s at least, goal tolerance 0.1 m, avoid_dist
  0.4 m, safety_dist 0, stuck after 5 s without 0.15 m or 10 deg, the last two laser scans. It
  gives up (its stall flag) on an emergency stop, with no navigable region or when stuck.
  ``"gap"`` is the earlier planner (a disc of ``radius + margin`` choosing the free heading closest
  to the waypoint, with a slow squeeze mode); it never gives up by itself.

Oracle (``RobotMonitors``, the paper's monitors), checked on every pose in this order:

* *stall*: the body touches a wall (Stage's stall: blocked, it cannot move), or the robot's
  stall flag is up (the ND driver gave up), or the loitering rule below fires on a robot that did
  not move at all (no route: it never starts). ``metrics["stall_cause"]`` says which: contact |
  emergency_stop | no_region | no_progress | no_motion | stationary | no_route;
* *success*: within ``goal_tolerance`` of the goal (the route's last waypoint);
* *loiter*: once the run covers ``stall_time`` (the loitering window, 10 s), the robot lies
  within ``stall_radius`` (0.5 m) of the mean position of the window's poses;
* *timeout*: the time limit, ``max(timeout, timeout_route_factor x route length / cruise_speed
  + timeout_margin)`` = max(300 s, 2 x route / 0.3 m/s + 60 s): a long route alone never fails.
  (The paper stopped a run after 300 s of wall clock on a simulation about 8x faster than real
  time; a fixed limit is ``timeout_route_factor = timeout_margin = 0``.)

Unsafe proximity (body within ``proximity`` = 0.2 m of a wall) and waypoint arrivals are recorded
(``unsafe_proximity_events``/``_s``, ``waypoints_reached``), not failures: the paper's verdict
counted stalls and loitering only (its proximity monitor watched pairs of robots).
Metrics: outcome, time, time limit, path length, minimum clearance (body to wall), route length.

Speed: the laser and the body clearance run as compiled loops (``engine``; the numpy code gives
the same numbers); a run of a 50 m map takes 1.5-2.5 s, about 150x real time (ND itself, numpy,
is most of a step).
"""
from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..core.accel import jit
from ..core.attributes import ScenarioError
from ..problems.robot import DIAGONAL_RULES, astar, inflate
from .nearness_diagram import NDDriver, NDParams, NearnessDiagram
from .outcome import Outcome

PLANNERS = ("nd", "gap")
ENGINES = ("auto", "numba", "numpy")
STALL_CAUSES = ("contact", "emergency_stop", "no_region", "no_progress", "no_motion", "stationary", "no_route",
                "reported")


@dataclass(frozen=True)
class RobotSimConfig:
    """Every number of the full-model robot (defaults: Stage's pioneer2dx, the paper's player.cfg
    and monitors)."""

    planner: str = "nd"  # nd | gap
    radius: float = 0.3  # route inflation; the gap planner's disc [m]
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
    route_diagonal: str | None = None  # A* diagonal rule of the route: None = the problem's (the route it scored)
    rdp_epsilon: float = 0.5  # Ramer-Douglas-Peucker tolerance [m]
    waypoint_tolerance: float = 0.5  # the controller moves on this close to a waypoint [m]
    # nearness diagram (Player's nd driver, the paper's player.cfg)
    nd_turn_rate_deg: float = 30.0  # max_speed[1] [deg/s]
    nd_min_speed: float = 0.1  # min_speed[0] [m/s]
    nd_min_turn_rate_deg: float = 10.0  # min_speed[1] [deg/s]
    nd_goal_tolerance: float = 0.1  # goal_tol[0] [m]
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
    goal_tolerance: float = 0.5  # route completed this close to the goal [m]
    stall_radius: float = 0.5  # loitering radius [m]
    stall_time: float = 10.0  # loitering window [s]
    proximity: float = 0.2  # unsafe proximity (recorded) [m]
    timeout: float = 300.0  # the time limit is at least this [s]
    timeout_route_factor: float = 2.0  # ... and at least this x route length / cruise_speed ...
    timeout_margin: float = 60.0  # ... + this [s]
    clearance_cells: int = 3  # clearance is measured to walls within this many cells (capped beyond)
    run_invalid: bool = False  # also simulate scenarios the problem calls invalid
    engine: str = "auto"  # laser and body clearance: numba (compiled, same numbers) | numpy | auto

    def __post_init__(self):
        if self.planner not in PLANNERS:
            raise ScenarioError("option.planner", f"unknown planner {self.planner!r}", "|".join(PLANNERS))
        for name in ("radius", "cruise_speed", "max_speed", "max_turn_rate", "max_accel", "max_turn_accel",
                     "dt", "laser_range", "fov_deg", "lookahead", "turn_gain", "slow_distance",
                     "goal_tolerance", "stall_radius", "stall_time", "timeout", "waypoint_tolerance",
                     "nd_turn_rate_deg", "nd_goal_tolerance", "avoid_dist", "stuck_time", "stuck_distance",
                     "stuck_angle_deg"):
            if not getattr(self, name) > 0:
                raise ScenarioError(f"option.{name}", "must be > 0")
        for name in ("laser_noise", "rdp_epsilon", "margin", "squeeze_margin", "squeeze_lookahead", "squeeze_speed",
                     "nd_min_speed", "nd_min_turn_rate_deg", "safety_dist", "proximity", "timeout_route_factor",
                     "timeout_margin"):
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

    def time_limit(self, route_length: float | None) -> float:
        """max(timeout, timeout_route_factor x route / cruise_speed + timeout_margin) [s]."""
        if route_length is None or not math.isfinite(route_length):
            return float(self.timeout)
        return float(max(self.timeout, self.timeout_route_factor * route_length / self.cruise_speed
                         + self.timeout_margin))


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
              max_range: float, padded: np.ndarray | None = None, engine: str = "auto") -> np.ndarray:
    """Exact range to the first occupied cell along each ray (grid ``[y, x]``; outside = wall).

    All rays at once: a ray's grid-line crossings (every cell it enters) are ``first + k / |cos|``
    and ``first + k / |sin|``; sorted, they split it into segments, each inside one cell (looked up
    at the segment's middle); the range is where the first occupied segment starts, or
    ``max_range``. ``padded`` (the grid with a ring of wall, see ``pad_grid``) can be passed to save
    building it on every call. ``engine``: "numba" (a compiled loop over rays, the same numbers),
    "numpy", or "auto" (numba when importable).
    """
    gp = pad_grid(grid) if padded is None else padded
    Hp, Wp = gp.shape
    angles = np.asarray(angles, dtype=float)
    px, py = x / resolution + 1.0, y / resolution + 1.0  # padded-grid cell units
    limit = max_range / resolution
    if _use_numba(engine):
        out = np.empty(len(angles))
        _kernels()["rays"](gp, px, py, np.cos(angles), np.sin(angles), limit, out)
        return out * resolution
    dx, dy = np.cos(angles)[:, None], np.sin(angles)[:, None]
    far = 2.0 * limit + 4.0
    k = np.arange(int(limit) + 2)[None, :]
    with np.errstate(divide="ignore"):
        inv_x, inv_y = 1.0 / np.abs(dx), 1.0 / np.abs(dy)
    first_x = np.where(dx > 0, math.floor(px) + 1 - px, px - math.floor(px))
    first_y = np.where(dy > 0, math.floor(py) + 1 - py, py - math.floor(py))
    t_x = np.where(np.isfinite(inv_x), np.minimum((first_x + k) * np.minimum(inv_x, far), far), far)
    t_y = np.where(np.isfinite(inv_y), np.minimum((first_y + k) * np.minimum(inv_y, far), far), far)
    starts = np.concatenate([np.zeros((len(angles), 1)), t_x, t_y], axis=1)
    starts.sort(axis=1)
    mid = (starts[:, :-1] + starts[:, 1:]) / 2
    cx = np.clip(np.floor(px + mid * dx), 0, Wp - 1).astype(np.int64)
    cy = np.clip(np.floor(py + mid * dy), 0, Hp - 1).astype(np.int64)
    hit = gp[cy, cx] & (starts[:, :-1] < limit)
    first = np.argmax(hit, axis=1)
    out = np.where(hit[np.arange(len(angles)), first], starts[np.arange(len(angles)), first], limit)
    return np.minimum(out, limit) * resolution


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



def clearances(grid: np.ndarray, resolution: float, x: np.ndarray, y: np.ndarray, cells: int,
               origin: tuple[float, float] = (0.0, 0.0)) -> np.ndarray:
    """``robot.wall_distance`` for many points at once: distance to the nearest occupied cell square
    within ``cells`` cells (capped there), 0 for a point whose neighbourhood lies off the grid."""
    grid = np.asarray(grid, dtype=bool)
    H, W = grid.shape
    x = np.asarray(x, dtype=float) - origin[0]
    y = np.asarray(y, dtype=float) - origin[1]
    cx = np.floor(x / resolution).astype(np.int64)
    cy = np.floor(y / resolution).astype(np.int64)
    off = np.arange(-cells, cells + 1)
    gx_cells = cx[:, None] + off[None, :]  # (N, 2c+1)
    gy_cells = cy[:, None] + off[None, :]
    inside_x = (gx_cells >= 0) & (gx_cells < W)
    inside_y = (gy_cells >= 0) & (gy_cells < H)
    occ = (grid[np.clip(gy_cells, 0, H - 1)[:, :, None], np.clip(gx_cells, 0, W - 1)[:, None, :]]
           & inside_y[:, :, None] & inside_x[:, None, :])  # (N, 2c+1 [y], 2c+1 [x])
    ddx = np.maximum(np.abs(x[:, None] - (gx_cells + 0.5) * resolution) - 0.5 * resolution, 0.0)
    ddy = np.maximum(np.abs(y[:, None] - (gy_cells + 0.5) * resolution) - 0.5 * resolution, 0.0)
    dist = np.hypot(ddx[:, None, :], ddy[:, :, None])
    cap = cells * resolution
    out = np.where(occ, dist, np.inf).min(axis=(1, 2), initial=np.inf)
    out = np.minimum(out, cap)
    off_grid = ~inside_x.any(axis=1) | ~inside_y.any(axis=1)
    return np.where(off_grid, 0.0, out)


# --- compiled loops (numba, optional) ------------------------------------------------------------
def _rays_kernel(gp, px, py, dx, dy, limit, out):
    """``cast_rays`` one ray after another (compiled by numba): the two sorted crossing sequences
    merged instead of sorted together, the same segment midpoints and cells, so the same ranges."""
    Hp, Wp = gp.shape
    far = 2.0 * limit + 4.0
    K = int(limit) + 2
    fx, fy = math.floor(px), math.floor(py)
    for r in range(len(dx)):
        ax, ay = abs(dx[r]), abs(dy[r])
        inv_x = 1.0 / ax if ax != 0.0 else math.inf
        inv_y = 1.0 / ay if ay != 0.0 else math.inf
        first_x = fx + 1 - px if dx[r] > 0 else px - fx
        first_y = fy + 1 - py if dy[r] > 0 else py - fy
        ix = iy = 0
        prev = 0.0
        result = limit
        for _ in range(2 * K):
            tx = math.inf
            if ix < K:
                tx = min((first_x + ix) * min(inv_x, far), far) if math.isfinite(inv_x) else far
            ty = math.inf
            if iy < K:
                ty = min((first_y + iy) * min(inv_y, far), far) if math.isfinite(inv_y) else far
            if tx <= ty:
                nxt = tx
                ix += 1
            else:
                nxt = ty
                iy += 1
            mid = (prev + nxt) / 2
            cx = math.floor(px + mid * dx[r])
            cy = math.floor(py + mid * dy[r])
            cx = 0.0 if cx < 0 else (Wp - 1.0 if cx > Wp - 1 else cx)
            cy = 0.0 if cy < 0 else (Hp - 1.0 if cy > Hp - 1 else cy)
            if prev < limit and gp[int(cy), int(cx)]:
                result = prev
                break
            prev = nxt
        out[r] = min(result, limit)


def _clearance_kernel(padded, boundary, corner, res, ox, oy, cap, window, reach, fp, x, y, c, s):
    """``WallGeometry.clearance_at`` as loops (compiled by numba), operation for operation."""
    Hp, Wp = padded.shape
    P = fp.shape[0]
    vx = np.empty(P)
    vy = np.empty(P)
    in_wall = False
    for p in range(P):
        vx[p] = x + c * fp[p, 0] - s * fp[p, 1]
        vy[p] = y + s * fp[p, 0] + c * fp[p, 1]
        ci = min(max(int(math.floor((vx[p] - ox) / res)) + 1, 0), Wp - 1)
        cj = min(max(int(math.floor((vy[p] - oy) / res)) + 1, 0), Hp - 1)
        if padded[cj, ci]:
            in_wall = True
    if in_wall:
        dist = 0.0
    else:
        dist = cap
        i = int(math.floor((x - ox) / res)) + 1
        j = int(math.floor((y - oy) / res)) + 1
        for jj in range(max(j - window, 0), min(j + window + 1, Hp)):
            for ii in range(max(i - window, 0), min(i + window + 1, Wp)):
                if boundary[jj, ii]:
                    lo_x = (ii - 1) * res + ox
                    lo_y = (jj - 1) * res + oy
                    for p in range(P):
                        gx = max(max(lo_x - vx[p], vx[p] - lo_x - res), 0.0)
                        gy = max(max(lo_y - vy[p], vy[p] - lo_y - res), 0.0)
                        dist = min(dist, math.hypot(gx, gy))
    Hc, Wc = corner.shape
    i = int(math.floor((x - ox) / res))
    j = int(math.floor((y - oy) / res))
    near = (max(dist, 0.0) + reach) ** 2
    best = dist
    for jj in range(max(j - window, 0), min(j + window + 2, Hc)):
        for ii in range(max(i - window, 0), min(i + window + 2, Wc)):
            if not corner[jj, ii]:
                continue
            dx = ii * res + ox - x
            dy = jj * res + oy - y
            if dx * dx + dy * dy >= near:
                continue
            qx = dx * c + dy * s
            qy = dy * c - dx * s
            edge = np.inf
            inside = True
            for p in range(P):
                q = (p + 1) % P
                ex, ey = fp[q, 0] - fp[p, 0], fp[q, 1] - fp[p, 1]
                rx, ry = qx - fp[p, 0], qy - fp[p, 1]
                t = min(max((rx * ex + ry * ey) / (ex * ex + ey * ey), 0.0), 1.0)
                edge = min(edge, math.hypot(rx - t * ex, ry - t * ey))
                if ex * ry - ey * rx < 0:
                    inside = False
            best = min(best, -edge if inside else edge)
    return best


_KERNELS: Any = None  # dict of compiled loops, or False when numba is unavailable


def _kernels():
    """Compile the loops on first use (``core.accel.jit``: cached on disk); False without numba."""
    global _KERNELS
    if _KERNELS is None:
        rays, clearance = jit(_rays_kernel), jit(_clearance_kernel)
        _KERNELS = {"rays": rays, "clearance": clearance} if rays is not None and clearance is not None else False
    return _KERNELS


def _use_numba(engine: str) -> bool:
    if engine == "numpy":
        return False
    if engine not in ENGINES:
        raise ScenarioError("option.engine", f"unknown engine {engine!r}", "|".join(ENGINES))
    if _kernels():
        return True
    if engine == "numba":
        raise ImportError("numba is not installed; use engine='numpy'")
    return False


# --- the body ------------------------------------------------------------------------------------
def _convex_hull(points: np.ndarray) -> np.ndarray:
    """Counterclockwise convex hull (monotone chain), no repeated vertex."""
    pts = sorted(set(map(tuple, np.round(np.asarray(points, dtype=float), 12))))
    if len(pts) < 3:
        return np.asarray(pts)

    def half(seq):
        out: list = []
        for p in seq:
            while len(out) >= 2 and ((out[-1][0] - out[-2][0]) * (p[1] - out[-2][1])
                                     - (out[-1][1] - out[-2][1]) * (p[0] - out[-2][0])) <= 0:
                out.pop()
            out.append(p)
        return out

    lower, upper = half(pts), half(reversed(pts))
    return np.asarray(lower[:-1] + upper[:-1])


def pioneer2dx_footprint(length: float = 0.44, width: float = 0.38, origin_x: float = -0.04) -> np.ndarray:
    """Stage's pioneer2dx outline in the robot frame (x ahead, y left; rotation centre at 0).

    The convex hull of the model's blocks in Stage's ``pioneer.inc`` (main body, sonar cases,
    wheels, castor, lid); Stage scales the blocks to the model's ``size`` [0.44 0.38] and centres
    them on its ``origin`` [-0.04 0]: the rotation centre lies 4 cm ahead of the centre of area.
    """
    half_lid = [(0.174, 0.0), (0.166, 0.056), (0.145, 0.107), (0.112, 0.155), (0.064, 0.190), (-0.074, 0.190),
                (-0.096, 0.160), (-0.151, 0.160), (-0.2, 0.155), (-0.236, 0.107), (-0.256, 0.056), (-0.264, 0.0)]
    half_rest = [(-0.215, 0.1), (-0.185, 0.135), (0.095, 0.135), (0.11, 0.08),  # main body
                 (-0.135, 0.136), (-0.223, 0.101), (-0.248, 0.054), (-0.258, 0.0),  # rear sonar case
                 (0.046, 0.136), (0.134, 0.101), (0.159, 0.054), (0.168, 0.0),  # front sonar case
                 (0.083, 0.177), (-0.083, 0.177), (-0.2475, 0.012), (-0.1825, 0.012)]  # wheels, castor
    half = np.asarray(half_lid + half_rest)
    pts = np.concatenate([half, half * [1.0, -1.0]])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    pts = (pts - (lo + hi) / 2) * ([length, width] / (hi - lo)) + [origin_x, 0.0]
    return _convex_hull(pts)


PIONEER2DX = pioneer2dx_footprint()
PIONEER2DX_LENGTH, PIONEER2DX_WIDTH, PIONEER2DX_ORIGIN_X = 0.44, 0.38, -0.04


def _polygon_signed_distance(qx: np.ndarray, qy: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Signed distance of points to a convex counterclockwise polygon's boundary (< 0 inside)."""
    a = polygon
    e = np.roll(polygon, -1, axis=0) - a
    rx = qx[:, None] - a[None, :, 0]
    ry = qy[:, None] - a[None, :, 1]
    t = np.clip((rx * e[:, 0] + ry * e[:, 1]) / (e[:, 0] ** 2 + e[:, 1] ** 2), 0.0, 1.0)
    dist = np.hypot(rx - t * e[:, 0], ry - t * e[:, 1]).min(axis=1)
    inside = np.all(e[:, 0] * ry - e[:, 1] * rx >= 0, axis=1)
    return np.where(inside, -dist, dist)


class WallGeometry:
    """A map's walls as the body meets them: ``clearance_at(x, y, yaw)`` is the distance from the
    body at a pose to the nearest wall cell, capped at ``cells`` cells, and <= 0 when it touches or
    overlaps one (outside the grid counts as wall); ``clearance`` does it for many poses.

    Exact for a convex body: the nearest pair of points is a body vertex against the square of a
    boundary wall cell (one with a free neighbour: the only cells the nearest point can lie on) or a
    wall corner (a lattice point where wall meets free space) against a body edge; a body vertex
    inside a wall cell or a corner inside the body means contact. Only cells and corners within
    the cap plus the body's reach are looked at.
    """

    def __init__(self, grid: np.ndarray, resolution: float, cells: int = 3,
                 origin: tuple[float, float] = (0.0, 0.0), footprint: np.ndarray = PIONEER2DX,
                 engine: str = "auto"):
        self.numba = _use_numba(engine)
        self.grid = np.asarray(grid, dtype=bool)
        self.res = float(resolution)
        self.origin = (float(origin[0]), float(origin[1]))
        self.cap = cells * self.res
        self.footprint = np.asarray(footprint, dtype=float)
        self.reach = float(np.hypot(self.footprint[:, 0], self.footprint[:, 1]).max())
        self.window = int(math.ceil((self.cap + self.reach) / self.res)) + 1
        gp = pad_grid(self.grid)
        self.padded = np.ascontiguousarray(gp)  # padded cell (j, i) is grid cell (i - 1, j - 1)
        free = ~pad_grid(gp)  # two rings of wall: every padded cell has four neighbours
        open_side = free[:-2, 1:-1] | free[2:, 1:-1] | free[1:-1, :-2] | free[1:-1, 2:]
        self.boundary = gp & open_side
        quad = np.stack([gp[:-1, :-1], gp[:-1, 1:], gp[1:, :-1], gp[1:, 1:]])
        self.corner = quad.any(axis=0) & ~quad.all(axis=0)  # lattice point (i, j) is the corner of grid cells i-1..i

    def clearance_at(self, x: float, y: float, yaw: float) -> float:
        fp, res, (ox, oy) = self.footprint, self.res, self.origin
        c, s = math.cos(yaw), math.sin(yaw)
        if self.numba:
            return _kernels()["clearance"](self.padded, self.boundary, self.corner, res, ox, oy, self.cap, self.window,
                                           self.reach, fp, float(x), float(y), c, s)
        vx = x + c * fp[:, 0] - s * fp[:, 1]
        vy = y + s * fp[:, 0] + c * fp[:, 1]
        Hp, Wp = self.padded.shape
        ci = np.clip(np.floor((vx - ox) / res).astype(np.int64) + 1, 0, Wp - 1)
        cj = np.clip(np.floor((vy - oy) / res).astype(np.int64) + 1, 0, Hp - 1)
        if self.padded[cj, ci].any():
            dist = 0.0
        else:
            dist = self.cap
            i = int(math.floor((x - ox) / res)) + 1
            j = int(math.floor((y - oy) / res)) + 1
            k = self.window
            i0, j0 = max(i - k, 0), max(j - k, 0)
            jy, ix = np.nonzero(self.boundary[j0:j + k + 1, i0:i + k + 1])
            if len(ix):
                lo_x = ((ix + i0 - 1) * res + ox)[:, None]
                lo_y = ((jy + j0 - 1) * res + oy)[:, None]
                gx = np.maximum(np.maximum(lo_x - vx, vx - lo_x - res), 0.0)
                gy = np.maximum(np.maximum(lo_y - vy, vy - lo_y - res), 0.0)
                dist = min(dist, float(np.hypot(gx, gy).min()))
        # wall corners against the body's edges (lattice point (i, j) sits at grid coordinates i, j)
        i = int(math.floor((x - ox) / res))
        j = int(math.floor((y - oy) / res))
        k = self.window
        i0, j0 = max(i - k, 0), max(j - k, 0)
        jy, ix = np.nonzero(np.asarray(self.corner)[j0:j + k + 2, i0:i + k + 2])
        if len(ix):
            dx = (ix + i0) * res + ox - x
            dy = (jy + j0) * res + oy - y
            near = dx * dx + dy * dy < (max(dist, 0.0) + self.reach) ** 2
            if near.any():
                qx = dx[near] * c + dy[near] * s
                qy = dy[near] * c - dx[near] * s
                dist = min(dist, float(_polygon_signed_distance(qx, qy, fp).min()))
        return dist

    def clearance(self, x, y, yaw) -> np.ndarray:
        x, y, yaw = (np.atleast_1d(np.asarray(a, dtype=float)) for a in (x, y, yaw))
        return np.array([self.clearance_at(float(a), float(b), float(c)) for a, b, c in zip(x, y, yaw)])


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
                 waypoints: np.ndarray | None = None, no_route: bool = False):
        self.cfg = config
        self.no_route = no_route
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

    def update(self, t: float, x: float, y: float, clearance: float, stall_cause: str | None = None) -> bool:
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

        if clearance <= 0.0:
            self.stall_cause = "contact"
            self._decide("stall", "stall", f"the body touches a wall at ({x:.2f}, {y:.2f}) after {self.t:.1f} s "
                         "and cannot move", x, y)
        elif stall_cause is not None:
            self.stall_cause = stall_cause
            self._decide("stall", "no_route" if stall_cause == "no_route" else "stall",
                         f"stalled at ({x:.2f}, {y:.2f}) after {self.t:.1f} s: {stall_cause.replace('_', ' ')}", x, y)
        elif first:
            return False
        elif math.hypot(self.goal[0] - x, self.goal[1] - y) <= cfg.goal_tolerance:
            self._decide("none", "success", f"goal reached in {self.t:.1f} s", x, y)
        elif self.t >= cfg.stall_time - 1e-9:
            n = len(self._window)
            cx, cy = self._sum[0] / n, self._sum[1] / n
            if math.hypot(x - cx, y - cy) < cfg.stall_radius and self._window_path < 1e-6:
                self.stall_cause = "no_route" if self.no_route else "stationary"
                self._decide("stall", "no_route" if self.no_route else "stall",
                             f"stalled at ({x:.2f}, {y:.2f}): no motion for {cfg.stall_time:g} s (after {self.t:.1f} s)"
                             + ("; no route" if self.no_route else ""), x, y)
            elif math.hypot(x - cx, y - cy) < cfg.stall_radius:
                self._decide("loiter", "loiter", f"loitering within {cfg.stall_radius:g} m of ({cx:.2f}, {cy:.2f}) "
                             f"for {cfg.stall_time:g} s (after {self.t:.1f} s)", x, y)
        if not self.decided and self.t >= self.time_limit - 1e-9:
            self._decide("timeout", "timeout", f"goal not reached within {self.time_limit:.0f} s", x, y)
        return self.decided

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
        }


def _wrap(a):
    return (a + np.pi) % (2 * np.pi) - np.pi


def _clip(value: float, low: float, high: float) -> float:
    return low if value < low else high if value > high else value


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
    """Drive from cell ``start`` to cell ``goal`` on occupancy ``grid`` ([y, x]) along the planned
    route (``plan_route``, A* with the problem's ``diagonal`` rule); returns ``drive``'s record."""
    cfg = config or RobotSimConfig()
    waypoints, route_length = plan_route(np.asarray(grid, dtype=bool), resolution, start, goal, cfg, diagonal)
    start_xy = ((start[0] + 0.5) * resolution, (start[1] + 0.5) * resolution)
    goal_xy = ((goal[0] + 0.5) * resolution, (goal[1] + 0.5) * resolution)
    run = drive(grid, resolution, start_xy, goal_xy, waypoints, cfg, seed, cfg.time_limit(route_length))
    run["route_length"] = float(route_length) if math.isfinite(route_length) else None
    return run


def drive(grid: np.ndarray, resolution: float, start_xy: tuple[float, float], goal_xy: tuple[float, float],
          waypoints: np.ndarray, config: RobotSimConfig | None = None, seed: int = 0,
          time_limit: float | None = None, heading: float | None = None) -> dict[str, Any]:
    """Drive the robot from ``start_xy`` (facing ``heading``; default ``waypoints[1]``, else the
    goal) through ``waypoints`` ((K, 2) metres, ``waypoints[0]`` = the start; none = no route) to
    ``goal_xy``, judged by the monitors; ``time_limit`` defaults to the config's for the waypoints'
    polyline.

    Keys: outcome, failure_kind, detail, time, time_limit, path_length, min_clearance, route_length,
    waypoints, waypoints_reached, stall_cause, unsafe_proximity_events, unsafe_proximity_s,
    failure_point, timeline (t, x, y, yaw, v, stall arrays; stall = the robot's stall flag, 0/1).
    """
    cfg = config or RobotSimConfig()
    grid = np.asarray(grid, dtype=bool)
    waypoints = np.asarray(waypoints, dtype=float).reshape(-1, 2)
    polyline = float(np.hypot(*np.diff(waypoints, axis=0).T).sum()) if len(waypoints) else math.inf
    time_limit = cfg.time_limit(polyline) if time_limit is None else float(time_limit)
    rng = np.random.default_rng(seed)
    walls = WallGeometry(grid, resolution, cfg.clearance_cells, engine=cfg.engine)
    padded = walls.padded
    sx, sy = float(start_xy[0]), float(start_xy[1])
    gx, gy = float(goal_xy[0]), float(goal_xy[1])
    if heading is None:
        ahead = waypoints[1] if len(waypoints) > 1 else (gx, gy)
        heading = math.atan2(ahead[1] - sy, ahead[0] - sx)
    yaw = float(heading)
    half_fov = math.radians(cfg.fov_deg) / 2
    beam_angles = np.linspace(-half_fov, half_fov, cfg.beams)
    driver = nd_driver(cfg) if cfg.planner == "nd" else None
    gap = GapPlanner(cfg, beam_angles) if cfg.planner == "gap" else None
    monitors = RobotMonitors(cfg, (gx, gy), time_limit, waypoints[1:], no_route=not len(waypoints))

    clearance_at = walls.clearance_at

    x, y, v, w = sx, sy, 0.0, 0.0
    n_max = int(math.ceil(time_limit / cfg.dt - 1e-9))
    rec = np.zeros((n_max + 1, 6))  # t, x, y, yaw, v, stall
    rec[0] = (0.0, x, y, yaw, 0.0, 0.0)
    wp = min(1, len(waypoints) - 1)
    if driver is not None and len(waypoints):
        driver.set_goal(waypoints[wp], 0.0, (x, y, yaw))
    k = 0
    monitors.update(0.0, x, y, clearance_at(x, y, yaw))
    while not monitors.decided and k < n_max:
        k += 1
        t = k * cfg.dt
        # --- sense and decide ---
        v_cmd = w_cmd = 0.0
        stall_cause = None
        while (wp < len(waypoints) - 1
               and math.hypot(waypoints[wp, 0] - x, waypoints[wp, 1] - y) < cfg.waypoint_tolerance):
            wp += 1
            if driver is not None:
                driver.set_goal(waypoints[wp], t, (x, y, yaw))
        if not len(waypoints):  # no route: nothing to drive to; the robot stands where it is
            rec[k] = (t, x, y, yaw, 0.0, 0.0)
            monitors.update(t, x, y, clearance_at(x, y, yaw))
            continue
        ranges = cast_rays(grid, resolution, x, y, beam_angles + yaw, cfg.laser_range, padded, cfg.engine)
        hits = ranges < cfg.laser_range
        if cfg.laser_noise > 0:  # noise on the returns; a beam that hit nothing reads the maximum range
            noisy = np.clip(ranges + rng.normal(0.0, cfg.laser_noise, ranges.shape), 0.0, cfg.laser_range)
            ranges = np.where(hits, noisy, ranges)
        if driver is not None:
            driver.add_scan(np.column_stack([x + ranges[hits] * np.cos(beam_angles[hits] + yaw),
                                             y + ranges[hits] * np.sin(beam_angles[hits] + yaw)]))
            v_cmd, w_cmd = driver.command(t, (x, y, yaw), v, w)
            stall_cause = driver.gave_up
        elif gap is not None:
            tx, ty = waypoints[wp]
            bearing = (math.atan2(ty - y, tx - x) - yaw + math.pi) % (2 * math.pi) - math.pi
            v_cmd, w_cmd = gap.command(bearing, math.hypot(tx - x, ty - y), wp == len(waypoints) - 1, ranges)
        # --- act (acceleration limits, unicycle, midpoint heading); a wall stops the body ---
        v_cmd = min(v_cmd, cfg.max_speed)
        v += _clip(v_cmd - v, -cfg.max_accel * cfg.dt, cfg.max_accel * cfg.dt)
        w += _clip(w_cmd - w, -cfg.max_turn_accel * cfg.dt, cfg.max_turn_accel * cfg.dt)

        def pose(f: float) -> tuple[float, float, float]:
            mid = yaw + 0.5 * w * f * cfg.dt
            return (x + v * math.cos(mid) * f * cfg.dt, y + v * math.sin(mid) * f * cfg.dt,
                    (yaw + w * f * cfg.dt + math.pi) % (2 * math.pi) - math.pi)

        nx, ny, nyaw = pose(1.0)
        clearance = clearance_at(nx, ny, nyaw)
        if clearance <= 0.0:  # the first contact along the step (bisection), where the body stops
            lo, hi = 0.0, 1.0
            for _ in range(14):
                mid_f = (lo + hi) / 2
                if clearance_at(*pose(mid_f)) <= 0.0:
                    hi = mid_f
                else:
                    lo = mid_f
            nx, ny, nyaw = pose(hi)
            clearance = clearance_at(nx, ny, nyaw)
            v = w = 0.0
        x, y, yaw = nx, ny, nyaw
        rec[k] = (t, x, y, yaw, v, float(stall_cause is not None))
        monitors.update(t, x, y, clearance, stall_cause)
    rec = rec[:k + 1]
    m = monitors.metrics()
    detail = monitors.detail
    if driver is not None and m["stall_cause"] in ("emergency_stop", "no_region", "no_progress", "no_motion"):
        detail += " (the ND driver gave up)"
    return {
        **m,
        "failure_kind": monitors.kind,
        "detail": detail,
        "route_length": polyline if math.isfinite(polyline) else None,
        "waypoints": waypoints,
        "failure_point": monitors.failure_point,
        "timeline": {"t": rec[:, 0], "x": rec[:, 1], "y": rec[:, 2], "yaw": rec[:, 3], "v": rec[:, 4],
                     "stall": rec[:, 5]},
    }


def simulate(problem: Any, scenario: Any, config: RobotSimConfig | None = None, seed: int = 0) -> Outcome:
    """Execute one robot scenario on the full model and judge it with the paper's monitors."""
    cfg = config or RobotSimConfig()
    env = problem.environment(scenario)
    pc = problem.config
    run = navigate(env.grid, env.resolution, pc.start, pc.goal, cfg, seed=seed,
                   diagonal=cfg.route_diagonal or pc.diagonal)
    timeline = run["timeline"]
    metrics = {
        "outcome": run["outcome"],
        "time": run["time"],
        "time_limit": run["time_limit"],
        "path_length": run["path_length"],
        "min_clearance": run["min_clearance"],
        "route_length": run["route_length"],
        "surrogate_path_length": env.path_length if env.reachable else None,
        "waypoints": int(len(run["waypoints"])),
        "waypoints_reached": run["waypoints_reached"],
        "planner": cfg.planner,
        "stall_cause": run["stall_cause"],
        "unsafe_proximity_events": run["unsafe_proximity_events"],
        "unsafe_proximity_s": run["unsafe_proximity_s"],
        "radius": cfg.radius,
        "distance_to_goal": float(math.hypot(timeline["x"][-1] - env.goal_m[0], timeline["y"][-1] - env.goal_m[1])),
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


__all__ = ["PIONEER2DX", "PLANNERS", "GapPlanner", "RobotMonitors", "RobotSimConfig", "WallGeometry", "cast_rays",
           "clearances", "drive", "nd_driver", "navigate", "pad_grid", "plan_route", "rdp", "simulate", "wall_distance"]
