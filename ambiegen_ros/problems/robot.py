"""Mobile-robot obstacle map (paper 5.2): walls on a 50 x 50 m grid; F1 = A* path length.

Representation: one element per interior row ``y = 1..48`` (element ``i`` -> row ``y = i + 1``),
each element one wall (``type`` horizontal/vertical, ``size`` in m, ``position`` = x of its centre),
so R1 (one obstacle per element) holds by construction. A wall of size ``s`` covers the cells whose
index differs from its centre by at most ``s / 2`` along its axis (inclusive, so an even size gives
``s + 1`` cells), clipped to the interior; cells inside the start/goal keep-out squares are never
walled, so R2 also holds by construction. The border is always wall. Grids are ``[y, x]``.

Motion model (shared by ``astar`` and the batch planner): 8-connected, steps of 1 and sqrt(2)
cells, a diagonal step needs both orthogonal neighbours free (``Config.diagonal``), and the robot
stands on cell centres. ``inflate`` grows obstacles by the robot radius: a cell is blocked when the
robot disc at its centre would overlap an occupied cell's square; with the paper's 0.5 m radius on
a 1 m grid the disc only touches its neighbours, so nothing is inflated (one robot = one cell).

Speed: ``astar`` (heapq, Euclidean heuristic, the paper's planner) is kept for single maps (the
path drawn in plots and sent to ROS). For a batch, F1 only needs the optimal *length*, which A*
with a consistent heuristic returns exactly as Dijkstra does; so ``batch_path_lengths`` builds one
block-diagonal CSR graph of all P maps with numpy (no sorting: rows are written in node order) and
makes ONE ``scipy.sparse.csgraph.dijkstra(min_only=True)`` call from the P start nodes (the maps
are disconnected, so each goal is reached only from its own start). Profiled on 2,000 sampled maps
(2-core machine): the Python ``astar`` plans ~350 maps/s, the batched Dijkstra ~2,500 maps/s;
graphs of ~32 maps per call beat one huge graph (cache), hence ``chunk``. Tests check both agree.
"""
from __future__ import annotations

import heapq
import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np
from scipy import ndimage
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from ..core.attributes import Categorical, IntRange, ScenarioError
from ..core.scenario import Scenario
from .base import Budget, Evaluation, Problem

HORIZONTAL, VERTICAL = 0, 1
DIAGONAL_RULES = ("both_free", "one_free", "always")
NO_PATH = "no path from start to goal"

# The 8 moves as (dy, dx), ordered by the flat-index offset dy * W + dx so CSR rows come out sorted.
_MOVES = ((-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0), (1, 1))


@dataclass(frozen=True)
class RobotConfig:
    """Every number of the robot case study (defaults = the paper / its replication code)."""

    alpha: float = 120.0  # MO constraint: a map is 'risky' when its path is longer [m]
    map_size: int = 50  # cells per side, border included (attribute domains assume 50)
    resolution: float = 1.0  # metres per cell; genome values are cells (= m at 1.0)
    start: tuple[int, int] = (1, 1)  # (x, y) cell
    goal: tuple[int, int] = (48, 48)  # (x, y) cell
    robot_radius: float = 0.5  # m; see ``inflate``
    keep_out: int = 1  # Chebyshev radius (cells) around start/goal never walled (R2)
    type_p_stay: float = 0.5  # Markov chain over wall type: P(next type = this type)
    sampling: str = "markov"  # "markov" (type by the chain) | "uniform"
    diagonal: str = "both_free"  # diagonal step needs: both_free | one_free | always

    def __post_init__(self):
        if self.sampling not in ("markov", "uniform"):
            raise ScenarioError("config.sampling", f"unknown sampling {self.sampling!r}", "markov|uniform")
        if self.diagonal not in DIAGONAL_RULES:
            raise ScenarioError("config.diagonal", f"unknown rule {self.diagonal!r}", "|".join(DIAGONAL_RULES))
        if not self.resolution > 0:
            raise ScenarioError("config.resolution", "must be positive")
        if self.robot_radius < 0:
            raise ScenarioError("config.robot_radius", "must be >= 0")
        if self.keep_out < 0:
            raise ScenarioError("config.keep_out", "must be >= 0")
        if not 0.0 <= self.type_p_stay <= 1.0:
            raise ScenarioError("config.type_p_stay", "must be a probability", "[0, 1]")
        # YAML/JSON give lists; keep the dataclass hashable and the cells integral.
        object.__setattr__(self, "start", tuple(int(v) for v in self.start))
        object.__setattr__(self, "goal", tuple(int(v) for v in self.goal))
        for name in ("start", "goal"):
            x, y = getattr(self, name)
            if not (0 < x < self.map_size - 1 and 0 < y < self.map_size - 1):
                raise ScenarioError(f"config.{name}", f"({x}, {y}) is not an interior cell",
                                    f"1..{self.map_size - 2}")


