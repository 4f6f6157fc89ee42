"""Full-model simulator speed: simulated seconds per wall second, and scenarios per minute.

Usage: python bench/simulators.py [--problems robot vehicle thermostat] [--n N] [--seed S]
Executes N sampled valid scenarios per problem with the default simulator settings (one process,
one core) and prints a table; writes bench/results/simulators.json. Targets (issue 4): robot
>= 50x real time, car >= 100x, thermostat >= 10,000x.

``--robot-failures`` instead measures how often the robot's full model (Nearness Diagram driver,
the paper's monitors, the fair time limit) fails on N random valid maps and on the N highest-F1
maps of a GA search (``--evaluations``, as ``ambiegen search --problem robot --algorithm ga``),
with the failure kinds, the ratio top / random, the real-time factor, the rank correlation of
surrogate F1 with the outcome, and how many failures sit at a corner cut of the route (a diagonal
step between two wall cells that touch at a corner); writes bench/results/robot_failures.json.
``--planner gap`` runs the earlier local planner, ``--route-diagonal both_free`` plans the robot's
route without such steps.
"""
from __future__ import annotations

import argparse
import math
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


def bench(name: str, n: int, seed: int, options: dict | None = None) -> dict:
    problem = get_problem(name)
    executor = full_model_executor(problem, **(options or {}))
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


def top_scenarios(problem, n: int, evaluations: int, seed: int):
    """The n highest-F1 distinct valid scenarios evaluated by a GA search (the surrogate's picks)."""
    from ambiegen_ros.core.search import Search, SearchSettings

    search = Search(problem, SearchSettings(algorithm="ga", evaluations=evaluations, seed=seed))
    rows, f1 = [], []
    while True:
        X = search.ask()
        if X is None:
            break
        ev = problem.evaluate_rows(X)
        search.tell(ev)
        rows.append(X[ev.valid])
        f1.append(ev.f1[ev.valid])
    X, f1 = np.concatenate(rows), np.concatenate(f1)
    X, first = np.unique(X, axis=0, return_index=True)
    order = np.argsort(-f1[first], kind="stable")[:n]
    return problem.codec.from_rows(X[order]), f1[first][order], search.evaluations


def _spearman(a, b) -> float | None:
    from scipy.stats import spearmanr

    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    if len(a) < 3 or np.ptp(a) == 0 or np.ptp(b) == 0:
        return None
    return round(float(spearmanr(a, b).statistic), 3)


def corner_cuts(problem, scenario, radius: float) -> list[tuple[float, float]]:
    """Where the problem's A* route steps diagonally between two wall cells that touch at a corner
    (a zero-width gap; the replication profile's rule ``always`` allows it): the corner points."""
    from ambiegen_ros.problems.robot import astar, inflate

    grid = problem.environment(scenario).grid
    _, cells = astar(inflate(grid, radius, 1.0), problem.config.start, problem.config.goal, problem.config.diagonal)
    cuts = []
    for (x0, y0), (x1, y1) in zip(cells[:-1], cells[1:]):
        dx, dy = x1 - x0, y1 - y0
        if dx and dy and grid[y0, x0 + dx] and grid[y0 + dy, x0]:
            cuts.append((x0 + 0.5 + dx / 2, y0 + 0.5 + dy / 2))
    return cuts


def execute_group(executor, scenarios, f1) -> dict:
    """Run each scenario on the full model; failure rate, kinds and speed of the group, and how
    many failures lie within 2 m of a corner cut of the problem's route."""
    rows, simulated, wall = [], 0.0, 0.0
    problem = executor.problem
    for i, (scenario, score) in enumerate(zip(scenarios, f1)):
        start = time.perf_counter()
        out = executor.execute(scenario, seed=i)
        wall += time.perf_counter() - start
        cuts = corner_cuts(problem, scenario, executor.config.radius)
        at_cut = bool(out.failed and out.failure_point is not None and cuts and min(
            math.hypot(out.failure_point[0] - cx, out.failure_point[1] - cy) for cx, cy in cuts) < 2.0)
        m = out.metrics
        simulated += float(m["time"])
        kind = out.failure_kind if out.failure_kind == "none" else f"{out.failure_kind}:{m.get('stall_cause') or '-'}"
        rows.append({"f1": round(float(score), 2), "failed": bool(out.failed), "kind": kind,
                     "time": round(m["time"], 1), "time_limit": round(m["time_limit"], 1),
                     "route_length": m["route_length"],
                     "waypoints": f"{m['waypoints_reached']}/{max(m['waypoints'] - 1, 0)}",
                     "min_clearance": m["min_clearance"], "failure_point": out.failure_point,
                     "corner_cuts": len(cuts), "failed_at_corner_cut": at_cut})
    failed = [r["failed"] for r in rows]
    return {
        "n": len(rows),
        "failures": int(sum(failed)),
        "failure_rate": round(sum(failed) / max(len(rows), 1), 3),
        "kinds": dict(Counter(r["kind"] for r in rows)),
        "maps_with_corner_cut": sum(r["corner_cuts"] > 0 for r in rows),
        "failures_at_corner_cut": sum(r["failed_at_corner_cut"] for r in rows),
        "distinct_failure_places": len({(round(r["failure_point"][0]), round(r["failure_point"][1]))
                                        for r in rows if r["failed"] and r["failure_point"]}),
        "mean_f1": round(float(np.mean(f1)), 2),
        "mean_route_length": round(float(np.mean([r["route_length"] or 0 for r in rows])), 1),
        "simulated_s": round(simulated, 1),
        "wall_s": round(wall, 2),
        "realtime_factor": round(simulated / wall, 1) if wall > 0 else None,
        "runs": rows,
    }


