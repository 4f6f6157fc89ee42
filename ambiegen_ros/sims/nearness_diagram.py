"""Nearness Diagram navigation (Minguez and Montano, IEEE T-RA 2004), as Player's ``nd`` driver ran it.

The paper's RQ3 robot was a Stage pioneer2dx driven by Player's ``nd`` driver towards the
RDP-simplified A* waypoints. ``NearnessDiagram`` is the method for a rectangular, non-holonomic
robot; ``NDDriver`` is what the Player driver adds around it (goal tolerance, minimum speeds, stuck
detection, giving up). Both are written from the paper and the driver's documented behaviour.

One control cycle, in the robot frame (x ahead, y left, angles counterclockwise, origin = rotation
centre):

1. *PND*: the obstacle points are binned into ``sectors`` angular sectors; each keeps its nearest
   point (distance, angle). A point inside the robot's rectangle is pushed out to 1 cm beyond it.
2. *Emergency stop*: a point in the cone of the two front corners, nearer than those corners.
3. *Gaps*: between neighbouring sectors where exactly one holds a point, or both do and their
   distances differ by at least the robot's width (``discontinuity``). Regions are the runs of
   sectors between two gaps; a gap *rises* into a region when the region's side is farther.
4. *Region selection*: the goal, when it is in sight (nearer than its sector's point) and the way
   to it is navigable; else the rising gaps, nearest to the goal's sector first, each tried with an
   intermediate goal in the gap (midway between its two points, or far out when the region's side
   is empty). Navigable (the free walking area): no point within half a robot width of the
   (intermediate) goal, and no two points on opposite sides of the way there closer than a robot
   width (the robot does not fit between them).
5. *RND and the five situations*: a sector's point is inside the security zone when its distance
   from the robot's perimeter is at most the security distance ``ds`` (``dsmin`` behind, growing to
   ``dsmax`` in front: the convex hull of discs on the rectangle's corners plus a frontal arc).
   None inside (high safety): HSGR goes to the goal, HSWR (a region wider than 90 deg) passes the
   gap's near point at half a robot width plus the frontal security distance, HSNR (narrow) takes
   the region's bisector. Inside on one side (low safety): LS1 (LSG towards the goal) turns away
   from the nearest point the deeper it is inside; on both sides: LS2 balances the two.
6. *Motion*: the direction, clipped to +-90 deg, gives ``v = vmax c cos(theta)``, ``w = wmax c
   sin(theta)`` with ``c = max(0.2, depth ratio of the nearest point)``; a front corner almost
   touching turns on the spot (or goes straight when both do); a rear corner about to sweep into
   a point behind stops the rotation.

Laser readings at the laser's maximum range are no obstacle here (empty sectors); Player's driver
turned every reading into a point. The driver gives up (the stall flag of its position2d device,
which the paper's monitors read) on an emergency stop, when no region is navigable, when the
method returns no motion, or after ``stuck_time`` without translating ``stuck_distance`` or turning
``stuck_angle``.
"""
from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np

FAR = 1e6  # distance of an intermediate goal in a gap whose region side is empty [m]


def wrap(a):
    """Angle(s) in [-pi, pi)."""
    return (a + np.pi) % (2 * np.pi) - np.pi


@dataclass(frozen=True)
class NDParams:
    """The method's numbers. ``player(...)`` derives them as Player's ``nd`` driver does."""

    front: float  # rotation centre to the front edge [m]
    back: float  # ... to the rear edge [m]
    left: float  # ... to either side [m]
    dsmax: float  # security distance in front [m]
    dsmin: float  # ... behind [m]
    enlarge: float  # tolerance of the sharp-turn and rear-sweep checks [m]
    discontinuity: float  # the width the robot needs: gap threshold and navigability [m]
    vmax: float  # [m/s]
    wmax: float  # [rad/s]
    almax: float = 0.75  # [m/s^2]
    aamax: float = 0.75  # [rad/s^2]
    period: float = 0.1  # control period [s]
    sectors: int = 180

    @classmethod
    def player(cls, length: float, width: float, origin_x: float, *, avoid_dist: float = 0.4,
               safety_dist: float = 0.0, max_speed: float = 0.3, max_turn_rate: float = math.radians(30.0),
               sectors: int = 180, period: float = 0.1) -> "NDParams":
        """Player's derivation: the rectangle of the base (``origin_x``: centre of area relative to
        the rotation centre) grown by ``safety_dist``; ``dsmax = avoid_dist``, ``dsmin = dsmax / 4``,
        ``enlarge = dsmin / 5``, ``discontinuity`` = the rectangle's width."""
        left = width / 2 + safety_dist
        dsmin = avoid_dist / 4
        return cls(front=length / 2 + origin_x + safety_dist, back=length / 2 - origin_x + safety_dist, left=left,
                   dsmax=avoid_dist, dsmin=dsmin, enlarge=0.2 * dsmin, discontinuity=2 * left,
                   vmax=max_speed, wmax=max_turn_rate, sectors=sectors, period=period)


