"""Near misses on Nav2, from campaign bags (issue 29): where a stack got through only by its recoveries.

    python bench/nav2_near_misses.py --label mppi-restarts ~/nav2-bags/mppi-robot-nsga2-s1-*.mcap
    python bench/nav2_near_misses.py --label mppi-random ~/nav2-bags/mppi-robot-random-s1-*.mcap \\
        --plot docs/results/nav2/mppi_goal_approach.png --plot-from mppi-restarts,mppi-random

Nav2 fails a map only after its behaviour tree's recovery rounds have run out; a map it passes after
any recovery is a **near miss**, and where those cluster is where a search might push a stack over.
Bags since the sut_adapter records ``nav2_recoveries`` (the action feedback's count, which in
Jazzy counts costmap clearings as well as spins, waits and back-ups) say it directly. Older bags do
not, so for every bag the progress checker is also replayed on ``/odom``: Nav2's
``SimpleProgressChecker`` with its defaults in both stacks' params (the robot must move 0.5 m
within 10 s), counted from the goal, restarted each time it fires. A PASS on which it fires is a
**stall**; each firing fails FollowPath, and Nav2's tree answers with a recovery, so a stall is a
near miss. For each map also the **arrival turn**: how far the
robot must still turn at the goal, the angle between its direction of travel over the last 1.5 m
into the goal and the goal's yaw. And the **closest call with a person** (issue 59): how near the
driving robot's body came to a walking person (``person_gap``), so a stack that survived a search
can be shown at its closest; each bag's row lists its passes with the smallest gaps.

A bag may be a campaign's (one run) or a ``bench/nav2_maps.py`` batch's (a run per map, each map's
row then names its run). One JSON row per bag is appended to ``bench/results/nav2_near_misses.jsonl`` (never rewritten), with
every driven map's figures; ``--plot`` draws the arrival turns of the rows with the ``--plot-from``
labels, near misses marked, and the tracks of the near misses around the goal. ``--compare
mppi-restarts,mppi-random`` counts the stalls per map of two labels' bags from the results file
and tests the first against the second (one-sided Fisher exact test over maps).
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from _common import append_row, read_rows  # noqa: E402
OUT = REPO / "bench" / "results" / "nav2_near_misses.jsonl"
PROGRESS_RADIUS, PROGRESS_TIME = 0.5, 10.0  # SimpleProgressChecker: required_movement_radius, movement_time_allowance
ARRIVAL_FROM, ARRIVAL_TO = 1.5, 0.6  # m from the goal: the stretch whose direction of travel is the arrival


def progress_failures(poses: np.ndarray, t_goal: float = 0.0) -> int:
    """How often Nav2's progress checker would fire on these poses (rows t, x, y, ...), from the goal on."""
    rows = poses[poses[:, 0] >= t_goal]
    if not len(rows):
        return 0
    fired, anchor = 0, rows[0]
    for row in rows[1:]:
        if math.hypot(row[1] - anchor[1], row[2] - anchor[2]) > PROGRESS_RADIUS:
            anchor = row
        elif row[0] - anchor[0] > PROGRESS_TIME:
            fired, anchor = fired + 1, row
    return fired


def arrival_turn(poses: np.ndarray, goal: tuple[float, float], goal_yaw: float) -> float | None:
    """Degrees the robot must still turn at the goal: its direction of travel from ``ARRIVAL_FROM``
    to ``ARRIVAL_TO`` metres off the goal (the first time it gets there) against the goal's yaw."""
    d = np.hypot(poses[:, 1] - goal[0], poses[:, 2] - goal[1])
    if not (d < ARRIVAL_TO).any():
        return None
    last = int(np.argmax(d < ARRIVAL_TO))
    before = np.nonzero(d[:last] >= ARRIVAL_FROM)[0]
    first = int(before[-1]) if len(before) else 0
    heading = math.atan2(poses[last, 2] - poses[first, 2], poses[last, 1] - poses[first, 1])
    return abs(math.degrees((heading - goal_yaw + math.pi) % (2 * math.pi) - math.pi))


