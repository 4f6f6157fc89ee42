"""`ambiegen rerun` and `ambiegen compare`: a suite N times on a stack, on one or more params files;
`ambiegen stack-search`: a search whose every scenario runs on a supervised stack.

The work is ``ambiegen_ros.trials``; this module turns flags into its calls and prints its tables.
"""
from __future__ import annotations

import argparse
import importlib.util
import json
import os
import shutil
import sys
from pathlib import Path
from typing import Any, Callable

from .common import BadInput, add_config_option

# a search's report draws this many failing scenarios of each kind (``report.failure_kind_of``): a
# planner search fails hundreds of times on one bug, and drawing each took minutes after the search
SEARCH_PICTURES_PER_KIND = 3
STACK_HELP = ("nd: our Nearness Diagram robot on Nav2's topics (no ROS needed); bringup: nav2_bringup's "
              "navigation_launch.py with the params; ours: the minimum Nav2 (controller, planner, behaviours, BT "
              "navigator) with the params; external: your Nav2, which you start when told; planner: Nav2's "
              "planner_server and smoother_server (and a lifecycle manager) alone, by ros2 run with the params on "
              "wall time, no world or controller: the adapter publishes each map and the static TF map -> odom -> "
              "base_link, asks compute_path_to_pose (compute_path_through_poses for a scenario with vias), and "
              "judges the path on the costmap it reads back "
              "(docs/planner_oracles.md; no --overlay unless given) (Nav2 stacks need a sourced ROS 2 Jazzy)")


