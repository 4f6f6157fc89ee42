"""Mobile-robot obstacle map (paper 5.2): walls on a 50 x 50 m grid; F1 = A* path length.

Representation: element ``i`` describes row (the replication code's "level") ``y = i + 1``, one
wall per element (``type`` horizontal/vertical, ``size`` in m, ``position`` = x of its centre), so
R1 (one obstacle per element) holds by construction. The border is always wall. Grids are ``[y, x]``.

Two fidelity profiles (``RobotConfig.profile``); each number below is a Config field whose default
follows the profile, except the two rules marked *rule*, which follow the profile itself:

============================  =====================================  =====================================
                              ``refined`` (paper + project spec)     ``replication`` (authors' code)
============================  =====================================  =====================================
elements / position domain    48 (rows 1..48) / 1..48                1..49 (its generator draws 49, rows
                                                                     1..49) / 1..49
wall extent (*rule*)          cells with ``|c - centre| <= s / 2``   ``|c - centre| <= round(s/2) - 1``,
                              (even ``s`` gives ``s + 1`` cells)     Python's round-half-to-even
                                                                     (5 -> 3 cells, 9 -> 7, 15 -> 15)
where walls may lie           the interior (``free_band`` 0)         ``0 < x, y < 46``: a free 3-cell band
                                                                     along the top/right (``free_band`` 3)
start / goal (R2)             never walled within ``keep_out`` 1     the cell itself (``keep_out`` 0); see
                              (cell and its 8 neighbours)            below
diagonal steps                both orthogonal neighbours free        always, also between two blocked
                              (``diagonal`` "both_free")             cells (``diagonal`` "always")
robot radius (*rule*)         blocks cells whose square the disc     blocks cells whose centre is within
                              overlaps                               the radius of a wall cell's centre
============================  =====================================  =====================================

With the default 0.5 m radius on 1 m cells neither radius rule inflates anything (one robot = one
cell). F1 is the optimal path length in both: the replication code's PythonRobotics A* (Euclidean
heuristic, consistent with the 1 / sqrt(2) costs) returns an optimal path and scores the length of
the polyline through it, which is that path's cost. No path = invalid, F1 = 0. With
``objective: narrow`` (issue 29, a search aimed at Nav2) F1 is instead ``narrow_route_metres``.

The replication code may wall the robot's start cell (32 of the 300 reference maps); its planner
never checks the start, so the robot simply leaves it. Here the start cell stays free in the map
instead (``keep_out`` 0): the same lengths and verdicts (a shortest path never re-enters its
start), but the map that is published and driven never puts the robot inside a wall. As there,
the planner ignores the start cell also when a larger radius inflates walls over it.

Speed: ``astar`` (heapq, Euclidean heuristic, the paper's planner) is kept for single maps (the
path drawn in plots and sent to ROS). For a batch, F1 only needs the optimal *length*, which A*
with a consistent heuristic returns exactly as Dijkstra does. ``batch_path_lengths`` runs a
numba-compiled Dijkstra per map that stops at the goal; without numba (``engine="numpy"``) it
builds one block-diagonal CSR graph of ~32 maps with numpy and makes one
``scipy.sparse.csgraph.dijkstra(min_only=True)`` call from their start nodes. Both give the same
floats (tests check it). On 2,000 sampled maps the compiled planner is ~5x faster than scipy
(2,500 vs 520 maps/s on the busy 2-core machine, both profiles), which the replication profile
needs: its open maps give scipy's full-graph Dijkstra about twice the work of refined maps.
"""
from __future__ import annotations

import heapq
import math
import dataclasses
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from ..core.accel import SMALL_BATCH
from ..core.attributes import Categorical, IntRange, ScenarioError
from ..core.scenario import Scenario
from ..core.problem import DEFAULT_PROFILE, Budget, Evaluation, Problem, check_profile

HORIZONTAL, VERTICAL = 0, 1
DIAGONAL_RULES = ("both_free", "one_free", "always")
INFLATION_RULES = ("overlap", "centre")  # how the robot radius blocks cells (see ``inflation_footprint``)
INFLATION_RULE = {"refined": "overlap", "replication": "centre"}
OBJECTIVES = ("route", "narrow", "threat", "block")  # what F1 measures (``RobotConfig.objective``; threat, block: hazards only)
HAZARD_OBJECTIVES = ("threat", "block")  # F1 from ``robot_hazards.features`` of that name
SCENARIO_KINDS = ("walls", "hazards")  # ``RobotConfig.scenario``: the paper's map, or issue 48's hazards
LOOP_OBJECTIVES = ("time", "pace", "time_share")  # what F1 of an execution measures in the loop (``RobotConfig.loop_objective``)
ENGINES = ("auto", "numba", "numpy")  # batch planner: numba when importable, else scipy
NO_PATH = "no path from start to goal"

# The 8 moves as (dy, dx), ordered by the flat-index offset dy * W + dx so CSR rows come out sorted.
_MOVES = ((-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0), (1, 1))


# Defaults of the fields that differ by profile (``None`` in a Config resolves to these).
PROFILE_DEFAULTS = {
    "replication": {"keep_out": 0, "free_band": 3, "diagonal": "always"},
    "refined": {"keep_out": 1, "free_band": 0, "diagonal": "both_free"},
}


def fold_above(length: np.ndarray, cap: float) -> np.ndarray:
    """F1 with a known failure's boundary ``cap`` (m; 0 = none): up to the cap the route length,
    beyond it ``cap^2 / length``, which falls the further a map lies past the cap yet stays above
    an invalid map's 0. A search then climbs to just below the cap and never past it, while maps
    beyond it stay valid tests (Nav2's NavFn cannot plan past twice the map's side:
    ``config/nav2/known_failures.yaml``; ``route_cap: 100`` on 50 m maps; docs/choices.md)."""
    if not cap > 0:
        return length
    return np.where(length > cap, cap * cap / np.maximum(length, cap), length)


