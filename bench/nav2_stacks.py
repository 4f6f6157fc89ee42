"""Nav2 runs per hour with K stacks at once (``nav2_campaign.launch.py stacks:=K``) on this machine.

    python bench/nav2_stacks.py --setup ~/jazzy-verify/install/setup.bash --stacks 1 2 --evaluations 12

Each K runs the same campaign (random search, the same seed, so the same suite of maps) through
the launch file on a private Jazzy + Nav2 build: K stacks of robot_world + Nav2 (our five nodes,
NavFn + DWB) + sut_adapter, one generator, one recorder. It prints and appends to
``bench/results/nav2_stacks.jsonl``: maps answered, wall time of the whole launch and from the
first result to the last, runs per hour, and the verdicts (a stack that cannot keep its loops on
time shows it there first: compare them across K).
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from collections import Counter
from datetime import datetime, timezone
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
for extra in (REPO, REPO / "test", REPO / "test" / "real_ros", REPO / "test" / "helpers"):
    sys.path.insert(0, str(extra))

from _common import append_row, read_rows  # noqa: E402

OUT = REPO / "bench" / "results" / "nav2_stacks.jsonl"


def run_one(k: int, args, install: Path, logs: Path, hosts: bool = False) -> dict:
    """K stacks on this host (one launch), or (``hosts``) across K + 1 network-namespace hosts:
    host a runs ``part:=generator``, host b<i> ``part:=stack<i>`` (stopped once a's launch ends)."""
    import jazzy_env as je

    from ambiegen_ros.core.runs import versions
    from ambiegen_ros.nodes.replay import recorded_scenarios
    from ambiegen_ros.ros.runlog import iter_messages, summarize
    from ambiegen_ros.ros import topics

    out_dir = Path(tempfile.mkdtemp(prefix=f"stacks{k}{'_hosts' if hosts else ''}_", dir=logs))
    graph = je.Graph(out_dir)
    launch = "ros2 launch ambiegen_ros nav2_campaign.launch.py " + " ".join(
        f"{key}:={value}" for key, value in dict(
            stacks=k, algorithm="random", evaluations=args.evaluations, seed=args.seed, output_dir=out_dir,
            time_scale=args.time_scale, config_file=REPO / "config" / "robot_small.yaml", profile="refined").items())
    env = je.ros_env(args.domain_id)
    net = None
    if hosts:
        import netns

        net = netns.TestNetwork(["a", *[f"b{i}" for i in range(k)]]).create()
        for i in range(k):
            graph.start(f"stack{i}", ["ip", "netns", "exec", net.ns(f"b{i}"),
                                      *je.ros_command(f"{launch} part:=stack{i}", install)], env)
    t0 = time.monotonic()
    try:
        if net is None:
            graph.ros("launch", launch, install, env)
        else:
            graph.start("launch", ["ip", "netns", "exec", net.ns("a"),
                                   *je.ros_command(f"{launch} part:=generator", install)], env)
        code = graph.procs["launch"].wait(args.timeout)
        wall = time.monotonic() - t0
    finally:
        if net is not None:
            for i in range(k):
                graph.stop(f"stack{i}", 60)  # the stack hosts serve until stopped: SIGINT, then a kill
            net.destroy()
    (mcap,) = out_dir.glob("*.mcap")
    summary = summarize(mcap)
    stamps = [t for _, _, t, _ in iter_messages(mcap, {topics.RESULTS})]
    outcomes = recorded_scenarios(mcap).outcomes
    ran = [o for o in outcomes.values() if o.failure_kind not in ("invalid_scenario", "invalid_test")]
    span = (max(stamps) - min(stamps)) / 1e9 if len(stamps) > 1 else 0.0
    return {"stacks": k, "hosts": k + 1 if hosts else 1, "exit": code, "maps_answered": summary["results_received"], "nav2_runs": len(ran),
            "wall_s": round(wall, 1), "first_to_last_result_s": round(span, 1),
            "nav2_runs_per_hour": round(len(ran) / wall * 3600, 1),
            "verdicts": dict(Counter(o.failure_kind for o in ran)),
            "workers": dict(Counter(str(w) for w in _workers(mcap))),
            "time_scale": args.time_scale, "seed": args.seed, "evaluations": args.evaluations, "mcap": str(mcap),
            "when": datetime.now(timezone.utc).isoformat(timespec="seconds"), "versions": versions(),
            "cpus": os.cpu_count()}


def _workers(mcap: Path) -> list[str]:
    from ambiegen_ros.ros import topics
    from ambiegen_ros.ros.runlog import iter_messages

    return [msg.worker for _, _, _, msg in iter_messages(mcap, {topics.RESULTS})]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--setup", default=os.path.expanduser("~/jazzy-verify/install/setup.bash"))
    ap.add_argument("--stacks", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--evaluations", type=int, default=12, help="random search: about this many maps")
    ap.add_argument("--seed", type=int, default=5)
    ap.add_argument("--time-scale", type=float, default=2.0)
    ap.add_argument("--domain-id", type=int, default=8, help="outside the test suite's pool (10-101)")
    ap.add_argument("--timeout", type=float, default=7200.0)
    ap.add_argument("--hosts", action="store_true",
                    help="each stack on a host of its own and the generator and recorder on another: network "
                         "namespaces on one bridge (test/helpers/netns.py; needs root)")
    args = ap.parse_args(argv)
    import jazzy_env as je

    os.environ[je.SETUP_VAR] = args.setup
    info = je.probe()
    if "skip" in info:
        raise SystemExit(info["skip"])
    logs = Path(tempfile.mkdtemp(prefix="nav2_stacks_"))
    install = je.working_tree_install(logs / "ws")
    for k in args.stacks:
        row = run_one(k, args, install, logs, args.hosts)
        append_row(OUT, row)
        print(json.dumps({key: row[key] for key in ("stacks", "hosts", "exit", "maps_answered", "nav2_runs", "wall_s",
                                                    "first_to_last_result_s", "nav2_runs_per_hour", "verdicts",
                                                    "workers")}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
