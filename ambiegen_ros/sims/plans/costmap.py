"""Nav2's costmap, restated in numpy: cost values, cell rounding, footprints and inflation.

Every rule below is read from navigation2's ``jazzy`` branch (release 1.3.x); the file and
function are named beside each one, so that a disagreement can be settled by reading the source.

* Cost values (``nav2_costmap_2d/include/nav2_costmap_2d/cost_values.hpp``): 0 ``FREE_SPACE``,
  252 ``MAX_NON_OBSTACLE``, 253 ``INSCRIBED_INFLATED_OBSTACLE``, 254 ``LETHAL_OBSTACLE``, 255
  ``NO_INFORMATION``.
* World to cell (``costmap_2d.cpp``, ``Costmap2D::worldToMap``): outside when ``wx < origin_x``;
  else ``mx = (unsigned int)((wx - origin_x) / resolution)`` (truncation, i.e. floor for the
  non-negative quotient), inside when ``mx < size_x``. Cell to world (``Costmap2D::mapToWorld``):
  the cell's centre, ``origin_x + (mx + 0.5) * resolution``. ``Costmap2D::cellDistance``:
  ``ceil(world_dist / resolution)`` in double precision (0.07 m at 0.005 m gives 15 cells: the
  quotient is 14.000000000000002; Jazzy's 0.7 m at 0.05 m gives 14, 0.55 m gives 11).
* A map as the static layer reads it (``plugins/static_layer.cpp``, ``StaticLayer::interpretValue``):
  the unknown value (-1) gives 255 when ``track_unknown_space`` (Jazzy's nav2_params.yaml: true),
  else 0; a value >= ``lethal_cost_threshold`` (100) gives 254; anything else 0 with
  ``trinary_costmap`` (default true).
* The published OccupancyGrid of a costmap (``src/costmap_2d_publisher.cpp``, the translation
  table): 0 -> 0, 253 -> 99, 254 -> 100, 255 -> -1, 1..252 -> ``1 + 97 * (c - 1) / 251``
  (integer division). ``from_costmap_grid`` inverts it exactly for 0, 253, 254, 255; the
  mid costs come back as the lowest cost with that grid value (lossy; the collision rules only
  use 253, 254 and 255, which survive).
* A round robot's footprint (``src/footprint.cpp``, ``makeFootprintFromRadius``): a 16-gon of the
  radius; its inscribed radius (``calculateMinAndMaxDistances``, the least distance from the
  centre to a vertex or an edge) is ``radius * cos(pi / 16)``, 0.2158 m for Jazzy's 0.22 m.
* Inflation (``plugins/inflation_layer.cpp`` and ``include/.../inflation_layer.hpp``):
  ``computeCost(d)`` with ``d`` the distance in cells between the cell and its obstacle cell:
  254 at d == 0; 253 when ``d * resolution <= inscribed_radius``; else
  ``(unsigned char)(252 * exp(-cost_scaling_factor * (d * resolution - inscribed_radius)))``
  (truncation, no rounding). ``updateCosts`` spreads from every LETHAL cell (and every unknown
  one under ``inflate_around_unknown``) in a brushfire: cells are queued in bins of increasing
  integer distance level (``generateIntegerDistances``), each cell is costed once, from the
  obstacle whose front reached it first, and only while the distance is ``<= cellDistance(
  inflation_radius)``. A cell keeps ``max(old, new)``; an unknown cell takes the new cost only when
  it is >= 253 (or > 0 under ``inflate_unknown``). ``inflate`` below runs that same algorithm,
  in the same order, so its costs are Nav2's to the bit (not a Euclidean distance transform,
  which differs where two obstacles' fronts meet).

Jazzy's defaults (``nav2_bringup/params/nav2_params.yaml`` on the jazzy branch and tags 1.3.0 to
1.3.13): ``robot_radius`` 0.22, ``resolution`` 0.05, ``track_unknown_space`` true, and the global
and local inflation ``cost_scaling_factor`` 3.0 with ``inflation_radius`` **0.7** (0.55 is
Humble's value, and the one of this project's ``config/nav2/pioneer_navfn_dwb.yaml``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from ...core.accel import compiled_or_plain

FREE_SPACE = 0
MAX_NON_OBSTACLE = 252
INSCRIBED = 253
LETHAL = 254
NO_INFORMATION = 255


@dataclass(frozen=True)
class Nav2Defaults:
    """Jazzy's nav2_params.yaml values that the costmap depends on (see the module docstring)."""

    robot_radius: float = 0.22
    resolution: float = 0.05
    inflation_radius: float = 0.7
    cost_scaling_factor: float = 3.0
    track_unknown_space: bool = True