def clearance(grid: np.ndarray, resolution: float) -> np.ndarray:
    """(H, W) metres from each free cell's centre to the nearest wall cell's centre (0 on walls)."""
    from scipy.ndimage import distance_transform_edt

    return distance_transform_edt(~np.asarray(grid, dtype=bool)) * resolution


def narrow_route_metres(grid: np.ndarray, planning: np.ndarray, config: "RobotConfig") -> float:
    """Metres of a clearance-seeking route that must run closer than ``narrow_clearance`` to a wall.

    The route is what a costmap planner (NavFn over inflation costs) prefers: the shortest one that
    keeps every cell at least ``narrow_clearance`` from walls if one exists (then 0 narrow metres),
    else at least half a cell less, and so on down to the robot's own planning grid. Cells within
    ``keep_out + 2`` of the start and goal never count (the start sits by the border on every map).
    Measured on Nav2 + DWB (docs/choices.md, "A search aimed at the stack"): the more of these
    metres, the slower Nav2 drives a metre of route, and its one new failure lay past 98 % of passes.
    """
    res = config.resolution
    clear = clearance(grid, res)
    near = keep_out_mask(config, config.keep_out + 2)
    wide = clear >= config.narrow_clearance
    if math.isfinite(astar(planning | ~(wide | near), config.start, config.goal, config.diagonal)[0]):
        return 0.0
    t = config.narrow_clearance - 0.5 * res
    while True:
        blocked = planning if t <= res else planning | ~((clear >= t) | near)
        length, path = astar(blocked, config.start, config.goal, config.diagonal)
        if math.isfinite(length) or t <= res:
            break
        t -= 0.5 * res
    if not path:
        return 0.0
    cells = np.array(path)
    narrow = ~(wide | near)[cells[:, 1], cells[:, 0]]
    steps = np.hypot(*np.diff(cells, axis=0).T) * res
    return float(steps[narrow[1:]].sum())


@dataclass(frozen=True)
class RobotConfig:
    """Every number of the robot case study; ``None`` fields take the profile's default."""

    alpha: float = 120.0  # MO constraint: a map is 'risky' when its path is longer [m]
    map_size: int = 50  # cells per side, border included (attribute domains assume 50)
    resolution: float = 1.0  # metres per cell; genome values are cells (= m at 1.0)
    start: tuple[int, int] = (1, 1)  # (x, y) cell
    goal: tuple[int, int] = (48, 48)  # (x, y) cell
    robot_radius: float = 0.5  # m; see ``inflate``
    keep_out: int | None = None  # Chebyshev radius (cells) around start/goal never walled (R2)
    free_band: int | None = None  # interior cells along the top and right borders never walled
    type_p_stay: float = 0.5  # Markov chain over wall type: P(next type = this type)
    sampling: str = "markov"  # "markov" (type by the chain) | "uniform"
    diagonal: str | None = None  # diagonal step needs: both_free | one_free | always
    engine: str = "auto"  # batch planner: "auto" (numba if importable) | "numba" | "numpy" (scipy)
    route_cap: float = 0.0  # m; > 0: F1 folds back above it (see ``fold_above``); 0 = off
    objective: str = "route"  # F1: "route" = the A* route length (the paper's) | "narrow" = ``narrow_route_metres``
    narrow_clearance: float = 2.0  # m from a wall cell's centre below which a route cell is narrow ("narrow")
    # in the loop, F1 of an execution: "time" = the time to the goal (the time limit on a failure;
    # the paper's full model) | "pace" = seconds per metre of the clearance route (a failure: the time
    # limit's, above any pass): how hard the stack found the map, whatever its length (``loop_f1``) |
    # "time_share" = the time over the time limit (1 on a failure): measured, and it climbs route length
    loop_objective: str = "time"
    profile: str = DEFAULT_PROFILE  # replication | refined (see the module docstring)
    # scenario kind (issue 48): "walls" = the paper's map; "hazards" = walls plus the start and goal
    # poses, unmapped boxes and posts and walking people (``problems.robot_hazards``; refined only)
    scenario: str = "walls"
    start_area: tuple | None = None  # hazards: ((x0, y0), (x1, y1)) cells the start lies in; None = start +- 2
    goal_area: tuple | None = None  # hazards: the goal's area; None = goal +- 2 cells
    max_hazards: int = 6  # hazards: boxes, posts and people per scenario, at most
    box_side: tuple = (0.3, 1.0)  # hazards: a box's side [m], min and max
    post_diameter: tuple = (0.05, 0.2)  # hazards: a thin post's diameter [m]
    person_radius: tuple = (0.2, 0.35)  # hazards: a person's radius [m]
    person_reach: float = 3.0  # hazards: a person walks this far on each side of its point on the route [m]
    clear_of_ends: float = 0.6  # hazards: obstacles and standing people keep this far from start and goal [m]
    # threat: the robot's pace along the route when it times a person's meeting [m/s]; the stack's
    # own pace makes the timing match what it meets (MPPI's measured median: 0.39 m/s)
    threat_speed: float = 0.5

    def __post_init__(self):
        check_profile(self.profile)
        for name, default in PROFILE_DEFAULTS[self.profile].items():
            if getattr(self, name) is None:
                object.__setattr__(self, name, default)
        if self.sampling not in ("markov", "uniform"):
            raise ScenarioError("config.sampling", f"unknown sampling {self.sampling!r}", "markov|uniform")
        if self.diagonal not in DIAGONAL_RULES:
            raise ScenarioError("config.diagonal", f"unknown rule {self.diagonal!r}", "|".join(DIAGONAL_RULES))
        if self.engine not in ENGINES:
            raise ScenarioError("config.engine", f"unknown engine {self.engine!r}", "|".join(ENGINES))
        if not self.resolution > 0:
            raise ScenarioError("config.resolution", "must be positive")
        if self.robot_radius < 0:
            raise ScenarioError("config.robot_radius", "must be >= 0")
        if self.objective not in OBJECTIVES:
            raise ScenarioError("config.objective", f"unknown objective {self.objective!r}", "|".join(OBJECTIVES))
        if self.loop_objective not in LOOP_OBJECTIVES:
            raise ScenarioError("config.loop_objective", f"unknown objective {self.loop_objective!r}",
                                "|".join(LOOP_OBJECTIVES))
        if not self.narrow_clearance > 0:
            raise ScenarioError("config.narrow_clearance", "must be positive")
        if not self.route_cap >= 0:
            raise ScenarioError("config.route_cap", "must be >= 0 (0 = off)")
        if self.keep_out < 0:
            raise ScenarioError("config.keep_out", "must be >= 0")
        if not 0 <= self.free_band <= self.map_size - 3:
            raise ScenarioError("config.free_band", "must leave interior cells for walls", f"0..{self.map_size - 3}")
        if not 0.0 <= self.type_p_stay <= 1.0:
            raise ScenarioError("config.type_p_stay", "must be a probability", "[0, 1]")
        if self.scenario not in SCENARIO_KINDS:
            raise ScenarioError("config.scenario", f"unknown scenario kind {self.scenario!r}", "|".join(SCENARIO_KINDS))
        if self.scenario == "hazards":
            self._check_hazards()
        elif self.objective in HAZARD_OBJECTIVES:
            raise ScenarioError("config.objective", f"{self.objective} scores hazards", "scenario: hazards")
        # YAML/JSON give lists; keep the dataclass hashable and the cells integral.
        object.__setattr__(self, "start", tuple(int(v) for v in self.start))
        object.__setattr__(self, "goal", tuple(int(v) for v in self.goal))
        for name in ("start", "goal"):
            x, y = getattr(self, name)
            if not (0 < x < self.map_size - 1 and 0 < y < self.map_size - 1):
                raise ScenarioError(f"config.{name}", f"({x}, {y}) is not an interior cell",
                                    f"1..{self.map_size - 2}")

    def _check_hazards(self) -> None:
        if self.profile != "refined":
            raise ScenarioError("config.scenario", "hazards scenarios need the refined profile", "profile: refined")
        if not 0 <= int(self.max_hazards) <= 20:
            raise ScenarioError("config.max_hazards", f"{self.max_hazards}", "0..20")
        for name in ("start_area", "goal_area"):
            value = getattr(self, name)
            if value is None:
                continue
            try:
                (x0, y0), (x1, y1) = value
                cells = tuple(tuple(int(v) for v in c) for c in value)
            except (TypeError, ValueError):
                raise ScenarioError(f"config.{name}", f"expected [[x0, y0], [x1, y1]], got {value!r}") from None
            (x0, y0), (x1, y1) = cells
            if not (1 <= x0 <= x1 <= 48 and 1 <= y0 <= y1 <= 48):
                raise ScenarioError(f"config.{name}", f"{cells} is not a box of interior cells", "1 <= x0 <= x1 <= 48")
            object.__setattr__(self, name, cells)
        for name in ("box_side", "post_diameter", "person_radius"):
            lo_hi = tuple(float(v) for v in getattr(self, name))
            if len(lo_hi) != 2 or not 0 < lo_hi[0] <= lo_hi[1]:
                raise ScenarioError(f"config.{name}", f"{getattr(self, name)!r}", "[min, max] with 0 < min <= max")
            object.__setattr__(self, name, lo_hi)
        for name in ("person_reach", "clear_of_ends", "threat_speed"):
            if not getattr(self, name) > 0:
                raise ScenarioError(f"config.{name}", "must be > 0")

    def for_profile(self, profile: str) -> "RobotConfig":
        """This config under another profile: fields still at this profile's default follow the new one.

        (``dataclasses.replace(config, profile=...)`` alone would keep the old profile's resolved
        values, e.g. a refined config with corner-cutting A*.)
        """
        follow: dict[str, Any] = {name: None for name, default in PROFILE_DEFAULTS[self.profile].items()
                  if getattr(self, name) == default}
        return dataclasses.replace(self, profile=check_profile(profile), **follow)