CLOSEST = 5  # passes listed per bag by their closest approach to a person
MOVING = 0.05  # m/s: a body slower than this is not driving at anyone (the world charges contacts from 0.01)


def person_gap(run, footprint: np.ndarray | None = None) -> dict | None:
    """The closest the robot's body came to a walking person while it drove (``run``: one
    ``robot_bag.RobotRun``): the gap [m] (<= 0: contact), when (s from the first
    pose) and the robot's speed then [m/s]. A person who walks into a robot standing still is left out:
    the robot could not have done anything, and the world does not charge it either.

    People are where the world's markers put them (``/ambiegen/world/markers``, sent with every scan),
    placed between two samples linearly at each ``/odom`` pose (they walk straight lines at a constant
    pace, so only a turn between two samples is cut); the body is the world's Pioneer outline, measured
    exactly against each disc. None: no person, no marker to place one, or the robot never moved."""
    from ambiegen_ros.sims.obstacles import Obstacles
    from ambiegen_ros.sims.robot_world import PIONEER2DX

    samples = [(t, m["people"]) for t, m in run.markers if len(m["people"])]
    if not samples or len({len(p) for _, p in samples}) != 1:
        return None  # none, or the count changed mid-run (a marker of another run): nothing to place
    ts = np.array([t for t, _ in samples])
    people = np.stack([p for _, p in samples])  # (S, M, 3)
    t, xy = run.poses[:, 0], run.poses[:, 1:3]
    lo, hi = np.maximum(np.arange(len(t)) - 2, 0), np.minimum(np.arange(len(t)) + 2, len(t) - 1)
    dt = t[hi] - t[lo]
    speed = np.where(dt > 0, np.hypot(*(xy[hi] - xy[lo]).T) / np.where(dt > 0, dt, 1.0), 0.0)
    keep = (t >= ts[0]) & (t <= ts[-1]) & (speed >= MOVING)
    poses, speed = run.poses[keep], speed[keep]
    if not len(poses):
        return None
    fp = PIONEER2DX if footprint is None else np.asarray(footprint, dtype=float)
    reach = float(np.hypot(fp[:, 0], fp[:, 1]).max())
    circles = np.stack([np.stack([np.interp(poses[:, 0], ts, people[:, k, c]) for c in range(3)], axis=1)
                        for k in range(people.shape[1])], axis=1)  # (N, M, 3) at the poses' stamps
    centre = np.hypot(circles[:, :, 0] - poses[:, 1:2], circles[:, :, 1] - poses[:, 2:3]) - circles[:, :, 2]
    bound = centre.min(axis=1) - reach  # the gap is at least this: only the nearest poses are measured
    best, k_best = math.inf, 0
    for k in np.argsort(bound):
        if bound[k] >= best:
            break
        gap = Obstacles(posts=circles[k]).body_clearance(*poses[k, 1:4], fp, 0.0)[0]  # the discs, frozen there
        if gap < best:
            best, k_best = gap, int(k)
    return {"person_gap_m": round(float(best), 3), "person_gap_t": round(float(poses[k_best, 0]), 2),
            "robot_speed_mps": round(float(speed[k_best]), 2)}


def bag_rows(path: Path) -> list[dict]:
    from ambiegen_ros.core.errors import BadInput
    from ambiegen_ros.ros.conversions import yaw_of
    from ambiegen_ros.ros.robot_bag import read_index, read_run

    index = read_index(path)
    rows = []
    for logged in index.runs:  # a campaign's bag holds one run; a nav2_maps.py batch's, a run per map
        shown = index.select(logged)
        for sid, entry in shown.entries.items():
            outcome = entry.outcome
            if outcome is None or outcome.failure_kind in ("invalid_scenario", "invalid_test"):
                continue
            try:
                run = read_run(shown, sid)
            except BadInput:
                continue
            rows.append(map_row(run, yaw_of(shown.scenario_msgs[sid].goal.pose.orientation),
                                several=len(index.runs) > 1))
    return rows


