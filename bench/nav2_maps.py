"""The Nav2 runs of before the fix loop (``docs/results/nav2/runs.jsonl``): their report and pictures,
and suites of maps for ``ambiegen rerun``, which now runs maps on Nav2 (issue 56).

    python bench/nav2_maps.py --report          # the table and three failure pictures, from the rows
    python bench/nav2_maps.py --picture narrow-s1-dwb-k1-confirm:0:docs/results/nav2/dwb_narrow_slot.png
    python bench/nav2_maps.py --maps random --count 20 --profile refined --seed 3 --write-suite maps.json
    ambiegen rerun maps.json --stack bringup --params NAV2_PARAMS.yaml --repeat 3 --results runs.jsonl

``runs.jsonl`` holds one JSON object per map that this script's batch runner executed on a real
Nav2 (a private Jazzy + Nav2 build; ``robot_world`` at a time scale, Nav2 as our five nodes or
``navigation_launch.py``, ``sut_adapter`` in Nav2 mode), appended and never rewritten. ``--report``
writes ``docs/results/nav2/README.md`` from them (per label: failure rate, distinct failures by
place and kind, Nav2's error codes, failures per hour) and pictures of three failures (map,
trajectory, Nav2's plan, where it failed). ``--write-suite`` writes maps for ``ambiegen rerun``:
``random`` = valid maps of the profile (seeded) that have a clearance route (else they would be
invalid tests); ``suite:FILE[,FILE...]`` = the best ``--count`` of searches' ``suite.json`` files
(ranked by F1 together); ``--config FILE.yaml`` gives their problem settings.
"""
from __future__ import annotations

import argparse
import json
import sys
from collections import Counter
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
for extra in (REPO, REPO / "test", REPO / "test" / "real_ros"):
    sys.path.insert(0, str(extra))

from _common import read_rows  # noqa: E402

import numpy as np  # noqa: E402

RESULTS = REPO / "docs" / "results" / "nav2"
RUNS = RESULTS / "runs.jsonl"  # --results moves it (a trial run), the pictures and README stay here


def problem_config(path: str) -> dict:
    """The ``problem_config`` of a run config (``--config``), {} without one."""
    if not path:
        return {}
    import yaml

    return dict((yaml.safe_load(Path(path).read_text()) or {}).get("problem_config") or {})


def pick_maps(spec: str, count: int, profile: str, seed: int, overrides: dict | None = None) -> list:
    from ambiegen_ros.problems import get_problem
    from ambiegen_ros.sims import reference
    from ambiegen_ros.sims.full_model import full_model_executor

    p = get_problem("robot", {**(overrides or {}), "profile": profile})
    full = full_model_executor(p)
    usable = lambda sc: full.validity(sc)[0] and reference.before(p, sc, full.config).passed  # noqa: E731
    if spec == "random":
        rng, out = np.random.default_rng(seed), []
        while len(out) < count:
            sc = p.codec.from_rows(p.sample_rows(1, rng))[0]
            if usable(sc):
                out.append(sc)
        return out
    if spec.startswith("suite:"):  # one or more suite.json files, comma-separated: the best of them all
        entries = []
        for name in spec[6:].split(","):
            suite = json.loads(Path(name).read_text())
            entries += (suite.get("suite") or suite.get("scenarios") or []) if isinstance(suite, dict) else suite
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


def write_suite(args) -> int:
    """``--write-suite FILE``: the maps of ``--maps`` as a suite file (with their problem settings)
    for ``ambiegen rerun FILE --stack bringup ...``, which runs them on Nav2 now; never over a file."""
    overrides = problem_config(args.config)
    maps = pick_maps(args.maps, args.count, args.profile, args.seed, overrides)
    out = Path(args.write_suite)
    if out.exists():
        print(f"--write-suite: {out} exists (not overwritten)", file=sys.stderr)
        return 2
    settings = {**overrides, "profile": args.profile}
    doc = {"source": f"bench/nav2_maps.py --maps {args.maps} --count {args.count} --seed {args.seed}",
           "problem": "robot", "problem_config": settings, "suite": [{"scenario": sc.to_dict()} for sc in maps]}
    out.write_text(json.dumps(doc, indent=1) + "\n")
    print(f"{out}: {len(maps)} maps; run them: ambiegen rerun {out} --stack bringup --params NAV2_PARAMS.yaml "
          "--repeat 3 --results RESULTS.jsonl")
    return 0


