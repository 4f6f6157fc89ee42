"""Robot scenarios with what breaks real navigation stacks (issue 48): ``scenario: hazards``.

The paper's robot scenario is a static map that the robot is given whole, with a fixed start and
goal. Real stacks fail on what that leaves out. A *hazards* scenario keeps the paper's 48 wall
rows (in ``/map`` and in the world) and adds, as more elements of the same matrix:

* **start** and **goal**: a cell inside the configured area (``start_area``, ``goal_area``; never
  walled) and a yaw (``heading``, 15 degree steps): a goal behind the robot, a turn in an aisle;
* **box** and **post**: static obstacles that are in the world but **not in the map** the stack is
  given (an axis-aligned square box of 0.3-1.0 m, a thin post of 5-20 cm);
* **person**: a disc (radius 0.20-0.35 m) walking a straight path of ``2 x person_reach`` metres
  at a constant ``speed`` (0.3-1.5 m/s), starting after ``delay`` seconds; it stands at its first
  point before and at its last point after. People follow their script and do not react to the
  robot: a run is reproducible, as DynaBARN's moving obstacles are, and the fault rule
  (``sims.obstacles.robot_at_fault``) decides who caused a contact.

Hazards are placed **relative to the route** the robot would take on the map it is given (the A*
route on the mapped walls, ``placement_route``): ``along`` is the share of that route's length
(0-100 %), ``offset`` the distance to its left (decimetres; negative = right). A box or post sits
there; a person's path passes through that point, walking at ``heading`` degrees from the route's
direction (0 = ahead of the robot, 180 = towards it, 90 = crossing from right to left). So a random
hazard is near the route, where a stack meets it, and the search can move it along and across.

Elements, in this order: 48 walls (``type`` horizontal | vertical, ``size``, ``position``, as the
paper's), the start, the goal, then 0..``max_hazards`` hazards. Every element has every attribute
(one matrix); a kind ignores the others, and ``canonical`` sets them to one value. ``extent`` is the
hazard's size as a share of its kind's range (0-100 %).

**Vias** (issue 68, Nav2's ``ComputePathThroughPoses``): ``min_vias..max_vias`` rows of kind
``via`` (a cell of ``via_area`` and a yaw, as the start and goal) after the goal, flown through in
the order they stand; hazards may stand among them (a crossover mixes the two lists) and
``canonical`` puts the vias first. A planner stack asks for a path start -> vias -> goal; a stack
that drives (Nav2's navigator, our ND robot) is given the start and the goal only, and hazards stay
on the start -> goal route. The code 7 comes after every older kind, so old files and genomes
decode unchanged; ``max_vias: 0`` (the default) draws no random number more than before.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from ..core.attributes import Categorical, FloatInterval, IntRange

TYPES = ("horizontal", "vertical", "start", "goal", "box", "post", "person", "via")  # append only: codes are stored
HORIZONTAL, VERTICAL, START, GOAL, BOX, POST, PERSON, VIA = range(8)
HAZARD_KINDS = (BOX, POST, PERSON)
MIN_WALK = 0.5  # a person's path between the walls is at least this long [m]
N_WALLS = 48
START_ROW, GOAL_ROW, FIRST_HAZARD = N_WALLS, N_WALLS + 1, N_WALLS + 2
TYPE, SIZE, POSITION, ROW, ALONG, OFFSET, HEADING, EXTENT, SPEED, DELAY = range(10)

ATTRIBUTES = (
    Categorical("type", TYPES),
    IntRange("size", 5, 15, 1, tolerance=2, unit="m"),  # walls
    IntRange("position", 1, 48, 1, tolerance=2, unit="m"),  # walls: x of the centre; start/goal/via: x cell
    IntRange("row", 1, 48, 1, tolerance=2, unit="m"),  # start/goal/via: y cell
    IntRange("along", 0, 100, 5, tolerance=10, unit="% of the route"),  # hazards
    IntRange("offset", -25, 25, 1, tolerance=3, unit="dm left of the route"),  # hazards
    IntRange("heading", 0, 345, 15, tolerance=30, unit="deg"),  # start/goal/via yaw; person: from the route
    IntRange("extent", 0, 100, 10, tolerance=20, unit="% of the kind's size range"),  # hazards
    FloatInterval("speed", 0.3, 1.5, tolerance=0.2, unit="m/s"),  # person
    FloatInterval("delay", 0.0, 60.0, tolerance=10.0, unit="s"),  # person
)
# the value every kind gives the cells it ignores (``canonical``)
IGNORED = {TYPE: None, SIZE: 5.0, POSITION: 1.0, ROW: 1.0, ALONG: 0.0, OFFSET: 0.0, HEADING: 0.0, EXTENT: 0.0,
           SPEED: 0.3, DELAY: 0.0}
USED = {
    HORIZONTAL: (SIZE, POSITION), VERTICAL: (SIZE, POSITION),
    START: (POSITION, ROW, HEADING), GOAL: (POSITION, ROW, HEADING),
    BOX: (ALONG, OFFSET, EXTENT), POST: (ALONG, OFFSET, EXTENT),
    PERSON: (ALONG, OFFSET, HEADING, EXTENT, SPEED, DELAY),
    VIA: (POSITION, ROW, HEADING),
}


@dataclass(frozen=True)
class HazardSettings:
    """The hazards' numbers (``RobotConfig`` fields of the same names)."""

    start_area: tuple  # ((x0, y0), (x1, y1)) cells, inclusive
    goal_area: tuple
    max_hazards: int
    box_side: tuple  # (min, max) m
    post_diameter: tuple
    person_radius: tuple
    person_reach: float  # a person walks this far on each side of its point on the route [m]
    clear_of_ends: float  # a hazard keeps this far from the start and goal centres [m]
    min_vias: int = 0  # vias (``via``) per scenario, at least and at most
    max_vias: int = 0

    @classmethod
    def of(cls, config: Any) -> "HazardSettings":
        return cls(**{f: getattr(config, f) for f in cls.__dataclass_fields__})


