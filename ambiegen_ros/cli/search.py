"""`ambiegen search`: a search with the surrogate model, written as a run directory."""
from __future__ import annotations

import argparse
from pathlib import Path

from .common import BadInput, Progress, add_config_option, add_profile_option, build_search


def cmd_search(args: argparse.Namespace) -> int:
    from ..core.runs import write_run
    from ..core.search import Search
    from ..viz.runs import plot_run

    problem, settings = build_search(args)
    out = Path(args.out)
    if not args.overwrite and any((out / name).exists() for name in ("config.json", "suite.json", "history.csv")):
        raise BadInput(f"{out} already holds a run; choose another --out or pass --overwrite")
    label = f"{problem.name}/{settings.algorithm} [{problem.profile}] seed {settings.seed}"
    progress = Progress(label, enabled=None if not args.quiet else False)
    result = Search(problem, settings).run(progress=progress)
    progress.close()
    write_run(out, problem, result, overwrite=args.overwrite)
    pictures = [] if args.no_plots else plot_run(out)
    front = "Pareto front" if settings.algorithm == "nsga2" else "suite"
    print(
        f"{label}: {result.evaluations} evaluations in {result.elapsed:.1f} s, best F1 {result.best_f1:.3f} "
        f"({problem.f1_label}), {front} of {len(result.suite)} (diversity {result.diversity:.2f}) -> {out}"
        + (f" [{len(pictures)} pictures]" if pictures else "")
    )
    return 0


def register(sub) -> None:
    from ..core.names import ALGORITHMS, REFERENCES
    from ..problems import PROBLEM_NAMES

    p = sub.add_parser("search", help="run a search with the surrogate model and write a run directory")
    p.add_argument("--problem", choices=PROBLEM_NAMES, help="case study")
    p.add_argument("--algorithm", choices=ALGORITHMS, help="ga (single objective), nsga2 (F1 + diversity), random")
    budget = p.add_mutually_exclusive_group()
    budget.add_argument("--evaluations", type=int, help="evaluation budget (default: the paper's)")
    budget.add_argument("--time-budget", type=float, metavar="SECONDS", help="wall-clock budget instead")
    p.add_argument("--population", type=int, help="population size (default: the paper's)")
    p.add_argument("--offspring", type=int, help="offspring per generation (default: the paper's)")
    p.add_argument("--seed", type=int, help="random seed (default: drawn and recorded)")
    p.add_argument("--reference", choices=REFERENCES, help="F2 reference: parent (paper) or nearest front member")
    add_config_option(p)
    add_profile_option(p)
    p.add_argument("--out", required=True, metavar="DIR", help="run directory to write (an existing run is refused)")
    p.add_argument("--overwrite", action="store_true", help="replace the run already in --out")
    p.add_argument("--no-plots", action="store_true", help="skip the pictures")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_search)
