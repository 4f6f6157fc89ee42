"""AmbieGen's search against random sampling on a real Nav2 planner_server (issue 68).

    python bench/planner_search.py --setup ~/jazzy-verify/install/setup.bash --plugin navfn --algorithm ga --seed 1
    python bench/planner_search.py --setup ... --plugin navfn --algorithm random --seed 1 --minutes 3
    python bench/planner_search.py --setup ... --plugin navfn --config config/robot_planner_vias.yaml
    python bench/planner_search.py --report

One run is one ``ambiegen stack-search --stack planner`` on ``config/robot_planner.yaml`` (walls, a
start and a goal anywhere; ``--config``: another, e.g. ``config/robot_planner_vias.yaml``, whose 1 to 3
vias are asked through ComputePathThroughPoses) against ``config/nav2/planners/<plugin>.yaml`` (Jazzy's costmap, one
planner plugin), for ``--minutes`` of wall time: the planner stack has no clock to scale. From its
rows: scenarios answered and their rate, findings (a failure the oracles of ``sims.plans`` give,
each certified by our own code on the costmap read back), **distinct findings** (one per
``finding_key``: plugin, oracle, Nav2's error code, shape; a row says its config), invalid tests (refusals the reference
proves right), errors, and the closest call (the least clearance of a path that held, m). One JSON
row per run is appended to ``bench/results/planner_search.jsonl``, never rewritten.

``--report`` prints, per plugin and run length, each algorithm's runs and, at 3 runs a side or more, one-sided
exact Mann-Whitney tests (``core.stats.greater_exact``, exact with ties) of the search against
random on distinct findings per hour and on the closest call; below 10 runs a side it is a hint.
Needs a sourced ROS 2 Jazzy with Nav2's planner_server (a private build; nothing here builds it).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
from collections import Counter
from datetime import datetime, timezone
from pathlib import Path
from statistics import median

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

OUT = REPO / "bench" / "results" / "planner_search.jsonl"
CONFIG = "config/robot_planner.yaml"
CLAIM_RUNS = 10
EDGE_CELLS = 1  # a start or goal this many scenario cells from the border wall is "at the edge"


def shape_of(row: dict) -> str:
    """Where a finding lies, coarsely, over the poses flown through (start, vias in order, goal):
    two in a row in one cell (a leg of no length), one at the map's edge, or all inside."""
    elements = row["scenario"]["elements"]
    sc = {e["type"]: e for e in elements if e["type"] in ("start", "goal")}
    s, g = sc.get("start"), sc.get("goal")
    if s is None or g is None:
        return "other"
    chain = [s, *(e for e in elements if e["type"] == "via"), g]
    if any((a["position"], a["row"]) == (b["position"], b["row"]) for a, b in zip(chain, chain[1:])):
        return "same_cell"
    if any(min(e["position"], e["row"]) <= EDGE_CELLS or max(e["position"], e["row"]) >= 49 - EDGE_CELLS
           for e in chain):
        return "edge"
    return "inside"


def finding_key(row: dict) -> str:
    """One bug, one key: the plugin, the oracle that flagged it, Nav2's error code, the shape. A
    finding through poses keys alike: its own oracles (``missed_via``, ``path_gap``) and error
    codes (30x) set it apart, and a collision in one of its legs is the same bug as in one path."""
    m = row.get("metrics", {})
    return "/".join(str(x) for x in (m.get("planner", row["label"]), m.get("plan_oracle", row["failure_kind"]),
                                     m.get("plan_error_code", ""), shape_of(row)))


def clearance_of(row: dict) -> float | None:
    """The least clearance of a path that held (m), None when the row has none."""
    value = row.get("metrics", {}).get("plan_clearance_m")
    return None if value in (None, "None") else float(value)


def summarise(rows: list[dict], minutes: float) -> dict:
    findings = [r for r in rows if r["failed"]]
    clearances = [c for r in rows if r["failure_kind"] == "none" and (c := clearance_of(r)) is not None]
    starts = sorted(r["wall_start_ns"] for r in rows)
    span = (starts[-1] - starts[0]) / 1e9 if len(starts) > 1 else math.nan
    keys = Counter(finding_key(r) for r in findings)
    return {"scenarios": len(rows), "scenarios_per_s": (len(rows) - 1) / span if span and span > 0 else None,
            "findings": len(findings), "distinct": len(keys), "distinct_keys": dict(keys),
            "distinct_per_hour": len(keys) / (minutes / 60.0),
            "invalid_tests": sum(r["failure_kind"] == "invalid_test" for r in rows),
            "errors": sum(r["failure_kind"] in ("error", "sim_timeout") for r in rows),
            "closest_m": min(clearances) if clearances else None,
            "kinds": dict(Counter(r["failure_kind"] for r in rows))}


