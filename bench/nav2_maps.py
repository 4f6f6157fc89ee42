"""What Nav2 fails on: robot maps executed on a real Nav2 (a private Jazzy + Nav2 build), each verdict appended.

    python bench/nav2_maps.py --setup ~/jazzy-verify/install/setup.bash --maps random --count 20 \\
        --profile refined --seed 3 --label random-refined
    python bench/nav2_maps.py --setup ... --maps suite:runs/top/suite.json --count 20 --label top-refined
    python bench/nav2_maps.py --report          # the table and three failure pictures, from the results

Each map runs through ``robot_world`` (free-running at ``--time-scale``, ``/clock``), Nav2 with
``--params-file`` (default ``config/nav2/pioneer_navfn_dwb.yaml``, loop rates x time scale), and
``sut_adapter`` in Nav2 mode (``navigate_to_pose``), all on the install's rclpy over
``rmw_cyclonedds_cpp``; a recorder writes a robot bag per batch to ``--mcap-dir`` (outside the
repository: they are large). Maps: ``random`` = valid maps of the profile (seeded) that have a
clearance route (else they would be invalid tests); ``suite:FILE`` = the best ``--count`` of a
search's ``suite.json``.

Results: ``docs/results/nav2/runs.jsonl``, one JSON object per executed map, appended and never
rewritten; a map already there with the same label and time scale is skipped, so a batch that
was stopped resumes where it stopped. ``--report`` writes ``docs/results/nav2/README.md`` (per
label: failure rate, distinct failures by place and kind, Nav2's error codes, failures per hour)
and pictures of three failures (map, trajectory, Nav2's plan, where it failed).
"""
from __future__ import annotations

import argparse
import hashlib
import json
import os
import sys
import tempfile
import time
from collections import Counter
from datetime import datetime, timezone
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
for extra in (REPO, REPO / "test", REPO / "test" / "real_ros"):
    sys.path.insert(0, str(extra))

import numpy as np  # noqa: E402

RESULTS = REPO / "docs" / "results" / "nav2"
RUNS = RESULTS / "runs.jsonl"  # --results moves it (a trial run), the pictures and README stay here


def scenario_key(scenario: dict) -> str:
    return hashlib.sha1(json.dumps(scenario, sort_keys=True).encode()).hexdigest()[:16]


def done_keys(label: str, time_scale: float) -> set[str]:
    if not RUNS.exists():
        return set()
    rows = [json.loads(line) for line in RUNS.read_text().splitlines() if line.strip()]
    return {r["key"] for r in rows if r["label"] == label and r["time_scale"] == time_scale}


def pick_maps(spec: str, count: int, profile: str, seed: int) -> list:
    from ambiegen_ros.problems import get_problem
    from ambiegen_ros.sims import reference
    from ambiegen_ros.sims.full_model import full_model_executor

    p = get_problem("robot", {"profile": profile})
    full = full_model_executor(p)
    usable = lambda sc: full.validity(sc)[0] and reference.before(p, sc, full.config).passed  # noqa: E731
    if spec == "random":
        rng, out = np.random.default_rng(seed), []
        while len(out) < count:
            sc = p.codec.from_rows(p.sample_rows(1, rng))[0]
            if usable(sc):
                out.append(sc)
        return out
    if spec.startswith("suite:"):
        suite = json.loads(Path(spec[6:]).read_text())
        entries = suite.get("scenarios", suite) if isinstance(suite, dict) else suite
        ranked = sorted(entries, key=lambda e: -float(e.get("f1", e.get("objectives", {}).get("f1", 0.0))))
        out = []
        for entry in ranked:
            data = entry.get("scenario", entry)
            sc = p.parse({"problem": "robot", "elements": data["elements"]})
            if usable(sc):
                out.append(sc)
            if len(out) == count:
                break
        return out
    raise SystemExit(f"--maps: random | suite:FILE, got {spec!r}")