def _common(p: argparse.ArgumentParser, many: bool, search: bool = False, shrink: bool = False) -> None:
    from ..core.names import ALGORITHMS, PROFILES
    from ..trials.configs import STACKS

    if search:
        p.add_argument("--algorithm", choices=ALGORITHMS, default="ga", help="the search (default ga; random: "
                       "random sampling of what the problem allows, the baseline)")
        p.add_argument("--hours", type=float, required=True, metavar="H", help="simulated hours of the stack to "
                       "spend: no scenario is sent after H x 3600 / --time-scale wall seconds (the one running "
                       "finishes)")
        p.add_argument("--mode", choices=("in_the_loop", "surrogate"), default="in_the_loop",
                       help="in_the_loop: the stack runs every scenario the search asks, and its verdicts steer the "
                            "search (default); surrogate: the search runs on the problem's surrogate first (e.g. the "
                            "threat score), then the stack runs its suite, best first")
        p.add_argument("--evaluations", type=int, metavar="N", help="scenarios the search asks at most (default: "
                       "in_the_loop 100000, the hours decide; surrogate: --config's budget)")
    else:
        p.add_argument("suite", nargs="+", metavar="SUITE", help="suite files (JSON: a search's suite.json, a "
                       "write-up's *_suite.json, one scenario), a campaign's MCAP (its certified failures) or a "
                       "results file (.jsonl of rerun, compare or stack-search: its failures, once each)")
    p.add_argument("--stack", required=True, choices=STACKS, help=STACK_HELP)
    p.add_argument("--params", action="append", default=[], metavar="[LABEL=]FILE[+FILE...]",
                   help=("a configuration: params files merged in order (the first is the stack's, e.g. Jazzy's "
                         "nav2_params.yaml; the others overlays; fix:NAME is the package's config/nav2/fixes/NAME.yaml)"
                         + ("; give two or more, the first is the baseline" if many else
                            "; one (our ND stack: optional)")))
    if not search and not shrink:
        p.add_argument("--repeat", type=int, default=3, metavar="N", help="runs of each scenario on each "
                       "configuration (default 3); runs already in --results count")
    p.add_argument("--results", required=True, metavar="FILE.jsonl", help="the results file: one row per run, "
                   "appended (never rewritten); the command resumes from it")
    p.add_argument("--bags", metavar="DIR", help="where each configuration's bag, node logs and merged params go, "
                   "one folder per run of the command (default: RESULTS's folder / <its name>_bags)")
    p.add_argument("--out", metavar="DIR", help="where the tables (markdown, JSON) and pictures (" +
                   ("of each scenario whose verdict changed" if many else "of each scenario that failed, a crash included")
                   + ") are written, under new names (default: RESULTS's folder / <its name>_reports)")
    add_config_option(p)
    p.add_argument("--profile", choices=PROFILES, help="fidelity profile of the scenarios' problem (default: the "
                   "suite's or --config's)")
    p.add_argument("--time-scale", type=float, default=1.0, help="Nav2 stacks: simulated seconds per wall second "
                   "(default 1: real time; Nav2's loop rates are scaled to it)")
    p.add_argument("--seed", type=int, default=0, help="the world's seed (laser noise)" + (" and the search's"
                   if search else "") + "; recorded (default 0)")
    p.add_argument("--fault-speed", type=float, metavar="M/S", help="a contact with a person is charged to the robot "
                   "only when it moves towards them faster than this (default: the world's, 0.01 m/s)")
    p.add_argument("--overlay", default="", metavar="FILE.yaml|none", help="Nav2 stacks: merged on the first params "
                   "file (default: the package's config/nav2/ambiegen_overlay.yaml, our world's frames and body)")
    p.add_argument("--robot", default="", metavar="NAME|FILE.yaml", help="the robot the world drives and the adapter "
                   "judges: a shipped profile (turtlebot4, turtlebot3_burger, omni_base, ackermann_car, pioneer2dx) or "
                   "a profile file (docs/robot_profiles.md); Nav2 stacks: its body and limits go into every "
                   "configuration's params, once their controller can drive it; recorded in every row (default: "
                   "Stage's Pioneer, as before)")
    p.add_argument("--known-failures", default="", metavar="FILE.yaml|none", help="Nav2 stacks: failures Nav2's "
                   "engineers know, recorded as known (default: the package's config/nav2/known_failures.yaml)")
    p.add_argument("--early-verdicts", action="store_true", help="Nav2 stacks: the paper's stall and loitering "
                   "monitors decide instead of Nav2's own result")
    p.add_argument("--domain-id", type=int, help="ROS_DOMAIN_ID of the stack and this command (default: inherited)")
    p.add_argument("--start-timeout", type=float, default=None, metavar="SECONDS", help="seconds the adapter waits "
                   "for the stack (default: 600 with --stack external, where you start it yourself; 120 otherwise); "
                   "a value given holds for every stack, external included")
    p.add_argument("--hang-after", type=float, default=30.0, metavar="SECONDS", help="a stack whose every sign of "
                   "life (/cmd_vel, navigate_to_pose feedback and status) is silent, or a node of it that is not "
                   "scheduled, for this long while a run is on has hung: FAIL(sut_crashed), and it is restarted (0: "
                   "not watched; default 30)")
    p.add_argument("--inject", action="append", default=[], metavar="TARGET:SIGNAL@RUN[+S][/HOLD]",
                   help="a fault on purpose, to see the runs survive it: e.g. nd_driver:SIGKILL@2 kills nd_driver when "
                        "this invocation's 2nd run has its robot moving (+S: S seconds later; /HOLD: SIGCONT a "
                        "SIGSTOP after HOLD s); TARGET: robot_world, sut_adapter, recorder, nd_driver, nav2 or a Nav2 "
                        "server's node name")
    p.add_argument("--our-transport", choices=("dds",), default=None, help="dds: run robot_world, the recorder "
                   "and the adapter on Cyclone DDS from PyPI, without rclpy's executor (less CPU: docs/speed.md), "
                   "beside a Nav2 on rmw_cyclonedds_cpp (default: the transport of this command)")
    if not search and not shrink:
        p.add_argument("--no-run", action="store_true", help="run nothing: the tables of what --results holds")


