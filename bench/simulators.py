"""Full-model simulator speed: simulated seconds per wall second, and scenarios per minute.

Usage: python bench/simulators.py [--problems robot vehicle thermostat] [--n N] [--seed S]
Executes N sampled valid scenarios per problem with the default simulator settings (one process,
one core) and prints a table; writes bench/results/simulators.json. Targets (issue 4): robot
>= 50x real time, car >= 100x, thermostat >= 10,000x.
"""
from __future__ import annotations

import argparse
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import write_result  # noqa: E402

from ambiegen_ros.problems import get_problem  # noqa: E402
from ambiegen_ros.sims.full_model import full_model_executor  # noqa: E402

TARGETS = {"robot": 50.0, "vehicle": 100.0, "thermostat": 10_000.0}
DEFAULT_N = {"robot": 8, "vehicle": 40, "thermostat": 200}


def valid_scenarios(problem, n: int, seed: int):
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < n:
        X = problem.sample_rows(max(4 * n, 50), rng)
        ok = problem.evaluate_rows(X).valid
        out.extend(problem.codec.from_rows(X[ok]))
    return out[:n]


def bench(name: str, n: int, seed: int) -> dict:
    problem = get_problem(name)
    executor = full_model_executor(problem)
    scenarios = valid_scenarios(problem, n, seed)
    executor.execute(scenarios[0])  # warm-up (imports, caches)
    simulated = wall = 0.0
    kinds: Counter = Counter()
    for i, scenario in enumerate(scenarios):
        start = time.perf_counter()
        outcome = executor.execute(scenario, seed=i)
        wall += time.perf_counter() - start
        simulated += float(outcome.metrics["time"])
        kinds[outcome.metrics["outcome"]] += 1
    factor = simulated / wall
    return {
        "scenarios": n,
        "simulated_s": round(simulated, 1),
        "wall_s": round(wall, 3),
        "realtime_factor": round(factor, 1),
        "target_factor": TARGETS[name],
        "meets_target": factor >= TARGETS[name],
        "scenarios_per_minute": round(60.0 * n / wall, 1),
        "outcomes": dict(kinds),
        "config": executor.config_dict(),
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--problems", nargs="+", default=list(TARGETS), choices=list(TARGETS))
    ap.add_argument("--n", type=int, help="scenarios per problem (default: robot 8, vehicle 40, thermostat 200)")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    figures = {}
    print(f"{'simulator':<11} {'n':>4} {'simulated s':>12} {'wall s':>8} {'x real time':>12} "
          f"{'target':>8} {'per min':>8}  outcomes")
    for name in args.problems:
        r = bench(name, args.n or DEFAULT_N[name], args.seed)
        figures[name] = r
        flag = "ok" if r["meets_target"] else "BELOW"
        print(f"{name:<11} {r['scenarios']:>4} {r['simulated_s']:>12.0f} {r['wall_s']:>8.2f} "
              f"{r['realtime_factor']:>12,.0f} {r['target_factor']:>8,.0f} {r['scenarios_per_minute']:>8.0f}  "
              f"{r['outcomes']} {flag}")
    path = write_result("simulators", figures)
    print(f"-> {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
