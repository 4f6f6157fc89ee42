"""How long one RQ3 run of one simulated hour takes (issue 26: at most 5 minutes of wall time on 2 cores).

Usage: python bench/rq3_hour.py [--problem vehicle] [--algorithm nsga2] [--runs 3] [--seed 2026]
       [--execution-cost 30] [--time-budget 3600]

Each run is what ``ambiegen experiment --full-model`` runs by default (``--search-for certified``,
never-idle executors, the cpu clock), one after another in this process, with the compile/cache
warm-up done once before the first (as a worker of the experiment's pool does). Prints and writes
the wall time of each run, and what it found, to bench/results/rq3_hour_<problem>_<algorithm>.json.
"""
from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import write_result  # noqa: E402

from ambiegen_ros.experiment import ExperimentSpec  # noqa: E402
from ambiegen_ros.experiment.runner import run_task  # noqa: E402
from ambiegen_ros.experiment.spec import resolve  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--problem", default="vehicle")
    ap.add_argument("--algorithm", default="nsga2")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--seed", type=int, default=2026)
    ap.add_argument("--execution-cost", type=float, default=30.0)
    ap.add_argument("--time-budget", type=float, default=3600.0)
    args = ap.parse_args()
    spec = ExperimentSpec(problem=args.problem, algorithms=(args.algorithm,), runs=args.runs, seed=args.seed,
                          full_model=True, time_budget=args.time_budget, execution_cost=args.execution_cost,
                          clock="cpu")
    identity = resolve(spec)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(args.runs):
            t0 = time.perf_counter()
            rec = run_task({"identity": identity, "algorithm": args.algorithm, "run": k,
                            "path": str(Path(tmp) / f"run-{k}.json")})
            wall = time.perf_counter() - t0
            rows.append({"run": k, "seed": rec["seed"], "wall_s": round(wall, 2), "executions": rec["executions"],
                         "failures": rec["failures"], "distinct_failures": rec["distinct_failures"],
                         "search_s": rec["search_s"], "evaluations": rec["evaluations"]})
            print(f"run {k}: {wall:.1f} s wall, {rec['executions']} executions, {rec['failures']} certified, "
                  f"{rec['distinct_failures']} distinct")
    walls = [r["wall_s"] for r in rows]
    print(f"median {statistics.median(walls):.1f} s, worst {max(walls):.1f} s per simulated "
          f"{args.time_budget:g} s at {args.execution_cost:g} s per execution (target: 300 s)")
    figures = {"problem": args.problem, "profile": identity["profile"], "algorithm": args.algorithm,
               "time_budget_s": args.time_budget, "execution_cost_s": args.execution_cost,
               "median_wall_s": statistics.median(walls), "worst_wall_s": max(walls), "runs": rows}
    print(f"wrote {write_result(f'rq3_hour_{args.problem}_{args.algorithm}', figures)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