def robot_failures(n: int, evaluations: int, seed: int, planner: str, route_diagonal: str | None = None) -> dict:
    problem = get_problem("robot")
    executor = full_model_executor(problem, planner=planner, route_diagonal=route_diagonal)
    random_sc = valid_scenarios(problem, n, seed)
    random_f1 = problem.evaluate_scenarios(random_sc).f1
    top_sc, top_f1, spent = top_scenarios(problem, n, evaluations, seed)
    executor.execute(random_sc[0])  # warm-up
    groups = {"random": execute_group(executor, random_sc, random_f1),
              "top": execute_group(executor, top_sc, top_f1)}
    both = groups["random"]["runs"] + groups["top"]["runs"]
    rate_r, rate_t = groups["random"]["failure_rate"], groups["top"]["failure_rate"]
    simulated = sum(g["simulated_s"] for g in groups.values())
    wall = sum(g["wall_s"] for g in groups.values())
    return {
        "profile": problem.profile,
        "planner": planner,
        "route_diagonal": route_diagonal or problem.config.diagonal,
        "search": {"algorithm": "ga", "evaluations": spent, "seed": seed},
        **groups,
        "ratio_top_vs_random": round(rate_t / rate_r, 2) if rate_r > 0 else None,
        "spearman_f1_failed": _spearman([r["f1"] for r in both], [r["failed"] for r in both]),
        "realtime_factor": round(simulated / wall, 1),
        "config": executor.config_dict(),
    }


def print_failures(r: dict) -> None:
    print(f"robot full model ({r['planner']}, route diagonal rule {r['route_diagonal']}, profile {r['profile']}), "
          f"GA search of {r['search']['evaluations']} "
          f"evaluations, seed {r['search']['seed']}")
    print(f"{'maps':<8} {'n':>3} {'mean F1':>8} {'failed':>7} {'rate':>6} {'cut':>4} {'at cut':>6} {'places':>6}"
          "  kinds")
    for name in ("random", "top"):
        g = r[name]
        print(f"{name:<8} {g['n']:>3} {g['mean_f1']:>8.1f} {g['failures']:>7} {g['failure_rate']:>6.0%} "
              f"{g['maps_with_corner_cut']:>4} {g['failures_at_corner_cut']:>6} {g['distinct_failure_places']:>6}  "
              f"{g['kinds']}")
    print("cut: maps whose problem route steps between two corner-touching wall cells; at cut: failures within "
          "2 m of one; places: distinct failure places (1 m)")
    print(f"ratio top / random: {r['ratio_top_vs_random']}; Spearman(F1, failed): {r['spearman_f1_failed']}; "
          f"{r['realtime_factor']:.0f}x real time")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--problems", nargs="+", default=list(TARGETS), choices=list(TARGETS))
    ap.add_argument("--n", type=int, help="scenarios per problem (default: robot 8, vehicle 40, thermostat 200; "
                                          "--robot-failures: 40 per group)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--robot-failures", action="store_true", help="robot failure rates: random vs top-F1 maps")
    ap.add_argument("--evaluations", type=int, default=4000, help="GA budget of --robot-failures")
    ap.add_argument("--planner", default="nd", choices=["nd", "gap"], help="the robot's local planner")
    ap.add_argument("--route-diagonal", choices=["both_free", "one_free", "always"],
                    help="A* diagonal rule of the robot's route (default: the problem's)")
    args = ap.parse_args(argv)
    if args.robot_failures:
        r = robot_failures(args.n or 40, args.evaluations, args.seed, args.planner, args.route_diagonal)
        print_failures(r)
        suffix = "".join(f"_{v}" for v in (args.planner if args.planner != "nd" else None, args.route_diagonal) if v)
        print(f"-> {write_result('robot_failures' + suffix, r)}")
        return 0
    figures = {}
    print(f"{'simulator':<11} {'n':>4} {'simulated s':>12} {'wall s':>8} {'x real time':>12} "
          f"{'target':>8} {'per min':>8}  outcomes")
    for name in args.problems:
        r = bench(name, args.n or DEFAULT_N[name], args.seed, {"planner": args.planner} if name == "robot" else None)
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
