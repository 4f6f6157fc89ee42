"""Robot case study, refined profile: wall geometry, R2 keep-out, planners, plotting.

Every problem here is built with ``profile="refined"`` (today's model: the paper's rules and the
project spec); the replication profile has its own tests in ``test_robot_replication.py``.
"""
from __future__ import annotations

import heapq
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ambiegen_ros.core.attributes import ScenarioError
from ambiegen_ros.core.scenario import Scenario
from ambiegen_ros.problems import get_problem
from ambiegen_ros.problems.robot import (
    NO_PATH,
    RobotProblem,
    astar,
    batch_path_lengths,
    build_grids,
    inflate,
    keep_out_mask,
)

N = 50
START, GOAL = (1, 1), (48, 48)
EMPTY_LENGTH = 47 * math.sqrt(2)


def refined(config=None, **overrides) -> RobotProblem:
    """A robot problem in the refined profile."""
    if config is not None:
        return RobotProblem({**config, "profile": "refined"}, **overrides)
    return RobotProblem(profile="refined", **overrides)


@pytest.fixture(scope="module")
def problem():
    return refined()


def empty_grid(n: int = N) -> np.ndarray:
    grid = np.zeros((n, n), dtype=bool)
    grid[0, :] = grid[-1, :] = grid[:, 0] = grid[:, -1] = True
    return grid


def reference_dijkstra(grid, start, goal, diagonal="both_free"):
    """Independent shortest path: plain Dijkstra over an explicit dict adjacency list."""
    H, W = grid.shape

    def free(x, y):
        return 0 <= x < W and 0 <= y < H and not grid[y, x]

    adjacency = {}
    for y in range(H):
        for x in range(W):
            if not free(x, y):
                continue
            edges = []
            for dx in (-1, 0, 1):
                for dy in (-1, 0, 1):
                    if (dx or dy) and free(x + dx, y + dy):
                        if dx and dy:
                            sides = (free(x + dx, y), free(x, y + dy))
                            if diagonal == "both_free" and not all(sides):
                                continue
                            if diagonal == "one_free" and not any(sides):
                                continue
                        edges.append(((x + dx, y + dy), math.hypot(dx, dy)))
            adjacency[(x, y)] = edges
    if start not in adjacency or goal not in adjacency:
        return math.inf
    dist = {start: 0.0}
    heap = [(0.0, start)]
    while heap:
        d, node = heapq.heappop(heap)
        if node == goal:
            return d
        if d > dist[node]:
            continue
        for nxt, cost in adjacency[node]:
            if d + cost < dist.get(nxt, math.inf):
                dist[nxt] = d + cost
                heapq.heappush(heap, (d + cost, nxt))
    return math.inf


def naive_grid(elements, config):
    """Wall rasterisation written element by element, as the spec words it."""
    grid = empty_grid(config.map_size)
    keep = keep_out_mask(config)
    for i, (kind, size, pos) in enumerate(elements):
        row = i + 1
        centre = pos if kind == 0 else row  # horizontal walls run along x, vertical along y
        for c in range(1, config.map_size - 1):
            if abs(c - centre) <= size / 2:
                x, y = (c, row) if kind == 0 else (pos, c)
                if not keep[y, x]:
                    grid[y, x] = True
    return grid


def check_path(grid, path, length, start, goal):
    """A returned path starts/ends right, uses legal moves only and its cost equals the length."""
    assert path[0] == tuple(start) and path[-1] == tuple(goal)
    total = 0.0
    for (x0, y0), (x1, y1) in zip(path, path[1:]):
        dx, dy = x1 - x0, y1 - y0
        assert max(abs(dx), abs(dy)) == 1
        assert not grid[y1, x1]
        if dx and dy:
            assert not grid[y0, x1] and not grid[y1, x0], "corner cut"
        total += math.hypot(dx, dy)
    assert total == pytest.approx(length)


def genome(elements):
    G = np.zeros((1, 48, 3))
    G[0, : len(elements)] = elements
    return G, np.array([48])


def wall_line_at_x10(sizes=(15, 15, 15, 15)):
    """Vertical walls at x = 10 on rows 4, 19, 34, 48 (size 15 = +-7 rows) seal the start side."""
    elements = [(0, 5, 40)] * 48  # filler: short horizontal walls far from the line
    for row, size in zip((4, 19, 34, 48), sizes):
        elements[row - 1] = (1, size, 10)
    return np.array(elements, dtype=float)


