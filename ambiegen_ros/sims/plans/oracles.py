"""Oracles for Nav2's global planners and smoothers: our own judgement of a path on Nav2's costmap.

A scenario is a costmap (read back from Nav2, or built by ``costmap.costmap_from_occupancy``), a
start, a goal and the planner's rules (``rules.PlannerRules``); the planner's answer is a path
(poses ``(N, 3)``: x, y, yaw; yaw may be NaN when the planner sets none) or an error. Nav2's own
checks are never trusted: each oracle recomputes from the cost array.

**The collision rule** (``pose_collisions``), the one no maintainer argues with:

* a pose whose centre lies in a LETHAL (254) cell (``Costmap2D::worldToMap``; a pose on a cell
  edge, as NavFn's corner-aligned poses are, counts only when every cell it touches is lethal);
* round robot: the robot's inscribed disc (the inscribed radius of Nav2's 16-gon,
  ``footprint.cpp`` ``makeFootprintFromRadius``/``calculateMinAndMaxDistances``; the radius
  behind the costmap's 253 ring, ``InflationLayer::computeCost``) holds the centre of a LETHAL
  cell, strictly, **and** the pose's own cell is INSCRIBED (253) or above, every cell it touches
  when it lies on a cell edge or corner. Both readings of "the centre in INSCRIBED or above" must
  agree: at the pose itself (a 253 cell is 253 because *its centre* is within the inscribed
  radius, and a pose near the far edge of such a cell may be clear of every lethal cell) and at
  its cell, as Nav2's own checkers read it (``Costmap2D::worldToMap``). A corner-aligned path
  (NavFn's, Smac 2D's: poses on the corners of the cells they checked) that comes a few
  millimetres inside the inscribed radius of a wall while in the cells the planner cleared is a
  half-cell offset, not a collision: the path holds, its clearance on the row (docs/planner_oracles.md);
* polygon robot: the oriented footprint's outline cells as Nav2 rasterises them
  (``FootprintCollisionChecker::footprintCost``: each vertex's cell and the Bresenham line between
  them, ``nav2_util::LineIterator``) include a LETHAL cell, or a vertex leaves the map (Nav2 scores
  that LETHAL), or a LETHAL cell's centre lies strictly inside the polygon.

Unknown space (255) is apart: a pose whose centre cell is 255 fails (``unknown_space``) only when
the planner's ``allow_unknown`` is false. INSCRIBED (253) alone is never a failure.

**Endpoints** (``check_endpoints``): the first pose within one cell (``resolution``) of the start:
NavFn starts on its rounded start corner (``NavFn::calcPath``), Smac on the start cell's centre,
both within ``resolution * sqrt(2) / 2``. The last pose within ``tolerance + resolution`` of the
goal, per axis for NavFn (its square search, ``NavfnPlanner::makePlan``), Euclidean for Smac
(``a_star.cpp``, in cells); the extra cell covers planners ending on a cell centre.

**Kinematics** (Hybrid-A* and Lattice, ``rules.min_turning_radius`` set): ``check_reversal`` flags a
segment whose displacement points more than 90 degrees away from the heading of the pose it leaves
(``reversing`` false: DUBIN, or Lattice without ``allow_reverse_expansion``). ``check_turning``
takes the radius of the circle through three consecutive poses (positions only: Smac's headings
are quantised to angle bins, and the last pose carries the goal's orientation), within one
driving direction (never across a cusp), skipping poses closer than half a cell to the previous
one. Hybrid-A*'s turning primitives are arcs of exactly the minimum radius (``node_hybrid.cpp``,
``HybridMotionTable::initDubin``: chord endpoints ``R sin a, R - R cos a``), and its analytic
expansions are Dubins/Reeds-Shepp curves of that radius, so three poses of a correct path lie on a
circle of radius >= R up to float32 rounding of cell coordinates (about 1e-5 m on a 0.07 m chord,
well under 1 % of R); the default tolerance, 2 %, leaves that margin twice over. Interpolated
primitives (``allow_primitive_interpolation``) have larger radii. The simple smoother is
documented to break feasibility (docs.nav2.org, Simple Smoother), so a smoothed path is checked
for collisions only.

**Failures** (``judge_failure``): an error is a failure only when the reference planner
(``reference.py``) finds a certificate under the same rules; a proof of absence makes it a correct
refusal; a goal outside the map makes any error correct (``GoalOutsideMapBounds``). For Hybrid and
Lattice a 2D reference path is a hint, not a certificate. A crash or hang is ``sut_crashed`` with
the server's stack trace; planning time over ``max_planning_time`` is a performance note, never a
failure.

**Through poses** (``vias``: Nav2's ``ComputePathThroughPoses``). Jazzy's ``planner_server``
(``PlannerServer::computePlanThroughPoses``) plans leg i from the *end pose* of the path so far to
via i ("to allow for path tolerance deviations") and joins the legs, dropping each later leg's
first pose. So such a path must start at the start and end at the goal (``check_endpoints``), come
within the tolerance of each via in order (``check_vias``: ``missed_via``, the same slack as the
goal's) and hold together (``check_gaps``: ``path_gap``, no step longer than ``max_step``). Every
other path oracle judges the whole joined path. A refusal is a finding only against
``reference.reference_through`` (leg by leg, with Jazzy's semantics); a via outside the map makes
any error right, as the goal does.

``judge_plan`` runs them in this order and returns every failure, the first one as the verdict:
crash; error (failure oracle); start, goal or a via outside the map (notes); empty path; endpoints;
vias; gaps; collision; unknown space; reversal; turning radius; smoother; then the performance note.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Optional, Sequence

import numpy as np
import shapely
from scipy.spatial import cKDTree

from .costmap import INSCRIBED, LETHAL, NO_INFORMATION, Costmap, footprint_from_radius, inscribed_radius
from .reference import ReferenceResult, reference_plan, reference_through
from .rules import PlannerRules

FAILURES = ("sut_crashed", "missed_path", "empty_path", "off_start", "off_goal", "collision",
            "unknown_space", "reversal", "tight_turn", "smoother_collision", "missed_via", "path_gap")
NOTES = ("pass", "performance", "goal_outside_map", "start_outside_map", "start_blocked",
         "correct_refusal", "undecided", "kinematic_hint")


@dataclass(frozen=True)
class PlanVerdict:
    """One oracle's finding: ``kind`` (``FAILURES`` or ``NOTES``), a one-line ``detail``, where."""

    kind: str
    detail: str
    index: Optional[int] = None  # the offending pose's index in the path
    cell: Optional[tuple[int, int]] = None  # the offending pose's cell (mx, my); a certificate's last cell
    evidence: Any = field(default=None, compare=False)  # lethal cells touched, a ReferenceResult, a stack trace

    @property
    def failed(self) -> bool:
        return self.kind in FAILURES