# --- grids ---------------------------------------------------------------------------------
def keep_out_mask(config: RobotConfig, radius: int | None = None) -> np.ndarray:
    """(H, W) True on the start/goal keep-out squares, where walls are never placed (Chebyshev
    ``radius`` cells around each; default ``keep_out``)."""
    n, k = config.map_size, config.keep_out if radius is None else radius
    if config.scenario == "hazards":  # the start and goal may lie anywhere in their areas
        from .robot_hazards import areas_mask

        return areas_mask(config, k)
    ys, xs = np.mgrid[0:n, 0:n]
    mask = np.zeros((n, n), dtype=bool)
    for cx, cy in (config.start, config.goal):
        mask |= (np.abs(xs - cx) <= k) & (np.abs(ys - cy) <= k)
    return mask


def wall_half_extent(size: np.ndarray, profile: str) -> np.ndarray:
    """Cells a wall of ``size`` covers on each side of its centre (*rule* of the profile).

    refined: every cell within s/2 (``floor(s / 2)``: an even size gives s + 1 cells);
    replication: ``round(s / 2) - 1`` with round-half-to-even (``np.rint``, like Python's round).
    """
    size = np.asarray(size, dtype=np.int64)
    if profile == "refined":
        return size // 2
    return np.rint(size / 2).astype(np.int64) - 1


def wall_zone(config: RobotConfig) -> np.ndarray:
    """(H, W) True where wall cells may lie: the interior minus the free band and keep-out squares."""
    n = config.map_size
    last = n - 2 - int(config.free_band or 0)  # highest x and y index a wall cell may have
    zone = np.zeros((n, n), dtype=bool)
    zone[1:last + 1, 1:last + 1] = True
    return zone & ~keep_out_mask(config)


