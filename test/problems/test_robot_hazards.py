"""Robot hazards scenarios (issue 48): the matrix (walls, start, goal, boxes, posts, people), where
hazards sit relative to the route, the scenario's own rules, and a search that keeps every element
in its kind."""
from __future__ import annotations

import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from ambiegen_ros.core.attributes import ScenarioError
from ambiegen_ros.core.search import Search, SearchSettings
from ambiegen_ros.problems import get_problem
from ambiegen_ros.problems import robot_hazards as hz
from ambiegen_ros.ros import conversions
from ambiegen_ros.ros.types import get_registry

def cross(a, b) -> float:
    return float(a[0] * b[1] - a[1] * b[0])


OPEN_WALLS = [{"type": "vertical", "size": 5, "position": 48} for _ in range(48)]  # all on the far column
FILLER = {"size": 5, "position": 1, "row": 1, "along": 0, "offset": 0, "heading": 0, "extent": 0, "speed": 0.3,
          "delay": 0.0}


def element(kind: str, **values) -> dict:
    return {**FILLER, "type": kind, **values}


def scenario(problem, start=(2, 2, 45), goal=(14, 14, 0), hazards=(), walls=None) -> object:
    els = [{**FILLER, **w} for w in (walls or OPEN_WALLS)]
    els.append(element("start", position=start[0], row=start[1], heading=start[2]))
    els.append(element("goal", position=goal[0], row=goal[1], heading=goal[2]))
    els += [element(k, **v) for k, v in hazards]
    return problem.parse({"problem": "robot", "elements": els})


@pytest.fixture(scope="module")
def problem():
    return get_problem("robot", {"profile": "refined", "scenario": "hazards", "goal": [14, 14],
                                 "start_area": [[1, 1], [4, 4]]})


def test_hazards_need_the_refined_profile():
    with pytest.raises(ScenarioError, match="refined"):
        get_problem("robot", {"scenario": "hazards"})
    with pytest.raises(ScenarioError, match="scenario"):
        get_problem("robot", {"profile": "refined", "scenario": "crowds"})


def test_sampled_scenarios_keep_every_kind_in_its_place(problem):
    G, lengths = problem.sample(200, np.random.default_rng(4))
    for i in range(len(G)):
        assert hz.kind_reason(G[i], int(lengths[i]), problem.config) is None
    kinds = np.rint(G[:, :, hz.TYPE]).astype(int)
    assert set(kinds[:, :48].ravel()) == {hz.HORIZONTAL, hz.VERTICAL}
    assert (kinds[:, hz.START_ROW] == hz.START).all() and (kinds[:, hz.GOAL_ROW] == hz.GOAL).all()
    hazards = {int(kinds[i, j]) for i in range(len(G)) for j in range(hz.FIRST_HAZARD, int(lengths[i]))}
    assert hazards == {hz.BOX, hz.POST, hz.PERSON}
    assert set(lengths.tolist()) == set(range(hz.FIRST_HAZARD, hz.FIRST_HAZARD + 7))  # 0..6 hazards
    ev = problem.evaluate(G, lengths)
    assert 0.3 < ev.valid.mean() < 0.95  # most fail only for a map without a route
    assert ev.metrics["people"][ev.valid].sum() > 0 and ev.metrics["boxes"][ev.valid].sum() > 0


def test_hazards_sit_where_the_route_says(problem):
    """A box at 50 % of the route lies on its middle; a post 1.5 m to the left of its middle lies
    to the left of the direction of travel; a person walks through its point at the heading given."""
    sc = scenario(problem, hazards=[("box", {"along": 50, "offset": 0, "extent": 50}),
                                    ("post", {"along": 50, "offset": 15, "extent": 0}),
                                    ("person", {"along": 50, "offset": 0, "heading": 90, "extent": 0, "speed": 1.0,
                                                "delay": 5.0})])
    env = problem.environment(sc)
    route = hz.PlacementRoute(np.asarray(env.path_m))
    mid, direction = route.at(0.5)
    (x0, y0, x1, y1), = env.unmapped["boxes"]
    assert (x0 + x1) / 2 == pytest.approx(mid[0]) and (y0 + y1) / 2 == pytest.approx(mid[1])
    assert x1 - x0 == pytest.approx(0.65)  # 50 % of 0.3..1.0 m
    (px, py, r), = env.unmapped["posts"]
    assert r == pytest.approx(0.025)
    left = cross(direction, np.array([px, py]) - mid)
    assert left > 0 and math.hypot(px - mid[0], py - mid[1]) == pytest.approx(1.5)
    person, = env.unmapped["people"]
    a, b = np.asarray(person["path"])
    walk = (b - a) / np.linalg.norm(b - a)
    assert np.dot(walk, direction) == pytest.approx(0.0, abs=1e-9)  # crossing, right to left
    assert cross(direction, walk) > 0
    t = np.dot(mid - a, walk)  # the path passes through the route's middle
    assert np.linalg.norm(a + t * walk - mid) < 1e-9
    assert (person["speed"], person["delay"], person["radius"]) == (1.0, 5.0, 0.2)


