"""Does the road-by-road duplicate check cost the vehicle GA at small budgets? (issue 28, section 4)

Usage: python bench/small_budget_duplicates.py [--seeds 100-119] [--population 100]
       [--offspring 500,100] [--evaluations 20000] [--checkpoints 1000,2000,5000,10000,20000]
       [--check-seeds 100-104] [--check-evaluations 5000]

The check ``core-search-beats-random`` compares GA and random search on the vehicle (replication
profile) at 5,000 evaluations, population 100, seeds 100-104, offspring left at the paper's 500:
GA 6.78 against random 6.13 since 7ea04ba, 7.41 against 6.13 before. 7ea04ba made the replication
profile compare duplicates road by road (``RoadDuplicateElimination``: genomes cut where their road
leaves the map) instead of genome by genome (``ScenarioDuplicateElimination``, canonical genomes).

Three searches per seed, everything else equal:

- ``road``: the replication profile as it is (road-by-road duplicates);
- ``genome``: the same GA with the genome-by-genome check it had before 7ea04ba (on seeds 100-119
  at 5,000 evaluations it gives fae6df6's figures to the bit);
- ``random``: random search (it uses no duplicate check and no offspring setting).

Each run goes to ``--evaluations``; its best F1 after the first k evaluations is what a run with a
budget of k gives (the budget cuts the last generation, the generations before it are the same;
checked on the first seed). Per checkpoint and offspring setting it prints the medians, the GA's
median over random's, the paired road-genome comparison (wins, median difference, Wilcoxon p,
Cliff's delta), the share of evaluations spent on a road already evaluated in the run, and the
spread of the check over every window of five consecutive seeds.

Writes bench/results/small_budget_duplicates.json.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import seed_list, write_result  # noqa: E402

from ambiegen_ros.core.search import Search, SearchSettings  # noqa: E402
from ambiegen_ros.core.stats import cliffs_delta  # noqa: E402
from ambiegen_ros.problems.vehicle import VehicleProblem  # noqa: E402
from ambiegen_ros.problems.vehicle.operators import cut_to_road  # noqa: E402

NAME = "small_budget_duplicates"
VARIANTS = ("road", "genome")
WINDOW = 5  # seeds per check, as in core-search-beats-random


class GenomeDuplicates(VehicleProblem):
    """The vehicle problem with the generic genome-by-genome duplicate check (before 7ea04ba)."""

    def search_operators(self, settings) -> dict:
        return {}


def one_run(problem, algorithm: str, seed: int, population: int, offspring: int | None,
            evaluations: int, checkpoints: list[int]) -> dict:
    """Best F1 and share of repeated roads after each checkpoint's number of evaluations."""
    search = Search(problem, SearchSettings(algorithm=algorithm, seed=seed, population=population,
                                            offspring=offspring, evaluations=evaluations))
    f1: list[float] = []
    roads: list[bytes] = []
    start = time.perf_counter()
    while (X := search.ask()) is not None:
        evaluation = problem.evaluate_rows(X)
        search.tell(evaluation)
        f1.extend(np.where(evaluation.valid, np.nan_to_num(evaluation.f1), 0.0).tolist())
        roads.extend(row.tobytes() for row in cut_to_road(problem, X))
    f1_arr = np.asarray(f1)
    return {
        "seed": seed,
        "best_f1": {str(c): float(f1_arr[:c].max()) for c in checkpoints},
        "repeated_roads": {str(c): 1 - len(set(roads[:c])) / c for c in checkpoints},
        "wall_s": round(time.perf_counter() - start, 2),
    }


def windows(ga: np.ndarray, rnd: np.ndarray) -> np.ndarray:
    """GA median over random median for every window of WINDOW consecutive seeds."""
    return np.array([np.median(ga[k:k + WINDOW]) / np.median(rnd[k:k + WINDOW])
                     for k in range(len(ga) - WINDOW + 1)])


