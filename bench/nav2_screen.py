"""How well does a cheap score predict Nav2's verdicts on hazards scenarios? (issue 49)

Usage: python bench/nav2_screen.py [--runs docs/results/nav2/runs.jsonl] [--mcap BAG ...]
       [--config config/robot_hazards.yaml] [--speed 0.5] [--tag TAG]

A search screens candidates on something cheap and spends Nav2 hours only on the best, so the
screen is worth what its ranking of Nav2's verdicts is worth. This takes every hazards scenario
Nav2 has executed (rows of ``nav2_maps.py``'s runs file whose problem is ``scenario: hazards``, and
any campaign bag given with ``--mcap``; invalid scenarios and invalid tests left out), computes the
screen's numbers for it (``RobotProblem.hazard_features``: the threat score the search climbs and
its parts), and prints the ROC AUC of each against three verdicts: a new certified failure (known
failures not counted), any certified failure, and a failure or a near miss (a pass that needed
Nav2's recoveries). AUC 0.5 is a coin, 1.0 ranks every failure above every pass; NaN when a class is
empty. The AUC within each batch that holds both verdicts is printed too: pooled over batches, it
also credits whatever made a search pick its batch. Writes bench/results/nav2_screen[_TAG].json.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import write_result  # noqa: E402

import numpy as np  # noqa: E402

from ambiegen_ros.core.config import load_config_file  # noqa: E402
from ambiegen_ros.core.stats import roc_auc  # noqa: E402
from ambiegen_ros.problems import get_problem  # noqa: E402
from ambiegen_ros.sims.outcome import NAV2_RECOVERIES, near_miss  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
NOT_RUN = ("invalid_scenario", "invalid_test")
KNOWN = REPO / "config" / "nav2" / "known_failures.yaml"
# the screen's numbers, signed so that higher means "more likely to fail"
SCORES = {"threat": 1.0, "static_gap_m": -1.0, "person_meet_s": -1.0, "goal_turn_rad": 1.0, "start_turn_rad": 1.0,
          "person_approach_mps": 1.0, "block": 1.0, "person_block_s": 1.0}


def pace(facts: dict) -> float | None:
    """The stack's pace on a pass (m/s: the clearance route's length over the run's time); None on
    a failure. Recoveries are left in; ``main`` takes the passes without them."""
    try:
        return float(facts["route_length_m"]) / float(facts["time"]) if facts["failure_kind"] == "none" else None
    except (KeyError, TypeError, ValueError, ZeroDivisionError):
        return None


def from_runs(path: Path) -> list[dict]:
    """Hazards rows of a runs file: the scenario, its problem config, its verdict."""
    out = []
    for line in path.read_text().splitlines():
        r = json.loads(line)
        cfg = r.get("problem_config") or {}
        if cfg.get("scenario") != "hazards" or r.get("failure_kind") in NOT_RUN:
            continue
        out.append({"source": r["label"], "problem_config": cfg, "scenario": r["scenario"], "failed": bool(r["failed"]),
                    "kind": r["failure_kind"], "known": bool(r.get("known_failure")), "row": r,
                    "recoveries": int(r.get("nav2_recoveries") or 0), "pace": pace(r)})
    return out


def known_today(problem, row: dict, entries: list) -> bool:
    """Whether a failure recorded before today's known failures would match one of them, with the
    evidence ``sut_adapter`` records now (``nav2_maps.known_facts``)."""
    from ambiegen_ros.sims import known_failures
    from ambiegen_ros.sims.outcome import Outcome
    from nav2_maps import known_facts

    outcome = Outcome(objectives={}, failed=True, failure_kind=row["failure_kind"], detail="",
                      metrics=known_facts(row, problem))
    return known_failures.is_known(known_failures.mark(outcome, entries))


def from_bag(path: Path, problem_config: dict) -> list[dict]:
    """Executed scenarios of one campaign bag, with the run config's problem settings."""
    from ambiegen_ros.nodes.replay import recorded_scenarios

    rec = recorded_scenarios(path)
    out = []
    for sid, o in sorted(rec.outcomes.items()):
        if o.failure_kind in NOT_RUN or sid not in rec.scenarios:
            continue
        sc = rec.scenarios[sid]
        out.append({"source": path.name, "problem_config": problem_config,
                    "scenario": {"problem": sc.problem, "elements": sc.elements}, "failed": bool(o.failed),
                    "kind": o.failure_kind, "known": bool(o.metrics.get("known_failure")),
                    "recoveries": int(o.metrics.get(NAV2_RECOVERIES) or 0),
                    "pace": pace({"failure_kind": o.failure_kind, **o.metrics})})
    return out