def test_start_and_goal_poses_reach_the_stack_with_their_yaw(problem):
    sc = scenario(problem, start=(3, 2, 180), goal=(13, 15, 270))
    env = problem.environment(sc)
    assert env.start == (3, 2) and env.goal == (13, 15)
    assert env.start_yaw == pytest.approx(math.pi) and env.goal_yaw == pytest.approx(1.5 * math.pi)
    reg = get_registry()
    msg = conversions.scenario_message(reg.new, 0, problem, sc, conversions.ScenarioMeta("r", 0))
    assert conversions.yaw_of(msg.start.pose.orientation) == pytest.approx(math.pi)
    assert conversions.yaw_of(msg.goal.pose.orientation) % (2 * math.pi) == pytest.approx(1.5 * math.pi)
    # the map the stack is given holds the walls and nothing else
    hazardous = scenario(problem, start=(3, 2, 180), goal=(13, 15, 270),
                         hazards=[("box", {"along": 50, "extent": 100})])
    msg2 = conversions.scenario_message(reg.new, 0, problem, hazardous, conversions.ScenarioMeta("r", 1))
    assert np.array_equal(np.asarray(msg.map.data), np.asarray(msg2.map.data))


@pytest.mark.parametrize("hazard, reason", [
    (("box", {"along": 0, "extent": 100}), "box 0 lies within 0.6 m of the start"),
    (("post", {"along": 100, "offset": 2}), "post 0 lies within 0.6 m of the goal"),
])
def test_nothing_may_sit_on_the_start_or_the_goal(problem, hazard, reason):
    ev = problem.evaluate_scenarios([scenario(problem, hazards=[hazard])])
    assert not ev.valid[0] and ev.reasons[0] == f"hazards: {reason}"


def test_a_start_outside_its_area_or_a_wall_in_the_wrong_place_is_invalid(problem):
    assert "outside start_area" in problem.evaluate_scenarios([scenario(problem, start=(6, 2, 0))]).reasons[0]
    els = scenario(problem).to_dict()["elements"]
    els[3] = element("person")
    ev = problem.evaluate_scenarios([problem.parse({"problem": "robot", "elements": els})])
    assert ev.reasons[0] == "hazards: elements[3] must be a wall (horizontal|vertical), not person"


def test_people_stop_short_of_the_walls(problem):
    """A person walking along a wall is cut where its disc would touch it."""
    walls = list(OPEN_WALLS)
    walls[7] = {"type": "horizontal", "size": 15, "position": 10}  # row 8: x 3..17
    sc = scenario(problem, walls=walls, hazards=[("person", {"along": 40, "heading": 90, "extent": 100})])
    env = problem.environment(sc)
    person, = env.unmapped["people"]
    pts = np.asarray(person["path"])
    grid = env.grid
    assert (hz.wall_distance(grid, 1.0, pts) >= person["radius"] - 1e-9).all()


def test_the_search_keeps_every_element_in_its_kind(problem):
    settings = SearchSettings(algorithm="nsga2", evaluations=300, population=30, offspring=30, seed=2)
    search = Search(problem, settings)
    result = search.run()
    for entry in result.suite:
        sc = problem.parse(entry["scenario"])
        G, lengths = problem.codec.split(problem.codec.to_row(sc))
        assert hz.kind_reason(G[0], int(lengths[0]), problem.config) is None
    assert result.best_f1 > 0