def register(sub) -> None:
    p = sub.add_parser("rerun", help="run a suite on a stack N times each: per scenario, passes and failures by kind "
                                     "(k of N), appended to a results file that resumes",
                       description="Does a failure reproduce? Each scenario of the suite runs --repeat times on the "
                                   "stack with one params configuration; the table gives, per scenario, its passes "
                                   "(near misses) and failures by kind, k of N.")
    _common(p, many=False)
    p.set_defaults(func=cmd_trials, many=False)
    p = sub.add_parser("compare", help="run a suite on two or more params files (and behaviour trees), N times each: "
                                       "what each fixes, keeps and breaks against the first, Fisher's test, the cost, "
                                       "pictures of what changed",
                       description="Is it my configuration, and does the usual fix fix it? Every scenario runs "
                                   "--repeat times on each configuration; the tables give k of N per scenario and "
                                   "configuration with Fisher's exact test against the first (the baseline), the "
                                   "failures each one fixes, keeps and breaks, and its cost on the scenarios the "
                                   "baseline passes (time to goal, recoveries: median, 90th percentile); a picture "
                                   "of the runs side by side for every scenario whose verdict changed.")
    _common(p, many=True)
    p.set_defaults(func=cmd_trials, many=True)
    p = sub.add_parser("stack-search", help="search a stack for failures as a campaign does, with the stack supervised: a "
                                      "crash is a finding, a part of ours that dies is run again, the night goes on",
                       description="AmbieGen's search (--config: its settings and problem) in the loop with a stack: "
                                   "each scenario it asks runs as `rerun` runs one, with the stack watched and "
                                   "restarted (a process of the stack that dies or hangs: FAIL(sut_crashed), run once "
                                   "more on a fresh stack; one of ours: an error record, and the scenario again). "
                                   "Every run is a row of --results; at the end the table and a picture of each "
                                   "failed scenario. A stopped search does not resume: run it again with a new "
                                   "--results.")
    _common(p, many=False, search=True)
    p.set_defaults(func=cmd_search, many=False)
    p = sub.add_parser("shrink", help="shrink a failing scenario on a stack to the fewest walls and cells that keep its "
                                      "failure, as a fuzzer minimises an input: every try a real run",
                       description="Delta debugging (ddmin) on a supervised stack (ambiegen_ros/trials/shrink.py): the "
                                   "scenario runs first, and its failure (the kind and, on the planner stack, the "
                                   "oracle) is the one to keep; then whole walls and border sides are taken away, "
                                   "then single cells, while a run still fails the same way. The genome stays; the "
                                   "cells taken away are listed in the scenario's metadata (cleared_cells). Writes "
                                   "the minimal scenario as a suite for `rerun` and `planner-report`.")
    _common(p, many=False, shrink=True)
    p.add_argument("--scenario", metavar="NAME", help="the scenario to shrink, by its name in the suite (needed when "
                   "the suite holds more than one)")
    p.add_argument("--tries", type=int, default=1, metavar="K", help="runs of each try at most: a try keeps the "
                   "failure when one of them fails the same way (default 1; a failure that comes and goes, as a "
                   "crash of undefined behaviour does, needs 3 or more)")
    p.add_argument("--minimal", metavar="FILE.json", help="where the minimal scenario goes, as a suite (default: "
                   "RESULTS's folder / <its name>_minimal_suite.json; never replaced)")
    p.set_defaults(func=cmd_shrink, many=False)
    p = sub.add_parser("planner-report", help="write a planner finding as Nav2's maintainers ask for one: map (yaml + "
                                              "pgm), params, start and goal, a script for a stock Jazzy, reruns",
                       description="From the rows of `ambiegen rerun --stack planner --repeat N`, one scenario's "
                                   "finding as a page with its files (ambiegen_ros/trials/planner_findings.py): "
                                   "the map as map_server loads it, at the costmap's resolution, the params, the "
                                   "start and goal, a nav2_simple_commander script that asks planner_server alone "
                                   "and checks the path on Nav2's own costmap, the picture and k of N reruns.")
    p.add_argument("results", help="the rerun's results file (JSON lines)")
    p.add_argument("--scenario", required=True, help="the scenario's name in the rows")
    p.add_argument("--params", required=True, help="the params file the rows ran with")
    add_config_option(p)
    p.add_argument("--label", required=True, choices=("new", "fixed_on_main", "known"),
                   help="new | fixed_on_main (still in Jazzy: a backport request) | known")
    p.add_argument("--references", default="", help="the tracker's issues or PRs, e.g. '#5863, fixed by #5908'")
    p.add_argument("--explain", default="", help="a paragraph: why it is a bug, and whose")
    p.add_argument("--picture", default="", help="the rerun's picture of the scenario (PNG)")
    p.add_argument("-o", "--out", required=True, help="the folder of the page and its files")
    p.set_defaults(func=cmd_planner_report)


