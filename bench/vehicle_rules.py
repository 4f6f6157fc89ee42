"""The vehicle reference check on replication-profile roads (issue 16): which rules top roads break,
and which brisk-driver failures a cautious driver passes.

Usage: python bench/vehicle_rules.py [--seeds 0,1,2] [--evaluations 100000] [--top 36] [--sampled 1000]

Roads: the ``--top`` distinct valid roads of highest F1 in the final population of an NSGA-II run
(replication profile, paper budget), and ``--sampled`` valid roads from the problem's own sampler
(what random search executes). Per road: the builder cut it (it left the map), the competition rules
(``problems.vehicle.validity.competition_rules``: map with the lanes' edges, overlap of the 8 m
surface, radius) and, for information, whether its centre line alone leaves the map's margin, whether
its edges leave the map itself, and whether its centre line comes within 4 m (a lane width) or
10 m of a non-neighbouring part of itself; the time of one rules check; then the brisk default
driver and the cautious reference driver on every road (also the rule-breaking ones, for the count).

Writes bench/results/vehicle_rules.json.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import write_result  # noqa: E402

from ambiegen_ros.core.search import Search, SearchSettings  # noqa: E402
from ambiegen_ros.problems import get_problem  # noqa: E402
from ambiegen_ros.problems.vehicle.validity import competition_rules, lane_edges  # noqa: E402
from ambiegen_ros.sims import car  # noqa: E402
from ambiegen_ros.sims.reference import vehicle as reference  # noqa: E402

RULES = {"leaves the map": "map", "overlaps itself": "overlap", "edge": "overlap", "too sharp": "radius"}


def top_roads(problem, seed: int, evaluations: int, top: int) -> list:
    """The ``top`` distinct valid roads (genomes) of highest F1 in the run's final population."""
    search = Search(problem, SearchSettings(algorithm="nsga2", seed=seed, evaluations=evaluations))
    search.run()
    pop = search._algorithm.pop
    order = np.argsort(-pop.get("f1").astype(float), kind="stable")
    out, seen = [], set()
    for ind in pop[order]:
        sc = problem.codec.from_row(ind.get("X"))
        key = str(sc.to_dict())
        if key in seen or not ind.get("info")["valid"]:
            continue
        seen.add(key)
        out.append(sc)
        if len(out) == top:
            break
    return out


def sampled_roads(problem, n: int, seed: int) -> list:
    G, lengths = problem.sample(3 * n, np.random.default_rng(seed))
    valid = problem.evaluate(G, lengths).valid
    rows = problem.codec.join(G[valid][:n], lengths[valid][:n])
    return [problem.codec.from_row(r) for r in rows]


def measure(problem, scenarios: list) -> dict:
    pc = problem.config
    sut = car.CarSimConfig()
    cautious = reference.cautious(sut)
    counts = dict(roads=len(scenarios), cut=0, map=0, overlap=0, radius=0, broken=0, centre_line_outside_margin=0,
                  edges_off_the_map=0, within_lane_width=0,
                  within_10m=0, brisk_failures=0, brisk_failures_cautious_passes=0, both_fail=0,
                  brisk_failures_on_valid_roads=0, certified_failures=0, invalid_after_drive=0)
    times, examples = [], []
    for sc in scenarios:
        check = car.road_check(problem, sc)
        radius = check.min_radius if pc.profile == "replication" else None
        t = time.perf_counter()
        ok, reason = competition_rules(check.road, pc.lane_width, pc.map_size, pc.margin, pc.min_radius, radius=radius)
        times.append(time.perf_counter() - t)
        broken = set()
        for part in (reason or "").split("; "):
            broken |= {rule for key, rule in RULES.items() if key in part}
        for rule in broken:
            counts[rule] += 1
        counts["cut"] += check.cut
        counts["broken"] += (not ok) or check.cut
        left, right = lane_edges(check.road, pc.lane_width)
        lo, hi = pc.margin, pc.map_size - pc.margin
        counts["centre_line_outside_margin"] += bool(np.any((check.road < lo) | (check.road > hi)))
        edges = np.vstack([left, right])
        counts["edges_off_the_map"] += bool(np.any((edges < 0) | (edges > pc.map_size)))
        for gap, name in ((4.0, "within_lane_width"), (10.0, "within_10m")):
            r = competition_rules(check.road, pc.lane_width, 1e9, -1e9, 0.0, radius=np.inf, gap=gap)[1]
            counts[name] += bool(r and "overlaps itself" in r)
        brisk = car.drive(check.road, pc.lane_width, sut)
        if brisk["failure_kind"] == "none":
            continue
        counts["brisk_failures"] += 1
        careful = car.drive(check.road, pc.lane_width, cautious)
        passed = careful["failure_kind"] == "none"
        counts["brisk_failures_cautious_passes"] += passed
        counts["both_fail"] += not passed
        if ok and not check.cut:
            counts["brisk_failures_on_valid_roads"] += 1
            counts["certified_failures"] += passed
            counts["invalid_after_drive"] += not passed
        if len(examples) < 5 and (reason or check.cut):
            examples.append({"reason": reason, "cut": check.cut, "brisk": brisk["detail"],
                             "cautious": careful["detail"]})
    counts["rules_ms_per_road_median"] = round(1e3 * float(np.median(times)), 2)
    counts["rules_ms_per_road_max"] = round(1e3 * float(np.max(times)), 2)
    counts["nodes_per_road_median"] = float(np.median([len(car.road_of(problem, s)[0]) for s in scenarios]))
    counts["examples"] = examples
    return counts


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", default="0", help="NSGA-II runs whose top roads are checked, e.g. 0,1,2")
    ap.add_argument("--evaluations", type=int, default=100000)
    ap.add_argument("--top", type=int, default=36)
    ap.add_argument("--sampled", type=int, default=1000, help="sampled valid roads (0: none)")
    args = ap.parse_args()
    problem = get_problem("vehicle")
    start = time.perf_counter()
    seeds = [int(s) for s in args.seeds.split(",")]
    figures = {"seeds": seeds, "evaluations": args.evaluations, "top": {}}
    for seed in seeds:
        figures["top"][seed] = measure(problem, top_roads(problem, seed, args.evaluations, args.top))
        print("top", seed, figures["top"][seed], flush=True)
    if args.sampled:
        figures["sampled"] = measure(problem, sampled_roads(problem, args.sampled, seeds[0]))
        print("sampled", figures["sampled"], flush=True)
    figures["wall_s"] = round(time.perf_counter() - start, 1)
    print(write_result("vehicle_rules", figures))


if __name__ == "__main__":
    main()