def run(args: argparse.Namespace) -> dict:
    params = REPO / "config" / "nav2" / "planners" / f"{args.plugin}.yaml"
    with tempfile.TemporaryDirectory(prefix="planner_search_") as tmp:
        d = Path(tmp)
        cmd = (f"source {args.setup} && export RMW_IMPLEMENTATION=rmw_cyclonedds_cpp AMBIEGEN_TRANSPORT=dds && "
               f"exec {REPO / '.venv' / 'bin' / 'ambiegen'} stack-search --algorithm {args.algorithm} "
               f"--hours {args.minutes / 60.0} --time-scale 1 --stack planner "
               f"--params {args.plugin}={params} --config {args.config} --our-transport dds "
               f"--domain-id {args.domain_id} "
               f"--results {d / 'rows.jsonl'} --bags {d / 'bags'} --out {d / 'out'} --seed {args.seed}")
        proc = subprocess.run(["bash", "-c", cmd], cwd=REPO, capture_output=True, text=True,
                              timeout=args.minutes * 60 + 900)
        if proc.returncode != 0:
            raise SystemExit(f"stack-search failed ({proc.returncode}):\n{proc.stdout[-2000:]}\n{proc.stderr[-2000:]}")
        rows = [json.loads(line) for line in (d / "rows.jsonl").read_text().splitlines() if line.strip()]
        found = [r for r in rows if r["failed"]]
        held = [r for r in rows if r["failure_kind"] == "none" and clearance_of(r) is not None]
        closest = [min(held, key=clearance_of)] if held else []
        if (found or closest) and args.keep:  # the findings, and the closest call to draw
            keep = Path(args.keep) / f"{args.plugin}_{args.algorithm}_{args.seed}.jsonl"
            keep.parent.mkdir(parents=True, exist_ok=True)
            keep.write_text("".join(json.dumps(r) + "\n" for r in found + closest))
    config = {} if args.config == CONFIG else {"config": args.config}  # the default's rows stay as they were
    return {"plugin": args.plugin, "algorithm": args.algorithm, "seed": args.seed, "minutes": args.minutes, **config,
            "when": datetime.now(timezone.utc).isoformat(timespec="seconds"), **summarise(rows, args.minutes)}


def setup_of(row: dict) -> str:
    """A run's configuration: its plugin, and the scenarios' config when not the default."""
    return row["plugin"] + (f" on {row['config']}" if row.get("config") else "")


def survived(rows: list[dict]) -> None:
    """Per plugin (config file), every run of any length together: what it was asked and what broke."""
    print("## What each configuration survived (every run, any length)")
    for plugin in sorted({setup_of(r) for r in rows}):
        mine = [r for r in rows if setup_of(r) == plugin]
        sent = sum(r["scenarios"] for r in mine)
        invalid = sum(r["invalid_tests"] for r in mine)
        keys: Counter = Counter()
        for r in mine:
            keys.update(r["distinct_keys"])
        print(f"- {plugin}: {len(mine)} runs, {sent} scenarios ({invalid} invalid tests: refusals our reference "
              f"proved right or could not judge), {sum(r['findings'] for r in mine)} failing; by key {dict(keys)}")