def _settings(args, results: Path):
    from ..nav2_params import package_file
    from ..trials.configs import NAV2_STACKS
    from ..trials.faults import parse_fault
    from ..trials.runner import TrialSettings

    nav2 = args.stack in NAV2_STACKS
    known = None
    if nav2 and args.known_failures.lower() != "none":
        known = args.known_failures or package_file("config", "nav2", "known_failures.yaml")
        if known and not Path(known).is_file():
            raise BadInput(f"--known-failures {known}: no such file")
    rmw = os.environ.get("RMW_IMPLEMENTATION", "")
    if nav2 and args.our_transport == "dds" and rmw != "rmw_cyclonedds_cpp":
        raise BadInput(f"--our-transport dds speaks rmw_cyclonedds_cpp's services to Nav2, which would run on "
                       f"{rmw or 'the default RMW (Fast DDS)'}: export RMW_IMPLEMENTATION=rmw_cyclonedds_cpp")
    if args.start_timeout is not None and not args.start_timeout > 0:
        raise BadInput("--start-timeout: must be > 0")
    bags = Path(args.bags) if args.bags else results.parent / f"{results.stem}_bags"
    robot = _robot(args.robot)
    return TrialSettings(robot=robot, stack=args.stack, results=results, bags=bags, repeat=getattr(args, "repeat", 1),
                         time_scale=args.time_scale,
                         seed=args.seed, domain_id=args.domain_id, known_failures=str(known) if known else None,
                         fault_speed=args.fault_speed, early_verdicts=args.early_verdicts,
                         start_timeout=args.start_timeout, hang_after=args.hang_after,
                         faults=[parse_fault(spec) for spec in args.inject], our_transport=args.our_transport)


def _robot(robot: str) -> str:
    """``--robot`` as the world and the adapter take it (``launch_logic.node_robot``, as the Nav2
    campaign launch resolves it), checked before anything starts; '' stays '' (the Pioneer)."""
    from ..launch_logic import node_robot

    if not robot:
        return ""
    try:
        return node_robot(robot)[0]
    except ValueError as exc:
        raise BadInput(f"--robot {robot}: {exc}") from None


def _overlay(args) -> str | None:
    from ..nav2_params import OVERLAY_FILE, package_file

    if args.overlay.lower() == "none" or (args.stack == "planner" and not args.overlay):
        return None  # the planner stack runs Jazzy's (the user's) footprint and frames, not our world's
    overlay = args.overlay or package_file(*OVERLAY_FILE)
    if not overlay or not Path(overlay).is_file():
        raise BadInput(f"--overlay {args.overlay or '/'.join(OVERLAY_FILE)}: no such file")
    return str(overlay)


def _guarded(command: str, results: Path, resumes: str, work: Callable[[], Any]) -> tuple[Any, int]:
    """(what ``work`` returned, 0); a stack that stopped is (None, 1) and an interrupt (None, 130),
    each said in one line: the runs made so far are in ``results`` either way."""
    from ..trials.runner import StackStopped

    try:
        return work(), 0
    except StackStopped as exc:
        print(f"ambiegen {command}: stopped: {exc}", file=sys.stderr)
        return None, 1
    except KeyboardInterrupt:
        print(f"ambiegen {command}: interrupted; the runs made are in {results}{resumes}", file=sys.stderr)
        return None, 130