# --- geometry and restrictions -------------------------------------------------------------
def test_wall_extent_and_clipping(problem):
    elements = wall_line_at_x10()
    elements[9] = (0, 5, 20)  # row 10, x 18..22
    elements[10] = (0, 6, 30)  # row 11, x 27..33 (even size: s/2 = 3 either side)
    grid = build_grids(*genome(elements), problem.config)[0]
    assert grid[10, 18:23].all() and not grid[10, 17] and not grid[10, 23]
    assert grid[11, 27:34].all() and not grid[11, 26] and not grid[11, 34]
    assert grid[1:49, 10].all()  # vertical walls clipped to the interior, line complete
    assert grid[0].all() and grid[-1].all() and grid[:, 0].all() and grid[:, -1].all()


elements_strategy = st.lists(
    st.tuples(st.integers(0, 1), st.integers(5, 15), st.integers(1, 48)), min_size=48, max_size=48
)


@settings(max_examples=60, deadline=None)
@given(elements_strategy)
def test_walls_match_naive_and_never_cover_start_goal(elements):
    problem = refined()
    G, lengths = genome(elements)
    grid = build_grids(G, lengths, problem.config)[0]
    np.testing.assert_array_equal(grid, naive_grid(elements, problem.config))
    for cx, cy in (START, GOAL):  # the cell and its 8 neighbours, wherever they are not border
        for dx in (-1, 0, 1):
            for dy in (-1, 0, 1):
                x, y = cx + dx, cy + dy
                if 1 <= x <= 48 and 1 <= y <= 48:
                    assert not grid[y, x], (x, y)
    keep = keep_out_mask(problem.config)
    interior = np.zeros_like(keep)
    interior[1:-1, 1:-1] = True
    assert not (grid & keep & interior).any()
    ev = problem.evaluate(G, lengths)
    assert ev.metrics["wall_cells"][0] == grid[1:-1, 1:-1].sum()


def test_keep_out_follows_config():
    wide = refined(keep_out=3)
    elements = [(0, 15, 5)] * 48  # every row walled over x 0..12
    grid = build_grids(*genome(elements), wide.config)[0]
    assert not grid[1:5, 1:5].any() and grid[5, 1:13].all() and grid[1:5, 5:13].all()


def test_batch_build_equals_single(problem):
    G, lengths = problem.sample(20, np.random.default_rng(3))
    batch = build_grids(G, lengths, problem.config)
    for i in range(len(G)):
        np.testing.assert_array_equal(batch[i], build_grids(G[i:i + 1], lengths[i:i + 1], problem.config)[0])


# --- planners -------------------------------------------------------------------------------
def test_empty_map_gives_47_sqrt2():
    grid = empty_grid()
    length, path = astar(grid, START, GOAL)
    assert length == pytest.approx(EMPTY_LENGTH) and round(length, 2) == 66.47
    check_path(grid, path, length, START, GOAL)
    assert batch_path_lengths(grid[None], START, GOAL)[0] == pytest.approx(EMPTY_LENGTH)


def random_maps(count, seed):
    rng = np.random.default_rng(seed)
    maps = []
    for i in range(count):
        grid = empty_grid(24) | (rng.random((24, 24)) < rng.uniform(0.1, 0.45))
        grid[1, 1] = grid[22, 22] = False
        maps.append(grid)
    return maps


@pytest.mark.parametrize("engine", ["numba", "numpy"])
@pytest.mark.parametrize("diagonal", ["both_free", "one_free", "always"])
def test_astar_and_batch_agree_with_reference_dijkstra(diagonal, engine):
    maps = random_maps(50, seed={"both_free": 1, "one_free": 2, "always": 3}[diagonal])
    batch = batch_path_lengths(np.stack(maps), (1, 1), (22, 22), diagonal, engine=engine)
    reach = 0
    for grid, fast in zip(maps, batch):
        ref = reference_dijkstra(grid, (1, 1), (22, 22), diagonal)
        length, path = astar(grid, (1, 1), (22, 22), diagonal)
        if math.isinf(ref):
            assert math.isinf(length) and path == [] and math.isinf(fast)
            continue
        reach += 1
        assert length == pytest.approx(ref) and fast == pytest.approx(ref)
        if diagonal == "both_free":
            check_path(grid, path, length, (1, 1), (22, 22))
    assert 5 < reach < 50  # the sample covers both reachable and blocked maps


