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

Package layout (imports point down): ``problem`` (``RobotProblem``, ``RobotMap``) -> ``route``
(what F1 measures of a route) -> ``planners`` (A*, the batch Dijkstra) and ``grids`` (walls to
occupancy, inflation) -> ``config`` (``RobotConfig`` and the constants). Issue 48's hazards
scenarios live beside the package (``problems.robot_hazards``), imported where used.
"""
from .config import (
    DIAGONAL_RULES,
    ENGINES,
    HAZARD_OBJECTIVES,
    HORIZONTAL,
    INFLATION_RULE,
    INFLATION_RULES,
    LOOP_OBJECTIVES,
    NO_PATH,
    OBJECTIVES,
    PROFILE_DEFAULTS,
    SCENARIO_KINDS,
    VERTICAL,
    RobotConfig,
)
from .grids import build_grids, dilate, inflate, inflation_footprint, keep_out_mask, wall_half_extent, wall_zone
from .planners import astar, batch_path_lengths, grid_graph
from .problem import REFINED_LAYOUT, REPLICATION_LAYOUT, RobotMap, RobotProblem
from .route import clearance, fold_above, narrow_route_metres

__all__ = [
    "DIAGONAL_RULES", "ENGINES", "HAZARD_OBJECTIVES", "HORIZONTAL", "INFLATION_RULE", "INFLATION_RULES",
    "LOOP_OBJECTIVES", "NO_PATH", "OBJECTIVES", "PROFILE_DEFAULTS", "REFINED_LAYOUT", "REPLICATION_LAYOUT",
    "SCENARIO_KINDS", "VERTICAL", "RobotConfig", "RobotMap", "RobotProblem",
    "astar", "batch_path_lengths", "build_grids", "clearance", "dilate", "fold_above", "grid_graph", "inflate",
    "inflation_footprint", "keep_out_mask", "narrow_route_metres", "wall_half_extent", "wall_zone",
]
