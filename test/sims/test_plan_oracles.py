"""Oracles for Nav2's global planners (issue 68), on crafted costmaps and paths.

Each test builds the costmap the way Nav2 would (``costmap_from_occupancy``: static layer, then
inflation) or by hand, and checks one rule of docs/planner_oracles.md: a path through a lethal cell
is flagged and one that only grazes inflated cells is not; a polygon corner on a lethal cell is
flagged; endpoints, turning radius, reversal, smoother and failure oracles; the reference planner's
certificate and proof of absence; the inflation's exact costs; Nav2's cell rounding.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from ambiegen_ros.core import accel
from ambiegen_ros.sims.plans import costmap as C
from ambiegen_ros.sims.plans import oracles as O
from ambiegen_ros.sims.plans import reference as R
from ambiegen_ros.sims.plans import rules as P
from ambiegen_ros.sims.plans.costmap import INSCRIBED, LETHAL, NO_INFORMATION, Costmap

RES = 0.05
INSCRIBED_R = 0.22 * math.cos(math.pi / 16)


def blank(nx: int = 60, ny: int = 60) -> np.ndarray:
    """An OccupancyGrid's values, all free."""
    return np.zeros((ny, nx), dtype=np.int16)


def centre(mx: float, my: float) -> tuple[float, float]:
    return ((mx + 0.5) * RES, (my + 0.5) * RES)


def line(a: tuple[float, float], b: tuple[float, float], step: float = RES, yaw: float | None = None) -> np.ndarray:
    """Poses from a to b every ``step`` metres, heading along the line unless ``yaw`` is given."""
    n = max(2, int(math.hypot(b[0] - a[0], b[1] - a[1]) / step) + 1)
    xs, ys = np.linspace(a[0], b[0], n), np.linspace(a[1], b[1], n)
    heading = math.atan2(b[1] - a[1], b[0] - a[0]) if yaw is None else yaw
    return np.column_stack([xs, ys, np.full(n, heading)])


# --- the costmap: rounding, layers, inflation -------------------------------------------------------------


def test_world_to_map_truncates_like_nav2_at_edges_and_the_map_border():
    cm = Costmap(np.zeros((10, 20), dtype=np.uint8), RES, origin_x=-1.0, origin_y=2.0)
    assert cm.world_to_map(-1.0, 2.0) == (0, 0)
    assert cm.world_to_map(-1.0 + 0.0499, 2.0) == (0, 0)
    assert cm.world_to_map(-1.0 + 0.05, 2.0)[0] in (0, 1)  # floating point decides, as in Nav2
    assert 0.15 / 0.05 < 3 and Costmap(np.zeros((5, 5), dtype=np.uint8), RES).world_to_map(0.15, 0.0) == (2, 0)
    assert cm.world_to_map(-1.0 + 20 * RES - 1e-9, 2.0 + 10 * RES - 1e-9) == (19, 9)  # the last cell
    assert cm.world_to_map(-1.0 + 20 * RES, 2.0) is None  # one past the last cell
    assert cm.world_to_map(-1.0 - 1e-12, 2.1) is None  # left of the origin: Nav2 says no, never cell 0
    assert cm.map_to_world(0, 0) == pytest.approx((-0.975, 2.025))
    assert sorted(cm.cells_at(-1.0 + 3 * RES, 2.0 + 4 * RES + 0.01)) == [(2, 4), (3, 4)]
    assert cm.cells_at(-1.0 + 3.5 * RES, 2.0 + 4.5 * RES) == [(3, 4)]


def test_cell_distance_is_a_ceiling_in_double_precision():
    cm = Costmap(np.zeros((2, 2), dtype=np.uint8), RES)
    assert cm.cell_distance(0.55) == 11 and cm.cell_distance(0.7) == 14  # 0.7 / 0.05 is 13.999999999999998
    fine = Costmap(np.zeros((2, 2), dtype=np.uint8), 0.005)
    assert 0.07 / 0.005 > 14 and fine.cell_distance(0.07) == 15  # a quotient just over an integer rounds up
    assert cm.cell_distance(0.0) == 0