@dataclass
class PlanJudgement:
    """Every failure found, in ``judge_plan``'s order, and the notes; ``verdict`` is the first failure."""

    failures: list[PlanVerdict]
    notes: list[PlanVerdict]
    judged_from: int = 0  # the first pose the path oracles judged: those leaving a colliding start are not

    @property
    def failed(self) -> bool:
        return bool(self.failures)

    @property
    def verdict(self) -> PlanVerdict:
        if self.failures:
            return self.failures[0]
        return next((n for n in self.notes if n.kind != "performance"), PlanVerdict("pass", "the path holds"))


def as_poses(path: Sequence[Sequence[float]]) -> np.ndarray:
    """(N, 3) float array x, y, yaw from rows of (x, y) or (x, y, yaw); a missing yaw is NaN."""
    arr = np.asarray(path, dtype=float)
    if arr.size == 0:
        return np.zeros((0, 3))
    arr = arr.reshape(len(arr), -1)
    if arr.shape[1] == 2:
        arr = np.column_stack([arr, np.full(len(arr), np.nan)])
    return arr[:, :3]


def yaw_from_quaternion(x: float, y: float, z: float, w: float) -> float:
    """The yaw of a pose's orientation (Nav2's planners rotate about z only)."""
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


# --- collisions ------------------------------------------------------------------------------------------