def from_regenerated(spec: str, verdict_rows: list[dict], readings: dict) -> list[dict]:
    """``REGEN.mcap,NAV2_BAG,CONFIG``: the scenarios of a Nav2 campaign whose bag is gone, regenerated
    from its seed (``ambiegen campaign`` with the same algorithm, mode, config and seed, sim-model
    surrogate: the same scenarios under the same ids), joined with that Nav2 bag's verdicts as
    ``nav2_near_misses.py`` recorded them (its row for NAV2_BAG). Each scenario's goal must equal the
    goal Nav2 was sent, or nothing is returned. ``readings``: {NAV2_BAG: {id: known | ours | setting}},
    failures read by hand: known = a known failure; ours (our machine) and setting (our stack's
    setting) are not verdicts on the stack and are left out."""
    from ambiegen_ros.nodes.replay import recorded_scenarios

    regen, nav2_bag, config = spec.split(",")
    row = next((r for r in verdict_rows if r["bag"] == nav2_bag), None)
    if row is None:
        raise SystemExit(f"--regenerated: no verdicts recorded for {nav2_bag}")
    cfg = load_config_file(REPO / config).get("problem_config") or {}
    problem = get_problem("robot", cfg)
    rec = recorded_scenarios(Path(regen))
    read = {int(k): v for k, v in (readings.get(nav2_bag) or {}).items()}
    out = []
    for m in row["maps"]:
        sid = int(m["scenario"])
        sc = rec.scenarios.get(sid)
        env = None if sc is None else problem.environment(problem.parse({"problem": sc.problem, "elements": sc.elements}))
        if env is None or not np.allclose((np.asarray(env.goal, float) + 0.5) * env.resolution, m["goal"], atol=0.05):
            raise SystemExit(f"--regenerated: {regen} scenario {sid} is not the one {nav2_bag} ran (its goal differs)")
        if read.get(sid) in ("ours", "setting"):
            continue
        kind = m["verdict"][5:-1] if m["verdict"].startswith("FAIL(") else "none"
        out.append({"source": nav2_bag, "problem_config": cfg, "scenario": {"problem": sc.problem, "elements": sc.elements},
                    "failed": bool(m["failed"]), "kind": kind, "known": read.get(sid) == "known",
                    "recoveries": int(m.get("nav2_recoveries") or 0), "pace": None})
    return out


def scored(rows: list[dict], speed: float = 0.5) -> list[dict]:
    from ambiegen_ros.sims import known_failures

    entries = known_failures.load(KNOWN)
    problems: dict[str, object] = {}
    for r in rows:
        key = json.dumps(r["problem_config"], sort_keys=True)
        p = problems.setdefault(key, get_problem("robot", r["problem_config"]))
        scenario = p.parse(r["scenario"])
        r["features"] = p.hazard_features(scenario, speed)
        if r["failed"] and not r["known"] and "row" in r:
            r["known"] = known_today(p, r["row"], entries)
        r.pop("row", None)
    return rows


