"""`ambiegen experiment`: the paper's RQ1-RQ3 in one command (the library is ``ambiegen_ros.experiment``)."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from .common import BadInput, add_config_option


def _spec_from_args(args: argparse.Namespace):
    from ..experiment import ExperimentSpec
    from ..sims.options import parse_options

    algorithms = tuple(a.strip() for a in args.algorithms.split(",") if a.strip())
    return ExperimentSpec(
        problem=args.problem, algorithms=algorithms, runs=args.runs, seed=args.seed, profile=args.profile,
        evaluations=args.evaluations, time_budget=args.time_budget, full_model=args.full_model,
        config_file=args.config, sim_options=parse_options(args.set), distinct_distance=args.distinct_distance,
        clock=args.clock, executors=args.executors, execution_cost=args.execution_cost,
        signature_radius=args.signature_radius, executor_idle=args.executor_idle, search_for=args.search_for,
        novelty=not args.no_novelty,
    )


def cmd_experiment(args: argparse.Namespace) -> int:
    from ..experiment import ALGORITHM_LABELS, ExperimentError, median, run_experiment, too_few_runs

    if args.jobs is not None and args.jobs < 1:
        raise BadInput("--jobs: must be >= 1")
    try:
        spec = _spec_from_args(args)
        result = run_experiment(spec, Path(args.out), jobs=args.jobs, resume=args.resume,
                                progress=False if args.quiet else None)
    except ExperimentError as exc:
        raise BadInput(str(exc))
    config, records, errors = result["config"], result["records"], result["errors"]
    print(f"{config['problem']} ({config['profile']} profile): {len(records)} runs -> {args.out}")
    for alg in config["algorithms"]:
        rs = [r for r in records if r["algorithm"] == alg]
        line = f"  {ALGORITHM_LABELS.get(alg, alg):<13} median best F1 {median([r['best_f1'] for r in rs]):.4g}"
        if spec.full_model:
            line += (f", executions {median([r['executions'] for r in rs]):g}"
                     f", failures {median([r['failures'] for r in rs]):g}"
                     f", distinct {median([r['distinct_failures'] for r in rs]):g}"
                     f", invalid tests {median([r.get('invalid_tests', 0) for r in rs]):g}")
        else:
            line += f", diversity {median([r['diversity'] for r in rs]):.3f}"
        print(line)
    counts = sorted(sum(r["algorithm"] == alg for r in records) for alg in config["algorithms"])
    why = too_few_runs(*counts[:2]) if len(counts) >= 2 else None
    if why:
        print(f"  too few runs to decide: {why} (the paper ran 30)")
    print(f"  report: {Path(args.out) / 'report.md'}")
    if errors:
        print(f"ambiegen experiment: {len(errors)} run(s) failed; see above; --resume re-runs them", file=sys.stderr)
        return 1
    return 0


def register(sub) -> None:
    """Add ``experiment`` to ``ambiegen``'s subparsers."""
    from ..problems import PROBLEM_NAMES, PROFILES

    p = sub.add_parser("experiment", help="the paper's RQ1-RQ3: repeated runs, statistics, report and plots",
                       description="Run every algorithm --runs times (run k with seed SEED + k) on a process pool and "
                                   "write results.csv, stats.json, report.md and plots. RQ1/RQ2 on the surrogate "
                                   "(same evaluation budget); RQ3 with --full-model (same clock budget for generating "
                                   "and executing scenarios on the full-model simulators).")
    p.add_argument("--problem", required=True, choices=PROBLEM_NAMES)
    p.add_argument("--algorithms", default="ga,nsga2,random", help="comma-separated (default ga,nsga2,random)")
    p.add_argument("--runs", type=int, default=30, help="runs per algorithm (default 30, as the paper; 3 or fewer cannot show a significant difference)")
    p.add_argument("--jobs", type=int, help="parallel runs (default: all cores)")
    p.add_argument("--out", required=True, metavar="DIR", help="experiment directory (must be new or empty, "
                                                                 "or an earlier experiment with --resume)")
    budget = p.add_mutually_exclusive_group()
    budget.add_argument("--evaluations", type=int, help="surrogate evaluations per run (default: the paper's budget)")
    budget.add_argument("--time-budget", type=float, metavar="S",
                        help="seconds per run (RQ1/RQ2: of search; --full-model: on the executors' clocks, default 7200)")
    p.add_argument("--full-model", action="store_true", help="RQ3: execute scenarios on the full-model simulators")
    p.add_argument("--profile", choices=PROFILES,
                   help="fidelity profile of the problem (default: replication; with --full-model, the profile "
                        "--search-for certified chooses: refined)")
    p.add_argument("--seed", type=int, default=0, help="base seed; run k uses seed + k (default 0)")
    p.add_argument("--resume", action="store_true", help="continue an experiment in --out: skip runs already done")
    add_config_option(p)
    p.add_argument("--set", action="append", default=[], metavar="OPTION=VALUE",
                   help="--full-model: simulator option (repeatable), as for `ambiegen execute`")
    p.add_argument("--distinct-distance", type=float, default=0.0,
                   help="--full-model: skip a candidate within this Jaccard distance of an executed failure "
                        "(default 0: only the same scenario within the attribute tolerances)")
    p.add_argument("--clock", choices=("wall", "cpu"), default="wall",
                   help="--full-model: how search and execution times are measured (default wall, as the paper; "
                        "cpu = process time, immune to other load on the machine)")
    p.add_argument("--executors", type=int, default=1,
                   help="--full-model: full-model executors running beside the search, each on its own clock "
                        "(default 1)")
    p.add_argument("--executor-idle", choices=("random", "wait"), default="random",
                   help="--full-model: an executor the search has no fresh candidate for runs a valid random "
                        "sample (default: a simulator never idles, so the search can only add to what random "
                        "search finds) or waits for the search (the schedule before issue 26)")
    p.add_argument("--execution-cost", type=float, default=0.0, metavar="S",
                   help="--full-model: seconds of budget charged per execution on top of the measured time, "
                        "without sleeping (e.g. 30 for a 30 s simulator; default 0)")
    p.add_argument("--search-for", choices=("certified", "paper"), default="certified",
                   help="--full-model: what the surrogate search climbs: certified failures (default: the "
                        "reference's static check as validity, F1 relative to the reference, e.g. the vehicle's "
                        "refined roads scored by its brisk and cautious drivers; docs/search_for_certified.md) or "
                        "the paper's F1 and profile")
    p.add_argument("--no-novelty", action="store_true",
                   help="--full-model: a search's executor also runs candidates whose predicted failure is the "
                        "same as one already found (default: it skips them; random search never does)")
    p.add_argument("--signature-radius", type=float, metavar="R",
                   help="--full-model: two failures of the same kind are the same when this close: robot metres "
                        "(default 2), vehicle degrees of the failing bend's turn (default 30), thermostat degC of the "
                        "set-point step into the failing element (default 1); docs/search_for_certified.md")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_experiment)


__all__ = ["cmd_experiment", "register"]