class CollisionChecker:
    """The collision rule above, for one costmap and one robot (round, or a polygon)."""

    def __init__(self, costmap: Costmap, rules: PlannerRules):
        self.costmap = costmap
        self.rules = rules
        self.footprint = rules.footprint
        disc = footprint_from_radius(rules.robot_radius) if rules.footprint is None else rules.footprint
        self.inscribed = inscribed_radius(disc)
        ly, lx = np.nonzero(costmap.cost == LETHAL)
        self.lethal_cells = np.column_stack([lx, ly])
        self.lethal_xy = np.column_stack([costmap.origin_x + (lx + 0.5) * costmap.resolution,
                                          costmap.origin_y + (ly + 0.5) * costmap.resolution])
        self.tree = cKDTree(self.lethal_xy) if len(lx) else None

    def centre_lethal(self, x: float, y: float) -> Optional[tuple[int, int]]:
        """The lethal cell holding the pose's centre (every cell it touches lethal), else None."""
        cells = self.costmap.cells_at(x, y)
        if cells and all(self.costmap.cost[c[1], c[0]] == LETHAL for c in cells):
            return cells[0]
        return None

    def hits(self, pose: Sequence[float]) -> tuple[str, list[tuple[int, int]]]:
        """Why the pose collides ('' when it does not) and the lethal cells it touches."""
        x, y, yaw = float(pose[0]), float(pose[1]), float(pose[2])
        centre = self.centre_lethal(x, y)
        if self.footprint is None:
            cells = self._disc_hits(x, y)
            if centre is not None:
                return f"its centre is in lethal cell {centre}", sorted(set(cells) | {centre})
            if cells and self.in_inscribed_cells(x, y):
                d = math.hypot(*(np.array(self.costmap.map_to_world(*cells[0])) - (x, y)))
                return (f"lethal cell {cells[0]}'s centre is {d:.3f} m from it, inside the inscribed radius "
                        f"{self.inscribed:.3f} m, in a cell of cost >= {INSCRIBED}"), cells
            return "", []
        return self._polygon_hits(x, y, 0.0 if math.isnan(yaw) else yaw, centre)

    def in_inscribed_cells(self, x: float, y: float) -> bool:
        """Is every cell the pose lies in (two or four on an edge or corner) of cost INSCRIBED or above?"""
        cells = self.costmap.cells_at(x, y)
        return bool(cells) and all(INSCRIBED <= self.costmap.cost[c[1], c[0]] <= LETHAL for c in cells)

    def _disc_hits(self, x: float, y: float) -> list[tuple[int, int]]:
        if self.tree is None:
            return []
        idx = self.tree.query_ball_point((x, y), self.inscribed)
        near = [i for i in idx if math.hypot(self.lethal_xy[i, 0] - x, self.lethal_xy[i, 1] - y) < self.inscribed]
        return sorted(tuple(int(v) for v in self.lethal_cells[i]) for i in near)

    def oriented(self, x: float, y: float, yaw: float) -> np.ndarray:
        """``footprintCostAtPose``'s oriented polygon."""
        c, s = math.cos(yaw), math.sin(yaw)
        fp = np.asarray(self.footprint, dtype=float)
        return np.column_stack([x + fp[:, 0] * c - fp[:, 1] * s, y + fp[:, 0] * s + fp[:, 1] * c])

    def _polygon_hits(self, x: float, y: float, yaw: float,
                      centre: Optional[tuple[int, int]]) -> tuple[str, list[tuple[int, int]]]:
        poly = self.oriented(x, y, yaw)
        outline = outline_cells(self.costmap, poly)
        if outline is None:
            return "its footprint leaves the map (Nav2 scores that lethal)", []
        cm = self.costmap
        cells = {c for c in outline if cm.cost[c[1], c[0]] == LETHAL}
        why = f"its footprint's outline crosses lethal cell {min(cells)}" if cells else ""
        if self.tree is not None:
            lo, hi = poly.min(axis=0), poly.max(axis=0)
            box = np.flatnonzero(np.all((self.lethal_xy >= lo) & (self.lethal_xy <= hi), axis=1))
            if len(box):
                inside = shapely.contains_xy(shapely.Polygon(poly), self.lethal_xy[box, 0], self.lethal_xy[box, 1])
                inner = {tuple(int(v) for v in self.lethal_cells[i]) for i in box[inside]}
                if inner and not why:
                    why = f"lethal cell {min(inner)} lies inside its footprint"
                cells |= inner
        if centre is not None:
            why = f"its centre is in lethal cell {centre}"
            cells.add(centre)
        return why, sorted(cells)


