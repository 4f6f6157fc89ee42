"""The reference planner: a path Nav2 should have found (a certificate), or a proof there is none.

When a Nav2 planner fails (NO_VALID_PATH, a timeout, any error), the failure counts only if a
path exists under that planner's own rules (``rules.PlannerRules``) on the costmap it saw. This
module decides that, on the grid, with two move sets so that neither answer can be argued with:

* **certificate** (strict): 8-connected moves between traversable cells, a diagonal only when both
  cells beside it are traversable too (no corner cutting), ending in a cell *surely* inside the
  goal tolerance: the goal's own cell, or a cell whose centre is within ``tolerance - resolution``
  of the goal (Euclidean for Smac, per axis for NavFn's square). Every move of such a path is a
  move NavFn (4-connected potential), Smac 2D (Moore neighbourhood) and Theta* make too, and every
  cell passes the planner's centre-cell test, so the path is a certificate for these planners.
* **proof of absence** (loose): the start's connected component under 8-connected moves *with*
  corner cutting, over the same traversable cells, holds no cell within ``tolerance + 2 *
  resolution`` of the goal (nor the goal's cell). No planner with that centre-cell rule can reach
  the goal then, however it rounds poses or tolerances.
* between the two (a loose route exists, a strict one does not): ``undecided``; such a failure is
  reported as a hint, never a finding.

**Through poses** (``reference_through``, Nav2's ``ComputePathThroughPoses``): leg by leg as
Jazzy's ``planner_server`` plans them (``PlannerServer::computePlanThroughPoses``), each leg from
where the previous one *ended* (a cell surely inside the via's tolerance), not from the via. The
legs joined are the certificate. It holds wherever in the tolerance region the planner's own leg
ended: that end is joined to the start by the planner's moves, which are symmetric and never fewer
than the strict ones (NavFn's 4-connected potential has the strict moves' components), so the next
leg exists from there too. A leg proved absent proves the whole question absent, by the same
argument with the loose moves.

A 2D reference path is a certificate only for planners that judge a pose by its centre cell (NavFn,
Smac 2D, Theta*, and Hybrid/Lattice with a round robot *as far as collisions go*). For Smac
Hybrid-A* and Lattice the path must also turn no tighter than the minimum radius (and, with a
polygon footprint, keep the outline off lethal cells): a 2D path is then a **hint**, not a
certificate, and a kinematic reference (a Hybrid-A* of our own) is not built yet. The proof of
absence holds for them as well (a kinematic path is a 2D path too).

Speed: traversability and the two connectivity questions are ``scipy.ndimage.label``; the
certificate path, once the labels say one exists, is an A* (octile heuristic) compiled by numba
when it loads (``core.accel``), plain Python otherwise (the figures: ``bench/plan_reference.py``).
"""
from __future__ import annotations

import heapq
import math
from dataclasses import dataclass, field
from typing import Any, Optional, Sequence

import numpy as np
from scipy import ndimage

from ...core.accel import compiled_or_plain

from .costmap import Costmap
from .rules import PlannerRules

_SQRT2 = math.sqrt(2.0)
_FOUR = ndimage.generate_binary_structure(2, 1)
_EIGHT = ndimage.generate_binary_structure(2, 2)


@dataclass
class ReferenceResult:
    """The reference planner's answer for one start and goal.

    ``status``: ``path`` (``cells``/``poses`` hold the certificate), ``absent`` (proved: see
    ``component_cells`` and ``closest``), ``undecided``, or why the question is void:
    ``start_outside``, ``goal_outside``, ``start_blocked`` (a planner may refuse such a start).
    """

    status: str
    detail: str
    cells: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), dtype=np.int64))  # (N, 2) mx, my
    poses: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))  # (N, 2) cell centres, metres
    length: float = 0.0  # metres, along the certificate
    component_cells: int = 0  # size of the start's (loose) component
    closest: float = math.inf  # metres from the goal to the nearest cell of that component
    legs: list = field(default_factory=list)  # through poses: the cells of each leg found (the last may be missing)

    @property
    def found(self) -> bool:
        return self.status == "path"

    def to_dict(self) -> dict:
        """JSON-ready, for saving the certificate beside the run."""
        out = {"status": self.status, "detail": self.detail, "cells": self.cells.tolist(),
               "poses": [[round(x, 4), round(y, 4)] for x, y in self.poses.tolist()],
               "length": round(self.length, 4), "component_cells": self.component_cells,
               "closest": None if math.isinf(self.closest) else round(self.closest, 4)}
        if self.legs:
            out["legs"] = list(self.legs)
        return out


