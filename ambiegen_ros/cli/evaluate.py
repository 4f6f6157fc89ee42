"""`ambiegen evaluate` (validity and surrogate F1 of a scenario or a suite) and `ambiegen show`
(a picture of a scenario or of a run directory)."""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from .common import EXIT_BAD_INPUT, BadInput, add_config_option, add_profile_option, load_scenario, scenario_problem


def cmd_evaluate(args: argparse.Namespace) -> int:
    if is_suite_file(args.scenario):
        return evaluate_suite(args)
    problem, scenario = load_scenario(args, args.scenario)
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
    entry, a reference verdict). A bad line (also one of another problem than --config's) is
    answered by ``{"line": k, "error": ...}`` and makes the exit status 2; the others are still
    evaluated. An unreadable --config stops the command before any line.
    """
    from ..core.attributes import ScenarioError
    from ..core.config import load_config_file
    from ..core.errors import ConfigError
    from ..core.scenario import Scenario
    from ..problems.scenario_file import read_text

    load_config_file(args.config)
    lines = read_text(args.scenario).splitlines()
    results: dict[int, dict[str, Any]] = {}
    groups: dict[str, tuple[Any, list[int], list[Any]]] = {}
    for k, text in enumerate(lines, start=1):
        if not text.strip():
            continue
        try:
            data = Scenario.parse_json(text)
            if "elements" not in data and isinstance(data.get("scenario"), dict):
                data = data["scenario"]
            named = data.get("problem")
            name = named if isinstance(named, str) else repr(named)
            if name not in groups:
                groups[name] = (scenario_problem(args, data), [], [])
            problem, numbers, scenarios = groups[name]
            scenarios.append(problem.parse(data))
            numbers.append(k)
        except (ScenarioError, BadInput, ConfigError) as exc:
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
    from ..viz import save_scenario_plot
    from ..viz.runs import plot_run

    target = Path(args.target)
    if target.is_dir():
        if not (target / "suite.json").exists():
            raise BadInput(f"{target}: not a run directory (no suite.json)")
        if args.config:
            raise BadInput("--config: a run directory is drawn with its own config (config.json); "
                           "--config is for a scenario file")
        written = plot_run(target, out=Path(args.output) if args.output else None)
        print("\n".join(str(p) for p in written))
        return 0
    problem, scenario = load_scenario(args, str(target))
    output = Path(args.output or target.with_suffix(".png"))
    if args.execute:
        from ..sims.full_model import full_model_executor
        from ..viz.execution import save_execution_plot

        outcome = full_model_executor(problem).execute(scenario, seed=args.seed)
        save_execution_plot(problem, scenario, outcome, output)
        print(f"{output}  [{outcome.verdict}]")
        return 0
    save_scenario_plot(problem, scenario, output)
    print(output)
    return 0


def register(sub) -> None:
    p = sub.add_parser(
        "evaluate", help="validity and surrogate F1 of a scenario JSON, or of a suite (.jsonl: one scenario per line)"
    )
    p.add_argument("scenario", metavar="SCENARIO.json|SCENARIOS.jsonl|-",
                   help="one scenario (.json) or JSON Lines (.jsonl, or - for standard input), evaluated as one batch")
    p.add_argument("--json", action="store_true", help="print JSON: one object (per line for a suite)")
    add_config_option(p)
    add_profile_option(p)
    p.set_defaults(func=cmd_evaluate)

    p = sub.add_parser("show", help="picture of a scenario, or of a run directory (convergence + best scenarios)")
    p.add_argument("target", metavar="SCENARIO.json|RUN_DIR")
    p.add_argument("-o", "--output", metavar="FILE.png", help="output picture (run dirs: a file prefix)")
    p.add_argument("--execute", action="store_true", help="run the scenario on its full-model simulator and draw the trajectory")
    p.add_argument("--seed", type=int, default=0, help="simulator seed for --execute (default 0)")
    add_config_option(p)
    add_profile_option(p)
    p.set_defaults(func=cmd_show)
