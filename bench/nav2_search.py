"""A search against random sampling on Nav2 (issue 29): campaigns given the same Nav2 time, counted
in distinct new certified failures.

    python bench/nav2_search.py --setup ~/jazzy-verify/install/setup.bash --algorithm random --seed 1 --nav2-hours 1
    python bench/nav2_search.py --setup ... --algorithm ga --mode in_the_loop --config config/robot_small_loop.yaml --seed 1
    python bench/nav2_search.py --report

Each run is one ``nav2_campaign.launch.py`` campaign on the maps of ``config/robot_small.yaml``
(goal (14, 14); ``route_cap`` 100 keeps a search off NavFn's known cap) with Nav2's own verdicts:
``--controller dwb`` = our five Nav2 nodes with ``config/nav2/pioneer_navfn_dwb.yaml`` at time scale
2, ``mppi`` = Jazzy's ``nav2_params.yaml`` + the overlay through ``navigation_launch.py`` at real
time (the largest time scales that keep real time's verdicts on this 2-core machine), ``hardened`` =
``mppi`` with ``fix:hardened`` (issue 59: the map's walls in the local costmap, the patient tree);
``ackermann`` = ``mppi`` with Nav2's Ackermann set-up (``config/nav2/robots/ackermann_car.yaml``, for
``--robot ackermann_car``); ``--robot`` drives another robot profile than Stage's Pioneer (issue 69). The campaign
stops sending maps after ``--nav2-hours`` of simulated time (its ``execution_budget`` in wall
seconds, at the time scale); the map in flight then finishes. From its bag: Nav2 runs, their simulated time, failures, known failures (not counted), the
distinct new certified failures (the campaign gallery's count: every failure has a clearance route,
known limits excluded), the early verdicts, counted separately, and the near misses (passes that
needed Nav2's recoveries, from its action feedback). One JSON row per run is appended
to ``bench/results/nav2_search.jsonl``, never rewritten. ``--report`` prints, per controller, each
algorithm's runs (their distinct failures per Nav2 hour; runs whose hour of sending held less than
a Nav2 hour are counted: pass ``--nav2-hours 1.1`` for a full one) and, from 3 runs a side (the issue's minimum), a one-sided Mann-Whitney U test of
its distinct failures against random's, exact with ties; below 10 runs a side (our rule for a claim
about a distribution) it is marked as a hint.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from collections import Counter
from datetime import datetime, timezone
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
for extra in (REPO, REPO / "test", REPO / "test" / "real_ros"):
    sys.path.insert(0, str(extra))

from _common import append_row, nav2_loop_misses, read_rows  # noqa: E402

OUT = REPO / "bench" / "results" / "nav2_search.jsonl"
DEFAULT_CONFIG = "config/robot_small.yaml"
MIN_RUNS = 3  # runs a side before a test is printed (issue 29's minimum)
PIONEER = "pioneer2dx"  # the robot of every row from before profiles (robot_profile '')
CLAIM_RUNS = 10  # runs a side before it is a claim: "beats random" is about a distribution
JAZZY_PARAMS = "{jazzy}/share/nav2_bringup/params/nav2_params.yaml"
CONTROLLERS = {  # controller: (launch arguments, time scale)
    "dwb": ({"nav2": "ours"}, 2.0),
    "mppi": ({"nav2": "bringup", "params_file": JAZZY_PARAMS}, 1.0),
    # Jazzy's MPPI stack with fix:hardened (issue 59), merged as `ambiegen compare` merges it
    "hardened": ({"nav2": "bringup", "params_file": JAZZY_PARAMS + "+fix:hardened"}, 1.0),
    # Jazzy's stack with Nav2's documented Ackermann set-up (issue 69), for --robot ackermann_car
    "ackermann": ({"nav2": "bringup", "params_file": JAZZY_PARAMS + "+" + str(REPO / "config/nav2/robots/ackermann_car.yaml")},
                  1.0),
}


def hardened_params(spec: str, jazzy: Path, out_dir: Path) -> dict:
    """``FILE+fix:...`` made into one params file (our overlay, the fixes, the derived tree from the
    installed nav2_bt_navigator) for the launch, which then merges nothing more."""
    from ambiegen_ros.nav2_params import OVERLAY_FILE, package_file
    from ambiegen_ros.trials.configs import parse_config, prepare

    os.environ.setdefault("AMENT_PREFIX_PATH", str(jazzy))  # where the tree to derive from is installed
    ready = prepare(parse_config(spec), "bringup", str(package_file(*OVERLAY_FILE)), 1.0, out_dir)
    return {"params_file": str(ready.path), "params_overlay": "none"}


def run_one(args, install: Path, logs: Path) -> dict:
    import jazzy_env as je

    extra, k = CONTROLLERS[args.controller]
    extra = {key: value.format(jazzy=Path(args.setup).parent) for key, value in extra.items()}
    out_dir = Path(tempfile.mkdtemp(prefix=f"{args.controller}_{args.algorithm}_s{args.seed}_", dir=logs))
    if "+" in extra.get("params_file", ""):  # the fixes or set-up merged as `ambiegen compare` merges them
        extra.update(hardened_params(extra["params_file"], Path(args.setup).parent, out_dir))
    budget = args.nav2_hours * 3600.0 / k
    launch = "ros2 launch ambiegen_ros nav2_campaign.launch.py " + " ".join(f"{key}:={value}" for key, value in dict(
        algorithm=args.algorithm, mode=args.mode, seed=args.seed, execution_budget=budget,
        evaluations=100000 if args.mode == "in_the_loop" else args.evaluations,
        output_dir=out_dir, time_scale=k, config_file=REPO / args.config, profile="refined",
        **({"robot_profile": args.robot} if args.robot else {}), **extra).items())
    graph = je.Graph(out_dir)
    t0 = time.monotonic()
    graph.ros("launch", launch, install, je.ros_env(args.domain_id))
    try:
        code = graph.procs["launch"].wait(budget + args.grace)
    except subprocess.TimeoutExpired:  # a hung stack, or maps offered to anyone: stop it, keep what ran
        print(f"campaign still running {budget + args.grace:.0f} s in: stopped (SIGINT), measured as it stands",
              file=sys.stderr, flush=True)
        graph.stop("launch", timeout=120.0)
        code = "timeout"
    finally:
        graph.cleanup()
    (mcap,) = out_dir.glob("*.mcap")
    return measure(args, mcap, code, time.monotonic() - t0)


def measure(args, mcap: Path, code, wall: float | None) -> dict:
    """The row of one campaign, from its bag: what ``--measure`` redoes for a bag already recorded."""
    from ambiegen_ros.core.runs import versions
    from ambiegen_ros.nodes.gallery import draw_failures
    from ambiegen_ros.nodes.replay import recorded_scenarios
    from ambiegen_ros.sims.outcome import NAV2_RECOVERIES, near_miss
    from ambiegen_ros.ros.runlog import summarize

    rec = recorded_scenarios(mcap)
    driven = [o for o in rec.outcomes.values() if o.failure_kind not in ("invalid_scenario", "invalid_test")]
    gallery = draw_failures(mcap, mcap.parent / "failures")
    early = Counter(str(o.metrics.get("early_verdict")) for o in driven)
    return {
        "controller": args.controller, "algorithm": args.algorithm, "mode": args.mode, "config": args.config,
        "seed": args.seed, "robot": args.robot or PIONEER,
        "time_scale": CONTROLLERS[args.controller][1], "exit": code, "wall_s": None if wall is None else round(wall, 1), "maps": len(rec.outcomes), "nav2_runs": len(driven),
        "nav2_hours": round(sum(float(o.metrics.get("time") or 0.0) for o in driven) / 3600.0, 3),
        "failures": sum(o.failed for o in driven), "known_failures": gallery["known_failures"],
        "distinct_new_failures": gallery["distinct_failures"],
        "kinds": dict(Counter(o.failure_kind for o in driven if o.failed)),
        "early_verdicts": dict(early),
        # passes that needed Nav2's recovery branch (nav2_recoveries, from the action's feedback)
        "near_misses": sum(near_miss(o.failure_kind, o.metrics.get(NAV2_RECOVERIES)) for o in driven),
        "recoveries": sum(int(o.metrics.get(NAV2_RECOVERIES) or 0) for o in driven),
        # each failure, to be read: id, kind, known entry, Nav2's error code (readings name them by id)
        "failure_list": [{"id": sid, "kind": o.failure_kind, "known": o.metrics.get("known_failure"),
                          "nav2_error_code": o.metrics.get("nav2_error_code")}
                         for sid, o in sorted(rec.outcomes.items()) if o.failed],
        "not_the_stacks": dict(Counter(o.failure_kind for o in driven if o.failure_kind in ("error", "sim_timeout"))),
        # the load the stack ran under: its controller's missed 20 Hz loops (the campaign's launch log)
        "controller_loop_misses": nav2_loop_misses(mcap.parent / "launch.log"),
        # the campaign drew them when it ended; drawing again draws nothing over them
        "pictures": sorted(str(p) for p in (mcap.parent / "failures").glob("failure_*.png")),
        "unresolved": summarize(mcap)["unresolved"], "mcap": str(mcap),
        "when": datetime.now(timezone.utc).isoformat(timespec="seconds"), "versions": versions(),
    }


def scenario_space(config: str) -> str:
    """What a run's scenarios are drawn from: ``hazards`` (issue 48's scenarios) or the paper's
    ``walls``; a search is compared with random runs of its own space."""
    import yaml

    path = REPO / config.split("@")[0].strip()  # a row may name the file at a commit: "FILE@abc (note)"
    data = (yaml.safe_load(path.read_text()) or {}) if path.is_file() else {}
    return str((data.get("problem_config") or {}).get("scenario", "walls"))


def report(path: Path | None = None) -> int:
    from ambiegen_ros.core.stats import greater_exact

    rows = read_rows(path or OUT)
    def side(r: dict) -> tuple[str, str, str]:
        return r["controller"], r.get("robot", PIONEER), scenario_space(r.get("config", DEFAULT_CONFIG))

    for controller, robot, space in sorted({side(r) for r in rows}):
        mine = [r for r in rows if side(r) == (controller, robot, space)]
        print(f"## {controller}, {robot}, {space} scenarios")
        by = {}
        for r in mine:
            by.setdefault((r["algorithm"], f'{r["mode"]}, {r.get("config", DEFAULT_CONFIG)}'), []).append(r)
        for (algorithm, mode), runs in sorted(by.items()):
            d = [r["distinct_new_failures"] for r in runs]
            hours = [r["nav2_hours"] for r in runs]
            # the budget is wall seconds of sending: invalid tests and start-ups leave a run short of it
            short = sum(h < 1.0 for h in hours)
            print(f"{algorithm} ({mode}): {len(runs)} runs, Nav2 hours {hours}, "
                  f"distinct new failures {d} (per Nav2 hour {[round(n / h, 1) if h else None for n, h in zip(d, hours)]}), "
                  f"known {[r['known_failures'] for r in runs]}, near misses "
                  f"{[r.get('near_misses', '-') for r in runs]} (- : a run from before they were recorded)"
                  + (f"; {short} under one Nav2 hour (next time: --nav2-hours 1.1)" if short else ""))
        for measure in ("distinct_new_failures", "near_misses"):
            base = [r.get(measure) for (a, _), runs in by.items() if a == "random" for r in runs]
            for (algorithm, mode), runs in sorted(by.items()):
                d = [r.get(measure) for r in runs]
                if algorithm == "random" or None in d + base or min(len(d), len(base)) < MIN_RUNS:
                    continue
                u, p = greater_exact(d, base)
                hint = "" if min(len(d), len(base)) >= CLAIM_RUNS else f" (a hint: under {CLAIM_RUNS} runs a side)"
                print(f"{algorithm} ({mode}) > random in {measure.replace('_', ' ')}, {len(d)} against {len(base)} "
                      f"runs: one-sided Mann-Whitney U = {u:g}, exact p = {p:.3f}{hint}")
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--setup", default=os.path.expanduser("~/jazzy-verify/install/setup.bash"))
    ap.add_argument("--controller", choices=sorted(CONTROLLERS), default="dwb")
    ap.add_argument("--algorithm", choices=("random", "ga", "nsga2"), default="random")
    ap.add_argument("--mode", choices=("surrogate", "in_the_loop"), default="in_the_loop")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--config", default=DEFAULT_CONFIG,
                    help="run config under the repository (config/robot_small_narrow.yaml: the search aimed at the stack; "
                         "robot_small_narrow_restarts.yaml: the same as 16 restarts; robot_small_loop.yaml: GA in the loop, "
                         "scored by each Nav2 run's pace, seconds per metre of its clearance route)")
    ap.add_argument("--evaluations", type=int, default=0,
                    help="surrogate mode: the search's surrogate evaluations (0 = the config's); Nav2 then runs its suite")
    ap.add_argument("--robot", default="",
                    help="the robot profile the world drives and the adapter judges, its body and limits written "
                         "into the params (issue 69: turtlebot4, ackermann_car, a file; '' = Stage's pioneer2dx)")
    ap.add_argument("--nav2-hours", type=float, default=1.0, help="simulated hours of Nav2 per run")
    ap.add_argument("--grace", type=float, default=1800.0,
                    help="wall seconds past the budget for the map in flight (one per stack) to finish; "
                         "then the campaign is stopped and measured as it stands")
    ap.add_argument("--domain-id", type=int, default=9, help="outside the test suite's pool (10-101)")
    ap.add_argument("--report", action="store_true")
    ap.add_argument("--results", type=Path, default=None, help=f"the JSON-lines file rows go to (default {OUT.name}; "
                                                            "another for a trial run)")
    ap.add_argument("--logs", type=Path, default=None,
                    help="a directory for the campaign's bag, pictures and logs (a new one under it per run; "
                         "default: a new temporary directory, which the machine may clear, taking the bag with it)")
    ap.add_argument("--measure", type=Path, metavar="MCAP",
                    help="append the row of a campaign already recorded (e.g. one this bench stopped waiting for), "
                         "from its bag, with the controller, algorithm, mode, config and seed given here")
    args = ap.parse_args(argv)
    if args.report:
        return report(args.results)
    if args.measure:
        if not args.measure.is_file():
            raise SystemExit(f"{args.measure}: no such bag")
        return append(measure(args, args.measure, code=None, wall=None), args.results)
    import jazzy_env as je

    os.environ[je.SETUP_VAR] = args.setup
    info = je.probe()
    if "skip" in info:
        raise SystemExit(info["skip"])
    if args.logs:
        args.logs.mkdir(parents=True, exist_ok=True)
    logs = Path(tempfile.mkdtemp(prefix="nav2_search_", dir=args.logs))
    print(f"campaign logs, bag and pictures: {logs}", flush=True)
    return append(run_one(args, je.working_tree_install(logs / "ws"), logs), args.results)


def append(row: dict, path: Path | None = None) -> int:
    append_row(path or OUT, row)
    print(json.dumps({key: row[key] for key in ("controller", "robot", "algorithm", "mode", "seed", "exit", "wall_s", "nav2_runs",
                                                "nav2_hours", "failures", "known_failures", "distinct_new_failures",
                                                "kinds", "early_verdicts", "near_misses")}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
