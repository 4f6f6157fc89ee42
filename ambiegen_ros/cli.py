"""`ambiegen`: the command line over the ROS-free core (search, evaluate, show).

Bad input (malformed JSON, unknown problem or attribute, out-of-domain values, NaN, wrong types,
bad options) exits with status 2 and one line naming the field and what is allowed; never a
traceback, never a silently repaired scenario.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any, Callable

from . import __version__
from .core.attributes import ScenarioError
from .core.scenario import Scenario
from .core.config import SETTING_NAMES, ConfigError, make_run
from .core.search import ALGORITHMS, REFERENCES, Search, SearchSettings
from .problems import PROBLEM_NAMES, PROFILES, get_problem

EXIT_BAD_INPUT = 2


class BadInput(Exception):
    """A user error reported as one line with exit status 2."""


# --- shared helpers (also used by later subcommands) -----------------------------------------
def read_text(path: str) -> str:
    """A file's text, or standard input for ``-``; unreadable files are a one-line error."""
    if path == "-":
        return sys.stdin.read()
    try:
        return Path(path).read_text()
    except OSError as exc:
        raise BadInput(f"{path}: cannot read ({exc.strerror})")
    except UnicodeDecodeError:
        raise BadInput(f"{path}: not a text file")


def scenario_problem(data: dict[str, Any], profile: str | None = None) -> Any:
    """The case study a scenario names, in the given fidelity profile (default: replication)."""
    name = data.get("problem") if isinstance(data.get("problem"), str) else repr(data.get("problem"))
    return get_problem(name, {"profile": profile} if profile else None)


def load_scenario_file(path: str, profile: str | None = None) -> tuple[Any, Scenario]:
    """Read and validate a scenario JSON file -> (problem, scenario)."""
    data = Scenario.parse_json(read_text(path))
    problem = scenario_problem(data, profile)
    return problem, problem.parse(data)


def add_profile_option(parser: argparse.ArgumentParser) -> None:
    """``--profile``: which models score, build and draw the environment (recorded in outputs)."""
    parser.add_argument(
        "--profile", choices=PROFILES, default=None,
        help="fidelity profile: replication (default; the authors' replication code, which made the paper's "
        "tables) or refined (the paper's equations and competition road rules)",
    )


def build_search(args: argparse.Namespace) -> tuple[Any, SearchSettings]:
    """Problem + settings from --config and the flags (flags win)."""
    overrides = {name: getattr(args, name, None) for name in SETTING_NAMES}
    return make_run(args.problem, getattr(args, "config", None), profile=getattr(args, "profile", None), **overrides)


class Progress:
    """A one-line progress display on a terminal (stderr); silent when not a TTY."""

    def __init__(self, label: str, enabled: bool | None = None):
        self.label = label
        self.enabled = sys.stderr.isatty() if enabled is None else enabled
        self._last = 0.0

    def __call__(self, search: Search) -> None:
        if not self.enabled:
            return
        now = time.monotonic()
        if now - self._last < 0.2 and not search.done():
            return
        self._last = now
        s = search.settings
        if s.evaluations is not None:
            frac = search.evaluations / s.evaluations
            budget = f"{search.evaluations}/{s.evaluations} evals"
        else:
            frac = min(search.elapsed / s.time_budget, 1.0)
            budget = f"{search.evaluations} evals, {search.elapsed:.0f}/{s.time_budget:.0f} s"
        bar = "#" * int(frac * 24)
        last = search.history[-1] if search.history else {"front_size": 0}
        sys.stderr.write(
            f"\r{self.label} [{bar:<24}] {budget}  best F1 {search.best_f1:.3f}  front {last['front_size']}   "
        )
        sys.stderr.flush()

    def close(self) -> None:
        if self.enabled:
            sys.stderr.write("\n")


# --- subcommands -----------------------------------------------------------------------------
def cmd_search(args: argparse.Namespace) -> int:
    from .core.runs import write_run
    from .viz.runs import plot_run

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


def cmd_evaluate(args: argparse.Namespace) -> int:
    if is_suite_file(args.scenario):
        return evaluate_suite(args)
    problem, scenario = load_scenario_file(args.scenario, args.profile)
    row = problem.evaluate_scenarios([scenario]).row(0)
    out = {"problem": problem.name, "profile": problem.profile, **row}
    if args.json:
        print(json.dumps(out))
    else:
        status = "valid" if out["valid"] else f"INVALID ({out['reason']})"
        print(f"{problem.name} [{problem.profile}]: {len(scenario.elements)} elements, {status}, "
              f"F1 = {out['f1']:.4f} ({problem.f1_label})")
        for key, value in out.items():
            if key not in ("problem", "profile", "valid", "reason", "f1"):
                print(f"  {key}: {value}")
    return 0


def is_suite_file(path: str) -> bool:
    """A suite is JSON Lines: a ``.jsonl`` / ``.ndjson`` file, or ``-`` (standard input)."""
    return path == "-" or Path(path).suffix.lower() in (".jsonl", ".ndjson")