def build_grids(G: np.ndarray, lengths: np.ndarray, config: RobotConfig) -> np.ndarray:
    """Occupancy ``(P, H, W)`` bool ``[y, x]`` of a batch: border + walls clipped to ``wall_zone``."""
    G = np.asarray(G, dtype=float)
    P, m_max = G.shape[0], G.shape[1]
    n = config.map_size
    lengths = np.asarray(lengths).reshape(-1)
    used = np.arange(m_max)[None, :] < lengths[:, None]
    kind = np.rint(G[:, :, 0]).astype(np.int64)
    half = wall_half_extent(np.rint(G[:, :, 1]), config.profile)
    pos = np.rint(G[:, :, 2]).astype(np.int64)
    rows = np.arange(m_max) + 1  # element i lies on row y = i + 1
    axis = np.arange(n)
    horiz = used & (kind == HORIZONTAL)
    h_cells = horiz[:, :, None] & (np.abs(axis[None, None, :] - pos[:, :, None]) <= half[:, :, None])
    vert = used & (kind == VERTICAL)
    v_cells = vert[:, :, None] & (np.abs(axis[None, None, :] - rows[None, :, None]) <= half[:, :, None])
    v_at = vert[:, :, None] & (axis[None, None, :] == pos[:, :, None])  # one-hot column x
    grid = np.zeros((P, n, n), dtype=bool)
    n_rows = min(m_max, n - 2)
    grid[:, 1:1 + n_rows, :] = h_cells[:, :n_rows, :]
    # Vertical walls: grid[p, y, x] |= any_i v_cells[p, i, y] & v_at[p, i, x] (a batched matmul).
    grid |= np.matmul(v_cells.transpose(0, 2, 1).astype(np.float32), v_at.astype(np.float32)) > 0
    grid &= wall_zone(config)[None]
    grid[:, 0, :] = grid[:, -1, :] = grid[:, :, 0] = grid[:, :, -1] = True
    return grid


def inflation_footprint(radius: float, resolution: float, rule: str = "overlap") -> np.ndarray:
    """Offsets of the cells a robot of ``radius`` standing on a cell centre is blocked by.

    ``overlap`` (refined): the disc overlaps the cell's square (touching does not count); the
    distance to the square at offset (dx, dy) is ``res * hypot(max(|dx| - 0.5, 0), max(|dy| - 0.5, 0))``
    and must be < radius. ``centre`` (replication, the PythonRobotics obstacle map): the cell's
    centre is within the radius, ``res * hypot(dx, dy) <= radius``.
    """
    if rule not in INFLATION_RULES:
        raise ScenarioError("inflation", f"unknown rule {rule!r}", "|".join(INFLATION_RULES))
    k = max(0, math.ceil(radius / resolution + 0.5))
    d = np.abs(np.arange(-k, k + 1))
    if rule == "overlap":
        gap = np.maximum(d - 0.5, 0.0)
        foot = resolution * np.hypot(gap[:, None], gap[None, :]) < radius
    else:
        foot = resolution * np.hypot(d[:, None], d[None, :]) <= radius
    foot[k, k] = True
    return foot


def inflate(occupied: np.ndarray, radius: float, resolution: float = 1.0, rule: str = "overlap") -> np.ndarray:
    """Grow obstacles by the robot radius so the planner can treat the robot as a point.

    Works on one ``(H, W)`` grid or a ``(P, H, W)`` batch. A larger radius blocks cells next to
    walls (and may leave start/goal inside an inflated border: then there is no path).
    """
    occupied = np.asarray(occupied, dtype=bool)
    foot = inflation_footprint(radius, resolution, rule)
    if foot.sum() == 1:
        return occupied.copy()
    return dilate(occupied, foot)


def dilate(occupied: np.ndarray, foot: np.ndarray) -> np.ndarray:
    """Binary dilation of the last two axes by a symmetric ``(2k+1, 2k+1)`` footprint, outside = free.

    The same cells as ``scipy.ndimage.binary_dilation`` (tested), with numpy alone: scipy's import
    costs more than a few maps do.
    """
    k = foot.shape[0] // 2
    H, W = occupied.shape[-2:]
    padded = np.zeros(occupied.shape[:-2] + (H + 2 * k, W + 2 * k), dtype=bool)
    padded[..., k:k + H, k:k + W] = occupied
    out = np.zeros_like(occupied, dtype=bool)
    for dy, dx in np.argwhere(foot):
        out |= padded[..., dy:dy + H, dx:dx + W]
    return out


# --- planners ------------------------------------------------------------------------------
def _diagonal_ok(free: np.ndarray, x: int, y: int, dx: int, dy: int, rule: str) -> bool:
    if rule == "always":
        return True
    a, b = bool(free[y, x + dx]), bool(free[y + dy, x])
    return (a and b) if rule == "both_free" else (a or b)


def astar(
    grid: np.ndarray,
    start: Sequence[int],
    goal: Sequence[int],
    diagonal: str = "both_free",
) -> tuple[float, list[tuple[int, int]]]:
    """A* on an occupancy grid ``[y, x]`` from cell ``start`` to ``goal`` (both ``(x, y)``).

    Returns ``(length in cells, path as (x, y) cells)``; ``(inf, [])`` when the goal is
    unreachable. The Euclidean heuristic is consistent with the 1 / sqrt(2) costs, so the length
    is optimal. Cells outside the grid count as occupied.
    """
    grid = np.asarray(grid, dtype=bool)
    H, W = grid.shape
    free = np.zeros((H + 2, W + 2), dtype=bool)  # padded so neighbour look-ups never go out
    free[1:-1, 1:-1] = ~grid
    sx, sy = int(start[0]) + 1, int(start[1]) + 1
    gx, gy = int(goal[0]) + 1, int(goal[1]) + 1
    if not (free[sy, sx] and free[gy, gx]):
        return math.inf, []
    sqrt2 = math.sqrt(2.0)
    moves = [(dx, dy, sqrt2 if dx and dy else 1.0) for dy, dx in _MOVES]
    best = {(sx, sy): 0.0}
    parent: dict[tuple[int, int], tuple[int, int]] = {}
    closed: set[tuple[int, int]] = set()
    heap = [(math.hypot(gx - sx, gy - sy), 0.0, (sx, sy))]
    while heap:
        _, g, node = heapq.heappop(heap)
        if node in closed:
            continue
        if node == (gx, gy):
            path = [node]
            while path[-1] in parent:
                path.append(parent[path[-1]])
            return g, [(x - 1, y - 1) for x, y in reversed(path)]
        closed.add(node)
        x, y = node
        for dx, dy, cost in moves:
            nx, ny = x + dx, y + dy
            if not free[ny, nx] or (nx, ny) in closed:
                continue
            if dx and dy and not _diagonal_ok(free, x, y, dx, dy, diagonal):
                continue
            ng = g + cost
            if ng < best.get((nx, ny), math.inf):
                best[(nx, ny)] = ng
                parent[(nx, ny)] = node
                heapq.heappush(heap, (ng + math.hypot(gx - nx, gy - ny), ng, (nx, ny)))
    return math.inf, []