def aucs(rows: list[dict]) -> dict:
    verdicts = {
        "new_certified_failure": [r["failed"] and not r["known"] for r in rows],
        "certified_failure": [r["failed"] for r in rows],
        "failure_or_near_miss": [r["failed"] or near_miss(r["kind"], r["recoveries"]) for r in rows],
    }
    out = {}
    for verdict, label in verdicts.items():
        out[verdict] = {"positives": int(sum(label))}
        for name, sign in SCORES.items():
            score = [sign * float(r["features"].get(name, math.nan)) for r in rows]  # inf: no such hazard
            score = [-math.inf if math.isnan(s) else s for s in score]
            out[verdict][name] = round(float(roc_auc(score, label)), 3)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=Path, default=REPO / "docs" / "results" / "nav2" / "runs.jsonl")
    ap.add_argument("--mcap", type=Path, nargs="*", default=[], help="campaign bags of hazards scenarios")
    ap.add_argument("--config", default="config/robot_hazards.yaml", help="the bags' run config (problem settings)")
    ap.add_argument("--speed", type=float, default=0.5,
                    help="the robot's pace (m/s) at which people meet it (0.5: the threat score's; MPPI's "
                         "measured median on hazards passes: 0.39, printed)")
    ap.add_argument("--regenerated", nargs="*", default=[], metavar="REGEN.mcap,NAV2_BAG,CONFIG",
                    help="a campaign whose bag is gone: its scenarios regenerated from its seed, its verdicts "
                         "from --verdicts (checked scenario by scenario by the goal Nav2 was sent)")
    ap.add_argument("--verdicts", type=Path, default=REPO / "bench" / "results" / "nav2_near_misses.jsonl",
                    help="nav2_near_misses.py's rows: each bag's verdicts, for --regenerated")
    ap.add_argument("--readings", type=Path, default=None,
                    help="JSON {NAV2_BAG: {scenario id: known | ours | setting}}: failures read by hand "
                         "(e.g. docs/results/nav2/hardened/readings.json)")
    ap.add_argument("--tag", default="")
    args = ap.parse_args(argv)
    rows = from_runs(args.runs) if args.runs.is_file() else []
    cfg = load_config_file(REPO / args.config).get("problem_config") or {}
    for bag in args.mcap:
        rows += from_bag(bag, dict(cfg))
    if args.regenerated:
        verdict_rows = [json.loads(line) for line in args.verdicts.read_text().splitlines() if line.strip()]
        readings = json.loads(args.readings.read_text()) if args.readings else {}
        for spec in args.regenerated:
            rows += from_regenerated(spec, verdict_rows, readings)
    if not rows:
        print("no executed hazards scenario found", file=sys.stderr)
        return 1
    rows = scored(rows, args.speed)
    paces = [r["pace"] for r in rows if r["pace"] and not r["recoveries"]]
    figures = {"speed": args.speed, "scenarios": len(rows), "by_source": dict(Counter(r["source"] for r in rows)),
               "known_failures": sum(r["known"] for r in rows),
               "kinds": dict(Counter(r["kind"] for r in rows)), "auc": aucs(rows),
               # the pace at which people really meet the stack (--speed): passes without recoveries
               "pace_mps_p10_p50_p90": [round(float(v), 3) for v in np.percentile(paces, [10, 50, 90])] if paces else None,
               "pace_runs": len(paces),
               # within one batch: a batch a search picked differs from a random one in more than the
               # score, so the pooled AUC also credits the choice of batch
               "auc_within": {src: aucs([r for r in rows if r["source"] == src])["new_certified_failure"]
                              for src in sorted({r["source"] for r in rows})
                              if 0 < sum(r["failed"] and not r["known"] for r in rows if r["source"] == src)
                              < sum(r["source"] == src for r in rows)},
               "scores": "higher = riskier: threat, -static_gap_m, -person_meet_s, goal_turn_rad, start_turn_rad, person_approach_mps"}
    print(f"{len(rows)} executed hazards scenarios: {figures['by_source']}; verdicts {figures['kinds']}")
    print(f"pace of passes without recoveries ({len(paces)} runs), 10th/50th/90th percentile: "
          f"{figures['pace_mps_p10_p50_p90']} m/s")
    for verdict, row in figures["auc"].items():
        print(f"ROC AUC against {verdict} ({row['positives']} positives): "
              + ", ".join(f"{k} {v}" for k, v in row.items() if k != "positives"))
    for src, row in figures["auc_within"].items():
        print(f"  within {src} ({row['positives']} positives): "
              + ", ".join(f"{k} {v}" for k, v in row.items() if k != "positives"))
    path = write_result("nav2_screen" + (f"_{args.tag}" if args.tag else ""), figures)
    print(f"written: {path.relative_to(REPO)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