def goal_distance(costmap: Costmap, goal: tuple[float, float], metric: str) -> np.ndarray:
    """Distance (m) from every cell's centre to the goal: Euclidean, or per axis (``square``)."""
    xs = costmap.origin_x + (np.arange(costmap.size_x) + 0.5) * costmap.resolution
    ys = costmap.origin_y + (np.arange(costmap.size_y) + 0.5) * costmap.resolution
    dx = np.abs(xs - goal[0])[None, :]
    dy = np.abs(ys - goal[1])[:, None]
    if metric == "square":
        return np.maximum(dx, dy)
    return np.hypot(dx, dy)


class ReferenceGrid:
    """One costmap under one planner's rules; answers many start/goal questions."""

    def __init__(self, costmap: Costmap, rules: PlannerRules):
        self.costmap = costmap
        self.rules = rules
        self.free = rules.traversable(costmap.cost)
        self._graph = None

    def plan(self, start: tuple[float, float], goal: tuple[float, float]) -> ReferenceResult:
        """The certificate, the proof of absence, or why neither applies."""
        cm, rules = self.costmap, self.rules
        s = cm.world_to_map(*start)
        if s is None:
            return ReferenceResult("start_outside", f"start ({start[0]:.3f}, {start[1]:.3f}) is outside the map")
        g = cm.world_to_map(*goal)
        if g is None:
            return ReferenceResult("goal_outside", f"goal ({goal[0]:.3f}, {goal[1]:.3f}) is outside the map")
        free = self.free
        if not free[s[1], s[0]]:
            if not rules.start_cleared:
                return ReferenceResult("start_blocked", f"start cell {s} has cost {cm.cost[s[1], s[0]]}: "
                                       f"{rules.name} may refuse it")
            free = free.copy()
            free[s[1], s[0]] = True
        dist = goal_distance(cm, goal, rules.tolerance_metric)
        res = cm.resolution
        strict_goal = free & (dist <= rules.tolerance - res)
        loose_goal = free & (dist <= rules.tolerance + 2 * res)
        strict_goal[g[1], g[0]] = loose_goal[g[1], g[0]] = bool(free[g[1], g[0]])
        loose_lab, _ = ndimage.label(free, structure=_EIGHT)
        component = loose_lab == loose_lab[s[1], s[0]]
        n_comp = int(component.sum())
        closest = float(dist[component].min())
        if not (component & loose_goal).any():
            return ReferenceResult("absent", f"the start's component ({n_comp} cells) comes no closer than "
                                   f"{closest:.3f} m to the goal (tolerance {rules.tolerance} m)",
                                   component_cells=n_comp, closest=closest)
        strict_lab, _ = ndimage.label(free, structure=_FOUR)
        reach = strict_lab == strict_lab[s[1], s[0]]
        targets = reach & strict_goal
        if not targets.any():
            return ReferenceResult("undecided", "the goal is reachable only by cutting a corner or just outside "
                                   "the sure part of the tolerance", component_cells=n_comp, closest=closest)
        return self._certificate(free, s, targets, dist, n_comp, closest)

    def _certificate(self, free: np.ndarray, s: tuple[int, int], targets: np.ndarray, dist: np.ndarray,
                     n_comp: int, closest: float) -> ReferenceResult:
        """Shortest strict path (A*, octile heuristic) to a reachable sure-goal cell nearest the goal."""
        cm = self.costmap
        nx = cm.size_x
        ty, tx = np.nonzero(targets)
        best = dist[ty, tx] == dist[ty, tx].min()
        aim = np.zeros(free.shape, dtype=np.bool_)
        aim[ty[best], tx[best]] = True
        cx, cy = float(tx[best].mean()), float(ty[best].mean())  # the heuristic aims at their middle ...
        slack = float(np.max(np.hypot(tx[best] - cx, ty[best] - cy))) * _SQRT2  # ... less this
        end, cost, parent = compiled_or_plain(_astar)(free, s[0], s[1], aim, cx, cy, slack)
        chain = [int(end)]
        start_i = s[1] * nx + s[0]
        while chain[-1] != start_i:
            chain.append(int(parent[chain[-1]]))
        ids = np.array(chain[::-1], dtype=np.int64)
        cells = np.column_stack([ids % nx, ids // nx])
        poses = np.column_stack([cm.origin_x + (cells[:, 0] + 0.5) * cm.resolution,
                                 cm.origin_y + (cells[:, 1] + 0.5) * cm.resolution])
        length = float(cost) * cm.resolution
        return ReferenceResult("path", f"a path of {len(cells)} cells ({length:.2f} m) to cell "
                               f"({cells[-1, 0]}, {cells[-1, 1]})", cells, poses, length, n_comp, closest)


def _astar(free: np.ndarray, sx: int, sy: int, aim: np.ndarray, cx: float, cy: float, slack: float):
    """A* over strict moves from (sx, sy) to any ``aim`` cell: (end index, its cost in cells, parents).

    The caller has proved an aim cell reachable (4-connected labels). Octile distance to (cx, cy)
    less ``slack`` never overestimates. Plain Python, or compiled by numba (same result).
    """
    ny, nx = free.shape
    n = ny * nx
    g = np.full(n, np.inf)
    parent = np.full(n, -1, dtype=np.int64)
    closed = np.zeros(n, dtype=np.bool_)
    s = sy * nx + sx
    g[s] = 0.0
    heap = [(0.0, 0.0, s)]
    dxs = (1, -1, 0, 0, 1, 1, -1, -1)
    dys = (0, 0, 1, -1, 1, -1, 1, -1)
    while len(heap) > 0:
        _, gu, u = heapq.heappop(heap)
        if closed[u]:
            continue
        closed[u] = True
        ux, uy = u % nx, u // nx
        if aim[uy, ux]:
            return u, gu, parent
        for k in range(8):
            vx, vy = ux + dxs[k], uy + dys[k]
            if vx < 0 or vy < 0 or vx >= nx or vy >= ny or not free[vy, vx]:
                continue
            w = 1.0
            if k >= 4:
                if not (free[uy, vx] and free[vy, ux]):
                    continue
                w = 1.4142135623730951
            v = vy * nx + vx
            ng = gu + w
            if ng < g[v]:
                g[v] = ng
                parent[v] = u
                ax, ay = abs(vx - cx), abs(vy - cy)
                h = max(ax, ay) + 0.41421356237309515 * min(ax, ay) - slack
                heapq.heappush(heap, (ng + max(h, 0.0), ng, v))
    return -1, np.inf, parent


def reference_plan(costmap: Costmap, rules: PlannerRules, start: tuple[float, float],
                   goal: tuple[float, float]) -> ReferenceResult:
    """One question, one answer (``ReferenceGrid`` keeps the grid for many)."""
    return ReferenceGrid(costmap, rules).plan(start, goal)


def reference_through(costmap: Costmap, rules: PlannerRules, start: tuple[float, float],
                      vias: Sequence[Sequence[float]], goal: tuple[float, float]) -> ReferenceResult:
    """Start -> vias -> goal leg by leg, each leg from where the last one ended (module docstring):
    the joined certificate (``legs``: cells per leg), or the first leg's proof of absence, its
    undecided answer or why it is void, its detail naming the leg."""
    grid = ReferenceGrid(costmap, rules)
    names = ["the start"] + [f"via {k + 1}" for k in range(len(vias))] + ["the goal"]
    here, parts = (float(start[0]), float(start[1])), []
    for k, target in enumerate([*vias, goal]):
        leg = grid.plan(here, (float(target[0]), float(target[1])))
        if not leg.found:
            leg.detail = f"leg {k + 1} ({names[k]} -> {names[k + 1]}): {leg.detail}"
            leg.legs = [len(p.cells) for p in parts]
            return leg
        parts.append(leg)
        here = (float(leg.poses[-1, 0]), float(leg.poses[-1, 1]))  # the next leg starts where this one ended
    cells = np.vstack([parts[0].cells] + [p.cells[1:] for p in parts[1:]])
    poses = np.vstack([parts[0].poses] + [p.poses[1:] for p in parts[1:]])
    length = sum(p.length for p in parts)
    sizes = [len(p.cells) for p in parts]
    return ReferenceResult("path", f"a path through {len(vias)} via(s), leg by leg ({' + '.join(map(str, sizes))} "
                           f"cells, {length:.2f} m) to cell ({cells[-1, 0]}, {cells[-1, 1]})", cells, poses, length,
                           parts[0].component_cells, parts[-1].closest, sizes)


def certificate_image(costmap: Costmap, paths: Optional[list[np.ndarray]] = None) -> np.ndarray:
    """An RGB picture (row 0 at the top, as a map is drawn) of the costmap with paths over it.

    Free white, inflated cost in shades of blue, 253 light red, 254 black, 255 grey; the paths'
    cells (``(N, 2)`` mx, my arrays) in green, then orange, then magenta.
    """
    c = costmap.cost
    img = np.empty(c.shape + (3,), dtype=np.uint8)
    shade = (255 - (c.astype(np.int32) * 160) // 252).astype(np.uint8)
    img[..., 0], img[..., 1], img[..., 2] = shade, shade, 255
    img[c == 253] = (255, 170, 170)
    img[c == 254] = (0, 0, 0)
    img[c == 255] = (128, 128, 128)
    for path, colour in zip(paths or [], [(0, 170, 0), (255, 140, 0), (200, 0, 200)]):
        p = np.asarray(path, dtype=np.int64)
        if len(p):
            img[p[:, 1], p[:, 0]] = colour
    return img[::-1]