def grid_graph(occupied: np.ndarray, diagonal: str = "both_free") -> Any:
    """Block-diagonal CSR graph of a batch ``(P, H, W)``: node ``p*H*W + y*W + x``, legal moves."""
    occupied = np.asarray(occupied, dtype=bool)
    P, H, W = occupied.shape
    fp = np.zeros((P, H + 2, W + 2), dtype=bool)
    fp[:, 1:-1, 1:-1] = ~occupied
    free = fp[:, 1:-1, 1:-1]
    valid = np.empty((P, H, W, len(_MOVES)), dtype=bool)
    for k, (dy, dx) in enumerate(_MOVES):
        ok = free & fp[:, 1 + dy:1 + dy + H, 1 + dx:1 + dx + W]
        if dx and dy and diagonal != "always":
            side_x = fp[:, 1:1 + H, 1 + dx:1 + dx + W]
            side_y = fp[:, 1 + dy:1 + dy + H, 1:1 + W]
            ok &= (side_x & side_y) if diagonal == "both_free" else (side_x | side_y)
        valid[..., k] = ok
    n_nodes = P * H * W
    valid = valid.reshape(n_nodes, len(_MOVES))
    offsets = np.array([dy * W + dx for dy, dx in _MOVES], dtype=np.int32)
    costs = np.array([math.sqrt(2.0) if dx and dy else 1.0 for dy, dx in _MOVES])
    node = np.arange(n_nodes, dtype=np.int32)
    # Boolean indexing walks row-major, so entries come out grouped by source node (CSR order).
    rows, ks = np.nonzero(valid)
    indices = node[rows] + offsets[ks]
    indptr = np.zeros(n_nodes + 1, dtype=np.int32)
    np.cumsum(valid.sum(axis=1, dtype=np.int32), out=indptr[1:])
    from scipy.sparse import csr_matrix

    return csr_matrix((costs[ks], indices, indptr), shape=(n_nodes, n_nodes))


def _scipy_lengths(occupied: np.ndarray, start, goal, diagonal: str, chunk: int) -> np.ndarray:
    """``batch_path_lengths`` with scipy: one Dijkstra call per ``chunk`` maps (bounds memory)."""
    from scipy.sparse.csgraph import dijkstra

    P, H, W = occupied.shape
    out = np.full(P, np.inf)
    sx, sy = int(start[0]), int(start[1])
    gx, gy = int(goal[0]), int(goal[1])
    for lo in range(0, P, chunk):
        block = occupied[lo:lo + chunk]
        n = len(block)
        base = np.arange(n) * (H * W)
        reach = ~block[:, sy, sx] & ~block[:, gy, gx]
        if not reach.any():
            continue
        dist = dijkstra(grid_graph(block, diagonal), directed=True,
                        indices=base[reach] + sy * W + sx, min_only=True)
        out[lo:lo + n][reach] = dist[base[reach] + gy * W + gx]
    return out


def _dijkstra_maps(occupied, sx, sy, gx, gy, rule, out):
    """Dijkstra per map with a binary heap, stopping at the goal (compiled by numba).

    Same motion model and the same floating-point sums as ``grid_graph`` + scipy (a node's
    distance is the smallest ``dist[u] + cost`` over its settled neighbours), so the lengths are
    bit-identical. ``rule``: 0 both_free, 1 one_free, 2 always.
    """
    P, H, W = occupied.shape
    n = H * W
    sqrt2 = np.sqrt(2.0)
    dist = np.empty(n)
    done = np.empty(n, dtype=np.bool_)
    cap = 8 * n + 1  # a push needs a strict improvement: at most one per edge
    keys = np.empty(cap)
    nodes = np.empty(cap, dtype=np.int64)
    for p in range(P):
        out[p] = np.inf
        if occupied[p, sy, sx] or occupied[p, gy, gx]:
            continue
        dist[:] = np.inf
        done[:] = False
        goal = gy * W + gx
        dist[sy * W + sx] = 0.0
        keys[0] = 0.0
        nodes[0] = sy * W + sx
        size = 1
        while size > 0:
            d = keys[0]
            v = nodes[0]
            size -= 1
            if size > 0:  # move the last entry to the root and sift it down
                key, node = keys[size], nodes[size]
                i = 0
                while True:
                    c = 2 * i + 1
                    if c >= size:
                        break
                    if c + 1 < size and keys[c + 1] < keys[c]:
                        c += 1
                    if keys[c] >= key:
                        break
                    keys[i], nodes[i] = keys[c], nodes[c]
                    i = c
                keys[i], nodes[i] = key, node
            if done[v]:
                continue
            done[v] = True
            if v == goal:
                out[p] = d
                break
            y, x = v // W, v % W
            for dy in range(-1, 2):
                for dx in range(-1, 2):
                    if dy == 0 and dx == 0:
                        continue
                    ny, nx = y + dy, x + dx
                    if ny < 0 or ny >= H or nx < 0 or nx >= W or occupied[p, ny, nx]:
                        continue
                    u = ny * W + nx
                    if done[u]:
                        continue
                    cost = 1.0
                    if dy != 0 and dx != 0:
                        cost = sqrt2
                        side_x = not occupied[p, y, nx]
                        side_y = not occupied[p, ny, x]
                        if rule == 0 and not (side_x and side_y):
                            continue
                        if rule == 1 and not (side_x or side_y):
                            continue
                    nd = d + cost
                    if nd < dist[u]:
                        dist[u] = nd
                        i = size  # push and sift up
                        size += 1
                        while i > 0:
                            parent = (i - 1) // 2
                            if keys[parent] <= nd:
                                break
                            keys[i], nodes[i] = keys[parent], nodes[parent]
                            i = parent
                        keys[i], nodes[i] = nd, u