def _need_ros(stack: str) -> None:
    if importlib.util.find_spec("rclpy") is None:
        raise BadInput(f"--stack {stack}: a Nav2 stack needs ROS 2 (rclpy): source /opt/ros/jazzy/setup.bash and "
                       "this package's install/setup.bash first (--stack nd runs without ROS)")
    if stack != "external" and shutil.which("ros2") is None:
        raise BadInput(f"--stack {stack}: no `ros2` on PATH (source /opt/ros/jazzy/setup.bash)")


def cmd_trials(args) -> int:
    from ..trials import report
    from ..trials.configs import NAV2_STACKS, StackConfig, parse_config, prepare
    from ..trials.runner import run_trials, utc_stamp
    from ..trials.suite import load_suite

    if args.repeat < 1:
        raise BadInput("--repeat: at least 1")
    if not args.time_scale > 0:
        raise BadInput("--time-scale: must be > 0")
    if args.fault_speed is not None and args.fault_speed < 0:
        raise BadInput("--fault-speed: must be >= 0")
    configs = [parse_config(spec) for spec in args.params]
    if args.many and len(configs) < 2:
        raise BadInput("compare: give two or more --params (the first is the baseline)")
    if not args.many and len(configs) > 1:
        raise BadInput("rerun: one --params (compare runs several)")
    if not configs:
        if args.stack in NAV2_STACKS:
            raise BadInput(f"--stack {args.stack}: name your Nav2 params with --params (e.g. Jazzy's "
                           "/opt/ros/jazzy/share/nav2_bringup/params/nav2_params.yaml)")
        configs = [StackConfig("nd", ())]
    labels = [c.label for c in configs]
    if len(set(labels)) < len(labels):
        raise BadInput(f"--params: two configurations are called {sorted(l for l in labels if labels.count(l) > 1)[0]!r}"
                       " (give each a LABEL=)")
    results = Path(args.results)
    suite = load_suite(args.suite, args.config, args.profile)
    if suite.problem != "robot":
        raise BadInput(f"a stack runs robot scenarios; the suite's are {suite.problem}")
    print(f"suite: {len(suite.entries)} scenarios from {', '.join(args.suite)}"
          + (f" ({suite.duplicates} given twice, run once)" if suite.duplicates else ""))
    settings = _settings(args, results)
    code = 0
    if not args.no_run:
        if args.stack in NAV2_STACKS:
            _need_ros(args.stack)
        overlay = _overlay(args) if args.stack in NAV2_STACKS else None
        settings.bags.mkdir(parents=True, exist_ok=True)
        prepared = [prepare(c, args.stack, overlay, args.time_scale, settings.bags, settings.robot) for c in configs]
        _, code = _guarded(args.command, results, " (the same command resumes)",
                           lambda: run_trials(suite, prepared, settings))
    md, _ = report.report(suite, results, labels)
    print("\n".join(md))
    out = args.out or str(results.parent / f"{results.stem}_reports")
    if results.exists():
        written = report.write(suite, results, labels, out, utc_stamp(), "compare" if args.many else "rerun")
        print(f"written: {written['md']}, {written['json']}")
        for picture in written.get("pictures", []):
            print(f"picture: {picture}")
    return code


