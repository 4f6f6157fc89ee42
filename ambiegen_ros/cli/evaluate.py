"""`ambiegen evaluate` (validity and surrogate F1 of a scenario or a suite) and `ambiegen show`
(a picture of a scenario or of a run directory, or an animation of one robot scenario of a robot bag)."""
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
    target = Path(args.target)
    if target.suffix.lower() == ".mcap":
        return show_bag(args, target)
    if args.scenario is not None or args.run is not None or args.fps is not None or args.speed is not None \
            or args.overwrite:
        raise BadInput("--run, --scenario, --fps, --speed and --overwrite are for a robot bag (RUN.mcap)")
    from ..viz import save_scenario_plot
    from ..viz.runs import plot_run

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
    if args.set and not args.execute:
        raise BadInput("--set: simulator options are for --execute")
    if args.execute:
        from ..sims.full_model import full_model_executor
        from ..sims.options import parse_options
        from ..viz.execution import save_execution_plot

        outcome = full_model_executor(problem, **parse_options(args.set)).execute(scenario, seed=args.seed)
        save_execution_plot(problem, scenario, outcome, output)
        print(f"{output}  [{outcome.verdict}]")
        return 0
    save_scenario_plot(problem, scenario, output)
    print(output)
    return 0


def show_bag(args: argparse.Namespace, path: Path) -> int:
    """One robot scenario of a robot bag as a GIF/MP4; without --scenario, the bag's scenarios (exit 2)."""
    from ..ros.robot_bag import read_index, read_run

    if args.execute or args.config or args.profile or args.set:
        raise BadInput("--execute, --set, --config and --profile are for a scenario file; a bag is drawn as recorded")
    output = Path(args.output) if args.output else None
    if args.scenario is not None and output is not None:  # a wrong -o fails before the bag is read
        _check_output(output, args.overwrite)
    index = read_index(path, args.run)
    several = len(index.runs) > 1 and args.run is None
    if args.scenario is None:
        for run in (index.runs if several else [index.run_id]):
            shown = index.select(run)
            for entry in shown.entries.values():
                named = f"{shown.run_id}  " if several else ""
                print(f"{named}{entry.scenario_id:6d}  {entry.verdict[:70]:<24s}  {_log_span(shown, entry)}")
        if several:
            raise BadInput(f"{path}: {sum(len(e) for e, _ in index.runs.values())} robot scenarios in "
                           f"{len(index.runs)} runs (above); pick one: ambiegen show {path} --run RUN --scenario ID "
                           "-o failure.gif")
        raise BadInput(f"{path}: {len(index.entries)} robot scenarios of run {index.run_id} (above); pick one: "
                       f"ambiegen show {path} --scenario ID -o failure.gif")
    if several:  # a scenario id names a run only when one run has it (a batch logs scenario 0 in every run)
        having = [run for run, (entries, _) in index.runs.items() if args.scenario in entries]
        if len(having) > 1:
            raise BadInput(f"{path}: scenario {args.scenario} is in {len(having)} runs of the bag; pick one with "
                           f"--run RUN (ambiegen show {path} lists them)")
        index = index.select(having[0]) if having else index
    if output is None:
        named = f"_{index.run_id}" if len(index.runs) > 1 else ""
        output = path.with_name(f"{path.stem}{named}_scenario_{args.scenario}.gif")
        _check_output(output, args.overwrite)
    from ..viz.animation import save_robot_animation

    run = read_run(index, args.scenario)
    try:
        facts = save_robot_animation(run, output, fps=args.fps or 10.0, speed=args.speed or 1.0,
                                     overwrite=args.overwrite)
    except ValueError as exc:
        raise BadInput(str(exc)) from None
    faster = f", played {facts['playback']:.3g}x (at most {facts['frames']} frames)" \
        if facts["playback"] > (args.speed or 1.0) + 1e-9 else f", played {facts['playback']:.3g}x"
    print(f"{facts['path']}  [{run.entry.verdict}] scenario {run.entry.scenario_id}: {facts['frames']} frames of "
          f"{facts['duration_s']:.1f} simulated s{faster}")
    print(f"  {_log_span(index, run.entry)}")
    return 0


def _check_output(output: Path, overwrite: bool) -> None:
    """An animation's output file, refused in one line (exists, or not .gif/.mp4)."""
    from ..viz.animation import check_output

    try:
        check_output(output, overwrite)
    except ValueError as exc:
        raise BadInput(str(exc)) from None


def _log_span(index, entry) -> str:
    """Where a scenario lies in the bag's log time: what Foxglove's timeline seeks to."""
    from datetime import datetime, timezone

    start, end = round(entry.start_ns / 1e9, 3), round(entry.end_ns / 1e9, 3)
    utc = datetime.fromtimestamp(start, timezone.utc).isoformat(sep=" ", timespec="milliseconds")[:-6]
    return (f"log time {start:.3f} .. {end:.3f} s ({utc} UTC; "
            f"+{(entry.start_ns - index.bag_start_ns) / 1e9:.2f} .. +{(entry.end_ns - index.bag_start_ns) / 1e9:.2f} s "
            "into the bag)")


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

    p = sub.add_parser("show", help="picture of a scenario, or of a run directory (convergence + best scenarios), "
                       "or an animation of one robot scenario of a robot bag (RUN.mcap)")
    p.add_argument("target", metavar="SCENARIO.json|RUN_DIR|RUN.mcap",
                   help="a robot bag (an MCAP with /odom, e.g. from `ambiegen campaign --stack nd`): without "
                   "--scenario its scenarios are listed, one line each with the verdict and log time, and the "
                   "exit status is 2 (nothing drawn)")
    p.add_argument("-o", "--output", metavar="FILE.png|FILE.gif",
                   help="output picture (run dirs: a file prefix); a bag: .gif, or .mp4 where ffmpeg is installed "
                   "(default RUN_scenario_ID.gif); an existing file is refused")
    p.add_argument("--execute", action="store_true", help="run the scenario on its full-model simulator and draw the trajectory")
    p.add_argument("--seed", type=int, default=0, help="simulator seed for --execute (default 0)")
    p.add_argument("--set", action="append", default=[], metavar="OPTION=VALUE",
                   help="--execute: simulator option, as for `ambiegen execute` (repeatable)")
    p.add_argument("--run", metavar="RUN", help="a bag with several runs (a bench/nav2_maps.py batch logs a run "
                   "per map): the run whose scenarios are listed or animated (default: the one run that has "
                   "--scenario ID, else the first)")
    p.add_argument("--scenario", type=int, metavar="ID", help="a bag: the scenario id to animate (the map, the "
                   "robot's footprint, /scan, /plan, the trajectory so far, and the verdict with the failure point)")
    p.add_argument("--fps", type=float, help="a bag: frames per second of the animation; one frame per "
                   "speed/fps simulated seconds (default 10; at most 300 frames: a longer run is played faster)")
    p.add_argument("--speed", type=float, help="a bag: playback factor of simulated time (default 1)")
    p.add_argument("--overwrite", action="store_true", help="a bag: replace an existing -o file")
    add_config_option(p)
    add_profile_option(p)
    p.set_defaults(func=cmd_show)
