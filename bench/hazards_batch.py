"""Random hazards scenarios (issue 48) on the in-process full model: what the ND robot fails on.

Usage: python bench/hazards_batch.py [--count 120] [--seed 11] [--config config/robot_hazards.yaml]

Draws ``--count`` random scenarios of the config's problem (seeded), executes the valid ones on the
full model with its reference checks (simulator seed 1) and counts the verdicts by kind, with each
failure's detail and reference. The ND stack behind ``sut_adapter`` gives the same verdicts to the
bit (test/ros/test_hazards_stack.py). Writes bench/results/hazards_batch.json.
"""
from __future__ import annotations

import argparse
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from bench._common import write_result  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--count", type=int, default=120)
    ap.add_argument("--seed", type=int, default=11)
    ap.add_argument("--config", default=str(REPO / "config" / "robot_hazards.yaml"))
    args = ap.parse_args(argv)
    from ambiegen_ros.run_config import make_run
    from ambiegen_ros.sims.full_model import full_model_executor

    problem = make_run("robot", args.config, seed=0)[0]
    X = problem.sample_rows(args.count, np.random.default_rng(args.seed))
    ev = problem.evaluate_rows(X)
    reasons = Counter(r.split(" lies")[0].split(" stands")[0].split(" has")[0] for r in ev.reasons if r)
    full = full_model_executor(problem)
    rows, t0 = [], time.perf_counter()
    for i in np.flatnonzero(ev.valid):
        sc = problem.codec.from_row(X[i])
        out = full.execute(sc, seed=1)
        rows.append({"sample": int(i), "verdict": out.verdict, "detail": out.detail, "reference": out.reference,
                     "contacts_not_at_fault": out.metrics.get("contacts_not_at_fault"),
                     "hazards": {k: int(ev.metrics[k][i]) for k in ("boxes", "posts", "people")}})
        print(f"{i}: {out.verdict} {out.detail[:90]}", flush=True)
    kinds = Counter(r["verdict"].split("(")[0] if r["verdict"] == "PASS" else r["verdict"] for r in rows)
    figures = {"count": args.count, "seed": args.seed, "config": str(Path(args.config).relative_to(REPO))
               if Path(args.config).is_relative_to(REPO) else args.config,
               "valid": int(ev.valid.sum()), "invalid_reasons": dict(reasons), "verdicts": dict(kinds),
               "certified_failures": sum(1 for r in rows if r["verdict"].startswith("FAIL")),
               "invalid_tests": sum(1 for r in rows if r["verdict"].startswith("INVALID_TEST")),
               "seconds": round(time.perf_counter() - t0, 1), "runs": rows}
    print({k: v for k, v in figures.items() if k != "runs"})
    print(f"wrote {write_result('hazards_batch', figures)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