@dataclass
class NDStep:
    """One cycle's output: speeds, the situation, the motion direction (robot frame)."""

    v: float
    w: float
    situation: str  # HSGR | HSWR | HSNR | LSG | LS1 | LS2 | emergency_stop | no_region
    direction: float = math.nan

    @property
    def stopped(self) -> bool:
        return self.situation in ("emergency_stop", "no_region")


class NearnessDiagram:
    """The method for one robot geometry; ``step(points, goal)`` is one control cycle."""

    def __init__(self, params: NDParams):
        p = self.p = params
        n = p.sectors
        if n < 8 or n % 4:
            raise ValueError("sectors: a multiple of 4, at least 8")
        self.n = n
        self.width = 2 * math.pi / n
        self.centres = wrap(np.arange(n) * self.width)
        cos_c, sin_c = np.cos(self.centres), np.sin(self.centres)
        # E: rotation centre to the rectangle's perimeter along each sector's bisector.
        with np.errstate(divide="ignore"):
            tx = np.where(cos_c > 1e-12, p.front / cos_c, np.where(cos_c < -1e-12, -p.back / cos_c, np.inf))
            ty = np.where(np.abs(sin_c) > 1e-12, p.left / np.abs(sin_c), np.inf)
        self.E = np.minimum(tx, ty)
        self.ds = self._security_distance(cos_c, sin_c)
        self.corner_dist = math.hypot(p.front, p.left)
        self.corner_angle = math.atan2(p.left, p.front)
        self.front_sector = 0
        self._next = (np.arange(n) + 1) % n

    def _security_distance(self, cos_c: np.ndarray, sin_c: np.ndarray) -> np.ndarray:
        """Perimeter-to-security-boundary distance per sector. The boundary is the convex hull of
        discs of radius ``dsmax`` on the front corners and ``dsmin`` on the rear ones, plus an arc
        of radius |front corner| + dsmax across the front cone; its distance along a bisector is
        the minimum of support / cos over the hull's normal directions."""
        p = self.p
        centres = np.array([[p.front, p.left], [p.front, -p.left], [-p.back, p.left], [-p.back, -p.left]])
        radii = np.array([p.dsmax, p.dsmax, p.dsmin, p.dsmin])
        arc_r = math.hypot(p.front, p.left) + p.dsmax
        arc_a = np.linspace(-math.atan2(p.left, p.front), math.atan2(p.left, p.front), 91)
        arc = arc_r * np.column_stack([np.cos(arc_a), np.sin(arc_a)])
        phi = np.linspace(-np.pi, np.pi, 1440, endpoint=False)
        u = np.column_stack([np.cos(phi), np.sin(phi)])
        support = np.maximum((u @ centres.T + radii).max(axis=1), (u @ arc.T).max(axis=1))
        cosines = cos_c[:, None] * u[None, :, 0] + sin_c[:, None] * u[None, :, 1]
        with np.errstate(divide="ignore"):
            rho = np.where(cosines > 1e-9, support[None, :] / cosines, np.inf).min(axis=1)
        return rho - self.E

    # --- helpers ----------------------------------------------------------------------------
    def sector_of(self, angle):
        return np.floor(np.asarray(angle) / self.width + 0.5).astype(np.int64) % self.n

    def _sector_gap(self, i: int, j: int) -> int:
        k = abs(i - j) % self.n
        return min(k, self.n - k)

    def diagram(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """PND: per sector the nearest point's distance (inf = empty) and angle (the sector's
        bisector when empty); points inside the rectangle are pushed 1 cm beyond its edge."""
        d = np.full(self.n, np.inf)
        a = self.centres.copy()
        if len(points):
            r = np.hypot(points[:, 0], points[:, 1])
            ang = np.arctan2(points[:, 1], points[:, 0])
            k = self.sector_of(ang)
            order = np.lexsort((r, k))
            ks = k[order]
            nearest = order[np.r_[True, ks[1:] != ks[:-1]]]
            d[k[nearest]] = r[nearest]
            a[k[nearest]] = ang[nearest]
        return np.where(np.isfinite(d), np.maximum(d, self.E + 0.01), d), a

    def _navigable(self, px: np.ndarray, py: np.ndarray, angle: float, dist: float) -> bool:
        """Free walking area to the (intermediate) goal at ``angle``/``dist``: no point within half
        a robot width of it, no left/right pair of points on the way closer than a robot width."""
        disc = self.p.discontinuity
        c, s = math.cos(angle), math.sin(angle)
        x = px * c + py * s
        y = py * c - px * s
        on_way = (x >= 0) & (x < dist) & (np.abs(y) <= disc)
        if not on_way.any():
            return True
        x, y = x[on_way], y[on_way]
        if np.any((x - dist) ** 2 + y * y < (disc / 2) ** 2):
            return False
        lft, rgt = y > 0, y <= 0
        if not (lft.any() and rgt.any()):
            return True
        dx = x[lft][:, None] - x[rgt][None, :]
        dy = y[lft][:, None] - y[rgt][None, :]
        return not bool(np.any(dx * dx + dy * dy < disc * disc))

    # --- one cycle ----------------------------------------------------------------------------
    def step(self, points: np.ndarray, goal: tuple[float, float], v_now: float = 0.0, w_now: float = 0.0) -> NDStep:
        """Speeds towards ``goal`` (robot frame) among ``points`` (robot frame, (M, 2))."""
        p, n = self.p, self.n
        d, a = self.diagram(np.asarray(points, dtype=float).reshape(-1, 2))
        occupied = np.isfinite(d)
        if np.any(occupied & (np.abs(a) <= self.corner_angle) & (d <= self.corner_dist)):
            return NDStep(0.0, 0.0, "emergency_stop")
        choice = self._select(d, a, occupied, goal)
        if choice is None:
            return NDStep(0.0, 0.0, "no_region")
        kind, direction, width, edge, bisector = choice

        # RND: depth of each sector's point inside the security zone (ratio dr / ds <= 1).
        dr = d - self.E
        inside = occupied & (dr <= self.ds)
        ratio = np.where(inside, dr / self.ds, np.inf)
        rel = wrap(a - direction)
        left_r = np.where(rel >= 0, ratio, np.inf)
        right_r = np.where(rel < 0, ratio, np.inf)
        il, ir = int(np.argmin(left_r)), int(np.argmin(right_r))
        has_l, has_r = bool(np.isfinite(left_r[il])), bool(np.isfinite(right_r[ir]))

        wide = width > n // 4
        if kind == "goal":
            base = direction
        elif wide:
            base = edge
        else:
            base = bisector
        if not has_l and not has_r:
            situation = "HSGR" if kind == "goal" else ("HSWR" if wide else "HSNR")
            theta = base
        elif has_l and has_r:
            situation = "LS2"
            cl, cr = float(ratio[il]), float(ratio[ir])
            k = (cl - cr) / (cl + cr)
            theta = direction + k * ((direction + math.pi / 2) if cl <= cr else (math.pi / 2 - direction))
        else:
            situation = "LSG" if kind == "goal" else "LS1"
            o = il if has_l else ir
            c = float(ratio[o])
            bound = base + float(wrap(a[o] + math.pi - base))  # straight away from the point
            theta = base * c + bound * (1 - c)
            theta = min(max(theta, -math.pi + 0.01), math.pi - 0.01)
        theta = float(wrap(theta))
        theta = min(max(theta, -math.pi / 2), math.pi / 2)

        cl = float(ratio[il]) if has_l else 1.0
        cr = float(ratio[ir]) if has_r else 1.0
        cv = max(0.2, min(cl, cr))
        v = min(max(p.vmax * cv * math.cos(theta), 0.0), p.vmax)
        w = min(max(p.wmax * cv * math.sin(theta), -p.wmax), p.wmax)
        if v < 1e-9:  # cos(+-pi/2) in floating point: a turn on the spot, not a crawl at min speed
            v = 0.0

        # Sharp turn: a front corner (almost) touching the nearest point on its side.
        reach = self.corner_dist + p.enlarge
        near_l = has_l and abs(a[il]) <= self.corner_angle and d[il] <= reach
        near_r = has_r and abs(a[ir]) <= self.corner_angle and d[ir] <= reach
        if near_l and near_r:
            w = 0.0
        elif near_l or near_r:
            v = 0.0

        # Rear sweep: turning would swing a rear corner into a point just behind it.
        rear = occupied & (np.abs(a) > math.pi / 2) & (dr <= p.enlarge / 2 + 1e-9)
        if rear.any():
            x, y = d[rear] * np.cos(a[rear]), d[rear] * np.sin(a[rear])
            on_left, on_right = bool(np.any(y >= p.left)), bool(np.any(y <= -p.left))
            behind = bool(np.any((y < p.left) & (y > -p.left) & (x <= -p.back)))
            if behind or (on_left and on_right) or (on_left and w < 0) or (on_right and w > 0):
                step_w = p.aamax * p.period
                if abs(w_now) > step_w:
                    w = w_now - math.copysign(step_w, w_now)
                    v = max(v_now - p.almax * p.period, 0.0)
                else:
                    v, w = p.vmax, 0.0
        v = min(max(v, 0.0), p.vmax)
        w = min(max(w, -p.wmax), p.wmax)
        return NDStep(v, w, situation, theta)

    def _select(self, d: np.ndarray, a: np.ndarray, occupied: np.ndarray, goal: tuple[float, float]):
        """The region to move through: (kind "goal" | "gap", direction, region width in sectors,
        edge angle for HSWR / wide LS1, the region's bisector for HSNR / narrow LS1), or None."""
        n, disc = self.n, self.p.discontinuity
        gx, gy = float(goal[0]), float(goal[1])
        g_dist, g_ang = math.hypot(gx, gy), math.atan2(gy, gx)
        sg = int(self.sector_of(g_ang))
        in_sight = (not occupied[sg]) or g_dist <= d[sg]
        px, py = d[occupied] * np.cos(a[occupied]), d[occupied] * np.sin(a[occupied])

        nxt = self._next
        both = occupied & occupied[nxt]
        jump = np.abs(np.where(both, d, 0.0) - np.where(both, d[nxt], 0.0))
        gaps = (occupied != occupied[nxt]) | (both & (jump >= disc))
        bounds = np.flatnonzero(gaps)  # gap b lies between sector b and b + 1
        if not len(bounds):
            if in_sight and self._navigable(px, py, g_ang, g_dist):
                return "goal", g_ang, n, g_ang, g_ang
            return None
        starts = (bounds + 1) % n
        ends = np.concatenate([bounds[1:], bounds[:1]])
        lengths = (ends - starts) % n + 1

        def region_of(s: int) -> int:
            return int(np.flatnonzero((s - starts) % n < lengths)[0])

        def bisector(j: int) -> float:
            return float(wrap((starts[j] + (lengths[j] - 1) / 2) * self.width))

        if in_sight and self._navigable(px, py, g_ang, g_dist):
            j = region_of(sg)
            return "goal", g_ang, int(lengths[j]), g_ang, bisector(j)

        # Rising gaps (inside sector farther than the outside one), nearest to the goal sector first.
        candidates = []
        for j in range(len(bounds)):
            for inner, outer, side in ((starts[j], (starts[j] - 1) % n, +1), (ends[j], (ends[j] + 1) % n, -1)):
                if occupied[outer] and (not occupied[inner] or d[inner] > d[outer]):
                    candidates.append((self._sector_gap(int(inner), sg), j, int(inner), int(outer), side))
        candidates.sort(key=lambda c: c[:3])
        for _, j, inner, outer, side in candidates:
            if occupied[inner]:
                mx = (d[inner] * math.cos(a[inner]) + d[outer] * math.cos(a[outer])) / 2
                my = (d[inner] * math.sin(a[inner]) + d[outer] * math.sin(a[outer])) / 2
                angle, dist = math.atan2(my, mx), math.hypot(mx, my)
            else:  # far out, between the empty sector's bisector and the outside point
                angle = float(wrap(a[outer] + wrap(self.centres[inner] - a[outer]) / 2))
                dist = d[outer] + FAR
            if self._navigable(px, py, angle, dist):
                # Pass the gap's near (outside) point at half a robot width plus the frontal
                # security distance, on the region's side (side +1: the point is on the right).
                edge = float(a[outer] + side * math.atan2(disc / 2 + self.ds[self.front_sector], d[outer]))
                return "gap", angle, int(lengths[j]), edge, bisector(j)
        return None


class NDDriver:
    """What Player's ``nd`` driver adds to the method.

    ``set_goal`` starts a goal (clears a previous give-up, restarts stuck detection); ``add_scan``
    buffers the last ``laser_buffer`` scans (world-frame points); ``command`` gives the velocity
    command for the robot's current pose. Within ``goal_tolerance`` of the goal it stops. It gives
    up (``gave_up`` names why; the driver's stall flag) on an emergency stop, with no navigable
    region, when the method returns no motion, or when the robot neither translated
    ``stuck_distance`` nor turned ``stuck_angle`` within ``stuck_time``; then it commands nothing
    until the next goal. Non-zero speeds are raised to the minimum speeds (a turn on the spot to
    ``min_turn_rate``).
    """

    def __init__(self, nd: NearnessDiagram, *, goal_tolerance: float = 0.1, min_speed: float = 0.1,
                 min_turn_rate: float = math.radians(10.0), stuck_time: float = 5.0, stuck_distance: float = 0.15,
                 stuck_angle: float = math.radians(10.0), laser_buffer: int = 2):
        self.nd = nd
        self.goal_tolerance = goal_tolerance
        self.min_speed, self.min_turn_rate = min_speed, min_turn_rate
        self.stuck_time, self.stuck_distance, self.stuck_angle = stuck_time, stuck_distance, stuck_angle
        self.scans: deque[np.ndarray] = deque(maxlen=max(1, int(laser_buffer)))
        self.goal: tuple[float, float] | None = None
        self.active = False
        self.gave_up: str | None = None
        self.situation = ""
        self._anchor = (0.0, 0.0, 0.0, 0.0)  # x, y, yaw, t

    def set_goal(self, goal: tuple[float, float], t: float, pose: tuple[float, float, float]) -> None:
        self.goal = (float(goal[0]), float(goal[1]))
        self.active, self.gave_up = True, None
        self._anchor = (pose[0], pose[1], pose[2], t)

    def add_scan(self, points_world: np.ndarray) -> None:
        self.scans.append(np.asarray(points_world, dtype=float).reshape(-1, 2))

    def _give_up(self, why: str) -> tuple[float, float]:
        self.active, self.gave_up, self.situation = False, why, why
        return 0.0, 0.0

    def command(self, t: float, pose: tuple[float, float, float], v_now: float = 0.0,
                w_now: float = 0.0) -> tuple[float, float]:
        if not self.active or self.goal is None:
            return 0.0, 0.0
        x, y, yaw = pose
        gx, gy = self.goal
        if math.hypot(gx - x, gy - y) < self.goal_tolerance:
            self.active, self.situation = False, "at_goal"
            return 0.0, 0.0
        ax, ay, ayaw, at = self._anchor
        if math.hypot(x - ax, y - ay) > self.stuck_distance or abs(float(wrap(yaw - ayaw))) > self.stuck_angle:
            self._anchor = (x, y, yaw, t)
        elif t - at > self.stuck_time:
            return self._give_up("no_progress")
        c, s = math.cos(yaw), math.sin(yaw)
        pts = np.concatenate(list(self.scans)) if self.scans else np.zeros((0, 2))
        rx, ry = pts[:, 0] - x, pts[:, 1] - y
        local = np.column_stack([rx * c + ry * s, ry * c - rx * s])
        dgx, dgy = gx - x, gy - y
        out = self.nd.step(local, (dgx * c + dgy * s, dgy * c - dgx * s), v_now, w_now)
        self.situation = out.situation
        if out.stopped:
            return self._give_up(out.situation)
        v, w = out.v, out.w
        if v == 0.0 and w == 0.0:
            return self._give_up("no_motion")
        if v != 0.0:
            v = min(max(v, self.min_speed), self.nd.p.vmax)
        else:
            w = math.copysign(min(max(abs(w), self.min_turn_rate), self.nd.p.wmax), w)
        return v, w


__all__ = ["NDDriver", "NDParams", "NDStep", "NearnessDiagram", "wrap"]
