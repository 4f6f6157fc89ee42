"""Vehicle search operators (issue 17). The replication profile compares duplicates road by road, as
the replication code does; the authors' own sampling, crossover and mutation (kept for the
measurement in docs/vehicle_search.md) cut every child to the road it builds, mutate by exchange /
flip / pairs and cross only roads of more than two elements."""
from __future__ import annotations

import numpy as np
import pytest
from pymoo.core.population import Population

from ambiegen_ros.core.operators import (
    CaseStudyProblem,
    OnePointCrossover,
    ScenarioDuplicateElimination,
    ScenarioMutation,
)
from ambiegen_ros.core.search import Search, SearchSettings
from ambiegen_ros.problems.vehicle import VehicleProblem
from ambiegen_ros.problems.vehicle.config import ANGLE, LEFT, LENGTH, RIGHT, STRAIGHT, TYPE
from ambiegen_ros.problems.vehicle.operators import (
    RoadCrossover,
    RoadDuplicateElimination,
    RoadMutation,
    RoadSampling,
    cut_to_road,
)


@pytest.fixture(scope="module")
def problem() -> VehicleProblem:
    return VehicleProblem()


@pytest.fixture(scope="module")
def pymoo_problem(problem) -> CaseStudyProblem:
    return CaseStudyProblem(problem, n_obj=1, n_ieq_constr=0)


def rows(problem, *roads) -> np.ndarray:
    """Genome rows from lists of ("straight", length) / ("left"|"right", angle) pairs."""
    G = np.zeros((len(roads), problem.m_max, 3))
    lengths = np.array([len(r) for r in roads])
    for i, road in enumerate(roads):
        for j, (kind, value) in enumerate(road):
            code = ("straight", "left", "right").index(kind)
            G[i, j] = (code, value if code == STRAIGHT else 5, value if code != STRAIGHT else 5)
    return problem.codec.join(G, lengths)


SHORT = [("straight", 5), ("left", 10), ("straight", 5), ("right", 10), ("straight", 5), ("left", 10)]
LEAVES = [("straight", 30)] * 5  # heading south from y = 100: the fourth straight leaves the map


def test_a_child_is_cut_to_the_road_it_builds(problem):
    X = rows(problem, LEAVES + [("left", 30)] * 3, SHORT)
    cut = cut_to_road(problem, X)
    used = problem.evaluate_rows(X).metrics["elements_used"]
    assert list(problem.codec.split(cut)[1]) == [3, 6] == list(used)
    assert np.array_equal(cut[1], X[1])  # a road on the map keeps every element
    assert np.array_equal(problem.evaluate_rows(cut).f1, problem.evaluate_rows(X).f1)  # the same road


def test_duplicates_are_compared_road_by_road(problem):
    """Two genomes of the same road with different tails past the map edge: the road check keeps
    one (the replication code compares its cut roads); a genome check would keep both."""
    a = rows(problem, LEAVES[:4] + [("left", 30), ("straight", 7)])
    b = rows(problem, LEAVES[:4] + [("right", 60)])
    c = rows(problem, LEAVES[:2] + [("straight", 29)])
    pop = Population.new("X", np.vstack([a, b, c]))
    assert len(RoadDuplicateElimination(problem).do(pop)) == 2
    assert len(ScenarioDuplicateElimination(problem).do(pop)) == 3
    assert len(RoadDuplicateElimination(problem).do(Population.new("X", b), Population.new("X", a))) == 0


def test_sampling_gives_cut_roads(problem, pymoo_problem):
    X = RoadSampling()._do(pymoo_problem, 300, random_state=np.random.default_rng(3))
    used = problem.evaluate_rows(X).metrics["elements_used"]
    assert np.array_equal(problem.codec.split(X)[1], used)


def test_flip_turns_a_straight_into_a_turn_and_back(problem):
    rng = np.random.default_rng(0)
    length_attr, angle_attr = RoadMutation.value_domains(problem)
    kinds = set()
    for _ in range(200):
        cell = np.array([STRAIGHT, 20.0, 5.0])
        RoadMutation._flip(cell, length_attr, angle_attr, rng)
        assert cell[TYPE] in (LEFT, RIGHT) and 10 <= cell[ANGLE] <= 85 and cell[ANGLE] % 5 == 0
        kinds.add(cell[TYPE])
        turn = np.array([LEFT, 5.0, 40.0])
        RoadMutation._flip(turn, length_attr, angle_attr, rng)
        assert turn[TYPE] == STRAIGHT and 5 <= turn[LENGTH] <= 50
    assert kinds == {LEFT, RIGHT}