def test_the_threat_score_rises_with_what_breaks_stacks(problem):
    """objective: threat (issue 49): an obstacle on the route, a person meeting the robot there and a
    goal turned away from the last leg each raise F1; the features say which and by how much."""
    threat = get_problem("robot", {**problem.config_dict(), "objective": "threat"})
    along = (14, 14, 45)  # the goal faces along the last leg
    plain = scenario(threat, goal=along)
    on_route = scenario(threat, goal=along, hazards=[("box", {"along": 50, "extent": 50})])
    aside = scenario(threat, goal=along, hazards=[("box", {"along": 50, "offset": 25, "extent": 50})])
    meeting = scenario(threat, goal=along, hazards=[("person", {"along": 50, "heading": 90, "extent": 50, "speed": 1.5,
                                                    "delay": 15.0})])
    late = scenario(threat, goal=along, hazards=[("person", {"along": 50, "heading": 90, "extent": 50, "speed": 1.5,
                                                 "delay": 60.0})])
    turned = scenario(threat, goal=(14, 14, 225))
    f1 = dict(zip(("plain", "on_route", "aside", "meeting", "late", "turned"),
                  threat.evaluate_scenarios([plain, on_route, aside, meeting, late, turned]).f1))
    assert f1["plain"] == pytest.approx(0.0)
    assert f1["on_route"] > f1["aside"] >= 0.0
    assert f1["meeting"] > f1["late"]
    assert f1["turned"] == pytest.approx(0.5, abs=0.01)  # a goal turned 180 degrees in the open
    feats = threat.hazard_features(meeting)
    assert feats["person_meet_s"] < 0.5 and feats["goal_turn_rad"] == pytest.approx(0.0)
    assert threat.hazard_features(turned)["goal_turn_rad"] == pytest.approx(math.pi)
    # closing speed of a person who meets the robot: head-on their speed, crossing half, walking ahead none
    for heading, closing in ((180, 1.5), (90, 0.75), (0, 0.0)):
        walker = scenario(threat, goal=along, hazards=[("person", {"along": 50, "heading": heading, "extent": 50,
                                                                   "speed": 1.5, "delay": 15.0})])
        assert threat.hazard_features(walker)["person_approach_mps"] == pytest.approx(closing, abs=0.05)
    assert threat.hazard_features(late)["person_approach_mps"] == 0.0  # gone long before the robot comes
    with pytest.raises(ScenarioError, match="threat"):
        get_problem("robot", {"profile": "refined", "objective": "threat"})


def test_the_threat_times_people_at_the_stacks_pace(problem):
    """threat_speed: a person scores where the robot, at that pace, meets them. The robot reaches the
    crossing 1.25x later at 0.4 m/s than at 0.5, so a person who starts that much later is the threat."""
    config = {**problem.config_dict(), "objective": "threat"}
    at_05, at_04 = get_problem("robot", config), get_problem("robot", {**config, "threat_speed": 0.4})

    def walker(delay):
        return scenario(at_05, goal=(14, 14, 45), hazards=[("person", {"along": 50, "heading": 90, "extent": 50,
                                                                        "speed": 1.5, "delay": delay})])

    on_time, later = walker(15.0), walker(18.75)
    assert at_05.evaluate_scenarios([on_time]).f1[0] > at_04.evaluate_scenarios([on_time]).f1[0]
    assert at_04.evaluate_scenarios([later]).f1[0] > at_05.evaluate_scenarios([later]).f1[0]
    assert at_04.hazard_features(later)["person_meet_s"] < 0.5 < at_05.hazard_features(later)["person_meet_s"]
    with pytest.raises(ScenarioError, match="threat_speed"):
        get_problem("robot", {**config, "threat_speed": 0.0})


def doorway_map(doors=(10,)) -> np.ndarray:
    """20 x 20 cells of 1 m: a border and a wall across y = 10 with 1 m doors at these x."""
    grid = np.zeros((20, 20), dtype=bool)
    grid[0, :] = grid[-1, :] = grid[:, 0] = grid[:, -1] = True
    grid[10, :] = True
    for x in doors:
        grid[10, x] = False
    return grid