def outline_cells(costmap: Costmap, polygon: np.ndarray) -> Optional[list[tuple[int, int]]]:
    """The cells ``FootprintCollisionChecker::footprintCost`` visits, or None if a vertex is off the map."""
    verts = [costmap.world_to_map(float(px), float(py)) for px, py in polygon]
    if any(v is None for v in verts):
        return None
    out: list[tuple[int, int]] = []
    for a, b in zip(verts, verts[1:] + verts[:1]):
        out.extend(bresenham(a[0], a[1], b[0], b[1]))
    return out


def bresenham(x0: int, y0: int, x1: int, y1: int) -> list[tuple[int, int]]:
    """``nav2_util::LineIterator``'s cells from (x0, y0) to (x1, y1), both ends included."""
    dx, dy = abs(x1 - x0), abs(y1 - y0)
    sx = 1 if x1 >= x0 else -1
    sy = 1 if y1 >= y0 else -1
    if dx >= dy:
        xinc1, yinc1, xinc2, yinc2, den, num, numadd, n = 0, sy, sx, 0, dx, dx // 2, dy, dx
    else:
        xinc1, yinc1, xinc2, yinc2, den, num, numadd, n = sx, 0, 0, sy, dy, dy // 2, dx, dy
    x, y, cells = x0, y0, []
    for _ in range(n + 1):
        cells.append((x, y))
        num += numadd
        if num >= den:
            num -= den
            x += xinc1
            y += yinc1
        x += xinc2
        y += yinc2
    return cells


def check_collisions(costmap: Costmap, poses: np.ndarray, rules: PlannerRules,
                     checker: Optional[CollisionChecker] = None, skip: int = 0) -> Optional[PlanVerdict]:
    """The first pose (from ``skip``) that collides, as a ``collision`` verdict; None when clear."""
    checker = checker or CollisionChecker(costmap, rules)
    for i in range(skip, len(poses)):
        why, cells = checker.hits(poses[i])
        if why:
            return PlanVerdict("collision", f"pose {i} at ({poses[i, 0]:.3f}, {poses[i, 1]:.3f}): {why}",
                               i, costmap.world_to_map(poses[i, 0], poses[i, 1]), evidence=cells)
    return None


def leaving_start(checker: CollisionChecker, poses: np.ndarray, start: Sequence[float]) -> int:
    """When the start itself collides, how many leading poses do: leaving it is not the planner's fault."""
    if not len(poses) or not checker.hits((start[0], start[1], poses[0, 2]))[0]:
        return 0
    n = 0
    while n < len(poses) and checker.hits(poses[n])[0]:
        n += 1
    return n if n < len(poses) else 0


def check_unknown(costmap: Costmap, poses: np.ndarray, rules: PlannerRules) -> Optional[PlanVerdict]:
    """The first pose whose centre cell is unknown (255) when the planner may not enter unknown space."""
    if rules.allow_unknown:
        return None
    for i, (x, y) in enumerate(poses[:, :2]):
        cell = costmap.world_to_map(x, y)
        if cell is not None and costmap.cost[cell[1], cell[0]] == NO_INFORMATION:
            return PlanVerdict("unknown_space", f"pose {i} at ({x:.3f}, {y:.3f}) is in unknown cell {cell} "
                               f"and {rules.name} has allow_unknown false", i, cell)
    return None


def _distance(a: Sequence[float], b: Sequence[float], metric: str) -> float:
    dx, dy = abs(a[0] - b[0]), abs(a[1] - b[1])
    return max(dx, dy) if metric == "square" else math.hypot(dx, dy)


