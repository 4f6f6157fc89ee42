"""Map generation: a batch of wall genomes to occupancy grids ``[y, x]`` (border, walls clipped to
where walls may lie, the start/goal keep-out), and the robot-radius inflation the planners use.

Apart from the planners, so that a map can be built (``sims``, ``bench/robot_route.py``) without
the planners' scipy and numba code.
"""
from __future__ import annotations

import math

import numpy as np

from ...core.attributes import ScenarioError
from .config import HORIZONTAL, INFLATION_RULES, VERTICAL, RobotConfig


def keep_out_mask(config: RobotConfig, radius: int | None = None) -> np.ndarray:
    """(H, W) True on the start/goal keep-out squares, where walls are never placed (Chebyshev
    ``radius`` cells around each; default ``keep_out``)."""
    n, k = config.map_size, config.keep_out if radius is None else radius
    if config.scenario == "hazards":  # the start and goal may lie anywhere in their areas
        from ..robot_hazards import areas_mask

        if config.walls_over_ends:  # walls anywhere, a start or goal on one included
            return np.zeros((n, n), dtype=bool)
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
