"""A chaos hour: an unattended batch on a real Nav2 with a fault every few minutes (issue 57).

    python bench/nav2_chaos.py docs/results/nav2/mppi_hazards_passes_suite.json \\
        --params jazzy=/opt/ros/jazzy/share/nav2_bringup/params/nav2_params.yaml --hours 1 --seed 1 \\
        --results /tmp/chaos.jsonl --bags /tmp/chaos_bags

Runs the suite again and again (``ambiegen rerun``'s runner, Nav2 through ``navigation_launch.py``,
real time) for ``--hours`` of sending, with faults drawn at random (seeded): each run has a fault
with probability ``mean run time / --fault-every`` (300 s: one every 5 minutes on average), fired
U(0, 20) s after the run's robot first moves: SIGKILL or SIGSEGV of one of Nav2's servers
(controller, planner, behaviours, BT navigator, collision monitor, velocity smoother, lifecycle
manager), SIGSTOP of one for 30 s, or SIGKILL of our world, adapter or recorder. It ends by itself.

``--never-back`` adds the one fault a campaign cannot survive, last: a stack that never comes back.
A fresh batch of the suite's first scenario, twice; once run 1 is filed, the params file goes away
and the controller is killed on run 2, so Nav2's relaunch fails. The command must stop with one
line naming what did not come back, run 2 filed as the stack's crash and answered in the bag.

Writes ``bench/results/nav2_chaos.json``: ``published`` (scenarios sent: in a bag or a row of the
results file), ``accounted_for`` (of them, those with a row and a result in a bag: a verdict, a
failure, an error or a timeout), ``faults`` (one
entry per injected fault: what, when, and what the log says of it: the row's verdict and detail),
the restarts with their seconds, and the Nav2 hours run and lost.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import signal
import sys
import time
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import write_result  # noqa: E402

import numpy as np  # noqa: E402

NAV2_SERVERS = ("controller_server", "planner_server", "behavior_server", "bt_navigator", "collision_monitor",
                "velocity_smoother", "lifecycle_manager_navigation")
OURS = ("robot_world", "sut_adapter", "recorder")


def draw_faults(runs: int, per_run: float, seed: int) -> list:
    """A fault for each run with probability ``per_run``: what, how, and when after the robot moves."""
    from ambiegen_ros.trials.faults import Fault

    rng = np.random.default_rng(seed)
    out = []
    for run in range(1, runs + 1):
        if rng.random() >= per_run:
            continue
        kind = rng.choice(["kill", "segv", "stop", "ours"], p=[0.35, 0.25, 0.2, 0.2])
        after = float(np.round(rng.uniform(0.0, 20.0), 1))
        if kind == "ours":
            out.append(Fault(str(rng.choice(OURS)), signal.SIGKILL, run, after))
        else:
            target = str(rng.choice(NAV2_SERVERS))
            sig = {"kill": signal.SIGKILL, "segv": signal.SIGSEGV, "stop": signal.SIGSTOP}[kind]
            out.append(Fault(target, sig, run, after, 30.0 if kind == "stop" else 0.0))
    return out


def bags_of(rows: list[dict]) -> list[Path]:
    """Every readable bag of the batch: each session's bags, a killed recorder's rebuilt one instead."""
    folders = {Path(r["bag"]).parent for r in rows}
    out = []
    for folder in sorted(folders):
        for bag in sorted(folder.glob("trials*.mcap")):
            if bag.name.endswith(".recovered.mcap"):
                continue
            rebuilt = bag.with_suffix(".recovered.mcap")
            out.append(rebuilt if rebuilt.exists() else bag)
    return out


def logged(bags: list[Path]) -> tuple[set, set]:
    """(run id, scenario id) of the scenarios and of the results the bags hold (read with rosbags)."""
    from rosbags.highlevel import AnyReader

    from ambiegen_ros.ros import topics

    sent, answered = set(), set()
    for bag in bags:
        try:
            with AnyReader([bag]) as reader:
                want = [c for c in reader.connections if c.topic in (topics.scenarios("robot"), topics.RESULTS)]
                for conn, _, raw in reader.messages(want):
                    msg = reader.deserialize(raw, conn.msgtype)
                    meta = getattr(msg, "meta", msg)
                    (sent if conn.topic != topics.RESULTS else answered).add((meta.run_id, int(meta.scenario_id)))
        except Exception as exc:  # noqa: BLE001 - an unreadable bag is a finding, reported
            print(f"{bag}: not readable ({type(exc).__name__}: {exc})", file=sys.stderr)
    return sent, answered


def never_back(suite, config, settings) -> dict:
    """The stack that never comes back (see the module's doc): what the batch said and filed."""
    import threading

    from ambiegen_ros.trials.faults import Fault
    from ambiegen_ros.trials.rows import TrialLog
    from ambiegen_ros.trials.runner import run_trials
    from ambiegen_ros.trials.session import StackStopped

    one = dataclasses.replace(suite, entries=suite.entries[:1])
    settings.repeat, settings.budget_s = 2, None
    settings.faults = [Fault("controller_server", signal.SIGKILL, 2, 5.0)]
    before = len(TrialLog(settings.results).rows())
    done = threading.Event()

    def params_away() -> None:  # once run 1 is filed (polled: a bench, not a test)
        while not done.wait(0.5):
            if len(TrialLog(settings.results).rows()) > before:
                config.path.rename(config.path.with_suffix(".away"))
                return

    watcher = threading.Thread(target=params_away, daemon=True)
    watcher.start()
    stopped = None
    try:
        run_trials(one, [config], settings)
    except StackStopped as exc:
        stopped = str(exc)
    finally:
        done.set()
    rows = TrialLog(settings.results).rows()[before:]
    sent, answered = logged(bags_of(rows))
    filed = {(r["run_id"], r["scenario_id"]) for r in rows}
    published = filed | sent
    return {"fault": settings.faults[0].spec() + " after the params file went away", "stopped": stopped,
            "runs": [{"verdict": r["verdict"], "detail": r["detail"][:300], "restarts": r.get("restarts")}
                     for r in rows],
            "published": len(published), "accounted_for": len(filed & answered)}


def fault_table(figures: dict) -> list[str]:
    """The faults as markdown: what was injected, when, and what the log says of it."""
    out = ["| # | injected | at (s) | the run's record | restarts (s) |", "|---|---|---|---|---|"]
    for k, fault in enumerate(figures["faults"], start=1):
        log = fault["log"] or {}
        said = f"{log.get('verdict', '(no row)')}: {(log.get('detail') or '')[:110]}".replace("|", "/")
        took = ", ".join(f"{r['process']} {r['took_s']:.0f}" for r in log.get("restarts") or [] if r.get("took_s"))
        out.append(f"| {k} | `{fault['what']}` | {fault['when_s']:.0f} | {said} | {took} |")
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("suite", nargs="+")
    ap.add_argument("--params", required=True)
    ap.add_argument("--hours", type=float, default=1.0, help="hours of sending")
    ap.add_argument("--fault-every", type=float, default=300.0, help="seconds between faults on average")
    ap.add_argument("--run-s", type=float, default=60.0, help="a run's mean wall seconds (for the fault rate)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--config", default="")
    ap.add_argument("--results", required=True)
    ap.add_argument("--bags", required=True)
    ap.add_argument("--domain-id", type=int, default=7)
    ap.add_argument("--tag", default="", help="results/nav2_chaos[_TAG].json")
    ap.add_argument("--never-back", action="store_true",
                    help="end with a stack that never comes back (its own batch: BAGS/never_back, RESULTS_never_back.jsonl)")
    args = ap.parse_args(argv)

    from ambiegen_ros.nav2_params import OVERLAY_FILE, package_file
    from ambiegen_ros.trials.configs import parse_config, prepare
    from ambiegen_ros.trials.rows import TrialLog
    from ambiegen_ros.trials.runner import TrialSettings, run_trials
    from ambiegen_ros.trials.session import StackStopped
    from ambiegen_ros.trials.suite import load_suite

    suite = load_suite(args.suite, args.config or None)
    budget = args.hours * 3600.0
    repeat = int(np.ceil(budget / args.run_s / len(suite.entries))) + 1
    faults = draw_faults(repeat * len(suite.entries) * 2, args.run_s / args.fault_every, args.seed)
    settings = TrialSettings(stack="bringup", results=Path(args.results), bags=Path(args.bags), repeat=repeat,
                             seed=args.seed, domain_id=args.domain_id, faults=faults, budget_s=budget,
                             known_failures=str(package_file("config", "nav2", "known_failures.yaml")))
    settings.bags.mkdir(parents=True, exist_ok=True)
    config = prepare(parse_config(args.params), "bringup", str(package_file(*OVERLAY_FILE)), 1.0, settings.bags)
    before = {(r["run_id"], r["scenario_id"]) for r in TrialLog(settings.results).rows()}
    t0 = time.monotonic()
    stopped = None
    try:
        if budget > 0:  # --hours 0: only the stack that never comes back
            run_trials(suite, [config], settings)
    except StackStopped as exc:
        stopped = str(exc)
    wall = time.monotonic() - t0
    rows = [r for r in TrialLog(settings.results).rows() if (r["run_id"], r["scenario_id"]) not in before]
    sent, answered = logged(bags_of(rows))
    filed = {(r["run_id"], r["scenario_id"]) for r in rows}
    published = filed | sent  # sent: in a bag; filed: a row of the results file
    fired = [f for f in faults if f.fired_at is not None]
    by_run = {}
    for number, r in enumerate(rows, start=1):
        by_run[number] = r
    entries = []
    for fault in fired:
        row = by_run.get(fault.run)
        entries.append({"what": fault.spec(), "when_s": round(fault.fired_at - t0, 1),
                        "log": None if row is None else {"verdict": row["verdict"], "detail": row["detail"][:300],
                                                         "events": row.get("events"), "restarts": row.get("restarts")}})
    restarts = [x for r in rows for x in r.get("restarts") or []]
    nav2_s = sum(r["wall_s"] for r in rows)
    lost_s = sum(r["wall_s"] for r in rows if r["failure_kind"] in ("error", "sim_timeout", "sut_crashed")) + \
        sum(x["took_s"] for x in restarts)
    figures = {
        "hours": args.hours, "seed": args.seed, "fault_every_s": args.fault_every, "wall_s": round(wall, 1),
        "published": len(published), "in_bags": len(sent), "filed": len(filed),
        "accounted_for": len(filed & answered), "unaccounted": sorted(map(list, published - (filed & answered)))[:20],
        "verdicts": dict(Counter(r["failure_kind"] for r in rows)),
        "faults": entries, "faults_fired": len(fired),
        "restarts": len(restarts), "restart_s": {"median": float(np.median([x["took_s"] for x in restarts]))
                                                 if restarts else None,
                                                 "max": max((x["took_s"] for x in restarts), default=None)},
        "nav2_hours": round(nav2_s / 3600, 3), "nav2_hours_lost": round(lost_s / 3600, 3),
        "stopped": stopped, "results": args.results, "bags": args.bags,
    }
    if args.never_back:
        # its own bags and rows: in the hour's results file its runs would count as done already
        settings.bags = settings.bags / "never_back"
        settings.bags.mkdir(parents=True, exist_ok=True)
        settings.results = settings.results.with_name(settings.results.stem + "_never_back.jsonl")
        last = prepare(parse_config(args.params), "bringup", str(package_file(*OVERLAY_FILE)), 1.0, settings.bags)
        figures["never_back"] = never_back(suite, last, settings)
        figures["published"] += figures["never_back"]["published"]
        figures["accounted_for"] += figures["never_back"]["accounted_for"]
    path = write_result("nav2_chaos" + (f"_{args.tag}" if args.tag else ""), figures)
    print(json.dumps({k: v for k, v in figures.items() if k != "faults"}, indent=2))
    print("\n".join(fault_table(figures)))
    print(f"written: {path}")
    return 0 if figures["accounted_for"] == figures["published"] else 1


if __name__ == "__main__":
    sys.exit(main())