_KERNEL: Any = None  # the numba-compiled ``_dijkstra_maps``, or False when numba is unavailable


def _kernel():
    """Compile the planner on first use (cached on disk by numba); False when numba does not load."""
    global _KERNEL
    if _KERNEL is None:
        from ..core.accel import numba_module  # any import failure falls back, with one warning

        numba = numba_module()
        _KERNEL = numba.njit(cache=True)(_dijkstra_maps) if numba else False
    return _KERNEL


def batch_path_lengths(
    occupied: np.ndarray,
    start: Sequence[int],
    goal: Sequence[int],
    diagonal: str = "both_free",
    chunk: int = 32,
    engine: str = "auto",
) -> np.ndarray:
    """Optimal path length (cells) per map of a ``(P, H, W)`` batch; ``inf`` where unreachable.

    Same motion model as ``astar``. ``engine``: "numba" (a compiled Dijkstra per map that stops at
    the goal), "numpy" (scipy on block-diagonal graphs of ``chunk`` maps) or "auto" (numba when
    importable); both give the same floats.
    """
    occupied = np.ascontiguousarray(occupied, dtype=bool)
    if engine not in ENGINES:
        raise ScenarioError("engine", f"unknown engine {engine!r}", "|".join(ENGINES))
    out = np.empty(len(occupied))
    if engine == "auto" and len(occupied) <= SMALL_BATCH and not _KERNEL:
        # a few maps: the kernel's own code as plain Python (~15 ms a map, the same floats), which
        # spares numba's import and cache load (~0.8 s) when nothing has compiled it yet
        _dijkstra_maps(occupied, int(start[0]), int(start[1]), int(goal[0]), int(goal[1]),
                       DIAGONAL_RULES.index(diagonal), out)
        return out
    kernel: Any = _kernel() if engine != "numpy" else False
    if engine == "numba" and not kernel:
        raise ImportError("numba is not installed; use engine='numpy'")
    if not kernel:
        return _scipy_lengths(occupied, start, goal, diagonal, chunk)
    kernel(occupied, int(start[0]), int(start[1]), int(goal[0]), int(goal[1]), DIAGONAL_RULES.index(diagonal), out)
    return out


# --- the problem ------------------------------------------------------------------------------
@dataclass
class RobotMap:
    """'TC to environment' for the robot: the occupancy map plus the planned A* route.

    ``grid`` is the raw occupancy (walls + border, ``[y, x]``, cell (0, 0)'s corner at (0, 0) m);
    points in metres are cell centres. ``path`` is empty and ``path_length`` 0 without a route.
    """

    grid: np.ndarray
    resolution: float
    start: tuple[int, int]
    goal: tuple[int, int]
    start_m: tuple[float, float]
    goal_m: tuple[float, float]
    path: list[tuple[int, int]] = field(default_factory=list)
    path_length: float = 0.0
    reachable: bool = False
    # hazards scenarios (issue 48): the poses' yaw [rad] (None: the paper's map, facing the route) and
    # what is in the world but not in ``grid`` (``sims.obstacles.Obstacles.to_dict`` form)
    start_yaw: float | None = None
    goal_yaw: float | None = None
    unmapped: dict = field(default_factory=dict)

    def to_metres(self, cell: Sequence[int]) -> tuple[float, float]:
        return ((cell[0] + 0.5) * self.resolution, (cell[1] + 0.5) * self.resolution)

    @property
    def path_m(self) -> list[tuple[float, float]]:
        return [self.to_metres(c) for c in self.path]


# Attribute domains and lengths per profile. The replication code's generator draws one element
# per level 1..49 (1 + (map_size - 2)) with positions 1..49; it scores any number of levels (a
# missing level is an empty row), so shorter scenarios, like the refined profile's 48, are accepted.
_TYPE = Categorical("type", ("horizontal", "vertical"))
_SIZE = IntRange("size", 5, 15, 1, tolerance=2, unit="m")
REFINED_LAYOUT = ((_TYPE, _SIZE, IntRange("position", 1, 48, 1, tolerance=2, unit="m")), 48, 48)
REPLICATION_LAYOUT = ((_TYPE, _SIZE, IntRange("position", 1, 49, 1, tolerance=2, unit="m")), 1, 49)