def test_mutation_mix_is_the_replication_codes(problem, pymoo_problem):
    """On a road that stays on the map whatever one element becomes: 21 in 101 children change their
    kinds (a flip always does; exchange, pairs and a re-drawn value never do), every child keeps
    its length, and the elements of an unflipped child are the parent's, reordered, but for at most
    one value."""
    n = 4000
    X = np.repeat(rows(problem, SHORT), n, axis=0)
    Y = RoadMutation()._do(pymoo_problem, X, random_state=np.random.default_rng(1))
    G0, _ = problem.codec.split(X[:1])
    G, lengths = problem.codec.split(Y)
    assert np.all(lengths == len(SHORT))
    kinds0 = np.sort(G0[0, :6, TYPE])
    flipped = np.array([not np.array_equal(np.sort(g[:6, TYPE]), kinds0) for g in G])
    assert 0.18 < flipped.mean() < 0.24
    parent = {tuple(e) for e in G0[0, :6]}
    for g in G[~flipped][:500]:
        assert sum(tuple(e) not in parent for e in g[:6]) <= 1
    assert 0.5 < np.mean([not np.array_equal(g, G0[0]) for g in G]) < 0.95  # some draws change nothing


def test_mutation_rate_is_per_child(problem, pymoo_problem):
    X = np.repeat(rows(problem, SHORT), 2000, axis=0)
    changed = {}
    for prob in (0.0, 0.4, 1.0):
        pop = RoadMutation(prob=prob).do(pymoo_problem, Population.new("X", X.copy()),
                                         random_state=np.random.default_rng(5))
        changed[prob] = np.mean(np.any(pop.get("X") != X, axis=1))
    assert changed[0.0] == 0.0
    assert 0.35 < changed[0.4] / changed[1.0] < 0.45


def test_mutation_cuts_a_road_that_now_leaves_the_map(problem, pymoo_problem):
    X = np.repeat(rows(problem, [("straight", 50), ("straight", 40)] + [("left", 10)] * 4), 300, axis=0)
    Y = RoadMutation()._do(pymoo_problem, X, random_state=np.random.default_rng(2))
    lengths = problem.codec.split(Y)[1]
    assert np.array_equal(lengths, problem.evaluate_rows(Y).metrics["elements_used"])
    assert 0 < np.mean(lengths < 6) < 1


def test_crossover_needs_more_than_two_elements(problem, pymoo_problem):
    two = rows(problem, SHORT[:2])[0]
    six, other = rows(problem, SHORT, list(reversed(SHORT)))
    X = np.stack([np.stack([two, six]), np.stack([six, other])])  # (parents, matings, n_var)
    Y = RoadCrossover()._do(pymoo_problem, X, random_state=np.random.default_rng(4))
    assert np.array_equal(Y[:, 0], X[:, 0])  # copied
    G, lengths = problem.codec.split(Y[:, 1])
    assert list(lengths) == [6, 6]
    assert not np.array_equal(Y[:, 1], X[:, 1])  # crossed: the heads and tails swapped at k in 1..5
    A, _ = problem.codec.split(X[:, 1])
    k = int(np.argmax(np.any(G[0] != A[0], axis=1)))
    assert 1 <= k <= 5
    assert np.array_equal(G[0, k:6], A[1, k:6]) and np.array_equal(G[1, k:6], A[0, k:6])


def test_the_replication_profile_compares_roads_and_keeps_our_variation():
    algorithm = Search(VehicleProblem(), SearchSettings(algorithm="ga", population=20, offspring=20,
                                                        evaluations=40))._algorithm
    assert isinstance(algorithm.mating.eliminate_duplicates, RoadDuplicateElimination)
    assert type(algorithm.mating.mutation) is ScenarioMutation
    assert type(algorithm.mating.crossover) is OnePointCrossover
    refined = Search(VehicleProblem(profile="refined"), SearchSettings(algorithm="nsga2", population=20,
                                                                       offspring=20, evaluations=40))
    assert type(refined._algorithm.mating.eliminate_duplicates) is ScenarioDuplicateElimination


def test_no_two_members_share_a_road(problem):
    """The stuck runs of issue 17: clones of one road (differing past the map cut) filled the
    population (here 9 roads among 30 members with genomes compared). Every member is a different road."""
    search = Search(problem, SearchSettings(algorithm="ga", population=30, offspring=30, evaluations=300, seed=13))
    search.run()
    X = search._algorithm.pop.get("X")
    assert len({row.tobytes() for row in cut_to_road(problem, X)}) == len(X)


def test_same_seed_same_search(problem):
    def run(seed):
        search = Search(problem, SearchSettings(algorithm="ga", population=30, offspring=30, evaluations=150,
                                                seed=seed))
        result = search.run()
        return search._algorithm.pop.get("X"), result.best_f1

    (X1, b1), (X2, b2), (X3, _) = run(5), run(5), run(6)
    assert np.array_equal(X1, X2) and b1 == b2
    assert not np.array_equal(X1, X3)
