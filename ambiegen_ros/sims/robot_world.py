"""The robot's world, ROS-free: the pioneer2dx body, its contact with walls, and the 2D laser.

Everything here is about the map and the body, nothing about where the robot wants to go (the
route, the planners and the monitors live in ``sims.robot``). ``RobotWorld`` holds one robot on
one occupancy grid: ``scan()`` gives a laser scan at the current pose, ``step(v, w)`` moves the
body one ``dt`` under velocity commands, and the body stops where it meets a wall. A ROS node that
hosts a map for someone else's robot (``robot_world``: ``/cmd_vel`` in, ``/scan`` and ``/odom``
out) is a thin wrapper over it; ``sims.robot.drive`` is the in-process one.

* *Body*: Stage's pioneer2dx footprint (the convex hull of its blocks, 0.44 x 0.38 m, rotation
  centre 4 cm ahead of the centre of area), unicycle kinematics with speed and acceleration
  limits, integrated with a fixed step ``dt``. As in Stage, the body cannot enter a wall: a step
  that would make it touch one ends at the contact and the robot is blocked there.
* *Contact*: ``WallGeometry`` measures the body's clearance to the walls, exactly for a convex body;
  <= 0 is contact.
* *Laser*: ``beams`` rays over ``fov_deg``, ``laser_range`` metres, cast exactly on the occupancy
  grid (all rays at once), plus optional Gaussian noise on the returns from the run's seeded
  generator; a beam that hits nothing reads the maximum range, which is no obstacle.

* *Robot profile* (issue 69, ``sims.robot_profile``; None: the Pioneer above, exactly as before):
  the body is the profile's footprint, the drive its kind (differential: v, w; omnidirectional:
  v, vy, w; Ackermann: the turn rate never above ``|v| / min_turning_radius``, so a turn command
  without speed turns nothing), speeds capped at its limits both ways, and each of its lasers cast
  from its mount pose (``scan(laser)``).

Speed: the laser and the body clearance run as compiled loops (``engine``; the numpy code gives
the same numbers).
"""
from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from ..core.accel import jit
from ..core.attributes import ScenarioError

ENGINES = ("auto", "numba", "numpy")
WORLD_FIELDS = ("dt", "max_speed", "max_accel", "max_turn_accel", "laser_range", "fov_deg", "beams", "laser_noise",
                "clearance_cells", "engine", "contact_fault_speed")
"""The config fields ``RobotWorld`` reads (``sims.robot.RobotSimConfig`` has them all)."""