def test_a_person_standing_in_the_only_door_blocks_the_way_for_a_while():
    """block / person_block_s (issue 49): a person who stands in a doorway when the robot gets there
    and walks off later shuts the way for that long; in the open, off the route, with another door,
    gone before the robot comes, or standing in the door for good (an invalid test), they do not."""
    route = hz.PlacementRoute(np.array([[10.5, 2.5], [10.5, 17.5]]))  # through the door at (10, 10)
    layout = hz.HazardLayout((10, 2), (10, 17), math.pi / 2, math.pi / 2, [])
    empty = np.zeros((0, 3)), np.zeros((0, 4))

    def person(a, b, delay, radius=0.25):
        return {"path": [list(a), list(b)], "speed": 1.0, "delay": delay, "radius": radius}

    def block(people, grid=None, speed=0.5):
        f = hz.features(route, layout, *empty, people, doorway_map() if grid is None else grid, 1.0, speed)
        return f["block"], f["person_block_s"]

    in_door_then_off = person((10.5, 10.5), (12.5, 12.5), delay=60.0)  # the robot is at the door after 8 m
    assert block([in_door_then_off]) == (pytest.approx(1.0), pytest.approx(60.0 - 8.0 / 0.5))
    assert block([in_door_then_off], speed=0.4)[1] == pytest.approx(60.0 - 8.0 / 0.4)  # timed at the pace
    half = block([person((10.5, 10.5), (12.5, 12.5), delay=31.0)])  # still there 15 s after the robot comes
    assert half == (pytest.approx(0.5), pytest.approx(15.0))
    assert block([person((10.5, 10.5), (12.5, 12.5), delay=10.0)]) == (0.0, 0.0)  # gone before it comes
    assert block([person((10.5, 5.5), (12.5, 7.5), delay=60.0)]) == (0.0, 0.0)  # on the route in the open
    assert block([person((14.5, 10.9), (16.5, 12.5), delay=60.0)]) == (0.0, 0.0)  # off the route
    assert block([person((12.5, 12.5), (10.5, 10.5), delay=60.0)]) == (0.0, 0.0)  # ends in the door: for good
    wide = block([person((11.0, 10.5), (13.0, 12.5), delay=60.0)], grid=doorway_map((10, 11)))  # 0.75 m each side
    partial = (hz.OPEN_GAP - 0.75) / (hz.OPEN_GAP - hz.PASSING_GAP)  # the walls are found in 5 cm steps
    assert wide[1] == 0.0 and wide[0] == pytest.approx(partial, abs=0.05 / (hz.OPEN_GAP - hz.PASSING_GAP) + 1e-9)
    two_doors = block([in_door_then_off], grid=doorway_map((3, 10)))  # a planner goes round by the other door
    assert two_doors[1] == 0.0 and 0.0 < two_doors[0] < 1.0
    assert hz.way_round(doorway_map((3, 10)), 1.0, layout, route, 8.0)
    assert not hz.way_round(doorway_map(), 1.0, layout, route, 8.0)


def test_the_block_search_finds_people_in_doorways(problem):
    """objective: block: F1 is the block feature, and a short search finds a person shutting the way."""
    config = {**problem.config_dict(), "objective": "block"}
    blocker = get_problem("robot", config)
    settings = SearchSettings(algorithm="nsga2", evaluations=1500, population=30, offspring=30, seed=2)
    result = Search(blocker, settings).run()
    best = blocker.parse(result.suite[0]["scenario"])
    assert result.best_f1 > 0.0
    assert blocker.evaluate_scenarios([best]).f1[0] == pytest.approx(blocker.hazard_features(best)["block"])
    with pytest.raises(ScenarioError, match="block"):
        get_problem("robot", {"profile": "refined", "objective": "block"})


def test_walls_may_lie_over_the_start_and_goal_areas_only_when_the_config_says_so():
    """config/robot_planner.yaml (issue 68): a planner's scenarios put walls anywhere, the start and
    goal areas included (``walls_over_ends``); the hazards scenarios keep those areas free."""
    from ambiegen_ros.problems.robot.grids import build_grids

    base = {"profile": "refined", "scenario": "hazards", "max_hazards": 0, "resolution": 0.25,
            "start_area": [[1, 1], [48, 48]], "goal_area": [[1, 1], [48, 48]]}
    kept, over = get_problem("robot", base), get_problem("robot", {**base, "walls_over_ends": True})
    G, lengths = over.sample(20, np.random.default_rng(3))
    walls = lambda p: build_grids(G[:, :hz.N_WALLS, :3], np.full(20, hz.N_WALLS), p.config)[:, 1:-1, 1:-1]  # noqa: E731
    assert not walls(kept).any()  # the areas cover the room: no wall anywhere
    assert walls(over).sum(axis=(1, 2)).min() > 100  # the paper's walls, over the whole room
    ends = [over.environment(sc) for sc in over.codec.from_rows(over.codec.join(G, lengths))]
    on_a_wall = sum(bool(e.grid[e.start[1], e.start[0]] or e.grid[e.goal[1], e.goal[0]]) for e in ends)
    assert on_a_wall > 0  # a start or goal on a wall: a scenario the reference refuses, as it should