def check_endpoints(costmap: Costmap, poses: np.ndarray, start: Sequence[float], goal: Sequence[float],
                    rules: PlannerRules) -> Optional[PlanVerdict]:
    """``empty_path``, ``off_start`` or ``off_goal`` (see the module docstring for the slack)."""
    if len(poses) == 0:
        return PlanVerdict("empty_path", "the planner reported success with a path of no poses")
    res = costmap.resolution
    d0 = math.hypot(poses[0, 0] - start[0], poses[0, 1] - start[1])
    if d0 > res:
        return PlanVerdict("off_start", f"the path starts {d0:.3f} m from the start (allowed {res:.3f} m)", 0,
                           costmap.world_to_map(poses[0, 0], poses[0, 1]))
    d1 = _distance(poses[-1], goal, rules.tolerance_metric)
    allowed = rules.tolerance + res
    if d1 > allowed:
        how = "per axis" if rules.tolerance_metric == "square" else "away"
        return PlanVerdict("off_goal", f"the path ends {d1:.3f} m {how} from the goal (tolerance {rules.tolerance} m "
                           f"+ one cell = {allowed:.3f} m)", len(poses) - 1,
                           costmap.world_to_map(poses[-1, 0], poses[-1, 1]))
    return None


def check_vias(costmap: Costmap, poses: np.ndarray, vias: Sequence[Sequence[float]],
               rules: PlannerRules) -> Optional[PlanVerdict]:
    """``missed_via``: the first via the path does not come within ``tolerance`` + one cell of (as
    the goal: per axis for NavFn) after it came within that of the via before. A leg of Jazzy's
    ends inside its via's tolerance and the next starts there, so such a pose exists, in order."""
    allowed = rules.tolerance + costmap.resolution
    at = 0
    for k, via in enumerate(vias):
        rest = poses[at:, :2]
        if rules.tolerance_metric == "square":
            d = np.max(np.abs(rest - np.asarray(via[:2], dtype=float)), axis=1)
        else:
            d = np.hypot(*(rest - np.asarray(via[:2], dtype=float)).T)
        hits = np.flatnonzero(d <= allowed)
        if len(hits):
            at += int(hits[0])
            continue
        near = at + int(np.argmin(d))  # a pose exists: the caller judged the ends of a path of poses
        after = "the start" if k == 0 else f"pose {at} (near via {k})"
        how = "per axis" if rules.tolerance_metric == "square" else "away"
        return PlanVerdict("missed_via", f"the path never comes within {allowed:.3f} m {how} of via {k + 1} at "
                           f"({via[0]:.3f}, {via[1]:.3f}) after {after}: at best {float(d.min()):.3f} m, pose {near} "
                           f"(tolerance {rules.tolerance} m + one cell)", near,
                           costmap.world_to_map(float(via[0]), float(via[1])))
    return None


HYBRID_BIN = 2.0 * math.pi / 72  # Smac Hybrid-A*'s default angle_quantization_bins: its primitives turn by multiples


def max_step(rules: PlannerRules, resolution: float) -> float:
    """The longest step between two poses of one planner's path, and of a join of two legs [m].

    Two diagonal cells (2 sqrt 2 cells): NavFn follows its gradient half a cell at a time, or the
    grid a cell (at most sqrt 2) at a time, and a leg's second pose lies within 0.71 + 1.41 cells of
    the end pose it starts from (``worldToMap`` rounds it to a corner); Theta*'s interpolation
    (``linearInterpolation``) leaves under 2 cells before each vertex; Smac 2D steps to a
    neighbouring cell, and Smac's analytic expansions are cut into pieces under 2 sqrt 2 cells. A
    Hybrid-A* primitive is a chord 2 R sin(a / 2) with a the first multiple of the angle bin whose
    chord passes sqrt 2 cells (``HybridMotionTable::initDubin``): under sqrt 2 cells + R times a bin."""
    step = 2.0 * math.sqrt(2.0) * resolution
    if rules.min_turning_radius is not None:
        step += rules.min_turning_radius * HYBRID_BIN
    return step