def cmd_search(args) -> int:
    from ..core.config import load_config_file
    from ..core.runs import run_config
    from ..core.search import Search
    from ..run_config import make_run
    from ..trials import report
    from ..trials.configs import NAV2_STACKS, StackConfig, parse_config, prepare
    from ..trials.rows import TrialLog
    from ..trials.runner import utc_stamp
    from ..trials.search import run_search
    from ..trials.suite import Entry, Suite

    if not args.hours > 0:
        raise BadInput("--hours: must be > 0")
    if not args.time_scale > 0:
        raise BadInput("--time-scale: must be > 0")
    if len(args.params) > 1:
        raise BadInput("stack-search: one --params (compare runs several configurations on a suite)")
    if not args.params and args.stack in NAV2_STACKS:
        raise BadInput(f"--stack {args.stack}: name your Nav2 params with --params (e.g. Jazzy's "
                       "/opt/ros/jazzy/share/nav2_bringup/params/nav2_params.yaml)")
    config = parse_config(args.params[0]) if args.params else StackConfig("nd", ())
    results = Path(args.results)
    record = results.with_name(results.stem + ".search.json")
    for path in (results, record):
        if path.exists():
            raise BadInput(f"{path} exists: a search starts files of its own (never appended to or replaced)")
    loop = args.mode == "in_the_loop"
    evaluations = args.evaluations or (100_000 if loop else None)
    problem, search_settings = make_run("robot", args.config, profile=args.profile, algorithm=args.algorithm,
                                        evaluations=evaluations, seed=args.seed)
    problem_config = dict(load_config_file(args.config).get("problem_config") or {}) if args.config else {}
    if args.profile:
        problem_config["profile"] = args.profile
    suite = Suite("robot", problem_config, [], [f"search:{args.algorithm}:{args.mode}:seed{args.seed}"])
    settings = _settings(args, results)
    settings.budget_s = args.hours * 3600.0 / args.time_scale
    if args.stack in NAV2_STACKS:
        _need_ros(args.stack)
    settings.bags.mkdir(parents=True, exist_ok=True)
    prepared = prepare(config, args.stack, _overlay(args) if args.stack in NAV2_STACKS else None, args.time_scale,
                       settings.bags, settings.robot)
    record.parent.mkdir(parents=True, exist_ok=True)
    record.write_text(json.dumps(run_config(problem, search_settings, {"mode": args.mode, "stack": args.stack,
                                                                      "params": prepared.record(), "hours": args.hours,
                                                                      "time_scale": args.time_scale,
                                                                      **({"robot": settings.robot} if settings.robot
                                                                         else {})}),
                                 indent=1, default=str) + "\n")
    print(f"search: {args.algorithm} ({args.mode}), seed {args.seed}, {args.hours:g} h of the stack at time scale "
          f"{args.time_scale:g}; rows to {results}, its settings to {record}")
    _, code = _guarded("stack-search", results, "", lambda: run_search(
        problem, Search(problem, search_settings, valid_samples=True), suite, prepared, settings, in_the_loop=loop))
    if not results.exists():
        return code or 1
    ran = {row["key"]: row for row in TrialLog(results).rows()}
    suite.entries = [Entry(name=row.get("scenario_name") or key, scenario=row["scenario"], key=key)
                     for key, row in ran.items()]
    md, _ = report.report(suite, results, [config.label])
    print("\n".join(md))
    written = report.write(suite, results, [config.label], args.out or str(results.parent / f"{results.stem}_reports"),
                           utc_stamp(), "rerun", pictures_per_kind=SEARCH_PICTURES_PER_KIND)
    print(f"written: {written['md']}, {written['json']}")
    for picture in written.get("pictures", []):
        print(f"picture: {picture}")
    if written.get("pictures_left_out"):
        print(f"pictures: the first {SEARCH_PICTURES_PER_KIND} failing scenarios of each kind; "
              f"{written['pictures_left_out']} more left out (each is a row of the report's table)")
    return code