# --- vias (issue 68: Nav2's ComputePathThroughPoses) -----------------------------------------------------


REPO_CONFIG = Path(__file__).resolve().parents[2] / "config"


def vias_problem(**extra):
    """config/robot_planner_vias.yaml's problem (1 to 3 vias), with ``extra`` fields."""
    from ambiegen_ros.run_config import make_run

    problem, _ = make_run("robot", str(REPO_CONFIG / "robot_planner_vias.yaml"), seed=0)
    return get_problem("robot", {**problem.config_dict(), **extra}) if extra else problem


def test_configs_without_vias_sample_and_mutate_the_genomes_they_always_did():
    """The digests were taken before vias existed: a seeded sample and one mutation of each config
    give the same genome bytes, and the kinds' codes 0..6 kept their meaning (old files decode)."""
    import hashlib

    from ambiegen_ros.run_config import make_run

    assert hz.TYPES[:7] == ("horizontal", "vertical", "start", "goal", "box", "post", "person") and hz.VIA == 7
    for name, digest in (("robot_planner.yaml", "fe988f2f272f2a40"), ("robot_hazards.yaml", "df291899cc88d37f")):
        problem, _ = make_run("robot", str(REPO_CONFIG / name), seed=0)
        G, lengths = problem.sample(50, np.random.default_rng(1))
        hz.mutate(G, lengths, np.random.default_rng(2), problem.config)
        assert hashlib.sha256(problem.codec.join(G, lengths).tobytes()).hexdigest()[:16] == digest, name


def test_seeded_vias_lie_in_their_area_in_order_and_every_leg_needs_a_route():
    from ambiegen_ros.problems.robot.problem import legs_length

    problem = vias_problem(via_area=[[10, 10], [20, 20]])
    G, lengths = problem.sample(300, np.random.default_rng(5))
    counts = lengths - hz.FIRST_HAZARD
    assert set(counts.tolist()) == {1, 2, 3} and problem.codec.m_max == hz.FIRST_HAZARD + 3
    for i in range(len(G)):
        assert hz.kind_reason(G[i], int(lengths[i]), problem.config) is None
        rows = hz.via_rows(G[i], int(lengths[i]))
        assert rows == list(range(hz.FIRST_HAZARD, int(lengths[i])))  # sampled: the vias right after the goal
        assert all(10 <= G[i, r, hz.POSITION] <= 20 and 10 <= G[i, r, hz.ROW] <= 20 for r in rows)
    ev = problem.evaluate(G, lengths)
    _, planning = problem.planning_grids(G, lengths)
    for i in range(len(G)):
        layout = hz.decode(G[i], int(lengths[i]), hz.HazardSettings.of(problem.config))
        legs, why = legs_length(planning[i], layout, problem.config.diagonal)
        assert ev.valid[i] == (why is None), (ev.reasons[i], why)
        if ev.valid[i]:  # F1: the route start -> vias -> goal, leg by leg
            assert ev.f1[i] == pytest.approx(legs * problem.config.resolution)
    leg_reasons = {r for r in ev.reasons if r and "via" in r}
    assert leg_reasons  # a via on a wall or boxed in: that leg has no route, the scenario is never sent
    sc = problem.codec.from_rows(problem.codec.join(G[:1], lengths[:1]))[0]
    env = problem.environment(sc)
    first = sc.to_dict()["elements"][hz.FIRST_HAZARD]
    assert first["type"] == "via" and env.vias[0] == (first["position"], first["row"])
    assert env.via_poses[0] == pytest.approx(((first["position"] + 0.5) * 0.25, (first["row"] + 0.5) * 0.25,
                                              math.radians(first["heading"])))  # a cell's centre, as the start's