# (label, k) batches this machine could not run on time, by their own logs rather than by a k = 1
# batch: MPPI at 2x missed its 40 Hz control loop 165 times and Jazzy's 20 ms behaviour-tree server
# timeout aborted goals before Nav2 planned (docs/external_sut.md, "Measured: Nav2's own verdicts")
HOST_LIMITED = {("small-mppi-jazzy-nav2-verdicts", 2.0), ("small-mppi-jazzy-frames-only", 2.0)}
# MPPI built here until this time (UTC) was compiled against Debian 12's xsimd 8.1.0 / xtensor 0.24.3,
# with which it integrates its sampled trajectories backwards (navigation2#4380, RoboStack/ros-jazzy#290):
# it reversed from every start, on an open map too. Rebuilt against xsimd 12.1.1 / xtensor 0.25.0
# (Ubuntu 24.04's, as Jazzy's binaries) it drives forward (docs/external_sut.md, "MPPI: the build").
MISBUILT_MPPI_UNTIL = "2026-11-27T11:15"
BUILD_NOTE = "MPPI misbuilt against xsimd 8.1.0: its trajectories ran backwards; our build's, not Nav2's"
HOST_NOTE = "beyond the time-scale limit: verdicts differ from real time, the host's, not Nav2's"


def not_nav2(rows: list[dict]) -> dict[tuple[str, float], str]:
    """(label, k) batches whose failures are not Nav2's, and why: the host's (``beyond_limit``) or
    an MPPI of our private build from before ``MISBUILT_MPPI_UNTIL``."""
    out = {key: HOST_NOTE for key in beyond_limit(rows)}
    for r in rows:
        if "MPPI" in str(r.get("controller")) and str(r.get("when", "")) < MISBUILT_MPPI_UNTIL:
            out[(r["label"], r["time_scale"])] = BUILD_NOTE
    return out


def beyond_limit(rows: list[dict]) -> set[tuple[str, float]]:
    """(label, k) batches run faster than real time whose verdicts differ from real time's on a
    map both ran (or named in ``HOST_LIMITED``): at that k the host could not keep Nav2's loops on time."""
    out = set(HOST_LIMITED)
    for r in rows:
        if r["time_scale"] != 1.0:
            base = [b for b in rows if b["label"] == r["label"] and b["time_scale"] == 1.0 and b["key"] == r["key"]]
            if base and base[0]["failure_kind"] != r["failure_kind"]:
                out.add((r["label"], r["time_scale"]))
    return out


def time_scale_check(rows: list[dict]) -> list[str]:
    """Per label run at several time scales: the verdicts at each k against real time (k = 1) on
    the same maps, and how far the simulated run times moved."""
    out = []
    for label in sorted({r["label"] for r in rows}):
        base = {r["key"]: r for r in rows if r["label"] == label and r["time_scale"] == 1.0}
        scales = sorted({r["time_scale"] for r in rows if r["label"] == label} - {1.0})
        if not base or not scales:
            continue
        out += ["", f"Time scale against real time, {label} (the same maps; Nav2's loop rates x k):", "",
                "| k | maps (also at k = 1) | same verdict | verdicts that differ | run time vs k = 1: median / "
                "largest difference |", "|---|---|---|---|---|"]
        for k in scales:
            pairs = [(base[r["key"]], r) for r in rows if r["label"] == label and r["time_scale"] == k
                     and r["key"] in base]
            same = [a["failure_kind"] == b["failure_kind"] for a, b in pairs]
            differ = "; ".join(f"{a['failure_kind']} -> {b['failure_kind']}" for (a, b), eq in zip(pairs, same)
                               if not eq) or "none"
            dt = [abs(float(b["time"]) - float(a["time"])) for a, b in pairs if a["time"] and b["time"]]
            move = f"{np.median(dt):.1f} s / {max(dt):.1f} s" if dt else "-"
            out.append(f"| {k:g} | {len(pairs)} | {sum(same)} | {differ} | {move} |")
    return out


