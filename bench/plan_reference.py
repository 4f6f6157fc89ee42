"""Speed of the planner oracles' reference planner and inflation (issue 68): is it cheap enough to
judge thousands of Nav2 planner scenarios?

Usage: python bench/plan_reference.py [--sizes 100,200,400] [--queries 40] [--seed 0]

Per map size (square, 0.05 m cells): random rooms (walls with doors, boxes), built into a costmap
the way Nav2 would (static layer, inflation with Jazzy's 0.7 m / 3.0 and the 0.22 m robot); then
``--queries`` random start/goal pairs in free cells, each asked of a fresh ``reference_plan`` (the
grid's traversability and labels included) under NavFn's rules, and the certificate, when one is
found, judged by ``judge_plan``. Times are medians (and 90th percentiles) in milliseconds, after
one warm-up call (numba's compile or cache load is not counted).

Writes bench/results/plan_reference.json.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import report  # noqa: E402

from ambiegen_ros.sims.plans import rules  # noqa: E402
from ambiegen_ros.sims.plans.costmap import costmap_from_occupancy  # noqa: E402
from ambiegen_ros.sims.plans.oracles import judge_plan  # noqa: E402
from ambiegen_ros.sims.plans.reference import reference_plan  # noqa: E402

RES = 0.05


def rooms(n: int, rng: np.random.Generator) -> np.ndarray:
    """An n x n OccupancyGrid: outer walls, a 4 x 4 grid of rooms with doors, a few boxes."""
    occ = np.zeros((n, n), dtype=np.int16)
    occ[[0, -1], :] = occ[:, [0, -1]] = 100
    step = n // 4
    for k in range(1, 4):
        occ[k * step, :] = occ[:, k * step] = 100
        for j in range(4):  # a door of 16 cells (0.8 m) in each wall segment
            d = j * step + int(rng.integers(2, max(3, step - 18)))
            occ[k * step, d:d + 16] = 0
            occ[d:d + 16, k * step] = 0
    for _ in range(n // 10):
        x, y = rng.integers(2, n - 8, size=2)
        occ[y:y + int(rng.integers(2, 6)), x:x + int(rng.integers(2, 6))] = 100
    return occ


def ms(values: list[float]) -> dict:
    arr = np.array(values) * 1000.0
    return {"median_ms": round(float(np.median(arr)), 3), "p90_ms": round(float(np.percentile(arr, 90)), 3),
            "n": len(values)}


def bench_size(n: int, queries: int, rng: np.random.Generator) -> dict:
    """Inflation, reference and judgement times on one n x n map."""
    occ = rooms(n, rng)
    costmap_from_occupancy(occ[:20, :20])  # warm-up: numba compile or cache load
    t = time.perf_counter()
    cm = costmap_from_occupancy(occ)
    inflate_s = time.perf_counter() - t
    planner = rules.navfn()
    free = np.argwhere(planner.traversable(cm.cost))
    pick = lambda: tuple(cm.map_to_world(*free[rng.integers(len(free))][::-1]))  # noqa: E731
    reference_plan(cm, planner, pick(), pick())  # warm-up
    times, judge_times, statuses = [], [], {}
    for _ in range(queries):
        start, goal = pick(), pick()
        t = time.perf_counter()
        ref = reference_plan(cm, planner, start, goal)
        times.append(time.perf_counter() - t)
        statuses[ref.status] = statuses.get(ref.status, 0) + 1
        if ref.found:
            t = time.perf_counter()
            verdict = judge_plan(cm, planner, start, goal, path=ref.poses)
            judge_times.append(time.perf_counter() - t)
            assert not verdict.failed, verdict.failures  # a certificate passes our own oracles
    return {"cells": n * n, "inflate_ms": round(inflate_s * 1000.0, 3), "reference": ms(times),
            "judge_certificate": ms(judge_times) if judge_times else None, "statuses": statuses}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="100,200,400")
    ap.add_argument("--queries", type=int, default=40)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    figures = {f"{n}x{n}": bench_size(n, args.queries, rng) for n in (int(v) for v in args.sizes.split(","))}
    figures["settings"] = {"resolution": RES, "planner": "navfn rules", "queries": args.queries, "seed": args.seed}
    report("plan_reference", "", figures)


if __name__ == "__main__":
    main()