def area_of(config: Any, name: str) -> tuple[tuple[int, int], tuple[int, int]]:
    """``start_area`` / ``goal_area`` / ``via_area`` as two cells; the goal's default: ``goal`` +- 2
    cells; the vias': the room inside its border."""
    area = getattr(config, name)
    n = config.map_size - 2
    if area is None and name == "via_area":
        area = ((1, 1), (n, n))
    elif area is None:
        cx, cy = config.goal if name == "goal_area" else config.start
        area = ((max(1, cx - 2), max(1, cy - 2)), (min(n, cx + 2), min(n, cy + 2)))
    (x0, y0), (x1, y1) = area
    return (int(x0), int(y0)), (int(x1), int(y1))


def areas_mask(config: Any, margin: int) -> np.ndarray:
    """(H, W) True on the start and goal areas grown by ``margin`` cells: never walled."""
    n = config.map_size
    ys, xs = np.mgrid[0:n, 0:n]
    mask = np.zeros((n, n), dtype=bool)
    for name in ("start_area", "goal_area"):
        (x0, y0), (x1, y1) = area_of(config, name)
        mask |= (xs >= x0 - margin) & (xs <= x1 + margin) & (ys >= y0 - margin) & (ys <= y1 + margin)
    return mask


def lerp(lo_hi: Sequence[float], share: float) -> float:
    return float(lo_hi[0] + (lo_hi[1] - lo_hi[0]) * share)


# --- the route hazards are placed on ------------------------------------------------------------
@dataclass
class PlacementRoute:
    """A polyline (K, 2) m with its cumulative arc length; ``point`` / ``tangent`` at a share."""

    points: np.ndarray
    arc: np.ndarray = field(init=False)

    def __post_init__(self):
        self.points = np.asarray(self.points, dtype=float).reshape(-1, 2)
        steps = np.hypot(*np.diff(self.points, axis=0).T) if len(self.points) > 1 else np.zeros(0)
        self.arc = np.concatenate([[0.0], np.cumsum(steps)])

    @property
    def length(self) -> float:
        return float(self.arc[-1])

    def at(self, share: float) -> tuple[np.ndarray, np.ndarray]:
        """The point at ``share`` of the length and the unit direction of travel there."""
        if len(self.points) < 2 or self.length <= 0:
            return self.points[0].copy(), np.array([1.0, 0.0])
        s = min(max(share, 0.0), 1.0) * self.length
        k = int(min(np.searchsorted(self.arc, s, side="right") - 1, len(self.points) - 2))
        seg = self.points[k + 1] - self.points[k]
        norm = math.hypot(*seg) or 1.0
        f = (s - self.arc[k]) / norm
        return self.points[k] + f * seg, seg / norm


def rotate(v: np.ndarray, degrees: float) -> np.ndarray:
    a = math.radians(degrees)
    c, s = math.cos(a), math.sin(a)
    return np.array([c * v[0] - s * v[1], s * v[0] + c * v[1]])


# --- one scenario's hazards in the world ---------------------------------------------------------
@dataclass
class HazardLayout:
    """What a hazards genome says, in metres: poses and the unmapped obstacles."""

    start: tuple[int, int]
    goal: tuple[int, int]
    start_yaw: float  # radians
    goal_yaw: float
    hazards: list[dict[str, Any]]  # one dict per hazard: kind and its numbers in metres / seconds
    vias: list[tuple[int, int]] = field(default_factory=list)  # cells, in the order flown through
    via_yaws: list[float] = field(default_factory=list)  # radians


