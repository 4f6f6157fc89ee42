"""How often three seeds show the search at 1.5 times random's best F1 (issue 17).

Usage: python bench/three_seed_check.py [--results docs/results/experiments/vehicle/results.csv]
       [--authors DIR] [--ratio 1.5] [--window 11]

A user who runs ``ambiegen experiment --runs 3`` draws three runs per algorithm; issue 17 asks
that GA's and NSGA-II's medians then be at least ``--ratio`` times random's. From an experiment's
``results.csv`` (30 runs per algorithm, run k with seed k) this measures, for GA and NSGA-II
against random:

- the windows of three consecutive seeds (k, k+1, k+2): how many pass, and their ratios;
- the odds a user's three seeds pass: the share of all pairs (3 of the search's runs, 3 of
  random's) where the search's median is at least ``ratio`` times random's;
- the odds given random's three runs of the window starting at ``--window`` (the issue's seeds
  11-13): the share of the search's 3-run subsets whose median reaches ``ratio`` times theirs.

``--authors DIR`` (a checkout of github.com/dgumenyuk/Environment_generation) adds the same odds
for the replication code's stored vehicle runs, against the same random median, and the stored
best-F1 medians, means and run counts of all three case studies (what ``report.md`` compares).

Writes bench/results/three_seed_check.json.
"""
from __future__ import annotations

import argparse
import csv
import itertools
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import write_result  # noqa: E402

NAME = "three_seed_check"
ROOT = Path(__file__).resolve().parent.parent
SEARCHES = ("ga", "nsga2")
# The replication code's stored results (RQ1_RQ2): one file per algorithm, {"runN": {"fitness": [...]}}
# with pymoo's minimised -F1 per generation (its last value is the run's best).
STORED = {
    "thermostat": {"ga": "Thermostat_case_study/EVALUATION/Results_dict_ga.json",
                   "nsga2": "Thermostat_case_study/EVALUATION/Results_dict_mo.json",
                   "random": "Thermostat_case_study/EVALUATION/Results_dict_random.json"},
    "robot": {"ga": "Robot_case_study/EVALUATIONS/Results_dict_ga2.json",
              "nsga2": "Robot_case_study/EVALUATIONS/Results_dict_mo2.json",
              "random": "Robot_case_study/EVALUATIONS/Results_dict_random2.json"},
    "vehicle": {"ga": "Vehicle_case_study/Results_vehicle_ga.json",
                "nsga2": "Vehicle_case_study/Results_vehicle_mo.json",
                "random": "Vehicle_case_study/Results_vehicle_ran.json"},
}


def our_runs(path: Path) -> dict[str, np.ndarray]:
    """Best F1 per run, in seed order, for each algorithm of an experiment's results.csv."""
    rows = list(csv.DictReader(path.open()))
    out = {}
    for alg in sorted({r["algorithm"] for r in rows}):
        mine = sorted((int(r["seed"]), float(r["best_f1"])) for r in rows if r["algorithm"] == alg)
        out[alg] = np.array([f for _, f in mine])
    return out


def stored_runs(authors: Path, problem: str) -> dict[str, np.ndarray]:
    """Best F1 per stored run of the replication code (the negated last fitness of each run)."""
    out = {}
    for alg, rel in STORED[problem].items():
        doc = json.loads((authors / "RQ1_RQ2" / rel).read_text())
        out[alg] = np.array([-float(run["fitness"][-1]) for run in doc.values()])
    return out


def medians_of_three(values: np.ndarray) -> np.ndarray:
    """The median of every 3-run subset."""
    return np.median(np.array(list(itertools.combinations(values, 3))), axis=1)


def odds(search: np.ndarray, random: np.ndarray, ratio: float, given_random_median: float | None) -> dict:
    s3 = np.sort(medians_of_three(search))
    r3 = medians_of_three(random)
    # share of (search triple, random triple) pairs that pass, by counting for each random triple
    passing = len(s3) - np.searchsorted(s3, ratio * r3, side="left")
    out = {"runs": int(len(search)), "p_pass_any_three_seeds": round(float(passing.mean() / len(s3)), 4)}
    if given_random_median is not None:
        out["p_pass_given_random_median"] = round(float(np.mean(s3 >= ratio * given_random_median)), 4)
    return out