def check_gaps(costmap: Costmap, poses: np.ndarray, rules: PlannerRules) -> Optional[PlanVerdict]:
    """``path_gap``: the first step between consecutive poses longer than ``max_step``: a jump no
    leg of the planner makes (a join that did not start where the last leg ended, poses lost)."""
    if len(poses) < 2:
        return None
    steps = np.hypot(*np.diff(poses[:, :2], axis=0).T)
    bound = max_step(rules, costmap.resolution)
    bad = np.flatnonzero(steps > bound)
    if not len(bad):
        return None
    i = int(bad[0])
    return PlanVerdict("path_gap", f"poses {i} and {i + 1} lie {steps[i]:.3f} m apart, more than {rules.name} steps "
                       f"({bound:.3f} m) from ({poses[i, 0]:.3f}, {poses[i, 1]:.3f}) to ({poses[i + 1, 0]:.3f}, "
                       f"{poses[i + 1, 1]:.3f})", i, costmap.world_to_map(poses[i, 0], poses[i, 1]))


# --- kinematics (Hybrid-A*, Lattice) --------------------------------------------------------------------


def directions(poses: np.ndarray, min_step: float) -> tuple[np.ndarray, np.ndarray]:
    """Kept pose indices (each at least ``min_step`` from the last kept) and, per kept segment,
    +1 forward / -1 reverse against the heading of the pose it leaves (0 when the heading is unknown)."""
    keep = [0] if len(poses) else []
    for i in range(1, len(poses)):
        if math.hypot(*(poses[i, :2] - poses[keep[-1], :2])) >= min_step:
            keep.append(i)
    k = np.asarray(keep, dtype=np.int64)
    if len(k) < 2:
        return k, np.zeros(0)
    d = poses[k[1:], :2] - poses[k[:-1], :2]
    yaw = poses[k[:-1], 2]
    dot = d[:, 0] * np.cos(yaw) + d[:, 1] * np.sin(yaw)
    sign = np.where(np.isnan(yaw), 0.0, np.where(dot < 0, -1.0, 1.0))
    return k, sign


def check_reversal(poses: np.ndarray, rules: PlannerRules, min_step: Optional[float] = None,
                   resolution: float = 0.05) -> Optional[PlanVerdict]:
    """A segment driven backwards (more than 90 degrees off its heading) where reversing is off."""
    if rules.min_turning_radius is None or rules.reversing:
        return None
    keep, sign = directions(poses, 0.5 * resolution if min_step is None else min_step)
    back = np.flatnonzero(sign < 0)
    if not len(back):
        return None
    i = int(keep[back[0]])
    j = int(keep[back[0] + 1])
    d = poses[j, :2] - poses[i, :2]
    off = abs(math.degrees(math.remainder(math.atan2(d[1], d[0]) - poses[i, 2], 2 * math.pi)))
    return PlanVerdict("reversal", f"pose {i} at ({poses[i, 0]:.3f}, {poses[i, 1]:.3f}) drives backwards to pose {j} "
                       f"({off:.0f} deg off its heading) and {rules.name} may not reverse", i)


