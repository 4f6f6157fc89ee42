"""The engine on a toy case study: codec, operators (property tests), Jaccard, search loop."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pymoo.core.population import Population

from ambiegen_ros.core.attributes import ScenarioError
from ambiegen_ros.core.diversity import jaccard_distance, mean_pairwise_diversity
from ambiegen_ros.core.operators import (
    CaseStudyProblem,
    OnePointCrossover,
    ScenarioDuplicateElimination,
    ScenarioMutation,
)
from ambiegen_ros.core.runs import read_run, write_run
from ambiegen_ros.core.scenario import Scenario
from ambiegen_ros.core.search import Search, SearchSettings, restart_seed
from toy_problem import ToyProblem

PROBLEM = ToyProblem()
CODEC = PROBLEM.codec


def sample(seed: int, n: int) -> np.ndarray:
    return PROBLEM.sample_rows(n, np.random.default_rng(seed))


# --- codec ---------------------------------------------------------------------------------
def test_scenario_round_trips_through_json_and_genome():
    rows = sample(1, 20)
    for row in rows:
        scenario = CODEC.from_row(row)
        again = PROBLEM.parse(json.loads(scenario.to_json()))
        assert np.array_equal(CODEC.to_row(again), row)


@pytest.mark.parametrize(
    "element, field",
    [
        ({"kind": "z", "size": 2, "weight": 0.0}, "elements[0].kind"),
        ({"kind": "a", "size": 3, "weight": 0.0}, "elements[0].size"),  # off the step grid
        ({"kind": "a", "size": 12, "weight": 0.0}, "elements[0].size"),
        ({"kind": "a", "size": "4", "weight": 0.0}, "elements[0].size"),
        ({"kind": "a", "size": True, "weight": 0.0}, "elements[0].size"),
        ({"kind": "a", "size": 4, "weight": float("nan")}, "elements[0].weight"),
        ({"kind": "a", "size": 4, "weight": 1.5}, "elements[0].weight"),
        ({"kind": "a", "size": 4}, "elements[0].weight"),
        ({"kind": "a", "size": 4, "weight": 0.0, "colour": 1}, "elements[0].colour"),
    ],
)
def test_validation_names_the_bad_field(element, field):
    with pytest.raises(ScenarioError) as err:
        PROBLEM.parse({"problem": "toy", "elements": [element]})
    assert err.value.field == field


def test_validation_rejects_wrong_length_and_problem():
    with pytest.raises(ScenarioError, match="elements"):
        PROBLEM.parse({"problem": "toy", "elements": []})
    with pytest.raises(ScenarioError, match="problem"):
        PROBLEM.parse({"problem": "robot", "elements": [{"kind": "a", "size": 2, "weight": 0}]})
    with pytest.raises(ScenarioError, match="malformed JSON"):
        Scenario.parse_json('{"problem": "toy", "elements": [}')


@pytest.mark.parametrize(
    "text, field, shown",
    [
        ('{"problem": "toy", "elements": [{"weight": 1}, {"weight": 2}, {"weight": NaN}]}', "elements[2].weight", "NaN"),
        ('{"problem": "toy", "elements": [{"size": -Infinity}]}', "elements[0].size", "-Infinity"),
        ('{"problem": "toy", "elements": [], "metadata": {"score": 1e999}}', "metadata.score", "inf"),
        ("[1, Infinity]", "json[1]", "Infinity"),
        ("NaN", "json", "NaN"),
    ],
)
def test_non_finite_json_names_the_field(text, field, shown):
    """A NaN is named where it is (issue 18), like every other field error, not just as 'json'."""
    with pytest.raises(ScenarioError) as err:
        Scenario.parse_json(text)
    assert err.value.field == field
    assert str(err.value) == f"{field}: {shown} is not a finite number (allowed: finite numbers)"


# --- operators -------------------------------------------------------------------------------
PYMOO_PROBLEM = CaseStudyProblem(PROBLEM, n_obj=1, n_ieq_constr=0)


def assert_in_domain(X: np.ndarray) -> None:
    G, lengths = CODEC.split(X)
    assert CODEC.in_domain(G, lengths).all()
    assert np.array_equal(CODEC.canonical(X), X), "padding cells must stay zero"


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(1, 12))
def test_crossover_keeps_domains_and_lengths(seed, n):
    rng = np.random.default_rng(seed)
    parents = np.stack([sample(seed, n), sample(seed + 1, n)])
    children = OnePointCrossover()._do(PYMOO_PROBLEM, parents, random_state=rng)
    assert children.shape == parents.shape
    for child in children:
        assert_in_domain(child)
    # lengths are exchanged (or kept when a parent is too short to cut)
    len_parents = sorted(np.concatenate([parents[0][:, 0], parents[1][:, 0]]))
    len_children = sorted(np.concatenate([children[0][:, 0], children[1][:, 0]]))
    assert len_parents == len_children


def test_crossover_cuts_between_heads_and_tails():
    a = CODEC.to_row(Scenario("toy", [{"kind": "a", "size": 2, "weight": 0.0}] * 4))
    b = CODEC.to_row(Scenario("toy", [{"kind": "b", "size": 10, "weight": 0.5}] * 6))
    rng = np.random.default_rng(0)
    for _ in range(30):
        c1, c2 = OnePointCrossover()._do(PYMOO_PROBLEM, np.stack([a[None], b[None]]), random_state=rng)
        s1, s2 = CODEC.from_row(c1[0]), CODEC.from_row(c2[0])
        assert len(s1.elements) == 6 and len(s2.elements) == 4
        kinds1 = [e["kind"] for e in s1.elements]
        k = kinds1.index("b")
        assert 1 <= k <= 3 and kinds1 == ["a"] * k + ["b"] * (6 - k)
        assert [e["kind"] for e in s2.elements] == ["b"] * k + ["a"] * (4 - k)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31 - 1))
def test_mutation_keeps_domains_and_changes_something(seed):
    rng = np.random.default_rng(seed)
    X = sample(seed, 30)
    Y = ScenarioMutation(prob=1.0)._do(PYMOO_PROBLEM, X, random_state=rng)
    assert_in_domain(Y)
    assert np.array_equal(Y[:, 0], X[:, 0]), "mutations never change the length"
    # element multisets are preserved by exchange/scramble; change-of-variable alters one cell
    Gx, lengths = CODEC.split(X)
    Gy, _ = CODEC.split(Y)
    for i in range(len(X)):
        diff = np.sum(np.any(Gx[i] != Gy[i], axis=1))
        assert diff <= lengths[i]


def test_duplicate_elimination_removes_exact_copies():
    X = sample(3, 5)
    pop = Population.new("X", np.concatenate([X, X[:2]]))
    kept = ScenarioDuplicateElimination().do(pop)
    assert len(kept) == 5
    other = Population.new("X", X[:1])
    kept = ScenarioDuplicateElimination().do(Population.new("X", X), other)
    assert len(kept) == 4


@pytest.mark.parametrize("profile", ["replication", "refined"])
def test_duplicates_of_the_same_road_are_removed(profile):
    """Genomes differing only in cells the road ignores (a straight's angle, a turn's length) are
    one environment: same F1, and the search keeps only one of them."""
    from ambiegen_ros.problems import get_problem

    vehicle = get_problem("vehicle", {"profile": profile})
    X = vehicle.sample_rows(40, np.random.default_rng(5))
    G, L = vehicle.codec.split(X)
    twin = G.copy()
    straight = twin[:, :, 0] == 0
    used = np.arange(G.shape[1])[None, :] < L[:, None]
    twin[:, :, 2] = np.where(straight & used, 85 - (twin[:, :, 2] - 5), twin[:, :, 2])  # another angle
    twin[:, :, 1] = np.where(~straight & used, 55 - twin[:, :, 1], twin[:, :, 1])  # another length
    Y = vehicle.codec.join(twin, L)
    changed = np.any(X != Y, axis=1)
    assert changed.sum() > 30
    np.testing.assert_array_equal(vehicle.evaluate_rows(X).f1, vehicle.evaluate_rows(Y).f1)
    kept = ScenarioDuplicateElimination(vehicle).do(Population.new("X", np.concatenate([X, Y])))
    assert len(kept) == len(X)
    assert len(ScenarioDuplicateElimination().do(Population.new("X", np.concatenate([X, Y])))) == len(X) + changed.sum()


def test_thermostat_days_equal_within_24h_are_duplicates_in_the_replication_profile():
    from ambiegen_ros.problems import get_problem

    day = [{"temperature": 20, "duration": 240, "model": 1}] * 6
    for profile, duplicates in (("replication", True), ("refined", False)):
        p = get_problem("thermostat", {"profile": profile})
        a = p.codec.to_row(p.parse({"problem": "thermostat", "elements": day + [{"temperature": 21, "duration": 60, "model": 2}]}))
        b = p.codec.to_row(p.parse({"problem": "thermostat", "elements": day + [{"temperature": 22, "duration": 90, "model": 3}]}))
        kept = ScenarioDuplicateElimination(p).do(Population.new("X", np.stack([a, b])))
        assert len(kept) == (1 if duplicates else 2)


# --- Jaccard ------------------------------------------------------------------------------------
def test_jaccard_is_zero_with_itself_and_symmetric():
    X = sample(5, 40)
    G, L = CODEC.split(X)
    assert np.allclose(jaccard_distance(G, L, G, L, CODEC.attributes), 0.0)
    Y = sample(6, 40)
    H, M = CODEC.split(Y)
    d1 = jaccard_distance(G, L, H, M, CODEC.attributes)
    d2 = jaccard_distance(H, M, G, L, CODEC.attributes)
    assert np.array_equal(d1, d2)
    assert np.all((d1 >= 0) & (d1 <= 1))


def test_jaccard_counts_same_position_matches_with_tolerance():
    base = [{"kind": "a", "size": 4, "weight": 0.0}, {"kind": "b", "size": 6, "weight": 0.5}]
    near = [{"kind": "a", "size": 6, "weight": 0.2}, {"kind": "b", "size": 10, "weight": 0.5}, base[0]]
    a = CODEC.to_row(Scenario("toy", base))[None]
    b = CODEC.to_row(Scenario("toy", near))[None]
    d = jaccard_distance(*CODEC.split(a), *CODEC.split(b), CODEC.attributes)[0]
    # element 0 matches (size within 2, weight within 0.25); element 1 does not (size 6 vs 10)
    assert math.isclose(d, 1 - 1 / (2 + 3 - 1))


# --- search -------------------------------------------------------------------------------------
@pytest.mark.parametrize("algorithm", ["ga", "nsga2", "random"])
def test_search_respects_budget_and_reports_positive_objectives(algorithm):
    result = Search(PROBLEM, SearchSettings(algorithm=algorithm, seed=1, evaluations=333)).run()
    assert result.evaluations == 333
    assert result.history[-1]["evaluations"] == 333
    assert result.suite, "a run always leaves a suite"
    f1 = [e["f1"] for e in result.suite]
    assert all(v >= 0 for v in f1)
    if algorithm != "nsga2":
        assert f1 == sorted(f1, reverse=True) and len(result.suite) <= 10
    else:
        assert all(v > PROBLEM.alpha for v in f1), "the MO suite is the feasible front"
        assert all(e["feasible"] for e in result.suite)
    # F1 stored with the suite is the surrogate's value for that scenario
    scenarios = [PROBLEM.parse(e["scenario"]) for e in result.suite]
    assert np.allclose(PROBLEM.evaluate_scenarios(scenarios).f1, f1)


def test_random_search_with_valid_samples_spends_its_budget_on_valid_scenarios_only():
    """A campaign's random search (issue 47): every sample it asks for is one the problem calls
    valid, the budget counts those, a seed gives the same samples; GA and NSGA-II are not affected."""
    settings = SearchSettings(algorithm="random", seed=4, evaluations=90, population=20)

    def asked(algorithm: str, valid_samples: bool) -> list[np.ndarray]:
        search, rows = Search(PROBLEM, SearchSettings(**{**vars(settings), "algorithm": algorithm}), valid_samples), []
        while (X := search.ask()) is not None:
            rows.append(X)
            search.tell(PROBLEM.evaluate_rows(X))
        assert search.evaluations == 90
        return rows

    plain, valid = asked("random", False), asked("random", True)
    assert not PROBLEM.evaluate_rows(np.vstack(plain)).valid.all()  # this seed's plain samples break the rule
    assert PROBLEM.evaluate_rows(np.vstack(valid)).valid.all() and len(np.vstack(valid)) == 90
    assert all(np.array_equal(a, b) for a, b in zip(valid, asked("random", True)))  # same seed, same samples
    for algorithm in ("ga", "nsga2"):
        assert all(np.array_equal(a, b) for a, b in zip(asked(algorithm, False), asked(algorithm, True)))
    never_valid = ToyProblem(max_valid_length=0)  # the sampler gives up: nothing to ask, the run ends
    assert Search(never_valid, settings, valid_samples=True).ask() is None


def test_a_population_suite_hands_on_every_feasible_member_best_first():
    """``suite: population``: the front and more (for a slow stack that can run more maps than a
    front holds), all above alpha, best F1 first; the front is among them."""
    front = Search(PROBLEM, SearchSettings(algorithm="nsga2", seed=3, evaluations=400)).run()
    search = Search(PROBLEM, SearchSettings(algorithm="nsga2", seed=3, evaluations=400, suite="population"))
    everyone = search.run()
    f1 = [e["f1"] for e in everyone.suite]
    assert f1 == sorted(f1, reverse=True) and all(v > PROBLEM.alpha for v in f1)
    pop_f1 = search._algorithm.pop.get("f1").astype(float)
    assert len(everyone.suite) == int((pop_f1 > PROBLEM.alpha).sum()) > len(front.suite)
    assert {json.dumps(e["scenario"]) for e in front.suite} <= {json.dumps(e["scenario"]) for e in everyone.suite}
    with pytest.raises(ValueError, match="suite"):
        SearchSettings(suite="all").resolved(PROBLEM)


def test_restarts_share_the_budget_and_interleave_their_suites():
    """``restarts: 2``: two independent searches, half the budget each; the first is the run's own
    seed (a run without restarts on its half), the second a derived one; their suites alternate."""
    settings = dict(algorithm="nsga2", suite="population")
    both = Search(PROBLEM, SearchSettings(seed=3, evaluations=400, restarts=2, **settings)).run()
    first = Search(PROBLEM, SearchSettings(seed=3, evaluations=200, **settings)).run()
    second = Search(PROBLEM, SearchSettings(seed=restart_seed(3, 1), evaluations=200, **settings)).run()
    assert both.evaluations == 400 and restart_seed(3, 1) != 3
    scenarios = [json.dumps(e["scenario"]) for e in both.suite]
    a, b = ([json.dumps(e["scenario"]) for e in r.suite] for r in (first, second))
    assert a != b, "a restart is its own search"
    n = min(len(a), len(b))
    assert scenarios[: 2 * n : 2] == a[:n] and scenarios[1 : 2 * n : 2] == b[:n]
    assert sorted(scenarios) == sorted(a + b)
    assert [h["best_f1"] for h in both.history] == sorted(h["best_f1"] for h in both.history)
    with pytest.raises(ValueError, match="restarts"):
        SearchSettings(evaluations=30, restarts=2).resolved(PROBLEM)  # a population (20) each: 40
    assert SearchSettings(evaluations=10).resolved(PROBLEM).evaluations == 10  # no restarts: less than a population is fine


def test_search_improves_over_its_initial_population():
    result = Search(PROBLEM, SearchSettings(algorithm="ga", seed=4, evaluations=600)).run()
    assert result.history[-1]["best_f1"] > result.history[0]["best_f1"]
    best = [h["best_f1"] for h in result.history]
    assert best == sorted(best), "best-so-far never decreases"


def test_same_seed_same_suite_file(tmp_path):
    docs = []
    for run in ("a", "b", "c"):
        seed = 9 if run != "c" else 10
        result = Search(PROBLEM, SearchSettings(algorithm="nsga2", seed=seed, evaluations=300)).run()
        paths = write_run(tmp_path / run, PROBLEM, result)
        docs.append(paths["suite"].read_bytes())
    assert docs[0] == docs[1]
    assert docs[0] != docs[2]
    loaded = read_run(tmp_path / "a")
    assert loaded["config"]["seed"] == 9 and loaded["config"]["search"]["evaluations"] == 300
    assert "pymoo" in loaded["config"]["versions"]


def test_ask_tell_with_external_results_matches_run():
    settings = SearchSettings(algorithm="ga", seed=2, evaluations=120)
    direct = Search(PROBLEM, settings).run()
    search = Search(PROBLEM, settings)
    while (X := search.ask()) is not None:
        # an "external" evaluator: decode to scenarios and evaluate them one by one
        rows = [PROBLEM.evaluate_scenarios([CODEC.from_row(x)]) for x in X]
        from ambiegen_ros.core.problem import Evaluation

        merged = Evaluation(
            np.array([r.f1[0] for r in rows]),
            np.array([r.valid[0] for r in rows]),
            [r.reasons[0] for r in rows],
            {k: np.array([r.metrics[k][0] for r in rows]) for k in rows[0].metrics},
        )
        search.tell(merged)
    assert search.result().suite == direct.suite


def test_time_budget_stops():
    result = Search(PROBLEM, SearchSettings(algorithm="ga", seed=1, time_budget=0.3)).run()
    assert result.elapsed >= 0.3  # stops once the budget is spent (how soon after is bench/'s business)
    assert result.evaluations > 0


def test_mo_front_is_more_diverse_than_so_best():
    so = Search(PROBLEM, SearchSettings(algorithm="ga", seed=3, evaluations=800)).run()
    mo = Search(PROBLEM, SearchSettings(algorithm="nsga2", seed=3, evaluations=800)).run()
    assert len(mo.suite) >= 2
    assert mo.diversity > so.diversity


def test_bad_settings_are_rejected():
    with pytest.raises(ValueError, match="algorithm"):
        Search(PROBLEM, SearchSettings(algorithm="cmaes"))
    with pytest.raises(ValueError, match="population"):
        Search(PROBLEM, SearchSettings(population=1))


def test_mean_pairwise_diversity_bounds():
    G, L = CODEC.split(sample(1, 10))
    assert 0 < mean_pairwise_diversity(G, L, CODEC.attributes) <= 1
    assert mean_pairwise_diversity(G[:1], L[:1], CODEC.attributes) == 0.0