def test_batch_f1_equals_astar_on_sampled_maps(problem):
    G, lengths = problem.sample(40, np.random.default_rng(7))
    ev = problem.evaluate(G, lengths)
    grids = build_grids(G, lengths, problem.config)
    assert 0 < ev.valid.sum() < 40
    for i in range(40):
        length, path = astar(grids[i], START, GOAL)
        if ev.valid[i]:
            assert ev.f1[i] == pytest.approx(length) and ev.f1[i] >= EMPTY_LENGTH - 1e-9
            check_path(grids[i], path, length, START, GOAL)
        else:
            assert math.isinf(length) and ev.f1[i] == 0 and ev.reasons[i] == NO_PATH


@pytest.mark.parametrize("diagonal", ["both_free", "one_free", "always"])
def test_batch_engines_give_identical_floats(problem, diagonal):
    """The compiled planner and scipy sum the same steps: F1 must not depend on the engine."""
    G, lengths = problem.sample(300, np.random.default_rng(13))
    grids = build_grids(G, lengths, problem.config)
    fast = batch_path_lengths(grids, START, GOAL, diagonal, engine="numba")
    slow = batch_path_lengths(grids, START, GOAL, diagonal, engine="numpy", chunk=17)
    np.testing.assert_array_equal(fast, slow)
    assert 0 < np.isfinite(fast).sum() < 300



@pytest.mark.parametrize("diagonal", ["both_free", "one_free", "always"])
def test_a_few_maps_planned_uncompiled_give_the_compiled_floats(problem, diagonal, monkeypatch):
    """``auto`` plans up to SMALL_BATCH maps with the kernel's code as plain Python when numba has
    not compiled it yet (start-up of `ambiegen evaluate`); F1 must not depend on that."""
    import ambiegen_ros.problems.robot.planners as module  # the module whose globals batch_path_lengths reads

    G, lengths = problem.sample(module.SMALL_BATCH, np.random.default_rng(5))
    grids = build_grids(G, lengths, problem.config)
    compiled = batch_path_lengths(grids, START, GOAL, diagonal, engine="numba")
    monkeypatch.setattr(module, "_KERNEL", None)  # as in a fresh process
    monkeypatch.setattr(module, "_kernel", lambda: pytest.fail("a few maps must not load numba"))
    plain = batch_path_lengths(grids, START, GOAL, diagonal)
    np.testing.assert_array_equal(plain, compiled)
    assert np.isfinite(plain).any()


@pytest.mark.parametrize("rule", ["overlap", "centre"])
@pytest.mark.parametrize("radius", [0.6, 1.0, 1.7, 2.5])
def test_dilation_equals_scipy(rule, radius):
    from scipy import ndimage

    from ambiegen_ros.problems.robot import dilate, inflation_footprint

    grids = np.random.default_rng(int(radius * 10)).random((6, 23, 31)) < 0.08
    grids[:, 0, :] = True  # walls on the border: the outside must count as free
    foot = inflation_footprint(radius, 1.0, rule)
    expected = ndimage.binary_dilation(grids, structure=foot[None])
    np.testing.assert_array_equal(dilate(grids, foot), expected)
    np.testing.assert_array_equal(dilate(grids[2], foot), expected[2])


def test_corner_cutting_forbidden():
    # A barrier whose only opening is a diagonal squeeze between (10, 20) and (11, 21).
    grid = empty_grid()
    grid[0:21, 10] = True
    grid[21:, 11] = True
    for rule in ("both_free", "one_free"):
        assert math.isinf(astar(grid, START, GOAL, rule)[0])
        assert math.isinf(batch_path_lengths(grid[None], START, GOAL, rule)[0])
    length, path = astar(grid, START, GOAL, "always")
    assert math.isfinite(length) and (11, 20) in path and (10, 21) in path