def verdict_agreement(rows: list[dict]) -> list[str]:
    """Per batch that recorded them: the early verdicts (the paper's stall / loiter monitors) beside
    the verdicts given, and how often the two agree on pass or fail."""
    out = []
    batches = sorted({(r["label"], r["time_scale"]) for r in rows if r.get("early_verdict")})
    if not batches:
        return out
    out += ["", "Early verdicts (the paper's stall and loitering monitors) beside the verdicts given "
                "(Nav2's own unless the batch ran with early verdicts):", "",
            "| label | time scale | decided by | verdicts | early verdicts | agree (pass / fail) | early said fail, "
            "Nav2 passed | early said pass, Nav2 failed | early undecided |", "|---|---|---|---|---|---|---|---|---|"]
    for label, k in batches:
        batch = [r for r in rows if r["label"] == label and r["time_scale"] == k and r.get("early_verdict")]
        kinds = lambda key: ", ".join(f"{kd} {n}" for kd, n in Counter(r[key] for r in batch).most_common())  # noqa: E731
        decided = [r for r in batch if r["early_verdict"] != "undecided"]
        agree = sum((r["early_verdict"] == "none") == (r["failure_kind"] == "none") for r in decided)
        early_fail = sum(r["early_verdict"] != "none" and r["failure_kind"] == "none" for r in decided)
        early_pass = sum(r["early_verdict"] == "none" and r["failure_kind"] != "none" for r in decided)
        by = "early monitors" if batch[0].get("early_verdicts") else "Nav2"
        out.append(f"| {label} | {k:g} | {by} | {kinds('failure_kind')} | {kinds('early_verdict')} | {agree} of "
                   f"{len(decided)} | {early_fail} | {early_pass} | {len(batch) - len(decided)} |")
    return out


def failure_place(row: dict) -> tuple[float, float] | None:
    """Where a row's run failed; rows from before results carried their failure point: the last
    pose recorded stands in."""
    point = row["failure_point"] or (row["trajectory_every_10"] or [None])[-1]
    return tuple(point[:2]) if point else None


def known_facts(row: dict, problem) -> dict:
    """What a known-failure entry reads of a row: the plans counted, the clearance route and map
    side (recorded since issue 27; planned again for older rows), Nav2's error code and, on hazards
    scenarios, how far it failed from an unmapped box or post."""
    from ambiegen_ros.sims.known_failures import unmapped_obstacle_m

    scenario = problem.parse(row["scenario"])
    route, side = row.get("route_length_m"), row.get("map_side_m")
    if route is None:
        from ambiegen_ros.sims import reference
        from ambiegen_ros.sims.full_model import full_model_executor

        full = full_model_executor(problem)
        env = problem.environment(scenario)
        route = reference.before(problem, scenario, full.config).metrics["route_length_m"]
        side = float(max(env.grid.shape) * env.resolution)
    return {"plans": row.get("plans"), "route_length_m": route, "map_side_m": side,
            "nav2_error_code": row.get("nav2_error_code"),
            "unmapped_obstacle_m": unmapped_obstacle_m(problem, scenario, failure_place(row))}