def run_batch(args) -> int:
    import jazzy_env as je
    from helpers.sut_graph import Driver
    from ambiegen_ros import launch_logic
    from ambiegen_ros.core.runs import versions
    from ambiegen_ros.problems import get_problem
    from ambiegen_ros.ros.transport import create_node

    os.environ[je.SETUP_VAR] = args.setup
    info = je.probe()
    if "skip" in info:
        raise SystemExit(info["skip"])
    maps = pick_maps(args.maps, args.count, args.profile, args.seed)
    done = done_keys(args.label, args.time_scale)
    todo = [sc for sc in maps if scenario_key(sc.to_dict()) not in done]
    print(f"{len(maps)} maps, {len(maps) - len(todo)} already in {RUNS}; running {len(todo)}")
    if not todo:
        return 0
    import yaml

    stamp = datetime.now(timezone.utc).strftime("%Y%m%dT%H%M%SZ")
    mcap_dir = Path(args.mcap_dir).expanduser()
    mcap_dir.mkdir(parents=True, exist_ok=True)
    mcap = mcap_dir / f"nav2_{args.label}_{stamp}.mcap"
    params = yaml.safe_load(Path(args.params_file).read_text())
    scaled = mcap.with_suffix(".nav2_params.yaml")
    scaled.write_text(yaml.safe_dump(launch_logic.scale_nav2_rates(params, args.time_scale), sort_keys=False))
    domain = args.domain_id
    ros = je.ros_env(domain)
    logs = Path(tempfile.mkdtemp(prefix=f"nav2_{args.label}_"))
    graph = je.Graph(logs)
    install = je.working_tree_install(logs / "ws")  # rclpy needs ambiegen_msgs built by colcon
    ours = lambda executable, **p: f"ros2 run ambiegen_ros {executable} {je.ros_args(**p)}"  # noqa: E731
    graph.ros("world", ours("robot_world", time_scale=args.time_scale, seed=args.seed, collision_topic="/collision"),
              install, ros)
    for name, package, executable in launch_logic.NAV2_NODES:
        graph.ros(name, f"ros2 run {package} {executable} --ros-args --params-file {scaled} -r __node:={name}",
                  install, ros)
    graph.ros("adapter", ours("sut_adapter", problem="robot", worker_id="nav2", goal_mode="action",
                              time_scale=args.time_scale, collision_topic="/collision", map_upsample=args.map_upsample,
                              settle_time=1.0, start_timeout=120.0, profile=args.profile), install, ros)
    graph.venv("recorder", "ambiegen_ros.nodes.recorder", {"output": str(mcap),
                                                          "extra_topics": ",".join(launch_logic.NAV2_TOPICS)},
               je.venv_env(domain))
    os.environ.update(ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE="SUBNET", AMBIEGEN_TRANSPORT="dds")
    node = create_node("nav2_maps", argv=[])
    p = get_problem("robot", {"profile": args.profile})
    limit = 2 * 300.0 / args.time_scale + 180.0
    print(f"logs in {logs}; bag {mcap}")
    try:
        driver = Driver(node, p)
        driver.wait_matched(count=2, timeout=300)  # the adapter and the recorder
        for i, sc in enumerate(todo):
            run_id = f"{args.label}-{stamp}-{i}"
            t0, w0 = time.monotonic(), time.time_ns()
            driver.send(run_id, [sc])
            (res,) = driver.wait(run_id, 1, limit)
            wall = time.monotonic() - t0
            if res is None:
                print(f"map {i}: no answer within {limit:.0f} s; stopping (see {logs})")
                return 1
            m = res.metrics
            traj = np.asarray(res.trajectory)[::10].round(3).tolist() if res.trajectory is not None else None
            row = {"label": args.label, "time_scale": args.time_scale, "key": scenario_key(sc.to_dict()),
                   "profile": args.profile, "params_file": str(args.params_file), "scenario": sc.to_dict(),
                   "failure_kind": res.failure_kind, "failed": res.failed, "detail": res.detail,
                   "nav2_status": m.get("nav2_status"), "nav2_error_code": m.get("nav2_error_code"),
                   "nav2_error_msg": m.get("nav2_error_msg"), "time": m.get("time"), "wall_s": round(wall, 2),
                   "failure_point": list(res.failure_point) if res.failure_point is not None else None,
                   "trajectory_every_10": traj, "mcap": str(mcap), "wall_start_ns": w0, "wall_end_ns": time.time_ns(),
                   "when": datetime.now(timezone.utc).isoformat(timespec="seconds"), "versions": versions()}
            RUNS.parent.mkdir(parents=True, exist_ok=True)
            with open(RUNS, "a") as fh:  # appended, never rewritten
                fh.write(json.dumps(row) + "\n")
            print(f"map {i}: {res.failure_kind} ({res.detail}); Nav2 {m.get('nav2_status')} "
                  f"{m.get('nav2_error_code')} {m.get('nav2_error_msg') or ''}; {wall:.0f} s wall", flush=True)
    finally:
        node.shutdown()
        for name in list(graph.procs):
            graph.stop(name)
    return 0