def test_diagonal_rules_differ_on_single_corner():
    one = empty_grid()
    one[24, 25] = True  # a single blocked cell beside the diagonal step (24,24) -> (25,25)
    lengths = {r: batch_path_lengths(one[None], START, GOAL, r)[0] for r in ("both_free", "one_free", "always")}
    assert lengths["one_free"] == pytest.approx(EMPTY_LENGTH)
    assert lengths["always"] == pytest.approx(EMPTY_LENGTH)
    assert lengths["both_free"] > EMPTY_LENGTH + 0.1
    assert astar(one, START, GOAL, "both_free")[0] == pytest.approx(lengths["both_free"])


def test_inflation_by_radius():
    grid = np.zeros((9, 9), dtype=bool)
    grid[4, 4] = True
    np.testing.assert_array_equal(inflate(grid, 0.5), grid)  # paper: one robot = one cell
    plus = inflate(grid, 0.6)
    assert plus.sum() == 5 and plus[3:6, 4].all() and plus[4, 3:6].all()
    square = inflate(grid, 1.0)
    assert square.sum() == 9 and square[3:6, 3:6].all()
    assert inflate(grid, 1.0, resolution=2.0).sum() == 1  # 1 m radius on 2 m cells fits one cell
    batch = inflate(np.stack([grid, np.roll(grid, 2, axis=1)]), 1.0)
    np.testing.assert_array_equal(batch[1], np.roll(square, 2, axis=1))


def test_larger_radius_lengthens_or_blocks_paths():
    G, lengths = refined().sample(30, np.random.default_rng(11))
    base = refined().evaluate(G, lengths)
    wide = refined(robot_radius=0.6, keep_out=2, start=(2, 2), goal=(47, 47)).evaluate(G, lengths)
    both = base.valid & wide.valid
    assert wide.valid.sum() < base.valid.sum()
    assert np.all(wide.f1[both] >= base.f1[both] - 2 * math.sqrt(2) - 1e-9)


# --- problem-level behaviour ----------------------------------------------------------------
def test_sealed_map_is_invalid_and_gap_reopens_it(problem):
    ev = problem.evaluate(*genome(wall_line_at_x10()))
    assert not ev.valid[0] and ev.f1[0] == 0 and ev.reasons[0] == NO_PATH
    scenario = problem.codec.from_row(problem.codec.join(*genome(wall_line_at_x10())))
    env = problem.environment(scenario)
    assert not env.reachable and env.path == [] and env.path_length == 0
    # Shrinking the wall on row 19 to size 13 (rows 13..25) opens rows 12 and 26 at x = 10.
    opened = wall_line_at_x10(sizes=(15, 13, 15, 15))
    ev = problem.evaluate(*genome(opened))
    assert ev.valid[0] and ev.f1[0] > EMPTY_LENGTH
    env = problem.environment(problem.codec.from_row(problem.codec.join(*genome(opened))))
    assert env.path_length == pytest.approx(ev.f1[0])
    assert {y for x, y in env.path if x == 10} <= {12, 26} and any(x == 10 for x, _ in env.path)


def test_out_of_domain_genome_is_invalid(problem):
    G, lengths = genome(wall_line_at_x10(sizes=(15, 13, 15, 15)))
    G[0, 5, 1] = 16
    ev = problem.evaluate(G, lengths)
    assert not ev.valid[0] and ev.f1[0] == 0 and "domain" in ev.reasons[0]


@pytest.mark.parametrize("sampling", ["markov", "uniform"])
def test_sampled_genomes_in_domain(sampling):
    problem = refined(sampling=sampling)
    G, lengths = problem.sample(200, np.random.default_rng(5))
    assert G.shape == (200, 48, 3) and np.all(lengths == 48)
    assert problem.codec.in_domain(G, lengths).all()
    for j in range(3):  # every value of every attribute occurs
        attr = problem.attributes[j]
        assert set(np.unique(G[:, :, j])) == set(np.arange(attr.low, attr.high + 1, dtype=float))


def test_markov_chain_stay_probability():
    rng = np.random.default_rng(9)
    types = refined(type_p_stay=1.0).sample(50, rng)[0][:, :, 0]
    assert np.all(types == types[:, :1]) and 0 < types[:, 0].mean() < 1
    types = refined(type_p_stay=0.0).sample(50, rng)[0][:, :, 0]
    assert np.all(types[:, 1:] != types[:, :-1])
    types = refined(type_p_stay=0.8).sample(400, rng)[0][:, :, 0]
    assert np.mean(types[:, 1:] == types[:, :-1]) == pytest.approx(0.8, abs=0.02)