def windows(runs: dict[str, np.ndarray], ratio: float) -> dict:
    """Windows of three consecutive seeds: the ratio of medians of each search to random's."""
    n = min(len(v) for v in runs.values())
    rand = np.array([np.median(runs["random"][k:k + 3]) for k in range(n - 2)])
    out = {}
    for alg in SEARCHES:
        r = np.array([np.median(runs[alg][k:k + 3]) for k in range(n - 2)]) / rand
        out[alg] = {"windows": len(r), "passing": int(np.sum(r >= ratio)),
                    "median_ratio": round(float(np.median(r)), 3), "lowest_ratio": round(float(r.min()), 3),
                    "lowest_at_seeds": [int(np.argmin(r)), int(np.argmin(r)) + 2],
                    "failing_windows": [int(k) for k in np.flatnonzero(r < ratio)]}
    return out


def summary(values: np.ndarray) -> dict:
    return {"runs": int(len(values)), "median": round(float(np.median(values)), 4),
            "mean": round(float(np.mean(values)), 4),
            "q25_q75": [round(float(q), 4) for q in np.percentile(values, [25, 75])],
            "lowest": round(float(values.min()), 4)}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--results", type=Path, default=ROOT / "docs/results/experiments/vehicle/results.csv",
                    help="an experiment's results.csv (GA, NSGA-II and random, run k with seed k)")
    ap.add_argument("--authors", type=Path, help="a checkout of github.com/dgumenyuk/Environment_generation")
    ap.add_argument("--ratio", type=float, default=1.5, help="the search's median over random's to pass")
    ap.add_argument("--window", type=int, default=11, help="first seed of the window whose random runs are given")
    args = ap.parse_args()

    ours = our_runs(args.results)
    missing = [a for a in (*SEARCHES, "random") if a not in ours]
    if missing:
        print(f"three_seed_check: {args.results} has no runs of {', '.join(missing)}", file=sys.stderr)
        return 2
    seeds = slice(args.window, args.window + 3)
    given = float(np.median(ours["random"][seeds]))
    figures: dict = {
        "results": str(args.results.resolve().relative_to(ROOT) if args.results.resolve().is_relative_to(ROOT)
                       else args.results),
        "ratio": args.ratio,
        "window": {"seeds": [args.window, args.window + 2], "random_median": round(given, 4),
                   "random_median_percentile_of_random_triples":
                       round(float(np.mean(medians_of_three(ours["random"]) < given) * 100), 1),
                   **{alg: [round(float(v), 4) for v in ours[alg][seeds]] for alg in (*SEARCHES, "random")}},
        "ours": {"summary": {alg: summary(v) for alg, v in ours.items()},
                 "consecutive_windows": windows(ours, args.ratio),
                 "odds": {alg: odds(ours[alg], ours["random"], args.ratio, given) for alg in SEARCHES}},
    }
    print(f"window {args.window}-{args.window + 2}: random's median {given:.2f} "
          f"(above {figures['window']['random_median_percentile_of_random_triples']} % of random's 3-run medians)")
    print(f"{'':<28}{'GA':>10}{'NSGA-II':>10}")
    w = figures["ours"]["consecutive_windows"]
    print(f"{'ours: windows passing':<28}" + "".join(f"{w[a]['passing']:>7}/{w[a]['windows']:<2}" for a in SEARCHES))
    for key, label in (("p_pass_any_three_seeds", "any three seeds"), ("p_pass_given_random_median", "given the window")):
        print(f"{'ours: P(pass), ' + label:<28}" + "".join(f"{figures['ours']['odds'][a][key]:>10.3f}" for a in SEARCHES))
    if args.authors is not None:
        stored = {p: stored_runs(args.authors, p) for p in STORED}
        figures["replication_code"] = {
            "source": "github.com/dgumenyuk/Environment_generation, RQ1_RQ2 (files in bench/three_seed_check.py)",
            "summary": {p: {alg: summary(v) for alg, v in runs.items()} for p, runs in stored.items()},
            "odds": {alg: odds(stored["vehicle"][alg], stored["vehicle"]["random"], args.ratio, given)
                     for alg in SEARCHES},
        }
        for key, label in (("p_pass_any_three_seeds", "any three seeds"), ("p_pass_given_random_median", "given the window")):
            print(f"{'stored: P(pass), ' + label:<28}"
                  + "".join(f"{figures['replication_code']['odds'][a][key]:>10.3f}" for a in SEARCHES))
        for p, algs in figures["replication_code"]["summary"].items():
            print(f"stored {p:<10} " + "  ".join(f"{a} median {s['median']:.4g} mean {s['mean']:.4g} ({s['runs']} runs)"
                                                 for a, s in algs.items()))
    print(f"wrote {write_result(NAME, figures)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