def circumradius(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Radius of the circle through three points, row-wise (inf when they are collinear)."""
    ab = np.hypot(*(b - a).T)
    bc = np.hypot(*(c - b).T)
    ca = np.hypot(*(a - c).T)
    cross = np.abs((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))
    with np.errstate(divide="ignore", invalid="ignore"):
        r = ab * bc * ca / (2.0 * cross)
    return np.where(cross > 0, r, np.inf)


def check_turning(poses: np.ndarray, rules: PlannerRules, rel_tol: float = 0.02,
                  resolution: float = 0.05) -> Optional[PlanVerdict]:
    """The first turn tighter than ``min_turning_radius * (1 - rel_tol)``, within one driving direction."""
    if rules.min_turning_radius is None or len(poses) < 3:
        return None
    keep, sign = directions(poses, 0.5 * resolution)
    if len(keep) < 3:
        return None
    a, b, c = poses[keep[:-2], :2], poses[keep[1:-1], :2], poses[keep[2:], :2]
    r = circumradius(a, b, c)
    same = sign[:-1] == sign[1:]  # no triple across a cusp
    limit = rules.min_turning_radius * (1.0 - rel_tol)
    bad = np.flatnonzero(same & (r < limit))
    if not len(bad):
        return None
    i = int(keep[bad[0] + 1])
    return PlanVerdict("tight_turn", f"the turn at pose {i} ({poses[i, 0]:.3f}, {poses[i, 1]:.3f}) has radius "
                       f"{r[bad[0]]:.3f} m, under the minimum {rules.min_turning_radius} m", i)


# --- smoothers, failures, crashes, time ------------------------------------------------------------------


def collision_cells(checker: CollisionChecker, poses: np.ndarray) -> dict[tuple[int, int], int]:
    """Every lethal cell a path touches, with the first pose touching it (or the pose's own cell
    when its footprint leaves the map)."""
    out: dict[tuple[int, int], int] = {}
    for i in range(len(poses)):
        why, cells = checker.hits(poses[i])
        if why and not cells:
            cells = [checker.costmap.world_to_map(*poses[i, :2]) or (-1, -1)]
        for c in cells:
            out.setdefault(c, i)
    return out


def check_smoother(costmap: Costmap, before: np.ndarray, after: np.ndarray,
                   rules: PlannerRules) -> Optional[PlanVerdict]:
    """A smoothed path touching a lethal cell that its input path did not touch."""
    checker = CollisionChecker(costmap, rules)
    old = collision_cells(checker, before)
    new = {c: i for c, i in collision_cells(checker, after).items() if c not in old}
    if not new:
        return None
    i = min(new.values())
    why = checker.hits(after[i])[0]
    return PlanVerdict("smoother_collision", f"smoothed pose {i} at ({after[i, 0]:.3f}, {after[i, 1]:.3f}): {why}; "
                       f"the input path {'was clear' if not old else 'touched other cells only'}", i,
                       costmap.world_to_map(after[i, 0], after[i, 1]), evidence=sorted(new))


def judge_failure(costmap: Costmap, rules: PlannerRules, start: Sequence[float], goal: Sequence[float],
                  error: str, reference: Optional[ReferenceResult] = None,
                  vias: Sequence[Sequence[float]] = ()) -> PlanVerdict:
    """A planner's error (NO_VALID_PATH, a timeout, any error): a failure only against a certificate
    (through ``vias``: the legs joined, ``reference_through``). Through poses Nav2 answers 303-306
    where it answers 203-206 to one pose; here as there the reference, not the code, decides."""
    if reference is None and vias:
        reference = reference_through(costmap, rules, (start[0], start[1]), vias, (goal[0], goal[1]))
    ref = reference or reference_plan(costmap, rules, (start[0], start[1]), (goal[0], goal[1]))
    said = f"{rules.name} answered {error!r}"
    if ref.status == "goal_outside":
        return PlanVerdict("goal_outside_map", f"{ref.detail}; {said}, which is right", evidence=ref)
    if ref.status == "start_outside":
        return PlanVerdict("start_outside_map", f"{ref.detail}; {said}, which is right", evidence=ref)
    if ref.status == "start_blocked":
        return PlanVerdict("start_blocked", f"{ref.detail}; {said}", evidence=ref)
    if ref.status == "absent":
        return PlanVerdict("correct_refusal", f"no path exists: {ref.detail}; {said}", evidence=ref)
    if ref.status == "undecided":
        return PlanVerdict("undecided", f"{ref.detail}; {said}", evidence=ref)
    end = (int(ref.cells[-1, 0]), int(ref.cells[-1, 1]))
    if rules.min_turning_radius is not None:
        return PlanVerdict("kinematic_hint", f"a 2D path exists ({ref.detail}) but {rules.name} must also turn no "
                           f"tighter than {rules.min_turning_radius} m: a hint, not a certificate; {said}",
                           cell=end, evidence=ref)
    return PlanVerdict("missed_path", f"{said} but the reference planner found {ref.detail}", cell=end, evidence=ref)


def crashed(server: str, trace: str = "") -> PlanVerdict:
    """FAIL(sut_crashed): a planner or smoother server that died or hung, with its stack trace."""
    first = next((line.strip() for line in trace.splitlines() if line.strip()), "no stack trace")
    return PlanVerdict("sut_crashed", f"{server} crashed or hung: {first}", evidence=trace)


def check_time(seconds: float, rules: PlannerRules) -> Optional[PlanVerdict]:
    """Planning time over the planner's own ``max_planning_time``: performance, never a failure."""
    if rules.max_planning_time is None or seconds <= rules.max_planning_time:
        return None
    return PlanVerdict("performance", f"{rules.name} took {seconds:.3f} s, over its max_planning_time "
                       f"{rules.max_planning_time} s")


def judge_plan(costmap: Costmap, rules: PlannerRules, start: Sequence[float], goal: Sequence[float], *,
               path: Optional[Sequence[Sequence[float]]] = None, error: Optional[str] = None,
               crash: Optional[tuple[str, str]] = None, planning_time: Optional[float] = None,
               smoothed: Optional[Sequence[Sequence[float]]] = None,
               vias: Sequence[Sequence[float]] = ()) -> PlanJudgement:
    """All the oracles on one answer, in the module docstring's order.

    ``path``: the planner's poses; ``error``: its error when it gave none; ``crash``: (server, stack
    trace) of a dead or hung server; ``smoothed``: the smoother's output for ``path``; ``vias``:
    the poses the path was asked through, in order (ComputePathThroughPoses), () for one goal.
    """
    failures: list[PlanVerdict] = []
    notes: list[PlanVerdict] = []
    skip = 0

    def add(v: Optional[PlanVerdict]) -> None:
        if v is not None:
            (failures if v.failed else notes).append(v)

    if crash is not None:
        add(crashed(*crash))
    elif error is not None or path is None:
        add(judge_failure(costmap, rules, start, goal, error or "no path", vias=vias))
    else:
        skip = _judge_path(costmap, rules, start, goal, as_poses(path), failures, notes, vias)
        if smoothed is not None:
            add(check_smoother(costmap, as_poses(path), as_poses(smoothed), rules))
    if planning_time is not None:
        add(check_time(planning_time, rules))
    return PlanJudgement(failures, notes, skip)


def _judge_path(costmap: Costmap, rules: PlannerRules, start: Sequence[float], goal: Sequence[float],
                poses: np.ndarray, failures: list[PlanVerdict], notes: list[PlanVerdict],
                vias: Sequence[Sequence[float]] = ()) -> int:
    """The path oracles, appending to ``failures`` and ``notes``; returns how many poses leaving a
    colliding start went unjudged."""
    for k, via in enumerate(vias):
        if costmap.world_to_map(*via[:2]) is None:
            notes.append(PlanVerdict("goal_outside_map", f"via {k + 1} ({via[0]:.3f}, {via[1]:.3f}) is outside "
                                     "the map"))
    if costmap.world_to_map(*goal[:2]) is None:
        notes.append(PlanVerdict("goal_outside_map", f"goal ({goal[0]:.3f}, {goal[1]:.3f}) is outside the map"))
    if costmap.world_to_map(*start[:2]) is None:
        notes.append(PlanVerdict("start_outside_map", f"start ({start[0]:.3f}, {start[1]:.3f}) is outside the map"))
    ends = check_endpoints(costmap, poses, start, goal, rules)
    if ends is not None:
        failures.append(ends)
    if not len(poses):
        return 0
    if len(vias):
        for v in (check_vias(costmap, poses, vias, rules), check_gaps(costmap, poses, rules)):
            if v is not None:
                failures.append(v)
    checker = CollisionChecker(costmap, rules)
    skip = leaving_start(checker, poses, start)
    if skip:
        notes.append(PlanVerdict("start_blocked", f"the start collides; poses 0-{skip - 1} leave it and are not judged"))
    for v in (check_collisions(costmap, poses, rules, checker, skip), check_unknown(costmap, poses, rules),
              check_reversal(poses, rules, resolution=costmap.resolution),
              check_turning(poses, rules, resolution=costmap.resolution)):
        if v is not None:
            failures.append(v)
    return skip
