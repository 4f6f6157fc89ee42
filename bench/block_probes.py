"""Probe scenarios for Nav2's give-up at a blocked passage (issue 49), from the block search.

    python bench/block_probes.py --seeds 1-40 -o probes.json
    ambiegen rerun probes.json --config config/robot_hazards.yaml --stack bringup \\
        --params jazzy=.../nav2_params.yaml --repeat 1 --results probes.jsonl

One NSGA-II run per seed on ``config/robot_hazards_block_mppi.yaml``'s problem (F1 = ``block``,
without its restarts: each run's front is what is kept), ``--evaluations`` each. A front scenario is
a probe when a person shuts the way for a while (``person_block_s`` > 0) and the exact checks agree:
with that person standing as an obstacle the true world has no clearance route
(``sims.reference.robot``), while without them it has one (``before``), and the patient reference,
knowing every path, reaches the goal (``after``). Nav2 then runs only what a reference passes.
Probes are kept once per distinct (block time, start and goal turn). The suite file is written with
each probe's ``f1`` = its block time (highest first) and never overwritten.

The 16 probes of docs/results/nav2/mppi_block_probes_suite.json came from a first form of this
script: the same searches (seeds 1-40, 4,000 evaluations) and checks, with ``PASSING_GAP`` at its
first value, 0.72 m (0.40 m since), and the threat config's constraint (``alpha`` 1.0, not 0.9).
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "bench"))
from _common import seed_list  # noqa: E402


def shuts_the_world(env, config) -> bool:
    """Whether some person, standing where their path starts, leaves the true world no route."""
    from ambiegen_ros.sims.obstacles import Obstacles
    from ambiegen_ros.sims.reference import robot as ref

    for person in env.unmapped["people"]:
        (x, y), radius = person["path"][0], person["radius"]
        standing = Obstacles.from_dict({**env.unmapped, "posts": list(env.unmapped["posts"]) + [[x, y, radius]],
                                        "people": []})
        if not ref.route_for(env.grid, env.resolution, env.start, env.goal, config, standing.static_distance).found:
            return True
    return False


def probes(seeds: list[int], evaluations: int) -> list[dict]:
    from ambiegen_ros.core.config import load_config_file
    from ambiegen_ros.core.search import Search, SearchSettings
    from ambiegen_ros.problems import get_problem
    from ambiegen_ros.sims.full_model import full_model_executor
    from ambiegen_ros.sims.outcome import Outcome
    from ambiegen_ros.sims.reference import robot as ref

    run = load_config_file(REPO / "config" / "robot_hazards_block_mppi.yaml")
    problem = get_problem("robot", dict(run["problem_config"]))
    config = full_model_executor(problem).config
    passed = Outcome(objectives={}, failed=False, failure_kind="none", detail="", metrics={})
    out, seen = [], set()
    for seed in seeds:
        settings = SearchSettings(algorithm="nsga2", evaluations=evaluations, population=run["population"],
                                  offspring=run["offspring"], seed=seed)
        for entry in Search(problem, settings).run().suite:
            scenario = problem.parse(entry["scenario"])
            f = problem.hazard_features(scenario)
            key = (round(f.get("person_block_s", 0.0), 1), round(f["start_turn_rad"], 2), round(f["goal_turn_rad"], 2))
            if f.get("person_block_s", 0.0) <= 0.0 or key in seen:
                continue
            env = problem.environment(scenario)
            if not (shuts_the_world(env, config) and ref.before(problem, scenario, config).passed):
                continue
            after = ref.after(problem, scenario, config, passed)  # the patient reference, the costly check, last
            if after is not None and after.passed:
                seen.add(key)
                out.append({"f1": round(float(f["person_block_s"]), 3), "seed": seed,
                            "note": f"patient reference waits {after.metrics['patient_waited_s']:.0f} s",
                            "scenario": json.loads(scenario.to_json())})
                print(f"seed {seed}: a probe, blocked {f['person_block_s']:.1f} s after the robot comes", flush=True)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", type=seed_list, default=seed_list("1-40"), metavar="A-B")
    ap.add_argument("--evaluations", type=int, default=4000)
    ap.add_argument("-o", "--output", type=Path, required=True, help="the suite file (never overwritten)")
    args = ap.parse_args(argv)
    if args.output.exists():
        raise SystemExit(f"{args.output} exists: not overwritten")
    found = probes(args.seeds, args.evaluations)
    with open(args.output, "x") as fh:
        json.dump({"suite": sorted(found, key=lambda e: -e["f1"])}, fh, indent=1)
    print(f"{len(found)} probes -> {args.output}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