def report(args) -> int:
    from ambiegen_ros.problems import get_problem
    from ambiegen_ros.sims import known_failures
    from ambiegen_ros.sims.outcome import Outcome
    from ambiegen_ros.sims.signature import DistinctFailures, signature

    rows = read_rows(RUNS)
    entries = known_failures.load(REPO / "config" / "nav2" / "known_failures.yaml")
    lines = ["# Nav2 on AmbieGen's maps (measured; appended by `bench/nav2_maps.py`)", "",
             "| label | time scale | maps | failures | rate | known (not counted) | distinct new (by place and kind) | "
             "kinds | failed without a plan | Nav2 results (error codes) | failures per hour of runs |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    failures, beyond = [], not_nav2(rows)
    everywhere = DistinctFailures()  # across the batches, for the pictures
    for (label, k), group in sorted(Counter((r["label"], r["time_scale"]) for r in rows).items()):
        batch = [r for r in rows if r["label"] == label and r["time_scale"] == k]
        failed = [r for r in batch if r["failed"]]
        distinct = DistinctFailures()
        problem = get_problem("robot", {**batch[0].get("problem_config", {}), "profile": batch[0]["profile"]})
        known = 0
        for r in failed:
            out = Outcome(objectives={}, failed=True, failure_kind=r["failure_kind"], detail=r["detail"],
                          failure_point=failure_place(r), metrics=known_facts(r, problem))
            if known_failures.mark(out, entries).metrics.get("known_failure"):
                known += 1  # recorded, never counted as a new distinct failure
                continue
            sig = signature(problem, None, out)
            if sig is not None:
                distinct.add(sig)
            # no picture of failures not Nav2's (the host's, our build's), nor of a run that
            # ended before the robot had a second of simulated time (nothing happened to draw)
            if (label, k) not in beyond and float(r.get("time") or 0.0) >= 1.0:
                failures.append((sig is not None and everywhere.add(sig), r, problem, out))
        hours = sum(r["wall_s"] for r in batch) / 3600.0
        kinds = ", ".join(f"{kd} {n}" for kd, n in Counter(r["failure_kind"] for r in batch).most_common())
        nav2 = ", ".join(f"{s} {n}" for s, n in Counter(f"{r['nav2_status']}"
                                                         + (f" ({r['nav2_error_code']})" if int(r["nav2_error_code"] or 0) else "")
                                                         for r in batch).most_common())
        counted = [r for r in failed if r.get("plans") is not None]  # rows from before plans were counted: "?"
        planless = f"{sum(int(r['plans']) == 0 for r in counted)}" + (f" of {len(counted)}" if len(counted) < len(failed)
                                                                        else "")
        mark = f" ({beyond[label, k]})" if (label, k) in beyond else ""
        lines.append(f"| {label}{mark} | {k:g} | {len(batch)} | {len(failed)} | {len(failed) / len(batch):.0%} | "
                     f"{known} | {len(distinct)} | {kinds} | {planless} | {nav2} | {len(failed) / hours if hours else 0:.1f} |")
    lines += ["", "Route lengths (the problem's A* length, F1) of the maps Nav2 failed and passed:", ""]
    for (label, k), _ in sorted(Counter((r["label"], r["time_scale"]) for r in rows).items()):
        batch = [r for r in rows if r["label"] == label and r["time_scale"] == k]
        problem = get_problem("robot", {**batch[0].get("problem_config", {}), "profile": batch[0]["profile"]})
        f1 = problem.evaluate_scenarios([problem.parse(r["scenario"]) for r in batch]).metrics["path_length"]
        span = lambda v: f"{len(v)} maps, {min(v):.0f}-{max(v):.0f} m" if len(v) else "none"  # noqa: E731
        lines.append(f"* {label} (time scale {k:g}): failed {span([x for x, r in zip(f1, batch) if r['failed']])}; "
                     f"passed {span([x for x, r in zip(f1, batch) if not r['failed']])}")
    lines += time_scale_check(rows)
    lines += verdict_agreement(rows)
    lines += ["", "Pictures: map, trajectory (coloured by time), Nav2's last plan, and where it failed.", ""]
    # three pictures: failures distinct across the batches first, then one of each batch not shown yet
    chosen = [f for f in failures if f[0]]
    for f in failures:
        if len(chosen) < 3 and f not in chosen and f[1]["label"] not in {c[1]["label"] for c in chosen}:
            chosen.append(f)
    chosen += [f for f in failures if f not in chosen]
    for i, (_, r, problem, out) in enumerate(chosen[:3]):
        path = draw_row(r, problem, out, RESULTS / f"failure_{i + 1}.png")
        lines.append(f"![{r['failure_kind']}]({path.name}) {r['label']}: {r['detail']}")
    (RESULTS / "README.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


def timed_path(r: dict) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """A row's path (every 10th odometry pose) and the simulated time of each pose: odometry comes
    at a fixed rate (50 Hz: (poses - 1) x 10 / time is 49.6-50.0 on every row measured), so the poses
    are spread evenly from 0 to the run's ``time``, and a picture's colour bar of seconds ends at
    the run's duration (not at the count of poses)."""
    traj = np.asarray(r["trajectory_every_10"] or [], dtype=float).reshape(-1, 2)
    return traj, {"t": np.linspace(0.0, float(r["time"] or 0.0), len(traj))}


def draw_row(r: dict, problem, out, path: Path) -> Path:
    """One row's run as a picture: the map, its path coloured by simulated time, Nav2's last plan
    (read from the row's bag, when it is on this machine) and where it failed."""
    from ambiegen_ros.ros.runlog import iter_messages
    from ambiegen_ros.viz.execution import save_execution_plot

    out.trajectory, out.timeline = timed_path(r)
    plan = None
    if Path(r["mcap"]).exists():
        for _, _, t, msg in iter_messages(r["mcap"], {"/plan"}):
            if r["wall_start_ns"] <= t <= r["wall_end_ns"]:
                plan = np.array([[q.pose.position.x, q.pose.position.y] for q in msg.poses])
    return save_execution_plot(problem, problem.parse(r["scenario"]), out, path, plan=plan,
                               system=f"Nav2 (time scale {r['time_scale']:g})")


def picture(spec: str) -> int:
    """``--picture LABEL:K:FILE``: the K-th failed run (0-based, in the order recorded) of the batch
    LABEL drawn to FILE, from ``runs.jsonl`` alone (a write-up's picture, redrawn without its bag)."""
    from ambiegen_ros.problems import get_problem
    from ambiegen_ros.sims.outcome import Outcome

    label, k, file = spec.split(":", 2)
    failed = [r for r in read_rows(RUNS) if r["label"] == label and r["failed"]]
    if not failed or int(k) >= len(failed):
        print(f"--picture: batch {label!r} has {len(failed)} failed runs", file=sys.stderr)
        return 2
    r = failed[int(k)]
    problem = get_problem("robot", {**r.get("problem_config", {}), "profile": r["profile"]})
    out = Outcome(objectives={}, failed=True, failure_kind=r["failure_kind"], detail=r["detail"],
                  failure_point=failure_place(r))
    print(draw_row(r, problem, out, Path(file)))
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--maps", default="random", help="random | suite:FILE[,FILE...]")
    ap.add_argument("--count", type=int, default=20)
    ap.add_argument("--profile", default="refined", choices=("replication", "refined"))
    ap.add_argument("--seed", type=int, default=3)
    ap.add_argument("--config", default="", metavar="FILE.yaml", help="problem_config of the maps (e.g. a nearer goal)")
    ap.add_argument("--write-suite", metavar="FILE.json", help="write the maps of --maps as a suite file for "
                    "`ambiegen rerun` (never over a file)")
    ap.add_argument("--report", action="store_true")
    ap.add_argument("--picture", metavar="LABEL:K:FILE", help="draw the K-th failed run of batch LABEL to FILE "
                    "(from runs.jsonl; Nav2's plan only when the row's bag is on this machine)")
    ap.add_argument("--results", default="", help="the JSONL file appended to (default: the committed one)")
    args = ap.parse_args(argv)
    if args.results:
        globals()["RUNS"] = Path(args.results).resolve()
    if args.picture:
        return picture(args.picture)
    if args.write_suite:
        return write_suite(args)
    return report(args) if args.report else ap.error("--report, --picture or --write-suite (runs: `ambiegen rerun`)")


if __name__ == "__main__":
    sys.exit(main())
