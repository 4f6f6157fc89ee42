"""The planners over an occupancy grid: ``astar`` for one map's route (drawn, sent to ROS), and
``batch_path_lengths`` for a batch's optimal lengths (a numba-compiled Dijkstra per map, else scipy
on block-diagonal graphs; the same floats), with ``grid_graph``, the motion model as a CSR graph.

One module for all of them, so the motion model (``_MOVES``, the diagonal rules) is defined once.
"""
from __future__ import annotations

import heapq
import math
from typing import Any, Sequence

import numpy as np

from ...core.accel import SMALL_BATCH
from ...core.attributes import ScenarioError
from .config import DIAGONAL_RULES, ENGINES

# The 8 moves as (dy, dx), ordered by the flat-index offset dy * W + dx so CSR rows come out sorted.
_MOVES = ((-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0), (1, 1))


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
        from ...core.accel import numba_module  # any import failure falls back, with one warning

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
