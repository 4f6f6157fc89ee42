"""Surrogate speed (evaluations/s on random valid scenarios) and paper-budget search wall time.

Usage: python bench/surrogates.py [--problems thermostat robot vehicle] [--profile replication refined]
                                  [--no-search]
Prints a table and writes bench/results/surrogates.json (figures per problem and fidelity profile;
problems and profiles not measured in this run keep their previous figures). Targets (issue 2, 2 cores):
thermostat >= 80,000/s, robot >= 600/s, vehicle >= 5,000/s; a paper-budget search < 60 s each.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import RESULTS, write_result  # noqa: E402

from ambiegen_ros.core.search import Search, SearchSettings  # noqa: E402
from ambiegen_ros.problems import PROBLEM_NAMES, PROFILES, get_problem  # noqa: E402

SAMPLES = {"thermostat": 50_000, "robot": 5_000, "vehicle": 10_000}


def valid_samples(problem, n: int, seed: int = 0) -> np.ndarray:
    """n sampled scenarios that pass the problem's restrictions (the surrogate's real workload)."""
    rng = np.random.default_rng(seed)
    rows = []
    have = 0
    while have < n:
        X = problem.sample_rows(max(n, 1000), rng)
        ok = problem.evaluate_rows(X).valid
        rows.append(X[ok])
        have += int(ok.sum())
    return np.concatenate(rows)[:n]


def eval_rate(problem, X: np.ndarray, batch: int, repeat: int = 3) -> float:
    best = 0.0
    for _ in range(repeat):
        start = time.perf_counter()
        for i in range(0, len(X), batch):
            problem.evaluate_rows(X[i : i + batch])
        best = max(best, len(X) / (time.perf_counter() - start))
    return best


def previous_figures() -> dict:
    """Figures of the last run, so that a run of some problems or profiles keeps the others'."""
    try:
        return dict(json.loads((RESULTS / "surrogates.json").read_text())["figures"])
    except (OSError, ValueError, KeyError, TypeError):
        return {}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--problems", nargs="+", default=list(PROBLEM_NAMES), choices=PROBLEM_NAMES)
    parser.add_argument("--no-search", action="store_true", help="skip the paper-budget searches")
    parser.add_argument("--algorithms", nargs="+", default=["ga", "nsga2", "random"])
    parser.add_argument("--profile", nargs="+", default=list(PROFILES), choices=PROFILES,
                        help="fidelity profiles to measure (default: all)")
    args = parser.parse_args()
    figures = previous_figures()
    for name, profile in ((n, p) for n in args.problems for p in args.profile):
        problem = get_problem(name, {"profile": profile})
        X = valid_samples(problem, SAMPLES[name])
        budget = problem.paper_budget
        entry = {
            "valid_samples": len(X),
            "evals_per_s_population_batch": eval_rate(problem, X, budget.offspring),
            "evals_per_s_batch_5000": eval_rate(problem, X, 5000),
            "population_batch": budget.offspring,
        }
        print(
            f"{name:10s} {profile:11s} surrogate: {entry['evals_per_s_population_batch']:10,.0f} evals/s (batches of "
            f"{budget.offspring}), {entry['evals_per_s_batch_5000']:10,.0f} evals/s (batches of 5000)"
        )
        if not args.no_search:
            for algorithm in args.algorithms:
                start = time.perf_counter()
                result = Search(problem, SearchSettings(algorithm=algorithm, seed=1)).run()
                wall = time.perf_counter() - start
                entry[f"paper_search_{algorithm}"] = {
                    "evaluations": result.evaluations,
                    "wall_s": round(wall, 2),
                    "best_f1": round(result.best_f1, 4),
                    "suite": len(result.suite),
                    "diversity": round(result.diversity, 3),
                }
                print(
                    f"{name:10s} {profile:11s} {algorithm:6s} paper budget: {result.evaluations} evals in "
                    f"{wall:6.1f} s, "
                    f"best F1 {result.best_f1:.3f}, suite {len(result.suite)}, diversity {result.diversity:.2f}"
                )
        per_profile = figures.get(name)
        if not (isinstance(per_profile, dict) and set(per_profile) <= set(PROFILES)):
            per_profile = figures[name] = {}  # none yet, or figures from before the profiles
        per_profile[profile] = entry
    print("wrote", write_result("surrogates", figures))


if __name__ == "__main__":
    main()