def report() -> None:
    from ambiegen_ros.core.stats import greater_exact

    rows = [json.loads(line) for line in OUT.read_text().splitlines() if line.strip()] if OUT.exists() else []
    survived(rows)
    for plugin, minutes in sorted({(setup_of(r), r["minutes"]) for r in rows}):
        # runs of one length only: a long survival run is no sample of what two minutes find
        side = {a: [r for r in rows if (setup_of(r), r["minutes"], r["algorithm"]) == (plugin, minutes, a)]
                for a in ("ga", "nsga2", "random")}
        print(f"## {plugin}, runs of {minutes:g} min")
        for algorithm, runs in side.items():
            if runs:
                print(f"- {algorithm}: {len(runs)} runs, {sum(r['scenarios'] for r in runs)} scenarios, "
                      f"{sum(r['findings'] for r in runs)} failing, distinct "
                      f"findings per hour {[round(r['distinct_per_hour'], 1) for r in runs]}, closest calls (m) "
                      f"{[r['closest_m'] for r in runs]}")
        for algorithm in ("ga", "nsga2"):
            a, b = side[algorithm], side["random"]
            if min(len(a), len(b)) < 3:
                continue
            tag = "" if min(len(a), len(b)) >= CLAIM_RUNS else f" (a hint: below {CLAIM_RUNS} runs a side)"
            u, p = greater_exact([r["distinct_per_hour"] for r in a], [r["distinct_per_hour"] for r in b])
            print(f"  {algorithm} > random on distinct findings per hour: U {u:g}, exact one-sided p {p:.4g}{tag}")
            per_hour = lambda runs: [r["findings"] / (r["minutes"] / 60.0) for r in runs]  # noqa: E731
            u, p = greater_exact(per_hour(a), per_hour(b))
            print(f"  {algorithm} > random on failing scenarios per hour (medians {median(per_hour(a)):.0f} vs "
                  f"{median(per_hour(b)):.0f}): U {u:g}, exact one-sided p {p:.4g}{tag}")
            near = lambda runs: [-(r["closest_m"] if r["closest_m"] is not None else 1e3) for r in runs]  # noqa: E731
            u, p = greater_exact(near(a), near(b))
            print(f"  {algorithm} closer than random (least clearance of a path that held): U {u:g}, exact "
                  f"one-sided p {p:.4g}{tag}")


def draw_closest(keeps: list[str], out: Path, config: str = CONFIG) -> None:
    """Per plugin, the path that held closest to a lethal cell over every kept run, drawn (``--keep``
    folders hold each run's findings and its closest call): what a planner survived, seen."""
    from ambiegen_ros.run_config import make_run
    from ambiegen_ros.viz.trials import save_runs_side_by_side

    problem = make_run("robot", str(REPO / config), seed=0)[0]
    best: dict[str, tuple[float, dict, str]] = {}
    for folder in keeps:
        for path in sorted(Path(folder).glob("*.jsonl")):
            for line in path.read_text().splitlines():
                row = json.loads(line)
                # a path from a blocked start is no clean call (before f93beed its unjudged poses counted)
                blocked = row.get("metrics", {}).get("plan_oracle") == "start_blocked"
                near = clearance_of(row) if row["failure_kind"] == "none" and not blocked else None
                plugin = row["label"]  # the configuration: a plugin, or a plugin and its smoother
                if near is not None and (plugin not in best or near < best[plugin][0]):
                    best[plugin] = (near, row, path.stem)
    out.mkdir(parents=True, exist_ok=True)
    for plugin, (near, row, run_name) in sorted(best.items()):
        title = f"{plugin}: closest call, {near:.3f} m from a lethal cell's centre"
        picture = save_runs_side_by_side(problem, problem.parse(row["scenario"]), [(title, [row])],
                                         out / f"{row['label']}_closest.png", title)
        print(f"{plugin}: {near:.4f} m (run {run_name}), {picture}")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--setup", default=os.environ.get("AMBIEGEN_ROS_SETUP", ""), help="a Jazzy install's setup.bash")
    ap.add_argument("--plugin", default="navfn", help="config/nav2/planners/<plugin>.yaml")
    ap.add_argument("--config", default=CONFIG, help="the scenarios' config (config/robot_planner_vias.yaml: "
                    "1 to 3 vias, asked through ComputePathThroughPoses)")
    ap.add_argument("--algorithm", choices=("ga", "nsga2", "random"), default="ga")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--minutes", type=float, default=3.0, help="wall minutes of the planner stack per run")
    ap.add_argument("--domain-id", type=int, default=6, help="a ROS domain no test or other run uses")
    ap.add_argument("--keep", default="", help="a folder for the rows of the run's findings and its closest call")
    ap.add_argument("--report", action="store_true")
    ap.add_argument("--draw-closest", nargs="+", metavar="KEEP", help="draw each plugin's closest call of these "
                    "--keep folders into --out")
    ap.add_argument("--out", default=str(REPO / "bench" / "results" / "planner_closest"), help="where --draw-closest "
                    "draws")
    args = ap.parse_args()
    if args.report:
        report()
        return 0
    if args.draw_closest:
        draw_closest(args.draw_closest, Path(args.out), args.config)
        return 0
    if not args.setup or not Path(args.setup).exists():
        raise SystemExit("--setup: a ROS 2 Jazzy install's setup.bash with Nav2's planner_server (or AMBIEGEN_ROS_SETUP)")
    row = run(args)
    OUT.parent.mkdir(parents=True, exist_ok=True)
    with OUT.open("a") as fh:
        fh.write(json.dumps(row) + "\n")
    print(json.dumps(row))
    return 0


if __name__ == "__main__":
    sys.exit(main())