def cmd_shrink(args) -> int:
    from ..trials import report
    from ..trials.configs import NAV2_STACKS, StackConfig, parse_config, prepare
    from ..trials.runner import utc_stamp
    from ..trials.shrink import run_shrink
    from ..trials.suite import Entry, Suite, load_suite, problem_of, scenario_key

    if args.tries < 1:
        raise BadInput("--tries: at least 1")
    if len(args.params) > 1:
        raise BadInput("shrink: one --params")
    if not args.params and args.stack in NAV2_STACKS:
        raise BadInput(f"--stack {args.stack}: name your Nav2 params with --params")
    results = Path(args.results)
    minimal_file = Path(args.minimal) if args.minimal else results.parent / f"{results.stem}_minimal_suite.json"
    for path in (results, minimal_file):
        if path.exists():
            raise BadInput(f"{path} exists: a shrink starts files of its own (never appended to or replaced)")
    suite = load_suite(args.suite, args.config, args.profile)
    if suite.problem != "robot":
        raise BadInput(f"a shrink takes robot scenarios (walls to take away); the suite's are {suite.problem}")
    chosen = [e for e in suite.entries if args.scenario is None or e.name == args.scenario]
    if len(chosen) != 1:
        names = ", ".join(e.name for e in suite.entries[:8]) + (" ..." if len(suite.entries) > 8 else "")
        which = f"no scenario called {args.scenario!r} in" if args.scenario else "name one of"
        raise BadInput(f"--scenario: {which} the suite's {len(suite.entries)} ({names})")
    entry = chosen[0]
    config = parse_config(args.params[0]) if args.params else StackConfig("nd", ())
    settings = _settings(args, results)
    settings.repeat = args.tries
    if args.stack in NAV2_STACKS:
        _need_ros(args.stack)
    settings.bags.mkdir(parents=True, exist_ok=True)
    prepared = prepare(config, args.stack, _overlay(args) if args.stack in NAV2_STACKS else None, args.time_scale,
                       settings.bags, settings.robot)
    print(f"shrink: {entry.name} on {args.stack}, up to {args.tries} run(s) a try; rows to {results}")
    feed, code = _guarded("shrink", results, "", lambda: run_shrink(problem_of(suite), entry, suite, prepared,
                                                                      settings, args.tries))
    if feed is None or feed.minimal is None or feed.step != "done":
        return code or 1
    minimal_file.parent.mkdir(parents=True, exist_ok=True)
    name = f"{entry.name}_minimal"
    minimal_file.write_text(json.dumps({"problem": "robot", "problem_config": suite.problem_config,
                                        "suite": [{"name": name, "scenario": feed.minimal,
                                                   "note": "; ".join(feed.history)}]}, indent=1) + "\n")
    print(f"written: {minimal_file} ({feed.count} tries)")
    shown = Suite("robot", suite.problem_config,
                  [entry, Entry(name=name, scenario=feed.minimal, key=scenario_key(feed.minimal, suite.problem_config))],
                  suite.sources)
    written = report.write(shown, results, [config.label], args.out or str(results.parent / f"{results.stem}_reports"),
                           utc_stamp(), "rerun")
    for picture in written.get("pictures", []):
        print(f"picture: {picture}")
    return code


def cmd_planner_report(args) -> int:
    import yaml

    from sim_nodes.adapter.robot_planner import parse_rules, planner_rules

    from ..core.config import ConfigError
    from ..launch_logic import planner_under_test
    from ..run_config import make_run
    from ..trials.planner_findings import write_finding
    from ..trials.rows import TrialLog
    from ..trials.runner import TrialSettings
    from ..trials.session import planner_upsample

    params = Path(args.params)
    try:
        loaded = yaml.safe_load(params.read_text()) or {}
    except (OSError, yaml.YAMLError) as exc:
        raise BadInput(f"--params {params}: {exc}") from None
    if not args.config:
        raise BadInput("--config: the run config the rows ran with (e.g. config/robot_planner.yaml)")
    problem = make_run("robot", args.config, seed=0)[0]
    try:  # the planner's rules: a kinematic planner's script also reports the tightest turn
        _, key, overrides = planner_under_test(loaded)
        min_radius = planner_rules(key, parse_rules(overrides)).min_turning_radius
    except (ValueError, ConfigError) as exc:
        raise BadInput(f"--params {params}: {exc}") from None
    # without a costmap resolution in the params, the runs' own default (TrialSettings), not a copy of it
    upsample = planner_upsample(loaded, TrialSettings, problem.config.resolution)
    try:
        page = write_finding(TrialLog(Path(args.results)).rows(), args.scenario, problem, params, upsample,
                             Path(args.out), args.label, args.references or "no reference yet", args.explain,
                             Path(args.picture) if args.picture else None, min_turning_radius=min_radius,
                             config=args.config)
    except ValueError as exc:
        raise BadInput(str(exc)) from None
    print(f"written: {page}")
    return 0