def evaluate_suite(args: argparse.Namespace) -> int:
    """One scenario per line -> one JSON object per line, same order; each problem one batch.

    A line may also be a record that holds its scenario under ``"scenario"`` (a run's suite
    entry, a reference verdict). A bad line is answered by ``{"line": k, "error": ...}`` and
    makes the exit status 2; the others are still evaluated.
    """
    lines = read_text(args.scenario).splitlines()
    results: dict[int, dict[str, Any]] = {}
    groups: dict[str, tuple[Any, list[int], list[Scenario]]] = {}
    for k, text in enumerate(lines, start=1):
        if not text.strip():
            continue
        try:
            data = Scenario.parse_json(text)
            if "elements" not in data and isinstance(data.get("scenario"), dict):
                data = data["scenario"]
            name = data.get("problem") if isinstance(data.get("problem"), str) else repr(data.get("problem"))
            if name not in groups:
                groups[name] = (scenario_problem(data, args.profile), [], [])
            problem, numbers, scenarios = groups[name]
            scenarios.append(problem.parse(data))
            numbers.append(k)
        except (ScenarioError, BadInput) as exc:
            results[k] = {"line": k, "error": str(exc)}
    for problem, numbers, scenarios in groups.values():
        ev = problem.evaluate_scenarios(scenarios)
        for i, k in enumerate(numbers):
            results[k] = {"line": k, "problem": problem.name, "profile": problem.profile, **ev.row(i)}
    bad = sum("error" in r for r in results.values())
    for k in sorted(results):
        r = results[k]
        if args.json:
            print(json.dumps(r))
        elif "error" in r:
            print(f"line {k}: error: {r['error']}")
        else:
            status = "valid" if r["valid"] else f"INVALID ({r['reason']})"
            print(f"line {k}: {r['problem']} [{r['profile']}] {status}, F1 = {r['f1']:.4f}")
    if not args.json:
        scored = [r for r in results.values() if "error" not in r]
        valid = [r["f1"] for r in scored if r["valid"]]
        best = f", best F1 {max(valid):.4f}" if valid else ""
        print(f"{len(scored)} scenarios evaluated, {len(valid)} valid{best}; {bad} bad lines", file=sys.stderr)
    return EXIT_BAD_INPUT if bad else 0


def cmd_show(args: argparse.Namespace) -> int:
    from .viz import save_scenario_plot
    from .viz.runs import plot_run

    target = Path(args.target)
    if target.is_dir():
        if not (target / "suite.json").exists():
            raise BadInput(f"{target}: not a run directory (no suite.json)")
        written = plot_run(target, out=Path(args.output) if args.output else None)
        print("\n".join(str(p) for p in written))
        return 0
    problem, scenario = load_scenario_file(str(target), args.profile)
    output = Path(args.output or target.with_suffix(".png"))
    if args.execute:
        from .sims.full_model import full_model_executor
        from .viz.execution import save_execution_plot

        outcome = full_model_executor(problem).execute(scenario, seed=args.seed)
        save_execution_plot(problem, scenario, outcome, output)
        verdict = f"FAILED ({outcome.failure_kind})" if outcome.failed else outcome.failure_kind
        print(f"{output}  [{verdict}]")
        return 0
    save_scenario_plot(problem, scenario, output)
    print(output)
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="ambiegen",
        description="AmbieGen: evolutionary search for environments in which autonomous systems fail.",
    )
    parser.add_argument("--version", action="version", version=f"ambiegen-ros {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")

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
    p.add_argument("--config", metavar="FILE.yaml", help="search settings and problem_config overrides")
    add_profile_option(p)
    p.add_argument("--out", required=True, metavar="DIR", help="run directory to write (an existing run is refused)")
    p.add_argument("--overwrite", action="store_true", help="replace the run already in --out")
    p.add_argument("--no-plots", action="store_true", help="skip the pictures")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_search)

    p = sub.add_parser(
        "evaluate", help="validity and surrogate F1 of a scenario JSON, or of a suite (.jsonl: one scenario per line)"
    )
    p.add_argument("scenario", metavar="SCENARIO.json|SCENARIOS.jsonl|-",
                   help="one scenario (.json) or JSON Lines (.jsonl, or - for standard input), evaluated as one batch")
    p.add_argument("--json", action="store_true", help="print JSON: one object (per line for a suite)")
    add_profile_option(p)
    p.set_defaults(func=cmd_evaluate)

    p = sub.add_parser("show", help="picture of a scenario, or of a run directory (convergence + best scenarios)")
    p.add_argument("target", metavar="SCENARIO.json|RUN_DIR")
    p.add_argument("-o", "--output", metavar="FILE.png", help="output picture (run dirs: a file prefix)")
    p.add_argument("--execute", action="store_true", help="run the scenario on its full-model simulator and draw the trajectory")
    p.add_argument("--seed", type=int, default=0, help="simulator seed for --execute (default 0)")
    add_profile_option(p)
    p.set_defaults(func=cmd_show)

    for register in EXTRA_COMMANDS:
        register(sub)
    return parser


def _ros_commands(sub) -> None:
    from .campaign import register_cli

    register_cli(sub)


def _execute_command(sub) -> None:
    from .sims.cli import register_cli

    register_cli(sub)


def _experiment_command(sub) -> None:
    from .experiment import register_cli

    register_cli(sub)


def _doctor_command(sub) -> None:
    from .doctor import register_cli

    register_cli(sub)


EXTRA_COMMANDS: list[Callable[[Any], None]] = [_execute_command, _ros_commands, _experiment_command, _doctor_command]
"""Subcommand registrars of other modules (ROS campaign, recover, replay)."""


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return EXIT_BAD_INPUT
    from .deps import broken_environment

    if args.command != "doctor" and broken_environment(f"ambiegen {args.command}"):  # fail before any work
        return EXIT_BAD_INPUT
    try:
        return int(args.func(args) or 0)
    except (BadInput, ScenarioError, ConfigError) as exc:
        print(f"ambiegen {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print(f"ambiegen {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
