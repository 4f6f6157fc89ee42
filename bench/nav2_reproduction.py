"""How often each reported Nav2 failure reproduces, from the rows of ``ambiegen rerun`` (issue 56).

    python bench/nav2_reproduction.py RESULTS.jsonl[+MORE.jsonl] --label jazzy SUITE.json [SUITE.json ...] [--tag TAG]

Per scenario of the suites: the runs on ``--label``, the failures by kind (k of n), and the mechanism
of each failure (a collision with a person, a wall contact, Nav2 giving up). Then the distinct-failure
count as our campaigns count it (``sims.signature``: kind and place within 2 m), over every scenario,
and over those that reproduce in at least 2 of 3 of their runs (k/n >= 2/3); and for every collision
with a person, the robot's speed and both speeds along the line of contact, and how many collisions
(and scenarios) a threshold of 0.1 m/s on the robot's speed would no longer charge. Prints a markdown
table and writes ``bench/results/nav2_reproduction[_TAG].json``.
"""
from __future__ import annotations

import argparse
import json
import sys
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import write_result  # noqa: E402

BAR = 2 / 3
THRESHOLD = 0.1


def mechanism(row: dict) -> str:
    """What the stack did, as an engineer would file it."""
    kind, detail = row["failure_kind"], row.get("detail") or ""
    if kind == "collision":
        return "person" if "drove into person" in detail else "wall"
    return {"nav2_aborted": "gave up"}.get(kind, kind)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("results", help="a results file of rerun/compare; several joined with +")
    ap.add_argument("suite", nargs="+")
    ap.add_argument("--label", default="jazzy")
    ap.add_argument("--config", default=None)
    ap.add_argument("--tag", default="")
    args = ap.parse_args(argv)

    from ambiegen_ros.sims.outcome import Outcome
    from ambiegen_ros.sims.signature import DistinctFailures, signature
    from ambiegen_ros.trials.rows import counted, rows_of
    from ambiegen_ros.trials.suite import load_suite, problem_of

    suite = load_suite(args.suite, args.config)
    problem = problem_of(suite)
    names = suite.names()
    rows = [r for path in args.results.split("+") for r in rows_of(path, [args.label], set(names)) if counted(r)]
    every, reproducing = DistinctFailures(), DistinctFailures()
    table, per = [], {}
    hits = []
    for key, name in names.items():
        mine = [r for r in rows if r["key"] == key]
        failed = [r for r in mine if r["failed"]]
        kinds = Counter(mechanism(r) for r in failed)
        n, k = len(mine), len(failed)
        reproduces = bool(n) and k / n >= BAR - 1e-9
        first = failed[0] if failed else None
        if first is not None:
            out = Outcome(objectives={}, failed=True, failure_kind=first["failure_kind"],
                          failure_point=tuple(first["failure_point"][:2]) if first.get("failure_point") else None)
            sig = signature(problem, None, out)
            every.add(sig)
            if reproduces:
                reproducing.add(sig)
        for r in failed:
            if r.get("contact"):
                hits.append((name, r["contact"]))
        speeds = [abs(r["contact"]["robot_mps"]) for r in failed if r.get("contact")]
        per[name] = {"runs": n, "failures": k, "kinds": dict(kinds), "reproduces": reproduces,
                     "robot_mps": speeds}
        table.append(f"| {name} | {k} of {n} | " + (", ".join(f"{m} {c}" for m, c in kinds.most_common()) or "-")
                     + f" | {'yes' if reproduces else 'no'} | " + (", ".join(f"{v:.2f}" for v in speeds) or "-") + " |")
    slow = [(name, c) for name, c in hits if abs(c["robot_mps"]) <= THRESHOLD]
    slow_scenarios = {name for name, _ in slow}
    only_slow = sorted(name for name in slow_scenarios
                       if all(abs(c["robot_mps"]) <= THRESHOLD for m, c in hits if m == name)
                       and per[name]["failures"] == sum(1 for m, _ in hits if m == name))
    figures = {
        "label": args.label, "results": args.results, "suites": args.suite, "bar": BAR,
        "scenarios": len(names), "runs": len(rows),
        "scenarios_failing_at_least_once": sum(p["failures"] > 0 for p in per.values()),
        "scenarios_reproducing": sum(p["reproduces"] for p in per.values()),
        "distinct_all": len(every), "distinct_reproducing": len(reproducing),
        "collisions_with_people": len(hits), "collisions_at_or_below_0.1": len(slow),
        "scenarios_whose_every_failure_is_at_or_below_0.1": only_slow,
        "per_scenario": per,
    }
    print("| scenario | failed (k of n) | what Nav2 did | reproduces (k/n >= 2/3) | robot speed at each contact, m/s |")
    print("|---|---|---|---|---|")
    print("\n".join(table))
    print(json.dumps({k: v for k, v in figures.items() if k != "per_scenario"}, indent=1))
    print(f"written: {write_result('nav2_reproduction' + (f'_{args.tag}' if args.tag else ''), figures)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