def report(args) -> int:
    from ambiegen_ros.problems import get_problem
    from ambiegen_ros.ros.runlog import iter_messages
    from ambiegen_ros.sims.outcome import Outcome
    from ambiegen_ros.sims.signature import DistinctFailures, signature
    from ambiegen_ros.viz.execution import save_execution_plot

    rows = [json.loads(line) for line in RUNS.read_text().splitlines() if line.strip()]
    lines = ["# Nav2 on AmbieGen's maps (measured; appended by `bench/nav2_maps.py`)", "",
             "| label | time scale | maps | failures | rate | distinct (by place and kind) | kinds | Nav2 results "
             "(error codes) | failures per hour of runs |", "|---|---|---|---|---|---|---|---|---|"]
    failures = []
    for (label, k), group in sorted(Counter((r["label"], r["time_scale"]) for r in rows).items()):
        batch = [r for r in rows if r["label"] == label and r["time_scale"] == k]
        failed = [r for r in batch if r["failed"]]
        distinct = DistinctFailures()
        problem = get_problem("robot", {"profile": batch[0]["profile"]})
        for r in failed:
            out = Outcome(objectives={}, failed=True, failure_kind=r["failure_kind"], detail=r["detail"],
                          failure_point=tuple(r["failure_point"]) if r["failure_point"] else None)
            sig = signature(problem, None, out)
            if sig is not None:
                distinct.add(sig)
            failures.append((r, problem, out))
        hours = sum(r["wall_s"] for r in batch) / 3600.0
        kinds = ", ".join(f"{kd} {n}" for kd, n in Counter(r["failure_kind"] for r in batch).most_common())
        nav2 = ", ".join(f"{s} {n}" for s, n in Counter(f"{r['nav2_status']}"
                                                         + (f" ({r['nav2_error_code']})" if int(r["nav2_error_code"] or 0) else "")
                                                         for r in batch).most_common())
        lines.append(f"| {label} | {k:g} | {len(batch)} | {len(failed)} | {len(failed) / len(batch):.0%} | "
                     f"{len(distinct)} | {kinds} | {nav2} | {len(failed) / hours if hours else 0:.1f} |")
    lines += ["", "Pictures: map, trajectory (coloured by time), Nav2's last plan, and where it failed.", ""]
    for i, (r, problem, out) in enumerate(failures[:3]):
        sc = problem.parse(r["scenario"])
        traj = np.asarray(r["trajectory_every_10"] or [], dtype=float).reshape(-1, 2)
        out.trajectory, out.timeline = traj, {"t": np.arange(len(traj)) * 1.0}
        plan = None
        if Path(r["mcap"]).exists():
            for _, _, t, msg in iter_messages(r["mcap"], {"/plan"}):
                if r["wall_start_ns"] <= t <= r["wall_end_ns"]:
                    plan = np.array([[q.pose.position.x, q.pose.position.y] for q in msg.poses])
        path = save_execution_plot(problem, sc, out, RESULTS / f"failure_{i + 1}.png", plan=plan)
        lines.append(f"![{r['failure_kind']}]({path.name}) {r['label']}: {r['detail']}")
    (RESULTS / "README.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--setup", default=os.path.expanduser("~/jazzy-verify/install/setup.bash"))
    ap.add_argument("--maps", default="random", help="random | suite:FILE")
    ap.add_argument("--count", type=int, default=20)
    ap.add_argument("--profile", default="refined", choices=("replication", "refined"))
    ap.add_argument("--seed", type=int, default=3)
    ap.add_argument("--label", default="random-refined")
    ap.add_argument("--time-scale", type=float, default=1.0)
    ap.add_argument("--map-upsample", type=int, default=5)
    ap.add_argument("--params-file", default=str(REPO / "config" / "nav2" / "pioneer_navfn_dwb.yaml"))
    ap.add_argument("--mcap-dir", default="~/nav2-bags")
    ap.add_argument("--domain-id", type=int, default=61)
    ap.add_argument("--report", action="store_true")
    ap.add_argument("--results", default="", help="the JSONL file appended to (default: the committed one)")
    args = ap.parse_args(argv)
    if args.results:
        globals()["RUNS"] = Path(args.results).resolve()
    return report(args) if args.report else run_batch(args)


if __name__ == "__main__":
    sys.exit(main())