# --- the laser and wall distances ----------------------------------------------------------------
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
    """``wall_distance`` for many points at once: distance to the nearest occupied cell square
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


def _clip(value: float, low: float, high: float) -> float:
    return low if value < low else high if value > high else value


# --- the world -----------------------------------------------------------------------------------
class RobotWorld:
    """One robot on one occupancy grid (``[y, x]``, outside = wall), stepped by velocity commands.

    ``config``: any object with the ``WORLD_FIELDS`` (a ``RobotSimConfig``); ``pose``: (x, y, yaw)
    in metres and radians; ``rng``: the generator of the laser noise (seeded by the caller, so a run
    is deterministic for its seed). State: ``x``, ``y``, ``yaw``, ``v``, ``w``; ``contact`` is True
    after a step that ended at a wall.

    ``obstacles`` (``sims.obstacles.Obstacles``, issue 48): what is in the world but not on the grid.
    The laser sees them; boxes and posts stop the body as walls do; people walk their paths on the
    world's clock ``t`` (seconds since the world started) and never stop for the robot. A contact
    with a person is the robot's fault only when it moves towards it faster than
    ``config.contact_fault_speed`` (``robot_at_fault``): then the
    body stops and ``person_contact`` says so (a collision); otherwise it is counted in
    ``contacts_not_at_fault`` and the robot goes on.
    """

    def __init__(self, grid: np.ndarray, resolution: float, config: Any, pose: tuple[float, float, float],
                 rng: np.random.Generator | None = None, footprint: np.ndarray = PIONEER2DX, obstacles: Any = None,
                 profile: Any = None):
        self.profile = profile
        if profile is not None:  # the profile's body, base limits and first laser (``RobotProfile.world_config``)
            config = profile.world_config(config)
            footprint = profile.footprint()
        self.cfg = config
        self.grid = np.asarray(grid, dtype=bool)
        self.resolution = resolution
        self.walls = WallGeometry(self.grid, resolution, config.clearance_cells, footprint=footprint,
                                  engine=config.engine)
        self.footprint = np.asarray(footprint, dtype=float)
        half_fov = math.radians(config.fov_deg) / 2
        self.beam_angles = np.linspace(-half_fov, half_fov, config.beams)  # in the robot frame
        # each laser: mount x, y, yaw in the robot frame, beam angles in its own frame, range, noise
        self.lasers = [(0.0, 0.0, 0.0, self.beam_angles, config.laser_range, config.laser_noise)]
        if profile is not None:
            self.lasers = [(las.x, las.y, las.yaw, las.beam_angles(), las.range, las.noise) for las in profile.lasers]
            self.beam_angles = self.lasers[0][3]
        self.vy = 0.0  # sideways speed (an omnidirectional base only)
        self.rng = rng if rng is not None else np.random.default_rng(0)
        self.x, self.y, self.yaw = float(pose[0]), float(pose[1]), float(pose[2])
        self.v = self.w = 0.0
        self.contact = False
        self.obstacles = obstacles if obstacles is not None and not obstacles.empty() else None
        self.statics = None if self.obstacles is None else dataclasses.replace(self.obstacles, people=())
        self.t = 0.0
        self.person_contact: str | None = None  # the at-fault contact with a person, once there is one
        self.contacts_not_at_fault = 0
        self._touching: set[int] = set()  # people the body touches now

    @property
    def pose(self) -> tuple[float, float, float]:
        return self.x, self.y, self.yaw

    def _static_clearance(self, x: float, y: float, yaw: float) -> float:
        """Walls, boxes and posts: what stops the body."""
        d = self.walls.clearance_at(x, y, yaw)
        if self.statics is not None and not self.statics.empty():
            d = min(d, self.statics.body_clearance(x, y, yaw, self.footprint, self.t)[0])
        return d

    def clearance(self) -> float:
        """The body's distance to the nearest wall, box or post at the current pose (<= 0: contact)."""
        return self._static_clearance(self.x, self.y, self.yaw)

    def laser_pose(self, laser: int = 0) -> tuple[float, float, float]:
        """Where a laser sits in the world (its mount pose on the body at the current pose)."""
        mx, my, myaw = self.lasers[laser][:3]
        if mx == 0.0 and my == 0.0:
            return self.x, self.y, self.yaw + myaw
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        return self.x + c * mx - s * my, self.y + s * mx + c * my, self.yaw + myaw

    def scan(self, laser: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """Ranges of a laser's beams from its mount (noisy where they hit), and which beams hit; the
        beams in the laser's own frame (``lasers[laser][3]``)."""
        cfg = self.cfg
        _, _, _, angles, max_range, noise = self.lasers[laser]
        x, y, yaw = self.laser_pose(laser)
        ranges = cast_rays(self.grid, self.resolution, x, y, angles + yaw, max_range, self.walls.padded, cfg.engine)
        if self.obstacles is not None:
            ranges = np.minimum(ranges, self.obstacles.ray_ranges(x, y, angles + yaw, max_range, self.t))
        hits = ranges < max_range
        if noise > 0:  # noise on the returns; a beam that hit nothing reads the maximum range
            noisy = np.clip(ranges + self.rng.normal(0.0, noise, ranges.shape), 0.0, max_range)
            ranges = np.where(hits, noisy, ranges)
        return ranges, hits

    def _pose_at(self, f: float) -> tuple[float, float, float]:
        """The pose after a fraction ``f`` of a step at the current speeds (midpoint heading)."""
        dt = self.cfg.dt
        mid = self.yaw + 0.5 * self.w * f * dt
        yaw = (self.yaw + self.w * f * dt + math.pi) % (2 * math.pi) - math.pi
        if self.vy != 0.0:  # an omnidirectional base moving sideways too
            c, s = math.cos(mid), math.sin(mid)
            return self.x + (self.v * c - self.vy * s) * f * dt, self.y + (self.v * s + self.vy * c) * f * dt, yaw
        return self.x + self.v * math.cos(mid) * f * dt, self.y + self.v * math.sin(mid) * f * dt, yaw

    def _accelerate(self, v_cmd: float, w_cmd: float, vy_cmd: float) -> None:
        """The speeds after one ``dt`` towards the commands, within the base's limits (the profile's,
        if any: its drive decides what a command can do)."""
        cfg, p = self.cfg, self.profile
        if p is None:
            v_cmd = min(v_cmd, cfg.max_speed)
        else:
            v_cmd = _clip(v_cmd, -p.max_speed[0], p.max_speed[0])
            w_cmd = _clip(w_cmd, -p.max_speed[2], p.max_speed[2])
            vy_cmd = _clip(vy_cmd, -p.max_speed[1], p.max_speed[1]) if p.drive == "omnidirectional" else 0.0
        self.v += _clip(v_cmd - self.v, -cfg.max_accel * cfg.dt, cfg.max_accel * cfg.dt)
        self.w += _clip(w_cmd - self.w, -cfg.max_turn_accel * cfg.dt, cfg.max_turn_accel * cfg.dt)
        if p is not None and p.drive == "omnidirectional":
            self.vy += _clip(vy_cmd - self.vy, -p.max_accel[1] * cfg.dt, p.max_accel[1] * cfg.dt)
        if p is not None and p.drive == "ackermann":  # a car turns only as it rolls: |w| <= |v| / r_min
            limit = abs(self.v) / p.min_turning_radius
            self.w = _clip(self.w, -limit, limit)

    def step(self, v_cmd: float, w_cmd: float, vy_cmd: float = 0.0) -> float:
        """One ``dt`` under the commands (acceleration limits, unicycle; ``vy_cmd``: sideways, an
        omnidirectional profile only); returns the new clearance.

        A step that would touch a wall, box or post ends at the first contact along it (bisection)
        and stops the body there (``v = w = 0``, ``contact``), as Stage's does. Then people: see the
        class docstring."""
        cfg = self.cfg
        self._accelerate(v_cmd, w_cmd, vy_cmd)
        clearance_at = self._static_clearance
        nx, ny, nyaw = self._pose_at(1.0)
        clearance = clearance_at(nx, ny, nyaw)
        if clearance <= 0.0:  # the first contact along the step, where the body stops
            lo, hi = 0.0, 1.0
            for _ in range(14):
                mid_f = (lo + hi) / 2
                if clearance_at(*self._pose_at(mid_f)) <= 0.0:
                    hi = mid_f
                else:
                    lo = mid_f
            nx, ny, nyaw = self._pose_at(hi)
            clearance = clearance_at(nx, ny, nyaw)
            self.v = self.w = self.vy = 0.0
        v_step = self.v
        self.x, self.y, self.yaw = nx, ny, nyaw
        self.t += cfg.dt
        self.contact = clearance <= 0.0
        if self.obstacles is not None and self.obstacles.people:
            self._meet_people(v_step, self.vy)
        return clearance

    def _meet_people(self, v: float, vy: float = 0.0) -> None:
        """Contacts with people after a step: the robot's fault (it moved towards the person: the body
        stops, ``person_contact``) or not (counted once per contact)."""
        from .obstacles import contact_point, person_contact_detail, robot_at_fault, speeds_along

        people = self.obstacles.people
        circles = self.obstacles.circles_at(self.t)[-len(people):]
        touching = set()
        for k, (cx, cy, r) in enumerate(circles):
            if math.hypot(cx - self.x, cy - self.y) > r + max(0.5, self.walls.reach + 0.05):  # beyond the body
                continue
            single = type(self.obstacles)(people=(people[k],))
            if single.body_clearance(self.x, self.y, self.yaw, self.footprint, self.t)[0] > 0.0:
                continue
            touching.add(k)
            if k in self._touching or self.person_contact is not None:
                continue
            point = contact_point(self.x, self.y, self.yaw, self.footprint, "person", 0, single, self.t)
            heading, speed = (self.yaw, v) if vy == 0.0 else (self.yaw + math.atan2(vy, v), math.hypot(v, vy))
            if robot_at_fault((self.x, self.y), heading, speed, point, min_speed=self.cfg.contact_fault_speed):
                person = people[k]  # how they moved in this step: their velocity along the line of contact
                walked = (person.position(self.t) - person.position(max(self.t - self.cfg.dt, 0.0))) / self.cfg.dt
                along, person_along = speeds_along((self.x, self.y), heading, speed, (cx, cy), walked)
                self.person_contact = person_contact_detail(k, point, v, along, person_along)
                self.v = self.w = self.vy = 0.0
            else:
                self.contacts_not_at_fault += 1
        self._touching = touching


__all__ = ["ENGINES", "PIONEER2DX", "PIONEER2DX_LENGTH", "PIONEER2DX_ORIGIN_X", "PIONEER2DX_WIDTH", "WORLD_FIELDS",
           "RobotWorld", "WallGeometry", "cast_rays", "clearances", "pad_grid", "pioneer2dx_footprint",
           "wall_distance"]
