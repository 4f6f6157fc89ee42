"""What F1 measures of a route beyond its length: ``fold_above`` (a known failure's cap folds the
length back) and ``narrow_route_metres`` (issue 29: metres a clearance-seeking route runs close
to walls), with ``clearance``, each free cell's distance to the nearest wall.

Apart from the problem class, so that the objectives can be computed and tested on a grid alone.
"""
from __future__ import annotations

import math

import numpy as np

from .config import RobotConfig
from .grids import keep_out_mask
from .planners import astar


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


def narrow_route_metres(grid: np.ndarray, planning: np.ndarray, config: RobotConfig) -> float:
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