def test_a_via_out_of_place_or_one_too_many_is_invalid():
    problem = vias_problem(via_area=[[10, 10], [20, 20]])
    G, lengths = problem.sample(1, np.random.default_rng(1))
    cells, m = G[0].copy(), int(lengths[0])
    cells[hz.FIRST_HAZARD, hz.POSITION] = 30
    assert "via 1 (30, " in hz.kind_reason(cells, m, problem.config)
    full = np.vstack([G[0, :hz.FIRST_HAZARD]] + [G[0, hz.FIRST_HAZARD:hz.FIRST_HAZARD + 1]] * 5)
    assert hz.kind_reason(full, len(full), problem.config) == "hazards: 5 vias, need 1..3 (min_vias..max_vias)"
    assert hz.kind_reason(G[0], hz.FIRST_HAZARD, problem.config) == "hazards: 0 vias, need 1..3 (min_vias..max_vias)"
    plain = get_problem("robot", {**problem.config_dict(), "min_vias": 0, "max_vias": 0, "max_hazards": 3})
    assert hz.kind_reason(G[0], m, plain.config).endswith("must be a box, post or person, not via")
    with pytest.raises(ScenarioError, match="max_vias"):
        get_problem("robot", {**problem.config_dict(), "min_vias": 4})


def test_the_operators_keep_vias_vias_and_their_order_and_canonical_puts_them_first():
    """Mutation adds, drops, swaps and moves vias within their area; the one-point crossover swaps
    tails, so with hazards too a via may land among them: canonical moves it before them, its order
    kept. With vias alone (the planner config) every child of both operators is a legal scenario."""
    from ambiegen_ros.core.operators import OnePointCrossover

    problem = vias_problem()
    G, lengths = problem.sample(200, np.random.default_rng(2))
    for seed in range(20):
        hz.mutate(G, lengths, np.random.default_rng(seed), problem.config)
        G, lengths = problem.canonical(G, lengths)
        assert all(hz.kind_reason(G[i], int(lengths[i]), problem.config) is None for i in range(len(G)))
    assert set((lengths - hz.FIRST_HAZARD).tolist()) == {1, 2, 3}
    pymoo_problem = SimpleNamespace(case=problem)
    X = problem.codec.join(G, lengths)
    parents = np.stack([X[:100], X[100:]])
    children = OnePointCrossover()._do(pymoo_problem, parents, random_state=np.random.default_rng(0))
    for row in children.reshape(-1, X.shape[1]):
        Gc, lc = problem.codec.split(row[None])
        assert hz.kind_reason(Gc[0], int(lc[0]), problem.config) is None
    mixed = vias_problem(max_hazards=3)
    cells = np.zeros((1, mixed.codec.m_max, len(hz.ATTRIBUTES)))
    cells[0, :hz.FIRST_HAZARD] = G[0, :hz.FIRST_HAZARD]
    order = [(hz.BOX, 0), (hz.VIA, 11), (hz.POST, 0), (hz.VIA, 22)]
    for k, (kind, x) in enumerate(order):
        cells[0, hz.FIRST_HAZARD + k, hz.TYPE] = kind
        cells[0, hz.FIRST_HAZARD + k, [hz.POSITION, hz.ROW]] = x or 1
    C, lc = mixed.canonical(cells, np.array([hz.FIRST_HAZARD + 4]))
    tail = C[0, hz.FIRST_HAZARD:hz.FIRST_HAZARD + 4]
    assert tail[:, hz.TYPE].tolist() == [hz.VIA, hz.VIA, hz.BOX, hz.POST]
    assert tail[:2, hz.POSITION].tolist() == [11, 22]
    assert hz.kind_reason(cells[0], hz.FIRST_HAZARD + 4, mixed.config) is None  # where hazards stand is free


def test_a_search_on_the_vias_config_sends_only_scenarios_with_vias():
    problem = vias_problem()
    result = Search(problem, SearchSettings(algorithm="ga", evaluations=80, population=20, offspring=10, seed=4)).run()
    for entry in result.suite:
        kinds = [e["type"] for e in entry["scenario"]["elements"][hz.FIRST_HAZARD:]]
        assert 1 <= len(kinds) <= 3 and set(kinds) == {"via"}
