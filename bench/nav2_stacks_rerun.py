"""K real-time Nav2 stacks on one machine, each rerunning the same suite (issue 58).

    python bench/nav2_stacks_rerun.py SUITE [SUITE ...] --params jazzy=.../nav2_params.yaml \\
        --stacks 2 --repeat 3 --out /tmp/k2 [--our-transport dds] [--tag k2]

Starts K ``ambiegen rerun --stack bringup`` commands at once, each on its own ROS domain (as two
users' stacks on one host would run), every one the same suite N times, and waits for them all. It
reports the Nav2 hours made per machine hour (the runs' wall seconds over the batch's), how often
Nav2's controller missed its rate (its own "Control loop missed its desired rate" warnings, per
Nav2 hour), the cores our nodes and the stack took while the runs were on (each row's ``cpu``),
and the verdicts: failed runs of each scenario. ``--against`` names the results of another K
(``bench/results/nav2_stacks_rerun_<tag>.json``): then the failure rates side by side, per
scenario and in all, with Fisher's exact test (two-sided) of equal proportions. Writes
``bench/results/nav2_stacks_rerun[_TAG].json``.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from collections import Counter, defaultdict
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from _common import nav2_loop_misses, read_rows, report  # noqa: E402


def stack_rows(results: Path) -> list[dict]:
    return [r for r in read_rows(results) if r["failure_kind"] not in ("error", "sim_timeout", "invalid_test")]


def missed_loops(rows: list[dict]) -> int:
    """Nav2's controller warnings in the logs of the sessions these rows ran in."""
    logs = {Path(r["bag"]).parent / "logs" / "nav2.log" for r in rows}
    return sum(nav2_loop_misses(log) or 0 for log in logs)


def fisher(a_fail: int, a_runs: int, b_fail: int, b_runs: int) -> float:
    from scipy.stats import fisher_exact

    return float(fisher_exact([[a_fail, a_runs - a_fail], [b_fail, b_runs - b_fail]])[1])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("suite", nargs="+")
    ap.add_argument("--params", required=True, help="LABEL=FILE, as ambiegen rerun takes it")
    ap.add_argument("--stacks", type=int, default=2)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--out", required=True, help="a directory for each stack's results and bags")
    ap.add_argument("--domain-base", type=int, default=70, help="stack i runs on ROS domain BASE + i")
    ap.add_argument("--our-transport", choices=("dds",), default=None)
    ap.add_argument("--against", default="", help="the tag of the other K's result file, to compare verdicts")
    ap.add_argument("--tag", default="")
    args = ap.parse_args(argv)

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    procs, files = [], []
    t0 = time.monotonic()
    for i in range(args.stacks):
        results = out / f"stack{i}.jsonl"
        files.append(results)
        cmd = [sys.executable, "-m", "ambiegen_ros", "rerun", *args.suite, "--stack", "bringup", "--params",
               args.params, "--repeat", str(args.repeat), "--results", str(results), "--bags",
               str(out / f"stack{i}_bags"), "--domain-id", str(args.domain_base + i)]
        if args.our_transport:
            cmd += ["--our-transport", args.our_transport]
        log = open(out / f"stack{i}.log", "ab")
        procs.append(subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, cwd=out,
                                      env=dict(os.environ, PYTHONUNBUFFERED="1")))
    codes = [p.wait() for p in procs]
    wall = time.monotonic() - t0
    per_stack, verdicts = [], defaultdict(Counter)
    cpu = defaultdict(list)
    for results in files:
        rows = stack_rows(results)
        nav2_s = sum(r["wall_s"] for r in rows)
        per_stack.append({"runs": len(rows), "nav2_hours": round(nav2_s / 3600, 3),
                          "missed_loops": missed_loops(rows),
                          "missed_per_nav2_hour": round(missed_loops(rows) / max(nav2_s / 3600, 1e-9), 1)})
        for r in rows:
            verdicts[r["scenario_name"]]["runs"] += 1
            verdicts[r["scenario_name"]]["failed"] += bool(r["failed"])
            verdicts[r["scenario_name"]][r["failure_kind"]] += 1
            for key in ("ours_cores", "stack_cores"):
                if (r.get("cpu") or {}).get(key) is not None:
                    cpu[key].append(r["cpu"][key])
    nav2_hours = sum(s["nav2_hours"] for s in per_stack)
    figures = {
        "stacks": args.stacks, "repeat": args.repeat, "suite": args.suite, "our_transport": args.our_transport,
        "exit_codes": codes, "wall_s": round(wall, 1), "nav2_hours": round(nav2_hours, 3),
        "nav2_hours_per_machine_hour": round(nav2_hours / (wall / 3600), 2), "per_stack": per_stack,
        "missed_loops_per_nav2_hour": round(sum(s["missed_loops"] for s in per_stack) / max(nav2_hours, 1e-9), 1),
        "cores_per_run_median": {k: round(float(sorted(v)[len(v) // 2]), 3) for k, v in cpu.items() if v},
        "verdicts": {name: dict(c) for name, c in sorted(verdicts.items())},
        "failed": sum(c["failed"] for c in verdicts.values()), "runs": sum(c["runs"] for c in verdicts.values()),
        "out": str(out),
    }
    if args.against:
        other = json.loads((HERE / "results" / f"nav2_stacks_rerun_{args.against}.json").read_text())["figures"]
        side = {}
        for name, mine in figures["verdicts"].items():
            theirs = other["verdicts"].get(name)
            if theirs:
                side[name] = {"this": f"{mine['failed']}/{mine['runs']}", "other": f"{theirs['failed']}/{theirs['runs']}",
                              "p": round(fisher(mine["failed"], mine["runs"], theirs["failed"], theirs["runs"]), 3)}
        figures["against"] = {"tag": args.against, "stacks": other["stacks"], "per_scenario": side,
                              "all": {"this": f"{figures['failed']}/{figures['runs']}",
                                      "other": f"{other['failed']}/{other['runs']}",
                                      "p": round(fisher(figures["failed"], figures["runs"], other["failed"],
                                                        other["runs"]), 3)}}
    report("nav2_stacks_rerun", args.tag, figures)
    return 0 if not any(codes) else 1


if __name__ == "__main__":
    sys.exit(main())