def compare(road: np.ndarray, genome: np.ndarray, rnd: np.ndarray) -> dict:
    from scipy.stats import wilcoxon

    diff = road - genome
    p = float(wilcoxon(road, genome).pvalue) if np.any(diff != 0) else 1.0
    w_road, w_genome = windows(road, rnd), windows(genome, rnd)
    return {
        "median": {"road": float(np.median(road)), "genome": float(np.median(genome)), "random": float(np.median(rnd))},
        "iqr": {name: [float(np.percentile(v, 25)), float(np.percentile(v, 75))]
                for name, v in (("road", road), ("genome", genome), ("random", rnd))},
        "ratio_to_random": {"road": float(np.median(road) / np.median(rnd)),
                            "genome": float(np.median(genome) / np.median(rnd))},
        "paired": {"road_wins": int(np.sum(diff > 0)), "genome_wins": int(np.sum(diff < 0)),
                   "ties": int(np.sum(diff == 0)), "median_difference": float(np.median(diff)),
                   "mean_difference": float(diff.mean()), "wilcoxon_p": p,
                   "cliffs_delta": float(cliffs_delta(road, genome))},
        "five_seed_windows": {
            "road": [round(float(v), 3) for v in w_road], "genome": [round(float(v), 3) for v in w_genome],
            "road_below_genome": int(np.sum(w_road < w_genome)), "count": int(len(w_road)),
        },
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="100-119", help="e.g. 100-119 or 100,101,102")
    ap.add_argument("--population", type=int, default=100)
    ap.add_argument("--offspring", default="500,100",
                    help="offspring settings to measure (500 = the paper's, what the check leaves unset)")
    ap.add_argument("--evaluations", type=int, default=20000, help="budget of each run (the largest checkpoint)")
    ap.add_argument("--checkpoints", default="1000,2000,5000,10000,20000")
    ap.add_argument("--check-seeds", default="100-104", help="the check's seeds (must lie within --seeds)")
    ap.add_argument("--check-evaluations", type=int, default=5000)
    args = ap.parse_args()

    seeds = seed_list(args.seeds)
    check_seeds = seed_list(args.check_seeds)
    offsprings = [int(v) for v in args.offspring.split(",")]
    checkpoints = sorted({int(c) for c in args.checkpoints.split(",")} | {args.check_evaluations})
    checkpoints = [c for c in checkpoints if c <= args.evaluations]
    if not set(check_seeds) <= set(seeds):
        ap.error("--check-seeds must lie within --seeds")

    problems = {"road": VehicleProblem(), "genome": GenomeDuplicates()}
    assert problems["road"].replication, "the replication profile is the default"
    common = dict(population=args.population, evaluations=args.evaluations, checkpoints=checkpoints)

    runs: dict[str, list[dict]] = {"random": []}
    for seed in seeds:
        runs["random"].append(one_run(problems["road"], "random", seed, offspring=None, **common))
    for offspring in offsprings:
        for variant in VARIANTS:
            key = f"{variant}-offspring{offspring}"
            runs[key] = []
            for seed in seeds:
                runs[key].append(one_run(problems[variant], "ga", seed, offspring=offspring, **common))
                print(f"  {key} seed {seed}: best F1 at {args.check_evaluations} "
                      f"{runs[key][-1]['best_f1'][str(args.check_evaluations)]:.3f}", file=sys.stderr, flush=True)

    # self-check: a run with the checkpoint as its budget gives the checkpoint's best F1
    first = offsprings[0]
    direct = Search(problems["road"], SearchSettings(algorithm="ga", seed=seeds[0], population=args.population,
                                                     offspring=first, evaluations=args.check_evaluations)).run()
    prefix = runs[f"road-offspring{first}"][0]["best_f1"][str(args.check_evaluations)]
    assert direct.best_f1 == prefix, (direct.best_f1, prefix)

    def best(key: str, c: int, among: list[int] = seeds) -> np.ndarray:
        return np.array([r["best_f1"][str(c)] for r in runs[key] if r["seed"] in among])

    def repeated(key: str, c: int) -> float:
        return float(np.mean([r["repeated_roads"][str(c)] for r in runs[key]]))

    figures: dict = {
        "settings": {"problem": "vehicle", "profile": "replication", "seeds": seeds, "population": args.population,
                     "offspring": offsprings, "evaluations": args.evaluations, "checkpoints": checkpoints,
                     "check_seeds": check_seeds, "check_evaluations": args.check_evaluations},
        "check": {}, "comparison": {}, "runs": runs,
    }
    rnd_check = best("random", args.check_evaluations, check_seeds)
    print(f"\nThe check: {args.check_evaluations} evaluations, population {args.population}, "
          f"seeds {check_seeds[0]}-{check_seeds[-1]} (medians)")
    print(f"{'offspring':>9} {'road':>7} {'genome':>7} {'random':>7} {'road/rnd':>8} {'genome/rnd':>10}")
    for offspring in offsprings:
        r = best(f"road-offspring{offspring}", args.check_evaluations, check_seeds)
        g = best(f"genome-offspring{offspring}", args.check_evaluations, check_seeds)
        row = {"road": float(np.median(r)), "genome": float(np.median(g)), "random": float(np.median(rnd_check))}
        figures["check"][str(offspring)] = row
        print(f"{offspring:>9} {row['road']:7.2f} {row['genome']:7.2f} {row['random']:7.2f} "
              f"{row['road'] / row['random']:8.2f} {row['genome'] / row['random']:10.2f}")

    print(f"\nSeeds {seeds[0]}-{seeds[-1]} ({len(seeds)} runs each): medians, GA/random, paired road vs genome, "
          f"repeated roads, {WINDOW}-seed windows of GA/random")
    print(f"{'offspring':>9} {'evals':>6} {'road':>6} {'genome':>6} {'random':>6} {'r/rnd':>5} {'g/rnd':>5} "
          f"{'wins r:g':>8} {'med diff':>8} {'p':>5} {'delta':>6} {'repeat r/g':>11} "
          f"{'windows road':>13} {'windows genome':>14}")
    for offspring in offsprings:
        figures["comparison"][str(offspring)] = {}
        for c in checkpoints:
            road_key, genome_key = f"road-offspring{offspring}", f"genome-offspring{offspring}"
            cmp = compare(best(road_key, c), best(genome_key, c), best("random", c))
            cmp["repeated_roads"] = {"road": repeated(road_key, c), "genome": repeated(genome_key, c),
                                     "random": repeated("random", c)}
            figures["comparison"][str(offspring)][str(c)] = cmp
            m, pr, w, rep = cmp["median"], cmp["paired"], cmp["five_seed_windows"], cmp["repeated_roads"]
            print(f"{offspring:>9} {c:>6} {m['road']:6.2f} {m['genome']:6.2f} {m['random']:6.2f} "
                  f"{cmp['ratio_to_random']['road']:5.2f} {cmp['ratio_to_random']['genome']:5.2f} "
                  f"{pr['road_wins']:>4}:{pr['genome_wins']:<3} {pr['median_difference']:+8.2f} "
                  f"{pr['wilcoxon_p']:5.2f} {pr['cliffs_delta']:+6.2f} {rep['road']:5.1%}/{rep['genome']:5.1%} "
                  f"{min(w['road']):6.2f}-{max(w['road']):<6.2f} {min(w['genome']):7.2f}-{max(w['genome']):<6.2f}")
    path = write_result(NAME, figures)
    print(f"\nwrote {path}")


if __name__ == "__main__":
    main()