# --- grids ---------------------------------------------------------------------------------
def keep_out_mask(config: RobotConfig) -> np.ndarray:
    """(H, W) True on the start/goal keep-out squares, where walls are never placed."""
    n, k = config.map_size, config.keep_out
    ys, xs = np.mgrid[0:n, 0:n]
    mask = np.zeros((n, n), dtype=bool)
    for cx, cy in (config.start, config.goal):
        mask |= (np.abs(xs - cx) <= k) & (np.abs(ys - cy) <= k)
    return mask


def build_grids(G: np.ndarray, lengths: np.ndarray, config: RobotConfig) -> np.ndarray:
    """Occupancy ``(P, H, W)`` bool ``[y, x]`` of a batch: border + clipped walls, R2 keep-out."""
    G = np.asarray(G, dtype=float)
    P, m_max = G.shape[0], G.shape[1]
    n = config.map_size
    lengths = np.asarray(lengths).reshape(-1)
    used = np.arange(m_max)[None, :] < lengths[:, None]
    kind = np.rint(G[:, :, 0]).astype(np.int64)
    size = np.rint(G[:, :, 1]).astype(np.int64)
    pos = np.rint(G[:, :, 2]).astype(np.int64)
    rows = np.arange(m_max) + 1  # element i lies on row y = i + 1
    axis = np.arange(n)
    # Cells within s/2 of the centre along the axis: 2 |c - centre| <= s (integer arithmetic).
    horiz = used & (kind == HORIZONTAL)
    h_cells = horiz[:, :, None] & (2 * np.abs(axis[None, None, :] - pos[:, :, None]) <= size[:, :, None])
    vert = used & (kind == VERTICAL)
    v_cells = vert[:, :, None] & (2 * np.abs(axis[None, None, :] - rows[None, :, None]) <= size[:, :, None])
    v_at = vert[:, :, None] & (axis[None, None, :] == pos[:, :, None])  # one-hot column x
    grid = np.zeros((P, n, n), dtype=bool)
    n_rows = min(m_max, n - 2)
    grid[:, 1:1 + n_rows, :] = h_cells[:, :n_rows, :]
    # Vertical walls: grid[p, y, x] |= any_i v_cells[p, i, y] & v_at[p, i, x] (a batched matmul).
    grid |= np.matmul(v_cells.transpose(0, 2, 1).astype(np.float32), v_at.astype(np.float32)) > 0
    interior = np.zeros((n, n), dtype=bool)
    interior[1:-1, 1:-1] = True
    grid &= (interior & ~keep_out_mask(config))[None]
    grid[:, 0, :] = grid[:, -1, :] = grid[:, :, 0] = grid[:, :, -1] = True
    return grid


def inflation_footprint(radius: float, resolution: float) -> np.ndarray:
    """Cells a robot disc of ``radius`` at a cell centre overlaps (touching does not count).

    The distance from the centre to the square of the cell at offset (dx, dy) is
    ``res * hypot(max(|dx| - 0.5, 0), max(|dy| - 0.5, 0))``; the cell is hit when it is < radius.
    """
    k = max(0, math.ceil(radius / resolution + 0.5))
    d = np.abs(np.arange(-k, k + 1))
    gap = np.maximum(d - 0.5, 0.0)
    dist = resolution * np.hypot(gap[:, None], gap[None, :])
    foot = dist < radius
    foot[k, k] = True
    return foot


def inflate(occupied: np.ndarray, radius: float, resolution: float = 1.0) -> np.ndarray:
    """Grow obstacles by the robot radius so the planner can treat the robot as a point.

    Works on one ``(H, W)`` grid or a ``(P, H, W)`` batch. A larger radius blocks cells next to
    walls (and may leave start/goal inside an inflated border: then there is no path).
    """
    occupied = np.asarray(occupied, dtype=bool)
    foot = inflation_footprint(radius, resolution)
    if foot.sum() == 1:
        return occupied.copy()
    structure = foot if occupied.ndim == 2 else foot[None]
    return ndimage.binary_dilation(occupied, structure=structure)


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