def decode(cells: np.ndarray, length: int, settings: HazardSettings) -> HazardLayout:
    """The start, goal, vias and hazards of one genome ``(m_max, 10)`` (walls are ``build_grids``')."""
    start, goal = cells[START_ROW], cells[GOAL_ROW]
    hazards = []
    for row in cells[FIRST_HAZARD:length]:
        kind = int(round(row[TYPE]))
        if kind == VIA:
            continue
        share = float(row[EXTENT]) / 100.0
        size = {BOX: settings.box_side, POST: settings.post_diameter, PERSON: settings.person_radius}.get(kind)
        hazards.append({
            "kind": TYPES[kind], "along": float(row[ALONG]) / 100.0, "offset": float(row[OFFSET]) / 10.0,
            "heading": float(row[HEADING]), "size": lerp(size, share) if size else 0.0,
            "speed": float(row[SPEED]), "delay": float(row[DELAY]),
        })
    rows = via_rows(cells, length)
    return HazardLayout((int(start[POSITION]), int(start[ROW])), (int(goal[POSITION]), int(goal[ROW])),
                        math.radians(float(start[HEADING])), math.radians(float(goal[HEADING])), hazards,
                        [(int(cells[i, POSITION]), int(cells[i, ROW])) for i in rows],
                        [math.radians(float(cells[i, HEADING])) for i in rows])


def via_rows(cells: np.ndarray, length: int) -> list[int]:
    """The rows of the vias, in the order they are flown through."""
    kinds = np.rint(cells[FIRST_HAZARD:length, TYPE]).astype(int)
    return (FIRST_HAZARD + np.flatnonzero(kinds == VIA)).tolist()


def obstacles_on(route: PlacementRoute, layout: HazardLayout, settings: HazardSettings, grid: np.ndarray,
                 resolution: float):
    """The unmapped obstacles placed on ``route`` (``sims.obstacles.Obstacles.to_dict``'s parts):
    posts ``(P, 3)``, boxes ``(B, 4)`` and people (path, speed, delay, radius).

    A person walks up to ``person_reach`` on each side of its point, and stops short of a mapped
    wall (its path is cut where the disc would touch one): people walk in the free space."""
    posts, boxes, people = [], [], []
    for h in layout.hazards:
        point, tangent = route.at(h["along"])
        normal = rotate(tangent, 90.0)
        centre = point + h["offset"] * normal
        if h["kind"] == "post":
            posts.append((centre[0], centre[1], h["size"] / 2.0))
        elif h["kind"] == "box":
            half = h["size"] / 2.0
            boxes.append((centre[0] - half, centre[1] - half, centre[0] + half, centre[1] + half))
        else:
            way = rotate(tangent, h["heading"])
            back, ahead = (free_reach(grid, resolution, centre, sign * way, h["size"], settings.person_reach)
                           for sign in (-1.0, 1.0))
            people.append({"path": [(centre - back * way).tolist(), (centre + ahead * way).tolist()],
                           "speed": h["speed"], "delay": h["delay"], "radius": h["size"]})
    return (np.asarray(posts, dtype=float).reshape(-1, 3), np.asarray(boxes, dtype=float).reshape(-1, 4), people)


def free_reach(grid: np.ndarray, resolution: float, origin: np.ndarray, direction: np.ndarray, radius: float,
               reach: float, step: float = 0.05) -> float:
    """How far a disc of ``radius`` moves from ``origin`` along ``direction`` before it would touch
    a mapped wall, at most ``reach`` [m] (0 when it touches one at the origin)."""
    s = np.arange(0.0, reach + 1e-9, step)
    clear = wall_distance(grid, resolution, origin + s[:, None] * direction) >= radius
    if clear.all():
        return float(reach)
    first = int(np.argmin(clear))
    return float(s[first - 1]) if first > 0 else 0.0


# --- what a hazard does to the route (issue 49: the search's features) --------------------------
PASSING_GAP = 0.40
"""The room a stack needs to squeeze past a standing person [m]: the pioneer's body is 0.38 m wide.
Measured on Jazzy's MPPI (16 block probes, docs/results/nav2/mppi_gives_up_blocked.md): it failed
or needed 12 and more recoveries where the room beside the person was 0.34 m or less, and got by
where it was 0.42 m or more. (The patient reference, which keeps 0.36 m from both sides, needs
0.72 m: it waits wherever MPPI is stopped.)"""
OPEN_GAP = 1.0  # a gap this wide beside a standing person does not narrow the way at all [m]
BLOCK_S = 30.0  # a block this long after the robot comes scores in full (Nav2's recoveries run out in about this) [s]