def test_environment_units_and_json_round_trip(problem):
    G, lengths = problem.sample(1, np.random.default_rng(2))
    scenario = problem.codec.from_row(problem.codec.join(G, lengths))
    again = problem.parse(Scenario.parse_json(scenario.to_json()))
    env = problem.environment(again)
    assert env.grid.shape == (50, 50) and env.start == START and env.goal == GOAL
    assert env.start_m == (1.5, 1.5) and env.goal_m == (48.5, 48.5)
    ev = problem.evaluate(G, lengths)
    assert env.reachable == bool(ev.valid[0]) and env.path_length == pytest.approx(ev.f1[0])


def test_config_checks():
    assert refined({"start": [2, 2]}).config.start == (2, 2)
    with pytest.raises(ScenarioError, match="sampling"):
        refined(sampling="perlin")
    with pytest.raises(ScenarioError, match="diagonal"):
        refined(diagonal="sometimes")
    with pytest.raises(ScenarioError, match="goal"):
        refined(goal=(49, 49))
    with pytest.raises(ScenarioError, match="map_size"):
        refined(map_size=60)


def test_plot_renders_png(problem, tmp_path):
    from ambiegen_ros.viz.robot import plot_scenario

    opened = wall_line_at_x10(sizes=(15, 13, 15, 15))
    scenario = problem.codec.from_row(problem.codec.join(*genome(opened)))
    ax = plot_scenario(problem, scenario, title="gap")
    f1 = problem.evaluate(*genome(opened)).f1[0]
    assert f"{f1:.2f} m" in ax.get_title() and "gap" in ax.get_title()
    out = tmp_path / "robot.png"
    ax.figure.savefig(out)
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and out.stat().st_size > 5000
    sealed = problem.codec.from_row(problem.codec.join(*genome(wall_line_at_x10())))
    assert "no path" in plot_scenario(problem, sealed).get_title()


def test_route_cap_folds_f1_back_past_a_known_failures_boundary():
    """NavFn's cap as ``route_cap``: a map past it scores below one at it, yet above an invalid map,
    and the path length recorded is still the A* length."""
    import json
    from pathlib import Path

    from ambiegen_ros.problems.robot import fold_above

    trap = json.loads((Path(__file__).parents[1] / "data" / "nav2_trap_map.json").read_text())
    plain = get_problem("robot", {**trap["problem_config"], "profile": trap["profile"]})
    capped = get_problem("robot", {**trap["problem_config"], "profile": trap["profile"], "route_cap": 100.0})
    sc = plain.parse(trap["scenario"])
    a, b = plain.evaluate_scenarios([sc]), capped.evaluate_scenarios([sc])
    assert a.f1[0] == pytest.approx(trap["f1"]) and b.valid[0]
    assert b.metrics["path_length"][0] == pytest.approx(trap["f1"])
    assert 0 < b.f1[0] < 100.0 and b.f1[0] == pytest.approx(100.0 ** 2 / trap["f1"])
    lengths = np.linspace(0.0, 400.0, 81)
    folded = fold_above(lengths, 100.0)
    assert folded.argmax() == np.searchsorted(lengths, 100.0) and np.all(folded[lengths > 0] > 0)
    assert np.all(np.diff(folded[lengths <= 100.0]) > 0) and np.all(np.diff(folded[lengths >= 100.0]) < 0)
    assert np.array_equal(fold_above(lengths, 0.0), lengths)
    with pytest.raises(ScenarioError, match="route_cap"):
        get_problem("robot", {"route_cap": -1.0})


def test_a_search_with_a_route_cap_stays_below_it():
    """Goal (14, 14): without a cap the GA's best route passes 40 m; with ``route_cap: 40`` its best
    lies at or just below 40 m, not past it."""
    from ambiegen_ros.core.search import Search, SearchSettings

    settings = SearchSettings(algorithm="ga", seed=2, population=40, offspring=20, evaluations=600)
    free = Search(get_problem("robot", {"goal": [14, 14], "profile": "refined"}), settings).run()
    problem = get_problem("robot", {"goal": [14, 14], "profile": "refined", "route_cap": 40.0})
    capped = Search(problem, settings).run()
    assert free.best_f1 > 40.0, free.best_f1
    routes = problem.evaluate_scenarios([problem.parse(e["scenario"]) for e in capped.suite]).metrics["path_length"]
    best = problem.parse(max(capped.suite, key=lambda e: e["f1"])["scenario"])
    best_route = float(problem.evaluate_scenarios([best]).metrics["path_length"][0])
    assert 30.0 < best_route <= 40.0, (best_route, sorted(routes)[-5:])