class RobotProblem(Problem):
    """Walls in a room; the longer the shortest route, the harder the map for the robot.

    The class attributes are the refined layout; an instance takes its profile's from ``layout()``.
    """

    name = "robot"
    attributes, m_min, m_max = REFINED_LAYOUT
    f1_label = "A* path length [m]"
    paper_budget = Budget(100, 50, 20000)
    Config = RobotConfig
    # refined: a diagonal step needs both orthogonal neighbours free, so a path keeps half a cell
    # (0.5 m) from every wall, more than the reference's clearance route needs (0.36 m; 40 of 40
    # sampled refined maps have one); the replication planner squeezes between walls touching at a corner
    certified_search = {"profile": "refined"}

    def __init__(self, config=None, **overrides):
        # Build the Config once from all given values, so profile-dependent defaults resolve for
        # the profile asked for (Config() followed by replace(profile=...) would not).
        if config is None:
            config = {}
        if isinstance(config, dict):
            config, overrides = {**config, **overrides}, {}
        elif overrides.get("profile", config.profile) != config.profile:
            config = config.for_profile(overrides.pop("profile"))
        super().__init__(config, **overrides)
        if self.config.objective == "narrow":
            self.f1_label = "narrow route [m]"
        elif self.config.objective == "threat":
            self.f1_label = "hazards' threat (obstacle on route + person meeting + goal turn, by narrowness)"
        elif self.config.objective == "block":
            self.f1_label = "a person shutting the way when the robot comes (closure x time left / 30 s)"
        walls = 48 if self.hazards else self.m_max  # hazards: 48 wall rows, then the start, goal and hazards
        rows = walls + (2 if self.profile == "refined" else 1)  # replication: levels up to the top border
        if self.config.map_size != rows:
            raise ScenarioError("config.map_size", f"{self.config.map_size} does not match one row per element",
                                str(rows))

    def layout(self):
        if self.config.scenario == "hazards":
            from .robot_hazards import ATTRIBUTES, FIRST_HAZARD

            return ATTRIBUTES, FIRST_HAZARD, FIRST_HAZARD + int(self.config.max_hazards)
        return REFINED_LAYOUT if self.profile == "refined" else REPLICATION_LAYOUT

    @property
    def hazards(self) -> bool:
        """A hazards scenario (issue 48: ``problems.robot_hazards``), not the paper's map of walls."""
        return self.config.scenario == "hazards"

    def canonical(self, G: np.ndarray, lengths: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if self.hazards:
            from .robot_hazards import canonical

            return canonical(G, lengths)
        return G, lengths

    def search_operators(self, settings: Any) -> dict[str, Any]:
        if self.hazards:  # walls stay walls, the start stays the start: a mutation within each kind
            from .robot_hazards_operators import HazardMutation

            return {"mutation": HazardMutation(prob=settings.mutation_rate)}
        return {}

    def loop_f1(self, outcome: Any) -> float:
        """``loop_objective: pace``: a pass's seconds per metre of its clearance route; a failure
        scores its time limit's pace, above any pass of the map. The time alone climbs towards long
        routes (and NavFn's known cap); so does the time over the time limit, whose 300 s floor
        makes it the time on most maps (Spearman 0.95 with the route on a GA run of DWB). The pace
        of MPPI's near misses was 2.75-5.05 s/m against 2.19-3.57 for plain passes, and of a DWB
        failure 7.9 (docs/external_sut.md, "In the loop"). ``time_share`` stays, so that the bags
        of the campaign that measured it replay."""
        if self.config.loop_objective == "time":
            return super().loop_f1(outcome)
        m = outcome.metrics
        try:
            spent = float(m["time_limit"] if outcome.failed else m["time"])
            route = m.get("route_length_m") or m.get("route_length")  # a stack's judge | our full model
            per = float(m["time_limit"] if self.config.loop_objective == "time_share" else route or 0.0)
            value = spent / per
        except (KeyError, TypeError, ValueError, ZeroDivisionError):
            return 0.0  # no route or no time on record: nothing to climb
        return value if math.isfinite(value) and value > 0 else 0.0

    # --- sampling ----------------------------------------------------------------------
    def sample(self, n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """Fixed length m_max (48 | 49); type by a 2-state Markov chain (or uniform), size/position uniform.

        With P(stay) = 0.5 (both profiles) the chain draws every type independently, as the
        replication code's generator does.
        """
        if self.hazards:
            from .robot_hazards import N_WALLS, sample

            walls = self._sample_walls(n, N_WALLS, REFINED_LAYOUT[0], rng)
            return sample(walls, self.config, rng)
        G = self._sample_walls(n, self.m_max, self.attributes, rng)
        return G, np.full(n, self.m_max, dtype=int)

    def _sample_walls(self, n: int, m: int, attributes, rng: np.random.Generator) -> np.ndarray:
        G = np.zeros((n, m, len(attributes)))
        if self.config.sampling == "markov":
            first = rng.integers(0, 2, size=(n, 1))
            switch = rng.random((n, m - 1)) >= self.config.type_p_stay
            G[:, :, 0] = (first + np.concatenate([np.zeros((n, 1), int), np.cumsum(switch, axis=1)], axis=1)) % 2
        else:
            G[:, :, 0] = attributes[0].sample(rng, (n, m))
        G[:, :, 1] = attributes[1].sample(rng, (n, m))
        G[:, :, 2] = attributes[2].sample(rng, (n, m))
        return G

    # --- fitness -------------------------------------------------------------------------
    def planning_grids(self, G: np.ndarray, lengths: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Raw occupancy and the radius-inflated grid the planners use (the mapped walls only)."""
        if self.hazards:
            from .robot_hazards import N_WALLS

            G, lengths = np.asarray(G)[:, :N_WALLS, :3], np.full(len(G), N_WALLS)
        grids = build_grids(G, lengths, self.config)
        planning = inflate(grids, self.config.robot_radius, self.config.resolution, INFLATION_RULE[self.profile])
        if self.profile == "replication":  # its planner never checks the start: the robot leaves it
            sx, sy = self.config.start
            planning[:, sy, sx] = False
        return grids, planning

    def evaluate(self, G: np.ndarray, lengths: np.ndarray) -> Evaluation:
        G = np.asarray(G, dtype=float)
        lengths = np.asarray(lengths, dtype=int).reshape(-1)
        if self.hazards:
            return self._evaluate_hazards(G, lengths)
        grids, planning = self.planning_grids(G, lengths)
        cells = batch_path_lengths(planning, self.config.start, self.config.goal, self.config.diagonal,
                                   engine=self.config.engine)
        in_domain = self.codec.in_domain(G, lengths)
        valid = np.isfinite(cells) & in_domain
        length = np.where(valid, cells * self.config.resolution, 0.0)
        f1 = fold_above(length, self.config.route_cap)
        metrics = {"path_length": length}
        if self.config.objective == "narrow":
            # past the cap a map keeps the same share of its narrow metres as of its folded length
            narrow = np.array([narrow_route_metres(grids[i], planning[i], self.config) if ok else 0.0
                               for i, ok in enumerate(valid.tolist())])
            f1 = narrow * np.divide(f1, length, out=np.zeros_like(f1), where=length > 0)
            metrics["narrow_m"] = narrow
        reasons = [None if ok else (NO_PATH if dom else self.codec.domain_reason(G[i], int(lengths[i])))
                   for i, (ok, dom) in enumerate(zip(valid.tolist(), in_domain.tolist()))]
        wall_cells = grids[:, 1:-1, 1:-1].sum(axis=(1, 2))
        return Evaluation(f1, valid, reasons, {**metrics, "wall_cells": wall_cells})

    # --- environment ---------------------------------------------------------------------
    def environment(self, scenario: Scenario) -> RobotMap:
        G, lengths = self.codec.split(self.codec.to_row(scenario))
        if self.hazards:
            return self._hazard_environment(G[0], int(lengths[0]))
        grids, planning = self.planning_grids(G, lengths)
        length, path = astar(planning[0], self.config.start, self.config.goal, self.config.diagonal)
        res = self.config.resolution
        out = RobotMap(grids[0], res, self.config.start, self.config.goal, (0.0, 0.0), (0.0, 0.0))
        out.start_m, out.goal_m = out.to_metres(self.config.start), out.to_metres(self.config.goal)
        if math.isfinite(length):
            out.path, out.path_length, out.reachable = path, length * res, True
        return out

    # --- hazards scenarios (issue 48; ``problems.robot_hazards``) ------------------------------
    def _evaluate_hazards(self, G: np.ndarray, lengths: np.ndarray) -> Evaluation:
        """The kinds in their places, a route on the mapped walls (F1: its length, the paper's
        objective), hazards clear of the start and goal, people with room to walk. Metrics count
        the hazards by kind."""
        from . import robot_hazards as hz

        cfg = self.config
        settings = hz.HazardSettings.of(cfg)
        grids, planning = self.planning_grids(G, lengths)
        in_domain = self.codec.in_domain(G, lengths)
        P = len(G)
        f1, valid, route_m = np.zeros(P), np.zeros(P, dtype=bool), np.zeros(P)
        reasons: list[str | None] = [None] * P
        counts = {name: np.zeros(P) for name in ("boxes", "posts", "people")}
        for i in range(P):
            m = int(lengths[i])
            reason = None if in_domain[i] else self.codec.domain_reason(G[i], m)
            reason = reason or hz.kind_reason(G[i], m, cfg)
            if reason is None:
                layout = hz.decode(G[i], m, settings)
                length, path = astar(planning[i], layout.start, layout.goal, cfg.diagonal)
                if not math.isfinite(length):
                    reason = NO_PATH
                else:
                    route = hz.PlacementRoute((np.asarray(path, dtype=float) + 0.5) * cfg.resolution)
                    posts, boxes, people = hz.obstacles_on(route, layout, settings, grids[i], cfg.resolution)
                    reason = hz.placement_reason(layout, posts, boxes, people, settings, cfg.resolution)
                    counts["boxes"][i], counts["posts"][i], counts["people"][i] = len(boxes), len(posts), len(people)
                    f1[i] = route_m[i] = length * cfg.resolution
                    if cfg.objective in HAZARD_OBJECTIVES and reason is None:
                        f1[i] = hz.features(route, layout, posts, boxes, people, grids[i], cfg.resolution,
                                            cfg.threat_speed)[cfg.objective]
            if reason is None:
                valid[i] = True
            else:
                reasons[i], f1[i] = reason, 0.0
        metrics = {"path_length": np.where(valid, route_m, 0.0), **counts}
        if cfg.objective in HAZARD_OBJECTIVES:
            metrics[cfg.objective] = f1.copy()
        return Evaluation(f1, valid, reasons, metrics)

    def _hazard_environment(self, cells: np.ndarray, length: int) -> "RobotMap":
        """The mapped walls, the poses, the route hazards sit on (``path``) and the unmapped
        obstacles (``unmapped``)."""
        from . import robot_hazards as hz

        cfg = self.config
        settings = hz.HazardSettings.of(cfg)
        grids, planning = self.planning_grids(cells[None], np.array([length]))
        layout = hz.decode(cells, length, settings)
        res = cfg.resolution
        out = RobotMap(grids[0], res, layout.start, layout.goal, (0.0, 0.0), (0.0, 0.0),
                       start_yaw=layout.start_yaw, goal_yaw=layout.goal_yaw)
        out.start_m, out.goal_m = out.to_metres(layout.start), out.to_metres(layout.goal)
        route_len, path = astar(planning[0], layout.start, layout.goal, cfg.diagonal)
        if math.isfinite(route_len):
            out.path, out.path_length, out.reachable = path, route_len * res, True
            route = hz.PlacementRoute((np.asarray(path, dtype=float) + 0.5) * res)
            posts, boxes, people = hz.obstacles_on(route, layout, settings, grids[0], res)
            out.unmapped = {"posts": posts.tolist(), "boxes": boxes.tolist(), "people": people}
        return out

    def hazard_features(self, scenario: Scenario, speed: float | None = None) -> dict[str, float]:
        """``robot_hazards.features`` of one hazards scenario (what its hazards do to the route), with
        the robot at ``speed`` (m/s; default: the config's ``threat_speed``)."""
        from . import robot_hazards as hz

        env = self.environment(scenario)
        if not env.reachable:
            return {}
        G, lengths = self.codec.split(self.codec.to_row(scenario))
        layout = hz.decode(G[0], int(lengths[0]), hz.HazardSettings.of(self.config))
        u = env.unmapped
        return hz.features(hz.PlacementRoute(np.asarray(env.path_m)), layout, np.asarray(u["posts"]).reshape(-1, 3),
                           np.asarray(u["boxes"]).reshape(-1, 4), u["people"], env.grid, env.resolution,
                           self.config.threat_speed if speed is None else speed)
