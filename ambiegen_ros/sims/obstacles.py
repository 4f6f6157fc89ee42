"""Obstacles that are not on the occupancy grid: thin posts, boxes and walking people (ROS-free).

A grid cell is too coarse for a 5 cm post, and a person moves, so these obstacles are kept as
exact shapes beside the map: posts are static circles, boxes static axis-aligned rectangles, and
people circles that walk a polyline at constant speed. One ``Obstacles`` answers what the robot's
world and its judges ask of them, all in closed form:

* ``ray_ranges``: the laser (ray-circle and ray-rectangle slab intersections, all rays at once);
* ``body_clearance``: the convex body's signed distance to the nearest obstacle (<= 0: contact);
* ``static_distance`` and ``occupancy``: the static ones as a route planner sees them;
* ``robot_at_fault`` and ``contact_point``: who ran into whom, by the driving-scenario convention.

Touching counts as meeting everywhere: a ray that grazes a surface hits it, a body at distance 0
is in contact. Inputs are checked on construction and a bad one raises ``ScenarioError`` (a
``ValueError``) naming its field, so scenario files fail with a message, not with NaNs later.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..core.attributes import ScenarioError

KINDS = ("post", "box", "person")
"""The obstacle kinds, as ``body_clearance`` names them."""


def _finite_array(value: Any, name: str, columns: int) -> np.ndarray:
    """A read-only float copy of ``value`` as rows of ``columns`` numbers (empty -> (0, columns))."""
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError):  # ragged rows, or a word where a number belongs
        raise ScenarioError(name, f"expected rows of {columns} numbers") from None
    if arr.size == 0:
        arr = np.zeros((0, columns))
    if arr.ndim != 2 or arr.shape[1] != columns:
        raise ScenarioError(name, f"expected rows of {columns} numbers, got shape {arr.shape}")
    bad = ~np.isfinite(arr).all(axis=1)
    if bad.any():
        raise ScenarioError(f"{name}[{int(np.argmax(bad))}]", "non-finite number")
    arr.setflags(write=False)
    return arr


def _finite(value: Any, name: str) -> float:
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise ScenarioError(name, f"not a number: {value!r}") from None
    if not math.isfinite(number):
        raise ScenarioError(name, f"non-finite number {number}")
    return number


# --- people --------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class Person:
    """A person walking ``path`` at ``speed`` after standing at its start until ``delay``; after the
    end they stand at ``path[-1]`` for ever. Equal by value (``to_dict``)."""

    path: np.ndarray
    speed: float
    delay: float
    radius: float
    _arc: np.ndarray = field(init=False, repr=False)  # arc length at each path point

    def __post_init__(self):
        path = _finite_array(self.path, "path", 2)
        if len(path) < 2:
            raise ScenarioError("path", f"needs at least 2 points, got {len(path)}")
        arc = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(path, axis=0).T))])
        if arc[-1] <= 0.0:
            raise ScenarioError("path", "has zero length")
        speed, delay, radius = (_finite(getattr(self, n), n) for n in ("speed", "delay", "radius"))
        for name, number, ok, allowed in (("speed", speed, speed > 0, "> 0"), ("delay", delay, delay >= 0, ">= 0"),
                                          ("radius", radius, radius > 0, "> 0")):
            if not ok:
                raise ScenarioError(name, f"got {number}", allowed)
        arc.setflags(write=False)
        for name, value in (("path", path), ("speed", speed), ("delay", delay), ("radius", radius), ("_arc", arc)):
            object.__setattr__(self, name, value)

    @property
    def end_time(self) -> float:
        """When the person reaches ``path[-1]`` and stops."""
        return self.delay + float(self._arc[-1]) / self.speed

    def _walked(self, t) -> np.ndarray:
        return np.clip((np.asarray(t, dtype=float) - self.delay) * self.speed, 0.0, self._arc[-1])

    def position(self, t) -> np.ndarray:
        """(2,) for a scalar ``t``, (N, 2) for N times."""
        s = self._walked(t)
        return np.stack([np.interp(s, self._arc, self.path[:, 0]), np.interp(s, self._arc, self.path[:, 1])], axis=-1)

    def velocity(self, t) -> np.ndarray:
        """The velocity from ``t`` on (right-continuous: at a corner, the next segment's); zero while
        standing, before ``delay`` and from ``end_time`` on."""
        t = np.asarray(t, dtype=float)
        step = np.diff(self.path, axis=0)
        length = np.diff(self._arc)
        unit = np.divide(step, length[:, None], out=np.zeros_like(step), where=length[:, None] > 0)
        seg = np.clip(np.searchsorted(self._arc, self._walked(t), side="right") - 1, 0, len(step) - 1)
        moving = (t >= self.delay) & (t < self.end_time)
        return unit[seg] * (self.speed * moving)[..., None]

    def to_dict(self) -> dict:
        return {"path": self.path.tolist(), "speed": self.speed, "delay": self.delay, "radius": self.radius}

    @classmethod
    def from_dict(cls, d: dict) -> Person:
        _known_keys(d, ("path", "speed", "delay", "radius"), "person")
        return cls(path=d["path"], speed=d["speed"], delay=d.get("delay", 0.0), radius=d["radius"])

    def __eq__(self, other: object) -> bool:
        return type(other) is type(self) and self.to_dict() == other.to_dict()  # type: ignore[attr-defined]

    def __hash__(self) -> int:
        return hash(repr(self.to_dict()))


def _known_keys(d: dict, keys: tuple[str, ...], name: str) -> None:
    """A misspelt key in a scenario file is an error, not a silent default."""
    if not isinstance(d, dict):
        raise ScenarioError(name, f"expected an object, got {type(d).__name__}")
    unknown = sorted(set(d) - set(keys))
    if unknown:
        raise ScenarioError(name, f"unknown keys {unknown}", ", ".join(keys))


# --- geometry helpers ----------------------------------------------------------------------------
def placed_footprint(footprint: np.ndarray, x: float, y: float, yaw: float) -> np.ndarray:
    """The convex footprint (robot frame) at pose (x, y, yaw), counterclockwise in the map frame."""
    fp = np.asarray(footprint, dtype=float)
    if fp.ndim != 2 or fp.shape[1] != 2 or len(fp) < 3:
        raise ValueError(f"footprint: expected (n >= 3, 2) vertices, got shape {fp.shape}")
    if np.sum(fp[:, 0] * np.roll(fp[:, 1], -1) - np.roll(fp[:, 0], -1) * fp[:, 1]) < 0:
        fp = fp[::-1]  # clockwise given: the inside tests below want counterclockwise
    c, s = math.cos(yaw), math.sin(yaw)
    return np.stack([x + c * fp[:, 0] - s * fp[:, 1], y + s * fp[:, 0] + c * fp[:, 1]], axis=1)


def _nearest_on_polygon(qx: np.ndarray, qy: np.ndarray, poly: np.ndarray):
    """For each point: the nearest point of the convex counterclockwise polygon's boundary, and the
    signed distance to it (< 0 inside)."""
    e = np.roll(poly, -1, axis=0) - poly
    rx, ry = qx[:, None] - poly[:, 0], qy[:, None] - poly[:, 1]
    u = np.clip((rx * e[:, 0] + ry * e[:, 1]) / (e[:, 0] ** 2 + e[:, 1] ** 2), 0.0, 1.0)
    d = np.hypot(rx - u * e[:, 0], ry - u * e[:, 1])
    k = np.argmin(d, axis=1)
    rows = np.arange(len(qx))
    near = poly[k] + u[rows, k, None] * e[k]
    inside = np.all(e[:, 0] * ry - e[:, 1] * rx >= 0, axis=1)
    return near, np.where(inside, -d[rows, k], d[rows, k])


def _box_gaps(px, py, x0, y0, x1, y1):
    """How far outside the box a point lies along x and along y (0 within the slab); broadcasts, so
    many points against one box (scalar bounds: the fast case) or a few against many."""
    return np.maximum(np.maximum(x0 - px, px - x1), 0.0), np.maximum(np.maximum(y0 - py, py - y1), 0.0)


def _box_corners(boxes: np.ndarray) -> np.ndarray:
    """(B, 4, 2) corners, counterclockwise."""
    x0, y0, x1, y1 = boxes.T
    return np.stack([np.stack([x0, y0], -1), np.stack([x1, y0], -1), np.stack([x1, y1], -1),
                     np.stack([x0, y1], -1)], axis=1)


def _circle_clearances(poly: np.ndarray, circles: np.ndarray) -> np.ndarray:
    """Exact signed distance from the body to each circle: centre to polygon minus radius."""
    if len(circles) == 0:
        return np.zeros(0)
    return _nearest_on_polygon(circles[:, 0], circles[:, 1], poly)[1] - circles[:, 2]


def _box_clearances(poly: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """Exact signed distance from the body to each box.

    Separating axes (the body's edge normals and x, y) decide overlap, and the least overlap is the
    penetration depth; two separate convex polygons are nearest at a vertex of one, so the distance
    is the least of body vertices to the box and box corners to the body."""
    if len(boxes) == 0:
        return np.zeros(0)
    e = np.roll(poly, -1, axis=0) - poly
    axes = np.concatenate([np.stack([e[:, 1], -e[:, 0]], 1) / np.hypot(e[:, 0], e[:, 1])[:, None], np.eye(2)])
    corners = _box_corners(boxes)  # (B, 4, 2)
    body = poly @ axes.T  # (n, A)
    box = corners @ axes.T  # (B, 4, A)
    gap = np.maximum(box.min(axis=1) - body.max(axis=0), body.min(axis=0) - box.max(axis=1)).max(axis=1)
    gx, gy = _box_gaps(poly[:, 0, None], poly[:, 1, None], *boxes.T)  # (n, B)
    corners = corners.reshape(-1, 2)
    from_corners = np.abs(_nearest_on_polygon(corners[:, 0], corners[:, 1], poly)[1]).reshape(-1, 4).min(axis=1)
    dist = np.minimum(np.hypot(gx, gy).min(axis=0), from_corners)
    return np.where(gap < 0, gap, dist)


# --- the obstacles -------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class Obstacles:
    """Posts (P, 3: cx, cy, radius), boxes (B, 4: x0, y0, x1, y1) and people, in the map frame (metres).
    Equal by value (``to_dict``)."""

    posts: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    boxes: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)))
    people: tuple[Person, ...] = ()

    def __post_init__(self):
        posts = _finite_array(self.posts, "posts", 3)
        boxes = _finite_array(self.boxes, "boxes", 4)
        thin = posts[:, 2] <= 0
        if thin.any():
            raise ScenarioError(f"posts[{int(np.argmax(thin))}].radius", f"got {posts[thin][0, 2]}", "> 0")
        flat = (boxes[:, 0] >= boxes[:, 2]) | (boxes[:, 1] >= boxes[:, 3])
        if flat.any():
            raise ScenarioError(f"boxes[{int(np.argmax(flat))}]", f"got {boxes[flat][0].tolist()}",
                                "x0 < x1 and y0 < y1")
        people = tuple(self.people)
        for i, person in enumerate(people):
            if not isinstance(person, Person):
                raise ScenarioError(f"people[{i}]", f"expected a Person, got {type(person).__name__}")
        for name, value in (("posts", posts), ("boxes", boxes), ("people", people)):
            object.__setattr__(self, name, value)

    def empty(self) -> bool:
        return len(self.posts) == 0 and len(self.boxes) == 0 and not self.people

    def circles_at(self, t: float) -> np.ndarray:
        """(P + len(people), 3): the posts, then the people where they are at ``t``."""
        walkers = [[*p.position(t), p.radius] for p in self.people]
        return np.concatenate([self.posts, np.asarray(walkers, dtype=float).reshape(-1, 3)])

    def ray_ranges(self, x: float, y: float, angles, max_range: float, t: float) -> np.ndarray:
        """Distance along each ray (map-frame ``angles``) from (x, y) to the first obstacle surface at
        ``t``, ``np.inf`` where none lies within ``max_range``; 0 for a ray that starts inside one."""
        angles = np.asarray(angles, dtype=float)
        dx, dy = np.cos(angles).ravel()[:, None], np.sin(angles).ravel()[:, None]
        best = np.full(dx.shape[0], np.inf)
        circles = self.circles_at(t)
        if len(circles):  # |o + s d|^2 = r^2 with |d| = 1: s = -b -/+ sqrt(b^2 - c)
            ox, oy = x - circles[:, 0], y - circles[:, 1]
            b = ox * dx + oy * dy  # (R, C)
            c = ox * ox + oy * oy - circles[:, 2] ** 2
            disc = b * b - c
            near = -b - np.sqrt(np.maximum(disc, 0.0))
            s = np.where(c <= 0, 0.0, np.where((disc >= 0) & (b < 0), near, np.inf))
            best = np.minimum(best, s.min(axis=1))
        if len(self.boxes):  # slabs: the ray is inside both [x0, x1] and [y0, y1] for s in [enter, leave]
            x0, y0, x1, y1 = self.boxes.T
            enter_x, leave_x = _slab(x, dx, x0, x1)
            enter_y, leave_y = _slab(y, dy, y0, y1)
            enter, leave = np.maximum(enter_x, enter_y), np.minimum(leave_x, leave_y)
            s = np.where((enter <= leave) & (leave >= 0), np.maximum(enter, 0.0), np.inf)
            best = np.minimum(best, s.min(axis=1))
        return np.where(best <= max_range, best, np.inf).reshape(angles.shape)

    def body_clearance(self, x: float, y: float, yaw: float, footprint: np.ndarray,
                       t: float) -> tuple[float, tuple[str, int] | None]:
        """The body's signed distance to the nearest obstacle at ``t`` (< 0: penetration depth; <= 0
        is contact) and which one, ``("post"|"box"|"person", index)``; ``(inf, None)`` without any."""
        if self.empty():
            return math.inf, None
        poly = placed_footprint(footprint, x, y, yaw)
        P = len(self.posts)
        circles = _circle_clearances(poly, self.circles_at(t))
        values = np.concatenate([circles[:P], _box_clearances(poly, self.boxes), circles[P:]])
        best = int(np.argmin(values))
        k = best
        for kind, n in zip(KINDS, (P, len(self.boxes), len(self.people))):
            if k < n:
                return float(values[best]), (kind, k)
            k -= n
        raise AssertionError("unreachable")

    def static_distance(self, px, py) -> np.ndarray:
        """Distance from each point to the nearest post or box surface (0 inside; inf without any).

        A route planner asks this of a whole fine grid, so it is one pass per obstacle over all the
        points in two reused buffers (in place, and ``sqrt(x*x + y*y)`` rather than ``np.hypot``:
        4 times faster than plain expressions on 250,000 points)."""
        px, py = np.broadcast_arrays(np.asarray(px, dtype=float), np.asarray(py, dtype=float))
        out = np.full(px.shape, np.inf)
        a, b = np.empty(px.shape), np.empty(px.shape)
        for cx, cy, r in self.posts:
            np.subtract(px, cx, out=a)
            np.subtract(py, cy, out=b)
            _norm(a, b)
            a -= r
            np.minimum(out, a, out=out)
        for x0, y0, x1, y1 in self.boxes:  # the gap outside each slab: |p - centre| - half size, >= 0
            for buf, p, lo, hi in ((a, px, x0, x1), (b, py, y0, y1)):
                np.subtract(p, (lo + hi) / 2, out=buf)
                np.abs(buf, out=buf)
                buf -= (hi - lo) / 2
                np.maximum(buf, 0.0, out=buf)
            _norm(a, b)
            np.minimum(out, a, out=out)
        return np.maximum(out, 0.0, out=out)

    def occupancy(self, shape: tuple[int, int], resolution: float, origin: tuple[float, float] = (0.0, 0.0),
                  t: float | None = None) -> np.ndarray:
        """Bool grid ``[y, x]`` of the cells whose square shares area with a static obstacle (and with
        the people at ``t`` when ``t`` is given); a cell that only touches one stays free."""
        H, W = shape
        ox, oy = origin
        grid = np.zeros((H, W), dtype=bool)
        circles = self.circles_at(t) if t is not None else self.posts
        shapes = [(cx - r, cy - r, cx + r, cy + r, (cx, cy, r)) for cx, cy, r in circles]
        shapes += [(*box, None) for box in self.boxes]
        for x0, y0, x1, y1, circle in shapes:
            i0, i1 = max(math.floor((x0 - ox) / resolution), 0), min(math.ceil((x1 - ox) / resolution), W)
            j0, j1 = max(math.floor((y0 - oy) / resolution), 0), min(math.ceil((y1 - oy) / resolution), H)
            if i0 >= i1 or j0 >= j1:
                continue
            lo_x = ox + np.arange(i0, i1) * resolution  # the cells' low edges
            lo_y = oy + np.arange(j0, j1) * resolution
            if circle is None:
                cols, rows = (lo_x < x1) & (lo_x + resolution > x0), (lo_y < y1) & (lo_y + resolution > y0)
                grid[j0:j1, i0:i1] |= rows[:, None] & cols[None, :]
            else:
                cx, cy, r = circle
                gx = np.maximum(np.maximum(lo_x - cx, cx - lo_x - resolution), 0.0)
                gy = np.maximum(np.maximum(lo_y - cy, cy - lo_y - resolution), 0.0)
                grid[j0:j1, i0:i1] |= gy[:, None] ** 2 + gx[None, :] ** 2 < r * r
        return grid

    def shifted(self, dx: float, dy: float) -> Obstacles:
        """The same obstacles moved by (dx, dy) (into a frame whose origin lies elsewhere)."""
        d = np.array([dx, dy])
        return Obstacles(self.posts + [dx, dy, 0.0], self.boxes + [dx, dy, dx, dy],
                         tuple(Person(p.path + d, p.speed, p.delay, p.radius) for p in self.people))

    def nearest_static_m(self, point: tuple[float, float] | None) -> float | None:
        """How far ``point`` lies from the nearest post or box surface; None without either (or a point)."""
        if point is None or (len(self.posts) == 0 and len(self.boxes) == 0):
            return None
        return float(self.static_distance(point[0], point[1]))

    def to_dict(self) -> dict:
        """Plain JSON: lists of floats, people as ``Person.to_dict``."""
        return {"posts": self.posts.tolist(), "boxes": self.boxes.tolist(),
                "people": [p.to_dict() for p in self.people]}

    @classmethod
    def from_dict(cls, d: dict) -> Obstacles:
        _known_keys(d, ("posts", "boxes", "people"), "obstacles")
        people = []
        for i, p in enumerate(d.get("people", [])):
            try:
                people.append(Person.from_dict(p))
            except ScenarioError as exc:  # name the place in the file, not just the field
                raise ScenarioError(f"people[{i}].{exc.field}", exc.message, exc.allowed) from None
        return cls(posts=d.get("posts", []), boxes=d.get("boxes", []), people=tuple(people))

    def __eq__(self, other: object) -> bool:
        return type(other) is type(self) and self.to_dict() == other.to_dict()  # type: ignore[attr-defined]

    def __hash__(self) -> int:
        return hash(repr(self.to_dict()))


def _norm(a: np.ndarray, b: np.ndarray) -> None:
    """``a = sqrt(a^2 + b^2)`` in place (``b`` is spoilt)."""
    a *= a
    b *= b
    a += b
    np.sqrt(a, out=a)


def _slab(origin: float, direction: np.ndarray, lo: np.ndarray, hi: np.ndarray):
    """Where a ray (R, 1) is between ``lo`` and ``hi`` (B,) along one axis: (enter, leave), each (R, B);
    a ray parallel to the slab is in it everywhere or nowhere."""
    with np.errstate(divide="ignore", invalid="ignore"):
        a, b = (lo - origin) / direction, (hi - origin) / direction
    parallel = direction == 0
    inside = (lo <= origin) & (origin <= hi)
    enter = np.where(parallel, np.where(inside, -np.inf, np.inf), np.minimum(a, b))
    leave = np.where(parallel, np.where(inside, np.inf, -np.inf), np.maximum(a, b))
    return enter, leave


# --- who hit whom --------------------------------------------------------------------------------
CONTACT_SPEEDS = re.compile(r"moving at (?P<robot>-?[0-9.]+) m/s towards it \((?P<along>-?[0-9.]+) m/s along the line "
                            r"of contact; the person (?P<person>[-+]?[0-9.]+) m/s towards the robot\)")


def person_contact_detail(k: int, point, v: float, along: float, person_along: float) -> str:
    """The words of an at-fault contact with person ``k``: where, the robot's speed, and both speeds
    along the line of contact (robot centre to person centre; each positive towards the other).
    ``contact_speeds`` reads them back: one format, written and read here. ``v`` is signed (< 0:
    reversing), as the words always said."""
    return (f"the robot drove into person {k} at ({point[0]:.2f}, {point[1]:.2f}) moving at {v:.2f} m/s towards "
            f"it ({along:.2f} m/s along the line of contact; the person {person_along:+.2f} m/s towards the robot)")


def contact_speeds(detail: str | None) -> dict[str, float] | None:
    """``{"robot_mps", "robot_along_mps", "person_along_mps"}`` of a collision with a person, read
    from its detail (``person_contact_detail``); None for anything else (a wall, a pass, older logs)."""
    found = CONTACT_SPEEDS.search(detail or "")
    if found is None:
        return None
    return {"robot_mps": float(found["robot"]), "robot_along_mps": float(found["along"]),
            "person_along_mps": float(found["person"])}


def speeds_along(robot_xy, yaw: float, v: float, person_xy, person_velocity) -> tuple[float, float]:
    """(robot, person) speeds along the line between their centres, each positive towards the other."""
    dx, dy = np.asarray(person_xy, dtype=float) - np.asarray(robot_xy, dtype=float)
    norm = math.hypot(dx, dy) or 1.0
    ux, uy = dx / norm, dy / norm
    pvx, pvy = np.asarray(person_velocity, dtype=float)
    return v * (math.cos(yaw) * ux + math.sin(yaw) * uy), -(pvx * ux + pvy * uy)


def robot_at_fault(robot_xy, yaw: float, v: float, contact_xy, min_speed: float = 0.01) -> bool:
    """The driving-scenario convention: the robot is at fault only when it drives into the contact,
    moving (``|v| > min_speed``, ``v < 0`` reversing) with a velocity that has a positive component
    towards the contact point. Standing still or moving away, it was hit."""
    if abs(v) <= min_speed:
        return False
    dx, dy = np.asarray(contact_xy, dtype=float) - np.asarray(robot_xy, dtype=float)
    towards = math.copysign(1.0, v) * (math.cos(yaw) * dx + math.sin(yaw) * dy)
    return bool(towards > 1e-9 * math.hypot(dx, dy))  # a contact abeam (cos(pi/2) = 6e-17) is not ahead


def contact_point(x: float, y: float, yaw: float, footprint: np.ndarray, obstacle_kind: str, index: int,
                  obstacles: Obstacles, t: float) -> np.ndarray:
    """The point of the obstacle's surface nearest the body at ``t`` (what the fault rule aims at).

    Where the body overlaps the obstacle every overlapping surface point is at distance 0, and the
    one nearest the robot's rotation centre (x, y) is taken: it lies on the side the body came from."""
    if obstacle_kind not in KINDS:
        raise ValueError(f"obstacle_kind: {obstacle_kind!r} is not one of {KINDS}")
    count = {"post": len(obstacles.posts), "box": len(obstacles.boxes), "person": len(obstacles.people)}[obstacle_kind]
    if not 0 <= index < count:
        raise ValueError(f"index: {index} is out of range for {count} {obstacle_kind}(s)")
    poly = placed_footprint(footprint, x, y, yaw)
    centre = np.array([x, y], dtype=float)
    if obstacle_kind == "box":
        box = obstacles.boxes[index:index + 1]
        if _box_clearances(poly, box)[0] < 0:
            return _nearest_on_box_surface(centre, box[0])
        gx, gy = _box_gaps(poly[:, 0, None], poly[:, 1, None], *box.T)
        corners = _box_corners(box)[0]
        from_corners = np.abs(_nearest_on_polygon(corners[:, 0], corners[:, 1], poly)[1])
        k = int(np.argmin(np.hypot(gx[:, 0], gy[:, 0])))
        if np.hypot(gx[k, 0], gy[k, 0]) <= from_corners.min():
            return np.clip(poly[k], box[0, :2], box[0, 2:])
        return corners[int(np.argmin(from_corners))].copy()
    if obstacle_kind == "post":
        c, r = obstacles.posts[index, :2], obstacles.posts[index, 2]
    else:
        c, r = obstacles.people[index].position(t), obstacles.people[index].radius
    near, signed = _nearest_on_polygon(c[:1], c[1:], poly)
    target = near[0] if signed[0] - r >= 0 else centre
    toward = target - c
    norm = math.hypot(*toward)
    direction = toward / norm if norm > 0 else np.array([math.cos(yaw), math.sin(yaw)])
    return c + r * direction


def _nearest_on_box_surface(point: np.ndarray, box: np.ndarray) -> np.ndarray:
    """The point of the rectangle's boundary nearest ``point`` (inside: straight out through the nearest side)."""
    inner = np.clip(point, box[:2], box[2:])
    if not np.array_equal(inner, point):
        return inner
    out = [point[0] - box[0], box[2] - point[0], point[1] - box[1], box[3] - point[1]]
    side = int(np.argmin(out))
    result = point.copy()
    result[side // 2] = box[[0, 2, 1, 3][side]]  # x0, x1, y0, y1
    return result


__all__ = ["KINDS", "Obstacles", "Person", "contact_point", "contact_speeds", "person_contact_detail", "placed_footprint",
           "robot_at_fault", "speeds_along"]