def grid_graph(occupied: np.ndarray, diagonal: str = "both_free") -> csr_matrix:
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
    return csr_matrix((costs[ks], indices, indptr), shape=(n_nodes, n_nodes))


def batch_path_lengths(
    occupied: np.ndarray,
    start: Sequence[int],
    goal: Sequence[int],
    diagonal: str = "both_free",
    chunk: int = 32,
) -> np.ndarray:
    """Optimal path length (cells) per map of a ``(P, H, W)`` batch; ``inf`` where unreachable.

    Same motion model as ``astar``; one Dijkstra call per ``chunk`` maps (bounds memory).
    """
    occupied = np.asarray(occupied, dtype=bool)
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

    def to_metres(self, cell: Sequence[int]) -> tuple[float, float]:
        return ((cell[0] + 0.5) * self.resolution, (cell[1] + 0.5) * self.resolution)

    @property
    def path_m(self) -> list[tuple[float, float]]:
        return [self.to_metres(c) for c in self.path]


class RobotProblem(Problem):
    """Walls in a room; the longer the shortest route, the harder the map for the robot."""

    name = "robot"
    attributes = (
        Categorical("type", ("horizontal", "vertical")),
        IntRange("size", 5, 15, 1, tolerance=2, unit="m"),
        IntRange("position", 1, 48, 1, tolerance=2, unit="m"),
    )
    m_min = 48
    m_max = 48
    f1_label = "A* path length [m]"
    paper_budget = Budget(100, 50, 20000)
    Config = RobotConfig

    def __init__(self, config=None, **overrides):
        super().__init__(config, **overrides)
        if self.config.map_size != self.m_max + 2:
            raise ScenarioError("config.map_size", f"{self.config.map_size} does not match one row per element",
                                str(self.m_max + 2))

    # --- sampling ----------------------------------------------------------------------
    def sample(self, n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """Fixed length 48; wall type by a 2-state Markov chain (or uniform), size/position uniform."""
        m = self.m_max
        G = np.zeros((n, m, len(self.attributes)))
        if self.config.sampling == "markov":
            first = rng.integers(0, 2, size=(n, 1))
            switch = rng.random((n, m - 1)) >= self.config.type_p_stay
            G[:, :, 0] = (first + np.concatenate([np.zeros((n, 1), int), np.cumsum(switch, axis=1)], axis=1)) % 2
        else:
            G[:, :, 0] = self.attributes[0].sample(rng, (n, m))
        G[:, :, 1] = self.attributes[1].sample(rng, (n, m))
        G[:, :, 2] = self.attributes[2].sample(rng, (n, m))
        return G, np.full(n, m, dtype=int)

    # --- fitness -------------------------------------------------------------------------
    def planning_grids(self, G: np.ndarray, lengths: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Raw occupancy and the radius-inflated grid the planners use."""
        grids = build_grids(G, lengths, self.config)
        return grids, inflate(grids, self.config.robot_radius, self.config.resolution)

    def evaluate(self, G: np.ndarray, lengths: np.ndarray) -> Evaluation:
        G = np.asarray(G, dtype=float)
        lengths = np.asarray(lengths, dtype=int).reshape(-1)
        grids, planning = self.planning_grids(G, lengths)
        cells = batch_path_lengths(planning, self.config.start, self.config.goal, self.config.diagonal)
        in_domain = self.codec.in_domain(G, lengths)
        valid = np.isfinite(cells) & in_domain
        f1 = np.where(valid, cells * self.config.resolution, 0.0)
        reasons = [None if ok else (NO_PATH if dom else self.codec.domain_reason(G[i], int(lengths[i])))
                   for i, (ok, dom) in enumerate(zip(valid.tolist(), in_domain.tolist()))]
        wall_cells = grids[:, 1:-1, 1:-1].sum(axis=(1, 2))
        return Evaluation(f1, valid, reasons, {"path_length": f1.copy(), "wall_cells": wall_cells})

    # --- environment ---------------------------------------------------------------------
    def environment(self, scenario: Scenario) -> RobotMap:
        G, lengths = self.codec.split(self.codec.to_row(scenario))
        grids, planning = self.planning_grids(G, lengths)
        length, path = astar(planning[0], self.config.start, self.config.goal, self.config.diagonal)
        res = self.config.resolution
        out = RobotMap(grids[0], res, self.config.start, self.config.goal, (0.0, 0.0), (0.0, 0.0))
        out.start_m, out.goal_m = out.to_metres(self.config.start), out.to_metres(self.config.goal)
        if math.isfinite(length):
            out.path, out.path_length, out.reachable = path, length * res, True
        return out
