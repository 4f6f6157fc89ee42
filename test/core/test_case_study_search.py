"""Short searches on the real case studies (small budgets; the paper budgets live in bench/)."""
from __future__ import annotations

import numpy as np
import pytest

from ambiegen_ros.core.search import Search, SearchSettings
from ambiegen_ros.problems import PROBLEM_NAMES, get_problem

SMALL = {"thermostat": (40, 40, 400), "robot": (30, 15, 300), "vehicle": (40, 40, 400)}


@pytest.mark.parametrize("problem_name", PROBLEM_NAMES)
@pytest.mark.parametrize("algorithm", ["ga", "nsga2", "random"])
def test_short_search_runs_and_its_suite_reevaluates(problem_name, algorithm):
    problem = get_problem(problem_name)
    population, offspring, evaluations = SMALL[problem_name]
    settings = SearchSettings(algorithm=algorithm, seed=5, population=population, offspring=offspring, evaluations=evaluations)
    result = Search(problem, settings).run()
    assert result.evaluations == evaluations
    assert result.suite and result.best_f1 > 0
    scenarios = [problem.parse(e["scenario"]) for e in result.suite]
    again = problem.evaluate_scenarios(scenarios)
    assert np.allclose(again.f1, [e["f1"] for e in result.suite])
    assert max(e["f1"] for e in result.suite) == pytest.approx(result.best_f1) or algorithm == "nsga2"


def test_ga_beats_random_search_on_the_robot():
    """Equal small budgets, several seeds: the GA's best path is longer than random search's."""
    problem = get_problem("robot")
    wins = 0
    ga_best, random_best = [], []
    for seed in range(4):
        common = dict(seed=seed, population=40, offspring=20, evaluations=1000)
        ga = Search(problem, SearchSettings(algorithm="ga", **common)).run().best_f1
        rnd = Search(problem, SearchSettings(algorithm="random", **common)).run().best_f1
        ga_best.append(ga)
        random_best.append(rnd)
        wins += ga > rnd
    assert wins >= 3, (ga_best, random_best)
    assert np.mean(ga_best) > np.mean(random_best) * 1.1