def map_row(run, goal_yaw: float, several: bool) -> dict:
    """One driven map's figures (``run``: its streams, ``robot_bag.RobotRun``); its run's id when the bag has several."""
    from ambiegen_ros.sims.outcome import NAV2_RECOVERIES, near_miss

    outcome = run.entry.outcome
    recorded = outcome.metrics.get(NAV2_RECOVERIES)
    fired = progress_failures(run.poses, run.t_goal)
    turn = arrival_turn(run.poses, run.goal, goal_yaw)
    stalled = not outcome.failed and fired > 0
    close = np.hypot(run.poses[:, 1] - run.goal[0], run.poses[:, 2] - run.goal[1]) < 2.0
    return {**({"run": run.run_id} if several else {}), "scenario": run.entry.scenario_id,
            "verdict": outcome.verdict, "failed": outcome.failed,
            "time": outcome.metrics.get("time"), "nav2_recoveries": recorded,
            "progress_failures_replayed": fired, "stalled": stalled,
            "near_miss": None if recorded is None else near_miss(outcome.failure_kind, recorded),
            "arrival_turn_deg": None if turn is None else round(turn, 1),
            "goal": list(run.goal), **(person_gap(run) or {}),
            "track_near_goal": run.poses[close][::10, 1:3].round(2).tolist() if stalled else None}


def turned_away(m: dict) -> bool:
    """The route arrives more than 100 degrees off the goal's yaw: where MPPI's near misses lie."""
    return (m["arrival_turn_deg"] or 0.0) > 100.0


def summary(maps: list[dict]) -> dict:
    turned = [m for m in maps if turned_away(m)]
    recorded = [m["near_miss"] for m in maps if m["near_miss"] is not None]
    passes = sorted((m for m in maps if not m["failed"] and m.get("person_gap_m") is not None),
                    key=lambda m: m["person_gap_m"])
    touched = [m for m in passes if m["person_gap_m"] <= 0.0]  # a person walked into it: the world charges nothing
    return {"maps": len(maps), "failures": sum(m["failed"] for m in maps), "stalls": sum(m["stalled"] for m in maps),
            "near_misses": sum(recorded) if recorded else None,
            "arrival_turn_over_100": len(turned), "stalls_there": sum(m["stalled"] for m in turned),
            # passes on which a person touched the driving robot, not by its doing (a side or the back)
            "passes_touched_by_a_person": [m["scenario"] for m in touched],
            # the passes on which the driving robot came nearest a person without a touch (person_gap)
            "closest_person_passes": [{k: m[k] for k in ("scenario", "person_gap_m", "person_gap_t", "robot_speed_mps")}
                                      for m in passes[len(touched):len(touched) + CLOSEST]]}


def results() -> list[dict]:
    """Every row of the results file, oldest first."""
    return read_rows(OUT)


def compare(rows: list[dict], label: str, baseline: str) -> dict:
    """Stalls per map, ``label``'s bags against ``baseline``'s, with a one-sided Fisher exact test.

    A bag counts once (its newest row), so reading a bag again does not double its maps. Maps of one
    campaign are not independent draws: the test over maps is a hint; the per-bag counts say more."""
    from scipy.stats import fisher_exact

    newest = {(r["label"], r["bag"]): r for r in rows}  # file order: a later row replaces an earlier one
    sides = {}
    for name in (label, baseline):
        bags = [r for (lab, _), r in newest.items() if lab == name]
        if not bags:
            raise SystemExit(f"no rows labelled {name!r} in {OUT.name}")
        maps = [m for r in bags for m in r["maps"]]
        sides[name] = {"bags": len(bags), "maps": len(maps), "stalls": sum(bool(m["stalled"]) for m in maps),
                       "stalls_per_bag": [sum(bool(m["stalled"]) for m in r["maps"]) for r in bags],
                       "arrival_turn_over_100": sum(turned_away(m) for m in maps)}
    a, b = sides[label], sides[baseline]
    p = fisher_exact([[a["stalls"], a["maps"] - a["stalls"]], [b["stalls"], b["maps"] - b["stalls"]]],
                     alternative="greater").pvalue
    return {label: a, baseline: b, "fisher_p_greater": round(float(p), 4)}