JAZZY = Nav2Defaults()


@dataclass
class Costmap:
    """A costmap as Nav2 holds it: ``cost[my, mx]`` (row-major, index ``my * size_x + mx``)."""

    cost: np.ndarray
    resolution: float
    origin_x: float = 0.0
    origin_y: float = 0.0

    def __post_init__(self) -> None:
        self.cost = np.ascontiguousarray(self.cost, dtype=np.uint8)
        if self.cost.ndim != 2:
            raise ValueError(f"a costmap is 2-D, got shape {self.cost.shape}")

    @property
    def size_x(self) -> int:
        return int(self.cost.shape[1])

    @property
    def size_y(self) -> int:
        return int(self.cost.shape[0])

    def world_to_map(self, wx: float, wy: float) -> tuple[int, int] | None:
        """``Costmap2D::worldToMap``: the cell holding (wx, wy), or None outside the map."""
        if wx < self.origin_x or wy < self.origin_y:
            return None
        mx = int((wx - self.origin_x) / self.resolution)
        my = int((wy - self.origin_y) / self.resolution)
        if mx < self.size_x and my < self.size_y:
            return mx, my
        return None

    def map_to_world(self, mx: float, my: float) -> tuple[float, float]:
        """``Costmap2D::mapToWorld``: the centre of cell (mx, my)."""
        return self.origin_x + (mx + 0.5) * self.resolution, self.origin_y + (my + 0.5) * self.resolution

    def cells_at(self, wx: float, wy: float, eps: float = 1e-6) -> list[tuple[int, int]]:
        """Every in-map cell whose closed square, grown by ``eps`` metres, holds (wx, wy).

        One cell inside a cell; two or four on an edge or a corner. A pose on a cell edge belongs
        to either cell up to floating point (NavFn's poses lie on cell corners), so the oracles
        call such a pose lethal only when all of them are.
        """
        fx = (wx - self.origin_x) / self.resolution
        fy = (wy - self.origin_y) / self.resolution
        e = eps / self.resolution
        xs = range(math.floor(fx - e), math.floor(fx + e) + 1)
        ys = range(math.floor(fy - e), math.floor(fy + e) + 1)
        return [(x, y) for y in ys for x in xs if 0 <= x < self.size_x and 0 <= y < self.size_y]

    def cell_distance(self, world_dist: float) -> int:
        """``Costmap2D::cellDistance``."""
        return int(max(0.0, math.ceil(world_dist / self.resolution)))

    @classmethod
    def from_flat(cls, data: Sequence[int], size_x: int, size_y: int, resolution: float,
                  origin_x: float = 0.0, origin_y: float = 0.0) -> "Costmap":
        """From a nav2_msgs/Costmap's ``data`` (uint8, row-major) and metadata."""
        arr = np.asarray(data, dtype=np.uint8).reshape(size_y, size_x)
        return cls(arr, resolution, origin_x, origin_y)

    @classmethod
    def from_costmap_grid(cls, data: Sequence[int], width: int, height: int, resolution: float,
                          origin_x: float = 0.0, origin_y: float = 0.0) -> "Costmap":
        """From the OccupancyGrid a Nav2 costmap publishes (``costmap_2d_publisher.cpp``)."""
        grid = np.asarray(data, dtype=np.int16).reshape(height, width)
        inverse = np.zeros(256, dtype=np.uint8)  # grid value (as uint8) -> lowest cost giving it
        for c in range(252, 0, -1):
            inverse[1 + (97 * (c - 1)) // 251] = c
        inverse[0], inverse[99], inverse[100], inverse[255] = FREE_SPACE, INSCRIBED, LETHAL, NO_INFORMATION
        return cls(inverse[grid.astype(np.uint8)], resolution, origin_x, origin_y)


def static_layer_costs(occupancy: np.ndarray, track_unknown_space: bool = True,
                       lethal_threshold: int = 100, trinary: bool = True) -> np.ndarray:
    """``StaticLayer::interpretValue`` over an OccupancyGrid's values (-1 unknown, 0..100)."""
    occ = np.asarray(occupancy, dtype=np.int16)
    out = np.zeros(occ.shape, dtype=np.uint8)
    unknown = occ == -1
    lethal = ~unknown & (occ >= lethal_threshold)
    if not trinary:
        scaled = (occ.astype(np.float64) / lethal_threshold * LETHAL).astype(np.uint8)
        out = np.where(~unknown & ~lethal & (occ > 0), scaled, out).astype(np.uint8)
    out[lethal] = LETHAL
    out[unknown] = NO_INFORMATION if track_unknown_space else FREE_SPACE
    return out


def footprint_from_radius(radius: float) -> np.ndarray:
    """``makeFootprintFromRadius``: the 16-gon Nav2 uses for a round robot, shape (16, 2)."""
    angles = np.arange(16) * 2 * math.pi / 16
    return np.column_stack([np.cos(angles) * radius, np.sin(angles) * radius])


def _distance_to_segment(x0: float, y0: float, x1: float, y1: float) -> float:
    """costmap_math.cpp ``distanceToLine`` from the origin to the segment (x0, y0)-(x1, y1)."""
    c, d = x1 - x0, y1 - y0
    param = (-x0 * c - y0 * d) / (c * c + d * d)
    if param < 0:
        xx, yy = x0, y0
    elif param > 1:
        xx, yy = x1, y1
    else:
        xx, yy = x0 + param * c, y0 + param * d
    return math.hypot(xx, yy)


def inscribed_radius(footprint: np.ndarray) -> float:
    """``calculateMinAndMaxDistances``'s first value: the footprint's inscribed radius."""
    pts = np.asarray(footprint, dtype=float)
    n = len(pts)
    if n <= 2:
        return float("inf")
    best = float("inf")
    for i in range(n):
        (x0, y0), (x1, y1) = pts[i], pts[(i + 1) % n]
        best = min(best, math.hypot(x0, y0), _distance_to_segment(x0, y0, x1, y1))
    return best


def _integer_levels(r: int) -> np.ndarray:
    """``generateIntegerDistances``: rank of x*x + y*y among the disc's points, (2r+1, 2r+1)."""
    span = np.arange(-r, r + 1)
    sq = span[:, None] ** 2 + span[None, :] ** 2  # indexed [x + r, y + r]
    levels = np.zeros(sq.shape, dtype=np.int64)
    inside = sq <= r * r
    uniq = np.unique(sq[inside])
    levels[inside] = np.searchsorted(uniq, sq[inside])
    return levels


def _brushfire(master: np.ndarray, sources: np.ndarray, cached: np.ndarray, levels: np.ndarray,
               cell_radius: int, n_levels: int, inflate_unknown: bool) -> None:
    """``InflationLayer::updateCosts`` over the whole map, in place (numba-compilable)."""
    size_y, size_x = master.shape
    r = cell_radius + 2
    seen = np.zeros(size_y * size_x, dtype=np.bool_)
    # the bins of Nav2's inflation_cells_, as one array of (mx, my, sx, sy) rows per level
    cap = size_x * size_y * 5 + 16  # each cell queued at most 4 times, plus the sources
    qx = np.empty(cap, dtype=np.int64)
    qy = np.empty(cap, dtype=np.int64)
    qsx = np.empty(cap, dtype=np.int64)
    qsy = np.empty(cap, dtype=np.int64)
    qlev = np.empty(cap, dtype=np.int64)
    heads = np.full(n_levels + 1, -1, dtype=np.int64)  # a linked list per level, in insertion order
    tails = np.full(n_levels + 1, -1, dtype=np.int64)
    nxt = np.full(cap, -1, dtype=np.int64)
    n = 0
    for k in range(sources.shape[0]):
        qx[n], qy[n], qsx[n], qsy[n], qlev[n] = sources[k, 0], sources[k, 1], sources[k, 0], sources[k, 1], 0
        if tails[0] < 0:
            heads[0] = n
        else:
            nxt[tails[0]] = n
        tails[0] = n
        n += 1
    for level in range(n_levels + 1):
        i = heads[level]
        while i >= 0:
            mx, my, sx, sy = qx[i], qy[i], qsx[i], qsy[i]
            index = my * size_x + mx
            if not seen[index]:
                seen[index] = True
                dx, dy = abs(mx - sx), abs(my - sy)
                cost = cached[dx, dy]
                old = master[my, mx]
                if old == 255 and ((cost > 0) if inflate_unknown else (cost >= 253)):
                    master[my, mx] = cost
                else:
                    master[my, mx] = max(old, cost)
                for nx_, ny_ in ((mx - 1, my), (mx, my - 1), (mx + 1, my), (mx, my + 1)):
                    if nx_ < 0 or ny_ < 0 or nx_ >= size_x or ny_ >= size_y:
                        continue
                    if seen[ny_ * size_x + nx_]:
                        continue
                    ddx, ddy = nx_ - sx, ny_ - sy
                    if math.sqrt(ddx * ddx + ddy * ddy) > cell_radius:
                        continue
                    lev = levels[ddx + r, ddy + r]
                    qx[n], qy[n], qsx[n], qsy[n], qlev[n] = nx_, ny_, sx, sy, lev
                    if tails[lev] < 0:
                        heads[lev] = n
                    else:
                        nxt[tails[lev]] = n
                    tails[lev] = n
                    n += 1
            i = nxt[i]


def inflate(costs: np.ndarray, resolution: float, inflation_radius: float = JAZZY.inflation_radius,
            cost_scaling_factor: float = JAZZY.cost_scaling_factor,
            inscribed: float | None = None, robot_radius: float = JAZZY.robot_radius,
            inflate_unknown: bool = False, inflate_around_unknown: bool = False) -> np.ndarray:
    """The master grid after Nav2's inflation layer (a new array; ``costs`` as the static layer gives).

    ``inscribed`` defaults to the inscribed radius of the 16-gon Nav2 builds from ``robot_radius``.
    """
    master = np.array(costs, dtype=np.uint8, copy=True)
    if inscribed is None:
        inscribed = inscribed_radius(footprint_from_radius(robot_radius))
    cell_radius = int(max(0.0, math.ceil(inflation_radius / resolution)))
    if cell_radius == 0:
        return master
    length = cell_radius + 2
    ij = np.arange(length)
    dist = np.hypot(ij[:, None], ij[None, :])
    cached = np.zeros((length, length), dtype=np.uint8)
    for a in range(length):
        for b in range(length):
            cached[a, b] = compute_cost(float(dist[a, b]), resolution, inscribed, cost_scaling_factor)
    levels = _integer_levels(length)
    src = (master == LETHAL) | ((master == NO_INFORMATION) if inflate_around_unknown else False)
    ys, xs = np.nonzero(src)  # row-major, as Nav2's loop (j outer, i inner)
    sources = np.column_stack([xs, ys]).astype(np.int64)
    compiled_or_plain(_brushfire)(master, sources, cached, levels, cell_radius, int(levels.max()), bool(inflate_unknown))
    return master


def compute_cost(distance_cells: float, resolution: float, inscribed: float, cost_scaling_factor: float) -> int:
    """``InflationLayer::computeCost``: the cost at ``distance_cells`` from an obstacle cell."""
    if distance_cells == 0:
        return LETHAL
    if distance_cells * resolution <= inscribed:
        return INSCRIBED
    factor = math.exp(-1.0 * cost_scaling_factor * (distance_cells * resolution - inscribed))
    return int((INSCRIBED - 1) * factor)


def costmap_from_occupancy(occupancy: np.ndarray, resolution: float = JAZZY.resolution,
                           origin: tuple[float, float] = (0.0, 0.0), defaults: Nav2Defaults = JAZZY,
                           **inflation: Any) -> Costmap:
    """The global costmap Nav2 builds from a map alone (static layer, then inflation).

    ``occupancy`` is an OccupancyGrid's values, row 0 at the map's origin. The obstacle layer
    adds what the robot's sensors see; a scenario's static map gives the rest.
    """
    static = static_layer_costs(occupancy, defaults.track_unknown_space)
    opts = {"inflation_radius": defaults.inflation_radius, "cost_scaling_factor": defaults.cost_scaling_factor,
            "robot_radius": defaults.robot_radius}
    opts.update(inflation)
    return Costmap(inflate(static, resolution, **opts), resolution, origin[0], origin[1])