def test_static_layer_and_published_grid_round_trip():
    occ = np.array([[-1, 0, 64, 65, 100]], dtype=np.int16)
    assert C.static_layer_costs(occ).tolist() == [[NO_INFORMATION, 0, 0, 0, LETHAL]]
    assert C.static_layer_costs(occ, track_unknown_space=False).tolist() == [[0, 0, 0, 0, LETHAL]]
    costs = np.arange(256, dtype=np.uint8)
    table = np.array([0] + [1 + (97 * (c - 1)) // 251 for c in range(1, 253)] + [99, 100, -1])
    back = Costmap.from_costmap_grid(table[costs], 256, 1, RES)
    assert back.cost[0, [0, 253, 254, 255]].tolist() == [0, INSCRIBED, LETHAL, NO_INFORMATION]
    assert (table[back.cost[0]] == table[costs]).all()  # mid costs: same grid value again


def test_round_robot_inscribed_radius_is_the_16_gon():
    assert C.inscribed_radius(C.footprint_from_radius(0.22)) == pytest.approx(INSCRIBED_R, abs=1e-12)
    assert C.inscribed_radius(np.array([[0.3, 0.1], [-0.3, 0.1], [-0.3, -0.1], [0.3, -0.1]])) == pytest.approx(0.1)


def test_inflation_reproduces_nav2_costs_around_one_obstacle():
    occ = blank(41, 41)
    occ[20, 20] = 100
    cm = C.costmap_from_occupancy(occ, inflation_radius=0.55, cost_scaling_factor=3.0)
    assert cm.cost[20, 20] == LETHAL
    for d in range(1, 16):
        expected = 0
        if d <= 11:  # cellDistance(0.55) cells
            if d * RES <= INSCRIBED_R:
                expected = INSCRIBED
            else:
                expected = int(252 * math.exp(-3.0 * (d * RES - INSCRIBED_R)))
        assert cm.cost[20, 20 + d] == expected, d
        assert cm.cost[20 - d, 20] == expected, d
    assert cm.cost[20, 25] == 227 and cm.cost[20, 31] == 92 and cm.cost[20, 32] == 0
    diag = math.hypot(3, 3) * RES  # 0.212 m: inside the inscribed radius
    assert diag <= INSCRIBED_R and cm.cost[23, 23] == INSCRIBED


def test_inflation_never_exceeds_the_nearest_obstacle_cost_and_mostly_equals_it():
    rng = np.random.default_rng(5)
    occ = blank(50, 40)
    occ[rng.random(occ.shape) < 0.02] = 100
    static = C.static_layer_costs(occ)
    got = C.inflate(static, RES, inflation_radius=0.55)
    ly, lx = np.nonzero(static == LETHAL)
    yy, xx = np.mgrid[0:40, 0:50]
    d = np.min(np.hypot(xx[..., None] - lx, yy[..., None] - ly), axis=-1)
    brute = np.zeros(static.shape, dtype=np.int64)
    for idx in np.ndindex(static.shape):
        if d[idx] <= 11:
            brute[idx] = C.compute_cost(float(d[idx]), RES, INSCRIBED_R, 3.0)
    assert (got <= brute).all()  # the brushfire's source is never nearer than the nearest obstacle
    assert (got == brute).mean() > 0.99


def test_inflation_keeps_unknown_unless_the_cost_is_inscribed():
    static = np.full((1, 30), NO_INFORMATION, dtype=np.uint8)
    static[0, 10] = LETHAL
    got = C.inflate(static, RES, inflation_radius=0.55)
    assert got[0, 10] == LETHAL and got[0, 14] == INSCRIBED  # 0.2 m <= inscribed: overwritten
    assert got[0, 15] == NO_INFORMATION  # 0.25 m: 227 would not overwrite unknown
    assert C.inflate(static, RES, inflation_radius=0.55, inflate_unknown=True)[0, 15] == 227


def test_compiled_and_plain_brushfire_agree():
    rng = np.random.default_rng(2)
    static = C.static_layer_costs(np.where(rng.random((30, 35)) < 0.05, 100, 0))
    compiled = C.inflate(static, RES)
    with pytest.MonkeyPatch.context() as mp:
        mp.setitem(accel.COMPILED, C._brushfire, C._brushfire)
        plain = C.inflate(static, RES)
    assert (compiled == plain).all()


# --- collisions ---------------------------------------------------------------------------------------------


def one_obstacle() -> Costmap:
    occ = blank()
    occ[30, 30] = 100
    return C.costmap_from_occupancy(occ)


def test_a_path_through_a_lethal_cell_is_flagged_at_that_pose():
    cm = one_obstacle()
    path = line(centre(5, 30), centre(55, 30))
    v = O.check_collisions(cm, path, P.smac_2d())
    assert v is not None and v.kind == "collision" and v.failed
    assert v.cell == (26, 30) and "inscribed radius" in v.detail  # the disc reaches it 4 cells early
    assert v.evidence == [(30, 30)]


def test_a_path_that_grazes_inflated_cells_is_clear():
    cm = one_obstacle()
    path = line(centre(5, 35), centre(55, 35))  # 0.25 m from the obstacle's centre: cost 227
    assert cm.cost[35, 30] == 227
    assert O.check_collisions(cm, path, P.navfn()) is None


def test_a_pose_in_an_inscribed_cell_collides_only_if_its_disc_holds_the_lethal_centre():
    cm = one_obstacle()
    assert cm.cost[30, 34] == INSCRIBED
    x, y = centre(34, 30)  # 0.20 m from the lethal centre
    checker = O.CollisionChecker(cm, P.navfn())
    assert checker.hits((x, y, 0.0))[0]
    assert not checker.hits((x + 0.024, y, 0.0))[0]  # same 253 cell, 0.224 m away: clear


def test_a_corner_pose_is_lethal_only_when_every_cell_it_touches_is():
    cost = np.zeros((10, 10), dtype=np.uint8)
    cost[4, 4] = LETHAL
    checker = O.CollisionChecker(Costmap(cost, RES), P.PlannerRules("bare", robot_radius=0.0001))
    assert checker.centre_lethal(4 * RES, 4 * RES) is None  # the corner of cells 3..4: three are free
    cost[3:5, 3:5] = LETHAL
    checker = O.CollisionChecker(Costmap(cost, RES), P.PlannerRules("bare", robot_radius=0.0001))
    assert checker.centre_lethal(4 * RES, 4 * RES) is not None


def test_a_corner_aligned_pose_in_the_cells_its_planner_cleared_is_a_half_cell_offset_not_a_collision():
    """NavFn and Smac 2D put their poses on the corners of the cells they checked: such a pose may
    come a few millimetres inside the inscribed radius of a lethal centre while every cell it
    touches is below INSCRIBED, as Nav2 reads it. Only a pose that both readings put in collision
    (its disc holds a lethal centre, and its cells are all INSCRIBED or above) is flagged."""
    cm = one_obstacle()
    checker = O.CollisionChecker(cm, P.navfn())
    lethal = np.array(centre(30, 30))
    offsets, flagged = [], []
    for cx in range(24, 38):
        for cy in range(24, 38):
            x, y = cx * RES, cy * RES  # a cell corner
            disc = math.hypot(*(lethal - (x, y))) < INSCRIBED_R
            cells = cm.cells_at(x, y)
            inscribed = all(cm.cost[c[1], c[0]] >= INSCRIBED for c in cells)
            hit = bool(checker.hits((x, y, 0.0))[0])
            assert hit == (disc and inscribed), (cx, cy)
            (offsets if disc and not inscribed else flagged if hit else []).append((cx, cy))
    assert offsets and flagged  # both cases occur around one obstacle


RECT = np.array([[0.3, 0.15], [-0.3, 0.15], [-0.3, -0.15], [0.3, -0.15]])


def test_a_polygon_corner_on_a_lethal_cell_is_flagged_and_a_clear_one_is_not():
    cost = np.zeros((40, 40), dtype=np.uint8)
    cost[20, 26] = LETHAL  # the cell spanning x 1.30..1.35, y 1.00..1.05
    cm = Costmap(cost, RES)
    rules = P.smac_hybrid(footprint=RECT)
    touching = (1.0 + 0.01, 1.025 - 0.15 + 0.0, 0.0)  # front-left corner at (1.31, 1.025)
    why, cells = O.CollisionChecker(cm, rules).hits(touching)
    assert why and (26, 20) in cells
    clear = (1.0 - 0.02, 1.025 - 0.15, 0.0)  # corner at (1.28, 1.025): the cell before
    assert O.CollisionChecker(cm, rules).hits(clear) == ("", [])
    turned = (1.0 + 0.01, 1.025 - 0.15, math.pi / 2)  # same place, turned: far from the cell
    assert O.CollisionChecker(cm, rules).hits(turned)[0] == ""


def test_a_lethal_cell_inside_a_large_footprint_is_flagged():
    cost = np.zeros((80, 80), dtype=np.uint8)
    cost[40, 44] = LETHAL
    big = RECT * 3  # 1.8 m x 0.9 m: the outline passes far from the cell
    why, cells = O.CollisionChecker(Costmap(cost, RES), P.smac_hybrid(footprint=big)).hits((2.0, 2.0, 0.3))
    assert why == "lethal cell (44, 40) lies inside its footprint" and cells == [(44, 40)]
    off_map = O.CollisionChecker(Costmap(cost, RES), P.smac_hybrid(footprint=big)).hits((0.5, 2.0, 0.0))
    assert "leaves the map" in off_map[0]


def test_bresenham_matches_nav2_line_iterator():
    assert O.bresenham(0, 0, 3, 1) == [(0, 0), (1, 0), (2, 1), (3, 1)]
    assert O.bresenham(2, 2, 2, -1) == [(2, 2), (2, 1), (2, 0), (2, -1)]
    assert O.bresenham(5, 5, 5, 5) == [(5, 5)]


def test_unknown_space_fails_only_without_allow_unknown():
    cost = np.zeros((20, 40), dtype=np.uint8)
    cost[:, 20] = NO_INFORMATION
    cm = Costmap(cost, RES)
    path = line(centre(2, 10), centre(38, 10))
    assert O.check_unknown(cm, path, P.smac_2d(allow_unknown=True)) is None
    v = O.check_unknown(cm, path, P.smac_2d(allow_unknown=False))
    assert v is not None and v.kind == "unknown_space" and v.cell == (20, 10)
    assert O.check_collisions(cm, path, P.smac_2d(allow_unknown=False)) is None  # unknown is no collision


# --- endpoints ------------------------------------------------------------------------------------------------


def test_a_path_must_start_at_the_start_and_end_within_tolerance():
    cm = Costmap(np.zeros((60, 60), dtype=np.uint8), RES)
    start, goal = (0.5, 0.5), (2.5, 2.5)
    good = line(start, goal)
    assert O.check_endpoints(cm, good, start, goal, P.smac_2d()) is None
    assert O.check_endpoints(cm, line((0.7, 0.5), goal), start, goal, P.smac_2d()).kind == "off_start"
    short = line(start, (2.5, 2.1))
    v = O.check_endpoints(cm, short, start, goal, P.smac_2d(tolerance=0.125))
    assert v.kind == "off_goal" and v.index == len(short) - 1
    assert O.check_endpoints(cm, np.zeros((0, 3)), start, goal, P.smac_2d()).kind == "empty_path"


def test_navfn_tolerance_is_a_square_smac_tolerance_a_circle():
    cm = Costmap(np.zeros((80, 80), dtype=np.uint8), RES)
    start, goal = (0.5, 0.5), (3.0, 3.0)
    corner = line(start, (2.5, 2.5))  # 0.5 m off on each axis: 0.71 m away
    assert O.check_endpoints(cm, corner, start, goal, P.navfn(tolerance=0.5)) is None
    assert O.check_endpoints(cm, corner, start, goal, P.smac_2d(tolerance=0.5)).kind == "off_goal"


# --- kinematics ------------------------------------------------------------------------------------------------


def hybrid_path(radius_m: float, plan: str, bins: int = 72, float32: bool = True) -> np.ndarray:
    """Poses chained from Smac Hybrid-A*'s Dubins primitives (``HybridMotionTable::initDubin``).

    ``plan``: one letter per primitive, S straight, L left, R right, B straight backwards.
    """
    r = radius_m / RES
    bin_size = 2 * math.pi / bins
    angle = 2.0 * math.asin(math.sqrt(2.0) / (2 * r))
    inc = 1.0 if angle < bin_size else math.ceil(angle / bin_size)
    angle = inc * bin_size
    dx, dy = r * math.sin(angle), r - r * math.cos(angle)
    step = {"S": (math.hypot(dx, dy), 0.0, 0.0), "L": (dx, dy, inc), "R": (dx, -dy, -inc),
            "B": (-math.hypot(dx, dy), 0.0, 0.0)}
    x, y, th = 100.0, 100.0, 0  # cells, heading bin
    out = [(x, y, th)]
    for p in plan:
        px, py, dth = step[p]
        c, s = math.cos(th * bin_size), math.sin(th * bin_size)
        x, y, th = x + px * c - py * s, y + px * s + py * c, (th + dth) % bins
        out.append((x, y, th))
    arr = np.array(out)
    xy = arr[:, :2] * RES
    if float32:
        xy = xy.astype(np.float32).astype(np.float64)
    return np.column_stack([xy, arr[:, 2] * bin_size])


def test_a_correct_hybrid_path_at_the_minimum_radius_is_not_flagged():
    path = hybrid_path(0.4, "SSS" + "L" * 12 + "SS" + "R" * 12 + "SLSRS")
    rules = P.smac_hybrid(minimum_turning_radius=0.4)
    assert O.check_turning(path, rules) is None
    assert O.check_reversal(path, rules) is None


def test_a_u_turn_tighter_than_the_minimum_radius_is_flagged():
    path = hybrid_path(0.25, "SS" + "L" * 12 + "SS")
    v = O.check_turning(path, P.smac_hybrid(minimum_turning_radius=0.4))
    assert v is not None and v.kind == "tight_turn" and v.failed
    assert "0.25" in v.detail or "0.24" in v.detail


def test_a_sampled_arc_of_the_minimum_radius_passes_and_a_smaller_one_fails():
    theta = np.linspace(0, math.pi, 40)
    arc = lambda r: np.column_stack([2 + r * np.sin(theta), 2 + r - r * np.cos(theta), theta])  # noqa: E731
    rules = P.smac_lattice(minimum_turning_radius=0.5)
    assert O.check_turning(arc(0.5), rules) is None
    assert O.check_turning(arc(0.45), rules).kind == "tight_turn"


def test_a_reversal_is_flagged_under_dubin_and_accepted_under_reeds_shepp():
    path = hybrid_path(0.4, "SSSS" + "BBBB" + "L" * 4)
    v = O.check_reversal(path, P.smac_hybrid("DUBIN"))
    assert v is not None and v.kind == "reversal" and v.index == 4
    assert O.check_reversal(path, P.smac_hybrid("REEDS_SHEPP")) is None
    assert O.check_turning(path, P.smac_hybrid("REEDS_SHEPP")) is None  # the cusp is no tight turn
    assert O.check_reversal(path, P.smac_lattice(allow_reverse_expansion=False)).kind == "reversal"
    assert O.check_reversal(path, P.navfn()) is None  # 2D planners: no kinematic oracle


# --- the reference planner --------------------------------------------------------------------------------------


def u_map() -> np.ndarray:
    """NavFn #6308's shape: a U corridor whose path is longer than twice the map's long side
    (NavFn's path extraction used to stop after 4 * max(nx, ny) half-cell steps)."""
    occ = np.full((100, 100), 100, dtype=np.int16)
    occ[5:96, 5:19] = 0  # left arm (rows are y), 0.7 m wide
    occ[5:96, 81:95] = 0  # right arm
    occ[5:19, 5:95] = 0  # the base, at low y
    return occ


def test_the_reference_finds_the_u_path_and_it_passes_our_own_oracles():
    cm = C.costmap_from_occupancy(u_map())
    start, goal = centre(12, 90), centre(88, 90)
    for rules in (P.navfn(), P.smac_2d(), P.theta_star()):
        ref = R.reference_plan(cm, rules, start, goal)
        assert ref.status == "path", (rules.name, ref.detail)
        steps = np.abs(np.diff(ref.cells, axis=0))
        assert steps.max() == 1 and (steps.sum(axis=1) >= 1).all()
        free = rules.traversable(cm.cost)
        assert free[ref.cells[:, 1], ref.cells[:, 0]].all()
        assert ref.length > 2 * 100 * RES  # longer than NavFn's old extraction limit allowed
        judged = O.judge_plan(cm, rules, start, goal, path=ref.poses)
        assert not judged.failed, judged.failures


def test_the_reference_proves_absence_when_the_goal_is_walled_off():
    occ = blank(60, 60)
    occ[35:50, 35] = occ[35:50, 49] = occ[35, 35:50] = occ[49, 35:50] = 100
    cm = C.costmap_from_occupancy(occ)
    ref = R.reference_plan(cm, P.smac_2d(), centre(5, 5), centre(42, 42))
    assert ref.status == "absent" and ref.closest > 0.125
    v = O.judge_failure(cm, P.smac_2d(), centre(5, 5), centre(42, 42), "NO_VALID_PATH", ref)
    assert v.kind == "correct_refusal" and not v.failed


def test_a_failure_with_a_certificate_is_a_finding_but_only_a_hint_for_hybrid():
    cm = C.costmap_from_occupancy(blank())
    start, goal = centre(5, 5), centre(50, 40)
    v = O.judge_failure(cm, P.navfn(), start, goal, "NO_VALID_PATH")
    assert v.kind == "missed_path" and v.failed and v.evidence.found
    assert v.evidence.to_dict()["status"] == "path"
    hint = O.judge_failure(cm, P.smac_hybrid(), start, goal, "TIMEOUT")
    assert hint.kind == "kinematic_hint" and not hint.failed


def test_a_goal_outside_the_map_makes_any_error_right():
    cm = C.costmap_from_occupancy(blank())
    v = O.judge_failure(cm, P.navfn(), centre(5, 5), (60 * RES + 0.01, 1.0), "GOAL_OUTSIDE_MAP")
    assert v.kind == "goal_outside_map" and not v.failed and "outside the map" in v.detail


def test_a_start_in_the_last_cell_is_inside_and_plannable():
    cm = C.costmap_from_occupancy(blank(40, 30))
    start = (40 * RES - 1e-9, 30 * RES - 1e-9)
    assert cm.world_to_map(*start) == (39, 29)
    ref = R.reference_plan(cm, P.smac_2d(), start, centre(10, 10))
    assert ref.status == "path" and tuple(ref.cells[0]) == (39, 29)
    # NavFn's outer ring is an obstacle (NavFn::setupNavFn) and its potential spreads 4-connected:
    # from the corner cell it reaches nothing, so no strict certificate exists
    assert R.reference_plan(cm, P.navfn(), start, centre(10, 10)).status in ("undecided", "absent")
    assert R.reference_plan(cm, P.navfn(), (40 * RES, 1.0), centre(10, 10)).status == "start_outside"


def test_a_smac_start_in_an_inscribed_cell_may_be_refused():
    cm = one_obstacle()
    assert cm.cost[30, 34] == INSCRIBED
    ref = R.reference_plan(cm, P.smac_2d(), centre(34, 30), centre(5, 5))
    assert ref.status == "start_blocked"
    assert R.reference_plan(cm, P.navfn(), centre(34, 30), centre(5, 5)).status == "path"  # NavFn clears it


def test_a_diagonal_only_gap_is_undecided_not_a_certificate():
    cost = np.full((10, 10), LETHAL, dtype=np.uint8)
    cost[1:4, 1:4] = 0
    cost[4:8, 4:8] = 0  # touches the first room only at a corner
    ref = R.reference_plan(Costmap(cost, RES), P.smac_2d(tolerance=0.0), centre(2, 2), centre(6, 6))
    assert ref.status == "undecided"


def test_compiled_and_plain_astar_agree():
    occ = u_map()
    cm = C.costmap_from_occupancy(occ)
    grid = R.ReferenceGrid(cm, P.smac_2d())
    compiled = grid.plan(centre(12, 90), centre(88, 90))
    with pytest.MonkeyPatch.context() as mp:
        mp.setitem(accel.COMPILED, R._astar, R._astar)
        plain = grid.plan(centre(12, 90), centre(88, 90))
    assert compiled.found and plain.length == pytest.approx(compiled.length)
    assert tuple(plain.cells[-1]) == tuple(compiled.cells[-1])


# --- smoother, crash, time, the combined judgement -----------------------------------------------------------------


def test_a_smoothed_path_that_cuts_into_a_lethal_cell_is_flagged():
    cm = one_obstacle()
    before = np.vstack([line(centre(20, 20), centre(20, 40))[:-1], line(centre(20, 40), centre(40, 40))])
    cut = line(centre(20, 20), centre(40, 40))  # the smoother took the diagonal through the obstacle
    assert O.check_collisions(cm, before, P.smac_2d()) is None
    v = O.check_smoother(cm, before, cut, P.smac_2d())
    assert v is not None and v.kind == "smoother_collision" and "was clear" in v.detail
    assert O.check_smoother(cm, before, before, P.smac_2d()) is None
    assert O.check_smoother(cm, cut, cut, P.smac_2d()) is None  # it collided already, in the same cells


def test_judge_plan_orders_failures_and_keeps_time_apart():
    cm = one_obstacle()
    start, goal = centre(5, 30), centre(55, 30)
    through = line(start, centre(45, 30))  # through the obstacle, and short of the goal
    j = O.judge_plan(cm, P.smac_2d(), start, goal, path=through, planning_time=9.0)
    assert [f.kind for f in j.failures] == ["off_goal", "collision"]
    assert j.verdict.kind == "off_goal"
    assert [n.kind for n in j.notes] == ["performance"] and not j.notes[0].failed
    around = O.judge_plan(cm, P.smac_2d(), start, goal, path=line(start, goal)[:, :2] + [0, 0.6], planning_time=0.1)
    assert around.failures[0].kind == "off_start"
    ok = O.judge_plan(cm, P.smac_2d(), centre(5, 10), centre(55, 10), path=line(centre(5, 10), centre(55, 10)),
                      planning_time=9.0)
    assert not ok.failed and ok.verdict.kind == "pass" and ok.notes[0].kind == "performance"


def test_a_crash_is_sut_crashed_with_its_stack_trace():
    cm = one_obstacle()
    trace = "\nterminate called after throwing 'std::out_of_range'\n#0 nav2_smac_planner::AStar...\n"
    j = O.judge_plan(cm, P.smac_hybrid(), centre(5, 5), centre(50, 50), crash=("planner_server", trace))
    assert j.verdict.kind == "sut_crashed" and j.failed
    assert "std::out_of_range" in j.verdict.detail and j.verdict.evidence == trace


def test_a_start_in_collision_is_noted_and_its_leaving_poses_not_judged():
    cm = one_obstacle()
    start = centre(31, 30)  # inside the inscribed disc of the obstacle
    path = line(start, centre(31, 50))
    j = O.judge_plan(cm, P.navfn(), start, centre(31, 50), path=path)
    assert not j.failed and any(n.kind == "start_blocked" for n in j.notes)


def test_quaternion_yaw():
    assert O.yaw_from_quaternion(0, 0, math.sin(0.35), math.cos(0.35)) == pytest.approx(0.7)


def test_the_certificate_is_drawn_over_the_costmap():
    cm = C.costmap_from_occupancy(u_map())
    ref = R.reference_plan(cm, P.navfn(), centre(12, 90), centre(88, 90))
    img = R.certificate_image(cm, [ref.cells])
    assert img.shape == (100, 100, 3)
    x, y = ref.cells[len(ref.cells) // 2]
    assert tuple(img[99 - y, x]) == (0, 170, 0)  # row 0 of the picture is the map's top
    assert tuple(img[0, 0]) == (0, 0, 0) and tuple(img[50, 50]) == (0, 0, 0)  # walls are black


def recorded(name: str):
    """A planner's answer recorded from Jazzy's own planner_server (test/data/planner_recorded:
    the global costmap it published, as an OccupancyGrid, and the path, from the run's bag)."""
    from pathlib import Path

    data = np.load(Path(__file__).resolve().parents[1] / "data" / "planner_recorded" / f"{name}.npz")
    grid = data["grid"]
    cm = Costmap.from_costmap_grid(grid.reshape(-1), grid.shape[1], grid.shape[0], float(data["resolution"]),
                                   *map(float, data["origin"]))
    path = np.column_stack([data["path"], np.full(len(data["path"]), np.nan)])
    return cm, path, tuple(data["start"]), tuple(data["goal"])


def test_jazzys_theta_star_path_through_inscribed_cells_is_a_collision():
    """Recorded (docs/results/nav2/planner_bugs/theta_star_los): 49 poses at the centres of cells of
    cost 253, along a wall; the oracles flag the first, whatever else holds."""
    cm, path, start, goal = recorded("theta_star_inscribed")
    judged = O.judge_plan(cm, P.theta_star(), start, goal, path=path)
    assert judged.failed and judged.verdict.kind == "collision", judged.verdict.detail
    inscribed = [i for i, (x, y, _) in enumerate(path) if cm.cost[cm.world_to_map(x, y)[::-1]] >= INSCRIBED]
    assert len(inscribed) == 49 and judged.verdict.index in inscribed  # the first whose disc holds a lethal centre


def test_jazzys_smac_2d_path_on_cell_corners_holds():
    """Recorded from our first sweep: Smac 2D's poses lie on the corners of the cells it cleared, one
    of them 0.215 m from a lethal centre (inside the 0.2158 m inscribed radius) while every cell it
    touches is below 253: a half-cell offset, not a collision (both readings must agree)."""
    cm, path, start, goal = recorded("smac_2d_corners")
    judged = O.judge_plan(cm, P.smac_2d(), start, goal, path=path)
    assert not judged.failed, judged.verdict.detail
    checker = O.CollisionChecker(cm, P.smac_2d())
    grazing = [i for i, pose in enumerate(path) if checker._disc_hits(pose[0], pose[1])]
    assert grazing and all(not checker.in_inscribed_cells(*path[i, :2]) for i in grazing)


# --- through poses (ComputePathThroughPoses) ------------------------------------------------------------------


def joined(*legs: np.ndarray) -> np.ndarray:
    """Legs joined as Jazzy's planner_server joins them: each later leg's first pose dropped."""
    return np.vstack([legs[0]] + [leg[1:] for leg in legs[1:]])


def test_a_path_through_every_via_in_order_holds_and_one_that_skips_or_reorders_them_misses_a_via():
    cm = C.costmap_from_occupancy(blank())
    start, a, b, goal = centre(5, 5), centre(50, 10), centre(50, 50), centre(5, 50)
    through = joined(line(start, a), line(a, b), line(b, goal))
    assert not O.judge_plan(cm, P.smac_2d(), start, goal, path=through, vias=[a, b]).failed
    skipped = O.judge_plan(cm, P.smac_2d(), start, goal, path=joined(line(start, a), line(a, goal)), vias=[a, b])
    assert [f.kind for f in skipped.failures] == ["missed_via"] and "via 2" in skipped.verdict.detail
    assert skipped.verdict.cell == cm.world_to_map(*b)  # the failure point is the via it missed
    backwards = joined(line(start, b), line(b, a), line(a, goal))  # b before a: a is met, b never after it
    assert O.judge_plan(cm, P.smac_2d(), start, goal, path=backwards, vias=[a, b]).verdict.kind == "missed_via"
    # the same poses asked without vias: nothing to miss
    assert not O.judge_plan(cm, P.smac_2d(), start, goal, path=joined(line(start, a), line(a, goal))).failed


def test_a_leg_may_end_anywhere_in_the_vias_tolerance_and_the_next_leg_starts_there():
    """Jazzy plans leg 2 from the end of leg 1 ("to allow for path tolerance deviations"): NavFn's
    0.5 m square lets leg 1 stop 0.4 m short of the via; Smac 2D's 0.125 m does not."""
    cm = C.costmap_from_occupancy(blank())
    start, via, goal = centre(5, 30), centre(30, 30), centre(30, 55)
    short = (via[0] - 0.4, via[1])
    path = joined(line(start, short), line(short, goal))
    assert not O.judge_plan(cm, P.navfn(), start, goal, path=path, vias=[via]).failed
    assert O.judge_plan(cm, P.smac_2d(), start, goal, path=path, vias=[via]).verdict.kind == "missed_via"


def test_a_jump_between_poses_is_a_path_gap_and_a_planners_own_steps_are_not():
    """Leg 2 starting at the via rather than where leg 1 ended jumps 0.4 m: no planner steps that far
    (two diagonal cells, 0.141 m at 0.05 m cells, plus R times Hybrid's angle bin when it turns)."""
    cm = C.costmap_from_occupancy(blank())
    start, via, goal = centre(5, 30), centre(30, 30), centre(30, 55)
    short = (via[0] - 0.4, via[1])
    jumped = joined(line(start, short), line(via, goal))
    v = O.judge_plan(cm, P.navfn(), start, goal, path=np.vstack([line(start, short), line(via, goal)]), vias=[via])
    assert [f.kind for f in v.failures] == ["path_gap"] and "0.400 m apart" in v.verdict.detail
    assert O.judge_plan(cm, P.navfn(), start, goal, path=jumped, vias=[via]).verdict.kind == "path_gap"
    coarse = joined(line(start, via, step=0.12), line(via, goal, step=0.12))  # 0.125 m: under 2 sqrt 2 cells
    assert not O.judge_plan(cm, P.navfn(), start, goal, path=coarse, vias=[via]).failed
    sparse = joined(line(start, via, step=0.15), line(via, goal, step=0.15))  # 0.156 m
    assert O.judge_plan(cm, P.navfn(), start, goal, path=sparse, vias=[via]).verdict.kind == "path_gap"
    hybrid = P.smac_hybrid(minimum_turning_radius=2.0)  # chords of 2 R sin(bin / 2) = 0.17 m are its own steps
    assert O.check_gaps(cm, sparse, hybrid) is None and O.max_step(hybrid, RES) > 0.17


def test_a_refusal_through_poses_is_a_finding_when_the_reference_passes_every_leg():
    """The U map, a via at the foot of the U: the reference plans leg by leg, each leg from where the
    last ended; the legs joined are the certificate, and they pass our own through-poses oracles."""
    cm = C.costmap_from_occupancy(u_map())
    start, via, goal = centre(12, 90), centre(50, 12), centre(88, 90)
    v = O.judge_failure(cm, P.navfn(), start, goal, "error 308", vias=[via])
    assert v.kind == "missed_path" and v.failed and "through 1 via" in v.detail
    cert = v.evidence
    assert len(cert.legs) == 2 and sum(cert.legs) - 1 == len(cert.cells) and cert.to_dict()["legs"] == cert.legs
    joint = cert.cells[cert.legs[0] - 1]  # leg 1's last cell is leg 2's first
    assert np.abs(np.asarray(cm.map_to_world(*joint)) - via).max() <= 0.5  # inside NavFn's square
    assert not O.judge_plan(cm, P.navfn(), start, goal, path=cert.poses, vias=[via]).failed
    # the one-goal certificate passes the U's foot but never goes back up the left arm after it
    off = centre(12, 50)
    direct = R.reference_plan(cm, P.smac_2d(), start, goal)
    assert O.judge_plan(cm, P.smac_2d(), start, goal, path=direct.poses, vias=[via, off]).verdict.kind == "missed_via"


def test_a_leg_starts_where_the_reference_ended_not_at_the_via():
    """A via on a lethal cell with free cells inside NavFn's 0.5 m square: leg 1 ends beside it and
    leg 2 starts from that cell; with Smac 2D's 0.125 m no cell of the tolerance is free: proved
    absent, the refusal right, and its detail names the leg."""
    occ = blank()
    occ[28:33, 28:33] = 100  # a pillar of 5 x 5 cells under the via
    cm = C.costmap_from_occupancy(occ)
    start, via, goal = centre(5, 30), centre(30, 30), centre(55, 30)
    cert = R.reference_through(cm, P.navfn(), start, [via], goal)
    assert cert.found, cert.detail
    joint = tuple(cert.cells[cert.legs[0] - 1])
    assert joint != cm.world_to_map(*via) and cm.cost[joint[1], joint[0]] < INSCRIBED
    proved = O.judge_failure(cm, P.smac_2d(), start, goal, "error 306", vias=[via])
    assert proved.kind == "correct_refusal" and not proved.failed
    assert proved.detail.startswith("no path exists: leg 1 (the start -> via 1)")


def test_an_unreachable_via_makes_the_refusal_right_and_a_via_off_the_map_any_error():
    occ = blank()
    occ[35:50, 35] = occ[35:50, 49] = occ[35, 35:50] = occ[49, 35:50] = 100  # a walled room
    cm = C.costmap_from_occupancy(occ)
    start, goal = centre(5, 5), centre(20, 50)
    v = O.judge_failure(cm, P.smac_2d(), start, goal, "error 308", vias=[centre(20, 20), centre(42, 42)])
    assert v.kind == "correct_refusal" and not v.failed and "leg 2 (via 1 -> via 2)" in v.detail
    assert v.evidence.legs == [v.evidence.legs[0]] and v.evidence.legs[0] > 1  # leg 1 was found
    off = O.judge_failure(cm, P.navfn(), start, goal, "error 304", vias=[(60 * RES + 0.01, 1.0)])
    assert off.kind == "goal_outside_map" and not off.failed
    judged = O.judge_plan(cm, P.navfn(), start, goal, path=line(start, goal), vias=[(60 * RES + 0.01, 1.0)])
    assert "goal_outside_map" in [n.kind for n in judged.notes]