def plot(rows: list[dict], labels: list[str], out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax, bx) = plt.subplots(1, 2, figsize=(11, 4.5))
    for k, label in enumerate(labels):
        maps = [m for r in rows if r["label"] == label for m in r["maps"] if m["arrival_turn_deg"] is not None]
        jitter = np.random.default_rng(k).uniform(-0.15, 0.15, len(maps))
        for m, j in zip(maps, jitter):
            style = dict(color="tab:red", marker="x", s=40) if m["stalled"] else dict(color="tab:blue", marker="o",
                                                                                          s=12, alpha=0.5)
            ax.scatter(m["arrival_turn_deg"], k + j, **style)
    ax.axvline(100.0, color="grey", linestyle=":")
    ax.set_yticks(range(len(labels)), labels)
    ax.set_xlabel("turn still needed at the goal [deg] (direction of travel against the goal's yaw)")
    ax.set_title("stalled, then passed (x); passed clean (o)")
    for r in rows:
        if r["label"] not in labels:
            continue
        for m in r["maps"]:
            if m["stalled"] and m["track_near_goal"]:
                track = np.array(m["track_near_goal"]) - np.array(m["goal"])
                bx.plot(track[:, 0], track[:, 1], color="tab:red", alpha=0.6)
                bx.scatter(track[-1, 0], track[-1, 1], color="tab:red", s=8)
    bx.add_patch(plt.Circle((0, 0), 0.25, fill=False, color="green", label="xy goal tolerance 0.25 m"))
    bx.annotate("", xy=(0.6, 0), xytext=(0, 0), arrowprops=dict(arrowstyle="->", color="green"))
    bx.set_aspect("equal")
    bx.set_xlim(-2, 2)
    bx.set_ylim(-2, 2)
    bx.set_xlabel("x - goal [m]")
    bx.set_ylabel("y - goal [m]")
    bx.set_title("stalls: tracks within 2 m of the goal (arrow: goal yaw)")
    bx.legend(loc="lower left", fontsize=8)
    fig.tight_layout()
    fig.savefig(out, dpi=100)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("bags", nargs="*", type=Path, help="robot bags with /odom: a campaign's, or a nav2_maps.py batch's")
    ap.add_argument("--label", default="", help="a name for these bags' rows (for --plot-from)")
    ap.add_argument("--plot", type=Path, help="draw the rows of the --plot-from labels here (PNG; not overwritten)")
    ap.add_argument("--plot-from", default="", help="comma-separated labels of rows in the results file")
    ap.add_argument("--compare", metavar="LABEL,BASELINE",
                    help="stalls per map of LABEL's bags against BASELINE's (one-sided Fisher exact test)")
    args = ap.parse_args(argv)
    from ambiegen_ros.core.runs import versions

    for bag in args.bags:
        maps = bag_rows(bag)
        row = {"label": args.label, "bag": bag.name, **summary(maps), "maps": maps,
               "when": datetime.now(timezone.utc).isoformat(timespec="seconds"), "versions": versions()}
        append_row(OUT, row)
        print(json.dumps({k: row[k] for k in ("label", "bag", "failures", "stalls", "near_misses",
                                              "arrival_turn_over_100", "stalls_there", "passes_touched_by_a_person",
                                              "closest_person_passes")}
                         | {"maps": len(maps)}))
    if args.compare:
        label, _, baseline = args.compare.partition(",")
        print(json.dumps(compare(results(), label, baseline)))
    if args.plot:
        if args.plot.exists():
            raise SystemExit(f"{args.plot} exists: not overwritten (remove it first)")
        plot(results(), [s for s in args.plot_from.split(",") if s], args.plot)
        print(args.plot)
    return 0


if __name__ == "__main__":
    sys.exit(main())