def _channel_map(width: int) -> np.ndarray:
    """A 50 x 50 room split by two full-height walls at x = 7 and x = 8 + width: the route from
    (1, 1) to (14, 14) goes up to a door in the first (y 40..42), down the channel between them and
    out of a door in the second (y 10..12)."""
    grid = np.zeros((N, N), dtype=bool)
    grid[0, :] = grid[-1, :] = grid[:, 0] = grid[:, -1] = True
    right = 8 + width
    grid[:, 7] = grid[:, right] = True
    grid[40:43, 7] = False
    grid[10:13, right] = False
    return grid


def test_narrow_route_metres_count_a_channel_the_route_cannot_avoid():
    """Issue 29's objective: a 2 m channel is narrow along its length, a 4 m one is not (its middle
    keeps 2 m from both walls), and a room without walls has no narrow metre (the start's corner is
    exempt)."""
    from ambiegen_ros.problems.robot import RobotConfig, narrow_route_metres

    config = RobotConfig(goal=(14, 14), profile="refined", objective="narrow")
    narrow, wide = _channel_map(2), _channel_map(4)
    assert astar(narrow, config.start, config.goal)[0] < math.inf and astar(wide, config.start, config.goal)[0] < math.inf
    assert narrow_route_metres(narrow, narrow, config) >= 28.0  # the channel from y 40 down to y 12
    assert narrow_route_metres(wide, wide, config) <= 6.0  # at most the doors
    empty = _channel_map(2)
    empty[:, 7] = empty[:, 10] = False
    empty[0, :] = empty[-1, :] = empty[:, 0] = empty[:, -1] = True
    assert narrow_route_metres(empty, empty, config) == 0.0


def test_the_narrow_objective_scores_maps_by_narrow_metres_and_keeps_the_route_cap():
    """F1 = narrow metres (metric ``narrow_m``) beside the route length; past the cap a map keeps the
    same share of them as of its folded length, so a search does not climb past NavFn's cap."""
    rng = np.random.default_rng(4)
    base = {"goal": [14, 14], "profile": "refined"}
    route = get_problem("robot", {**base, "route_cap": 30.0})
    narrow = get_problem("robot", {**base, "route_cap": 30.0, "objective": "narrow"})
    X = route.sample_rows(60, rng)
    a, b = route.evaluate_rows(X), narrow.evaluate_rows(X)
    assert np.array_equal(a.valid, b.valid) and np.array_equal(a.metrics["path_length"], b.metrics["path_length"])
    length, n = b.metrics["path_length"], b.metrics["narrow_m"]
    assert np.all(n[~b.valid] == 0) and n.max() > 0 and np.all(n <= length + 1e-9)
    inside = b.valid & (length <= 30.0)
    assert np.allclose(b.f1[inside], n[inside])
    past = b.valid & (length > 30.0)
    assert past.any() and np.allclose(b.f1[past], n[past] * (30.0 / length[past]) ** 2)
    assert narrow.f1_label == "narrow route [m]"
    with pytest.raises(ScenarioError, match="objective"):
        get_problem("robot", {"objective": "turning"})


def test_the_restarts_config_hands_nav2_different_maps_first():
    """``config/robot_small_narrow_restarts.yaml``: 16 searches, so the head of the suite (what an
    hour of Nav2 runs) is 16 different maps, each the best of its own search and above alpha."""
    from pathlib import Path

    from ambiegen_ros.core.search import Search
    from ambiegen_ros.run_config import make_run

    config = Path(__file__).resolve().parents[2] / "config" / "robot_small_narrow_restarts.yaml"
    problem, settings = make_run(None, config, seed=1, evaluations=16 * 200)
    assert settings.restarts == 16 and problem.config.objective == "narrow"
    head = Search(problem, settings).run().suite[:16]
    grids = {problem.environment(problem.parse(e["scenario"])).grid.tobytes() for e in head}
    assert len(head) == 16 and len(grids) == 16
    assert all(e["f1"] > problem.alpha for e in head)