def wrap(angle: float) -> float:
    return (angle + math.pi) % (2 * math.pi) - math.pi


def way_round(grid: np.ndarray, resolution: float, layout: HazardLayout, route: PlacementRoute, arc: float) -> bool:
    """Whether the mapped walls leave a route from start to goal with the route's cell at ``arc``
    walled up (coarse: the map's free cells, side by side, as a planner would look when a person
    shuts the way there)."""
    from scipy.ndimage import label

    q, _ = route.at(arc / route.length if route.length > 0 else 0.0)
    cx, cy = int(q[0] // resolution), int(q[1] // resolution)
    (sx, sy), (gx, gy) = layout.start, layout.goal
    if (cx, cy) in ((sx, sy), (gx, gy)):
        return False
    free = ~np.asarray(grid, dtype=bool)
    free[cy, cx] = False
    parts, _ = label(free)
    return bool(parts[sy, sx] and parts[sy, sx] == parts[gy, gx])


def closure(route: PlacementRoute, near: tuple[float, float], grid: np.ndarray, resolution: float,
            point: np.ndarray, radius: float) -> float:
    """How far a person standing at ``point`` (``near``: its distance to the route and the route's arc
    length there) shuts the way at that route point: 1 when the room left between the walls and their
    disc is under ``PASSING_GAP`` on both sides (no robot gets by there), falling to 0 at
    ``OPEN_GAP``; 0 when they stand off the route. Local: a way round elsewhere on the map is not
    looked for (``sims.reference.robot`` plans the true one)."""
    dist, arc = near
    if dist > radius + 1.0:
        return 0.0
    q, tangent = route.at(arc / route.length if route.length > 0 else 0.0)
    normal = rotate(tangent, 90.0)
    side = float((point - q) @ normal)  # the person's offset to the left of the route
    left = free_reach(grid, resolution, q, normal, 0.01, 3.0) - (side + radius)
    right = free_reach(grid, resolution, q, -normal, 0.01, 3.0) - (radius - side)
    return min(max((OPEN_GAP - max(left, right)) / (OPEN_GAP - PASSING_GAP), 0.0), 1.0)


def features(route: PlacementRoute, layout: HazardLayout, posts: np.ndarray, boxes: np.ndarray, people: list[dict],
             grid: np.ndarray | None = None, resolution: float = 1.0, speed: float = 0.5) -> dict[str, float]:
    """Numbers of one scenario a stack's failures may follow (issue 49):

    * ``static_gap_m``: how close the nearest unmapped box or post comes to the route (its surface;
      negative = on it); ``person_meet_s``: how near in time a person is to the point of the route
      where the robot is when it gets there (driving the route at ``speed``);
      ``start_turn_rad`` / ``goal_turn_rad``: how far the start and goal yaw turn from the route's
      first and last leg; ``person_approach_mps``: of the people who meet the robot within 5 s, the
      fastest closing speed, their speed times (1 - cos) / 2 of their heading against the route's
      (head-on = their speed, crossing = half, walking ahead = 0): MPPI's collisions with people
      were head-on or crossing at 1.0-1.3 m/s (docs/results/nav2/mppi_hazards_search.md);
    * with ``grid``, ``person_block_s``: how long a person still stands where they shut the way
      (``closure`` 1, before they walk off) once the robot gets there, and ``block``: their
      ``closure`` times that time over ``BLOCK_S`` (the best of them): a passage a person blocks for
      a while, where a patient robot waits and Nav2's default tree may give up (#2596, #2877);
    * with ``grid`` (the mapped walls), ``threat``: their sum as a search climbs it, each weighed
      by how narrow the place is (``narrowness``: 1 where the walls leave the robot no room beside
      the route, 0.5 in the open): an obstacle on the route, a person meeting the robot there, a goal
      turned away from the last leg. Heuristic, from what we measured (MPPI's near misses at goals
      turned away; docs/results/nav2/mppi_hazards.md) and what Nav2's issues report (obstacles and
      people in narrow aisles).
    """
    pts = route.points
    if len(pts) < 2:
        return {}
    seg_a, seg_b = pts[:-1], pts[1:]
    d = seg_b - seg_a
    length2 = np.maximum((d ** 2).sum(axis=1), 1e-12)

    def to_route(q: np.ndarray) -> tuple[float, float]:
        """(distance from q to the route, the route's arc length at its nearest point)."""
        t = np.clip(((q - seg_a) * d).sum(axis=1) / length2, 0.0, 1.0)
        near = seg_a + t[:, None] * d
        dist = np.hypot(*(near - q).T)
        k = int(np.argmin(dist))
        return float(dist[k]), float(route.arc[k] + t[k] * math.sqrt(length2[k]))

    def narrow(arc: float) -> float:
        if grid is None:
            return 0.0
        q, _ = route.at(arc / route.length if route.length > 0 else 0.0)
        room = float(wall_distance(grid, resolution, q[None])[0])
        return 0.5 + 0.5 * min(max(1.0 - (room - 0.36) / 1.0, 0.0), 1.0)

    static, static_threat = [], 0.0
    shapes = [(np.array([x, y]), r) for x, y, r in posts]
    shapes += [(np.array([(x0 + x1) / 2, (y0 + y1) / 2]), math.hypot(x1 - x0, y1 - y0) / 2) for x0, y0, x1, y1 in boxes]
    for centre, reach in shapes:
        dist, arc = to_route(centre)
        static.append(dist - reach)
        static_threat = max(static_threat, min(max(1.0 - (dist - reach) / 0.5, 0.0), 1.0) * narrow(arc))
    meet, person_threat, approach = [], 0.0, 0.0
    for person in people:
        a, b = np.asarray(person["path"], dtype=float)
        walk = math.hypot(*(b - a))
        best, at = math.inf, 0.0
        for f in np.linspace(0.0, 1.0, 21):  # along its path: when it is there, and when the robot is
            q = a + f * (b - a)
            dist, arc = to_route(q)
            if dist > person["radius"] + 0.5:
                continue
            gap = abs(person["delay"] + f * walk / person["speed"] - arc / speed)
            if gap < best:
                best, at = gap, arc
        meet.append(best)
        if best <= 5.0:
            _, tangent = route.at(at / route.length if route.length > 0 else 0.0)
            heading = float((b - a) @ tangent) / (walk or 1.0)
            approach = max(approach, person["speed"] * (1.0 - heading) / 2.0)
        if math.isfinite(best):
            person_threat = max(person_threat,
                                min(max(1.0 - best / 5.0, 0.0), 1.0) * narrow(at) * person["speed"] / 1.5)
    block_s, block = 0.0, 0.0
    if grid is not None:
        for person in people:
            a, b = np.asarray(person["path"], dtype=float)
            if closure(route, to_route(b), grid, resolution, b, person["radius"]) >= 1.0:
                continue  # where it ends it stands for good: no robot gets by (an invalid test)
            near = to_route(a)
            shut = closure(route, near, grid, resolution, a, person["radius"])
            if shut >= 1.0 and way_round(grid, resolution, layout, route, near[1]):
                shut = 0.5  # the way shut here, but the map has another one
            left = person["delay"] - near[1] / speed  # how long it still stands there when the robot comes
            if shut >= 1.0:
                block_s = max(block_s, left)
            block = max(block, shut * min(max(left / BLOCK_S, 0.0), 1.0))
    first, last = pts[1] - pts[0], pts[-1] - pts[-2]
    goal_turn = abs(wrap(layout.goal_yaw - math.atan2(last[1], last[0])))
    out = {
        "static_gap_m": float(min(static)) if static else math.inf,
        "person_meet_s": float(min(meet)) if meet else math.inf,
        "start_turn_rad": abs(wrap(layout.start_yaw - math.atan2(first[1], first[0]))),
        "goal_turn_rad": goal_turn,
        "person_approach_mps": approach,
        "person_block_s": block_s,
        "block": block,
    }
    if grid is not None:
        out["threat"] = static_threat + person_threat + goal_turn / math.pi * narrow(route.length)
    return out


# --- sampling, validity, canonical form ----------------------------------------------------------
def sample(walls_G: np.ndarray, config: Any, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Hazard genomes around sampled wall rows ``(n, 48, 3)``: start and goal uniform in their
    areas with any yaw, 0..max_hazards hazards of uniform kind and attributes; with ``max_vias``,
    min_vias..max_vias vias uniform in ``via_area`` before the hazards (drawn after everything
    else, so a config without vias samples what it always did)."""
    n = len(walls_G)
    settings = HazardSettings.of(config)
    m_max = FIRST_HAZARD + settings.max_hazards
    G = np.zeros((n, m_max, len(ATTRIBUTES)))
    G[:, :N_WALLS, :3] = walls_G[:, :N_WALLS, :3]
    for row, (name, kind) in ((START_ROW, ("start_area", START)), (GOAL_ROW, ("goal_area", GOAL))):
        (x0, y0), (x1, y1) = area_of(config, name)
        G[:, row, TYPE] = kind
        G[:, row, POSITION] = rng.integers(x0, x1 + 1, n)
        G[:, row, ROW] = rng.integers(y0, y1 + 1, n)
        G[:, row, HEADING] = ATTRIBUTES[HEADING].sample(rng, n)
    count = rng.integers(0, settings.max_hazards + 1, n)
    hz = G[:, FIRST_HAZARD:]
    hz[:, :, TYPE] = rng.choice(HAZARD_KINDS, size=(n, settings.max_hazards))
    for j in (ALONG, OFFSET, HEADING, EXTENT, SPEED, DELAY):
        hz[:, :, j] = ATTRIBUTES[j].sample(rng, (n, settings.max_hazards))
    lengths = FIRST_HAZARD + count
    if settings.max_vias:
        G, lengths = _with_vias(G, lengths, config, settings, rng)
    return canonical(G, lengths)


def _with_vias(G: np.ndarray, lengths: np.ndarray, config: Any, settings: HazardSettings,
               rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """``G`` widened by ``max_vias`` rows, each genome's vias (uniform count, cell and yaw) between
    its goal and its hazards."""
    n, top = len(G), settings.max_vias
    count = rng.integers(settings.min_vias, top + 1, n)
    (x0, y0), (x1, y1) = area_of(config, "via_area")
    V = np.zeros((n, top, G.shape[2]))
    V[:, :, TYPE] = VIA
    V[:, :, POSITION] = rng.integers(x0, x1 + 1, (n, top))
    V[:, :, ROW] = rng.integers(y0, y1 + 1, (n, top))
    V[:, :, HEADING] = ATTRIBUTES[HEADING].sample(rng, (n, top))
    out = np.zeros((n, G.shape[1] + top, G.shape[2]))
    out[:, :FIRST_HAZARD] = G[:, :FIRST_HAZARD]
    for i in range(n):
        k, h = int(count[i]), int(lengths[i]) - FIRST_HAZARD
        out[i, FIRST_HAZARD:FIRST_HAZARD + k] = V[i, :k]
        out[i, FIRST_HAZARD + k:FIRST_HAZARD + k + h] = G[i, FIRST_HAZARD:FIRST_HAZARD + h]
    return out, lengths + count


def canonical(G: np.ndarray, lengths: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Cells a kind ignores set to one value (walls' ``row`` etc.), padding zeroed; vias moved before
    the hazards, in their own order (where the hazards stand among them changes nothing)."""
    G = np.asarray(G, dtype=float).copy()
    kinds = np.rint(G[:, :, TYPE]).astype(int)
    for kind, used in USED.items():
        mask = kinds == kind
        for j, value in IGNORED.items():
            if value is not None and j not in used:
                G[:, :, j][mask] = value
    for i in np.flatnonzero((kinds[:, FIRST_HAZARD:] == VIA).any(axis=1)):
        m = int(lengths[i])
        order = np.argsort(kinds[i, FIRST_HAZARD:m] != VIA, kind="stable")
        G[i, FIRST_HAZARD:m] = G[i, FIRST_HAZARD:m][order]
    return G, lengths


def kind_reason(cells: np.ndarray, length: int, config: Any) -> str | None:
    """Why a genome's elements are not walls, start, goal and then vias and hazards, or outside
    their areas, or more or fewer than the config allows (None: fine)."""
    kinds = np.rint(cells[:length, TYPE]).astype(int)
    if length < FIRST_HAZARD:
        return f"hazards: {length} elements, need {N_WALLS} walls, the start and the goal"
    bad = np.flatnonzero(~np.isin(kinds[:N_WALLS], (HORIZONTAL, VERTICAL)))
    if len(bad):
        return f"hazards: elements[{bad[0]}] must be a wall (horizontal|vertical), not {TYPES[kinds[bad[0]]]}"
    for row, kind, name in ((START_ROW, START, "start_area"), (GOAL_ROW, GOAL, "goal_area")):
        if kinds[row] != kind:
            return f"hazards: elements[{row}] must be the {TYPES[kind]}, not {TYPES[kinds[row]]}"
        (x0, y0), (x1, y1) = area_of(config, name)
        x, y = int(cells[row, POSITION]), int(cells[row, ROW])
        if not (x0 <= x <= x1 and y0 <= y <= y1):
            return f"hazards: the {TYPES[kind]} ({x}, {y}) lies outside {name} ({x0}, {y0})..({x1}, {y1})"
    lo, hi = int(getattr(config, "min_vias", 0)), int(getattr(config, "max_vias", 0))
    tail = kinds[FIRST_HAZARD:]
    bad = np.flatnonzero(~np.isin(tail, HAZARD_KINDS + ((VIA,) if hi else ())))
    if len(bad):
        i = FIRST_HAZARD + bad[0]
        return f"hazards: elements[{i}] must be a {'via, ' if hi else ''}box, post or person, not {TYPES[kinds[i]]}"
    vias = int((tail == VIA).sum())
    if len(tail) - vias > int(config.max_hazards):
        return f"hazards: {len(tail) - vias} hazards, at most {config.max_hazards} (max_hazards)"
    if not lo <= vias <= hi:
        return f"hazards: {vias} vias, need {lo}..{hi} (min_vias..max_vias)"
    (x0, y0), (x1, y1) = area_of(config, "via_area")
    for k, i in enumerate(via_rows(cells, length)):
        x, y = int(cells[i, POSITION]), int(cells[i, ROW])
        if not (x0 <= x <= x1 and y0 <= y <= y1):
            return f"hazards: via {k + 1} ({x}, {y}) lies outside via_area ({x0}, {y0})..({x1}, {y1})"
    return None


# --- evaluation and environment ------------------------------------------------------------------
def wall_distance(grid: np.ndarray, resolution: float, pts: np.ndarray) -> np.ndarray:
    """Distance from points (N, 2) m to the nearest wall cell's square within 2 cells (capped
    there; off the grid counts as wall): enough to say whether a disc crosses a wall."""
    grid = np.asarray(grid, dtype=bool)
    H, W = grid.shape
    pts = np.asarray(pts, dtype=float).reshape(-1, 2)
    cx = np.floor(pts[:, 0] / resolution).astype(np.int64)
    cy = np.floor(pts[:, 1] / resolution).astype(np.int64)
    off = np.arange(-2, 3)
    gx, gy = cx[:, None, None] + off[None, None, :], cy[:, None, None] + off[None, :, None]
    inside = (gx >= 0) & (gx < W) & (gy >= 0) & (gy < H)
    wall = ~inside | grid[np.clip(gy, 0, H - 1), np.clip(gx, 0, W - 1)]
    dx = np.maximum(np.abs(pts[:, 0, None, None] - (gx + 0.5) * resolution) - 0.5 * resolution, 0.0)
    dy = np.maximum(np.abs(pts[:, 1, None, None] - (gy + 0.5) * resolution) - 0.5 * resolution, 0.0)
    return np.where(wall, np.hypot(dx, dy), 2.0 * resolution).min(axis=(1, 2))


def placement_reason(layout: HazardLayout, posts: np.ndarray, boxes: np.ndarray, people: list[dict],
                     settings: HazardSettings, resolution: float) -> str | None:
    """Why hazards placed on the route break the scenario's rules, or None: nothing on the start
    or goal (obstacles and standing people keep ``clear_of_ends`` from their centres), and every
    person has room to walk (``MIN_WALK``; ``obstacles_on`` stops its path short of the walls)."""
    ends = {"start": (np.asarray(layout.start) + 0.5) * resolution, "goal": (np.asarray(layout.goal) + 0.5) * resolution}
    keep = settings.clear_of_ends
    for name, c in ends.items():
        for k, (x, y, r) in enumerate(posts):
            if math.hypot(x - c[0], y - c[1]) - r < keep:
                return f"hazards: post {k} lies within {keep:g} m of the {name}"
        for k, (x0, y0, x1, y1) in enumerate(boxes):
            if math.hypot(max(x0 - c[0], 0.0, c[0] - x1), max(y0 - c[1], 0.0, c[1] - y1)) < keep:
                return f"hazards: box {k} lies within {keep:g} m of the {name}"
        for k, person in enumerate(people):
            for end in (person["path"][0], person["path"][-1]):
                if math.hypot(end[0] - c[0], end[1] - c[1]) - person["radius"] < keep:
                    return f"hazards: person {k} stands within {keep:g} m of the {name}"
    for k, person in enumerate(people):
        a, b = np.asarray(person["path"][0]), np.asarray(person["path"][-1])
        if math.hypot(*(b - a)) < MIN_WALK:
            return f"hazards: person {k} has no room to walk (its point lies against a wall)"
    return None


# --- search operators: kinds stay in their places ------------------------------------------------
def mutate(G: np.ndarray, lengths: np.ndarray, rng: np.random.Generator, config: Any) -> None:
    """One change per genome, in place: re-draw one attribute its element uses (a wall's type
    between the two wall types, a hazard's among the three hazards; the start, goal or a via one
    cell within its area), or add or drop a hazard; with ``max_vias``, also add, drop or swap vias
    (rolls a config without vias never makes: its genomes mutate as they always did)."""
    max_hazards = int(config.max_hazards)
    vias_on = bool(int(getattr(config, "max_vias", 0)))
    for i in range(len(G)):
        m = int(lengths[i])
        tail = np.rint(G[i, FIRST_HAZARD:m, TYPE]).astype(int) == VIA
        n_hazards = int((~tail).sum())
        roll = rng.random()
        if roll < 0.1 and n_hazards < max_hazards:  # a new hazard, uniform
            G[i, m] = 0.0
            G[i, m, TYPE] = rng.choice(HAZARD_KINDS)
            for j in (ALONG, OFFSET, HEADING, EXTENT, SPEED, DELAY):
                G[i, m, j] = ATTRIBUTES[j].sample(rng, 1)[0]
            lengths[i] = m + 1
            continue
        if roll < 0.2 and n_hazards:  # drop one hazard
            k = int(rng.integers(FIRST_HAZARD, m)) if not tail.any() else \
                FIRST_HAZARD + int(rng.choice(np.flatnonzero(~tail)))
            _drop_row(G[i], k, m)
            lengths[i] = m - 1
            continue
        if vias_on and 0.2 <= roll < 0.35 and _move_vias(G[i], lengths, i, roll, rng, config):
            continue
        e = int(rng.integers(0, m))
        kind = int(round(G[i, e, TYPE]))
        choices = list(USED[kind]) + ([TYPE] if kind not in (START, GOAL, VIA) else [])
        j = int(rng.choice(choices))
        if j == TYPE:
            pool = (HORIZONTAL, VERTICAL) if kind in (HORIZONTAL, VERTICAL) else HAZARD_KINDS
            G[i, e, TYPE] = rng.choice([k for k in pool if k != kind])
        elif kind in (START, GOAL, VIA) and j in (POSITION, ROW):
            area = {START: "start_area", GOAL: "goal_area", VIA: "via_area"}[kind]
            (x0, y0), (x1, y1) = area_of(config, area)
            lo, hi = (x0, x1) if j == POSITION else (y0, y1)
            G[i, e, j] = float(rng.integers(lo, hi + 1))
        else:
            old = G[i, e, j]
            for _ in range(20):
                new = float(ATTRIBUTES[j].sample(rng, 1)[0])
                if new != old:
                    break
            G[i, e, j] = new


def _drop_row(cells: np.ndarray, k: int, m: int) -> None:
    """Row ``k`` of a genome of ``m`` rows taken out, the rows after it moved up."""
    cells[k:m - 1] = cells[k + 1:m].copy()
    cells[m - 1] = 0.0


def _move_vias(cells: np.ndarray, lengths: np.ndarray, i: int, roll: float, rng: np.random.Generator,
               config: Any) -> bool:
    """``roll`` in [0.2, 0.25): a new via (uniform in ``via_area``) at a random place among them;
    [0.25, 0.3): one via dropped; [0.3, 0.35): two neighbouring vias swapped (the order flown
    changes). False when the counts allow none of that: the caller re-draws an attribute."""
    m = int(lengths[i])
    vias = FIRST_HAZARD + np.flatnonzero(np.rint(cells[FIRST_HAZARD:m, TYPE]).astype(int) == VIA)
    if roll < 0.25 and len(vias) < int(config.max_vias):
        at = int(rng.integers(FIRST_HAZARD, m + 1))
        cells[at + 1:m + 1] = cells[at:m].copy()
        (x0, y0), (x1, y1) = area_of(config, "via_area")
        cells[at] = 0.0
        cells[at, TYPE], cells[at, POSITION], cells[at, ROW] = VIA, rng.integers(x0, x1 + 1), rng.integers(y0, y1 + 1)
        cells[at, HEADING] = ATTRIBUTES[HEADING].sample(rng, 1)[0]
        lengths[i] = m + 1
        return True
    if 0.25 <= roll < 0.3 and len(vias) > int(getattr(config, "min_vias", 0)):
        _drop_row(cells, int(rng.choice(vias)), m)
        lengths[i] = m - 1
        return True
    if roll >= 0.3 and len(vias) >= 2:
        k = int(rng.integers(0, len(vias) - 1))
        a, b = vias[k], vias[k + 1]
        cells[[a, b]] = cells[[b, a]]
        return True
    return False


__all__ = ["ATTRIBUTES", "BOX", "FIRST_HAZARD", "GOAL", "GOAL_ROW", "HAZARD_KINDS", "HazardLayout", "HazardSettings",
           "N_WALLS", "PERSON", "POST", "PlacementRoute", "START", "START_ROW", "TYPES", "VIA", "area_of", "areas_mask",
           "canonical", "decode", "features", "kind_reason", "mutate", "obstacles_on",
           "free_reach", "placement_reason", "sample", "via_rows", "wall_distance"]
