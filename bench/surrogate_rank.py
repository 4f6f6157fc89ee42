"""Does the surrogate's F1 rank scenarios as the full model's certified verdict does? (issue 26)

Usage: python bench/surrogate_rank.py --problem thermostat [--config YAML] [--profile P] [--n 500]
       [--seed 2026] [--tag TAG] [--set key=value ...]

RQ3's executors take the highest surrogate F1 first, so what decides failures per hour is how well
F1 orders scenarios by the full model's *certified* verdict (failed, reference passed). This draws
N scenarios the surrogate calls valid (``problem.sample_rows`` / ``evaluate_rows``, seeded), runs
each on the full model (``full_model_executor(problem).execute``, with the run's reference checks;
seed of scenario k = ``scenario_seed(seed, k)``) and reports the Spearman rank correlation of F1
with the verdict (1 = ``outcome.failed``), the ROC AUC, the counts of certified failures / invalid
tests / passes, and the certified-failure and invalid-test rates among the top 10 % by F1.
Writes bench/results/surrogate_rank_<problem>_<tag>.json. Any problem with a full model.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import write_result  # noqa: E402

from ambiegen_ros.core.config import load_config_file  # noqa: E402
from ambiegen_ros.core.stats import roc_auc, spearman  # noqa: E402
from ambiegen_ros.problems import get_problem  # noqa: E402
from ambiegen_ros.sims.options import parse_options  # noqa: E402
from ambiegen_ros.sims.full_model import full_model_executor, scenario_seed  # noqa: E402


def valid_sample(problem, n: int, rng: np.random.Generator, batch: int = 256):
    """``n`` rows the surrogate calls valid, with their F1 and surrogate metrics, in sampling order."""
    rows, f1, metrics = [], [], {}
    drawn = 0
    while len(rows) < n:
        X = problem.sample_rows(batch, rng)
        ev = problem.evaluate_rows(X)
        drawn += len(X)
        for i in np.flatnonzero(ev.valid)[: n - len(rows)]:
            rows.append(X[i])
            f1.append(float(np.nan_to_num(ev.f1[i], nan=0.0)))
            for key, value in ev.metrics.items():
                metrics.setdefault(key, []).append(float(np.asarray(value)[i]))
        if drawn > 200 * max(n, 1) and not rows:
            raise SystemExit(f"no valid sample in {drawn} draws")
    return np.array(rows), np.array(f1), {k: np.array(v) for k, v in metrics.items()}, drawn


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--problem", required=True)
    ap.add_argument("--config", help="run config YAML (its problem_config is used)")
    ap.add_argument("--profile", help="replication | refined (wins over the file's)")
    ap.add_argument("--set", action="append", metavar="KEY=VALUE", help="problem_config override (repeatable)")
    ap.add_argument("--n", type=int, default=500)
    ap.add_argument("--seed", type=int, default=2026)
    ap.add_argument("--tag", default=None, help="result name suffix (default: profile + objective)")
    args = ap.parse_args(argv)

    file_cfg = dict(load_config_file(args.config)) if args.config else {}
    if file_cfg.get("problem") not in (None, args.problem):
        raise SystemExit(f"{args.config} is a config of {file_cfg['problem']!r}")
    problem_config = {**(file_cfg.get("problem_config") or {}), **parse_options(args.set)}
    if args.profile:
        problem_config["profile"] = args.profile
    problem = get_problem(args.problem, problem_config)
    cfg = problem.config
    tag = args.tag or "_".join(str(v) for v in (getattr(cfg, "profile", None), getattr(cfg, "objective", None)) if v)

    rng = np.random.default_rng(args.seed)
    t0 = time.perf_counter()
    X, f1, metrics, drawn = valid_sample(problem, args.n, rng)
    sample_s = time.perf_counter() - t0
    executor = full_model_executor(problem)
    kinds, failed = [], np.zeros(len(X), dtype=bool)
    t0 = time.perf_counter()
    for k, row in enumerate(X):
        out = executor.execute(problem.codec.from_row(row), seed=scenario_seed(args.seed, k))
        failed[k] = bool(out.failed)
        kinds.append(out.failure_kind)
    execute_s = time.perf_counter() - t0
    kinds_arr = np.array(kinds)
    invalid = kinds_arr == "invalid_test"
    rejected = kinds_arr == "invalid_scenario"
    top = np.argsort(-f1, kind="stable")[: max(1, math.ceil(0.1 * len(X)))]
    risky = f1 > problem.alpha
    figures = {
        "problem": problem.name, "tag": tag, "config_file": args.config, "overrides": parse_options(args.set),
        "problem_config": {k: v for k, v in dataclasses.asdict(cfg).items()
                           if isinstance(v, (int, float, str, bool, type(None)))} if dataclasses.is_dataclass(cfg) else None,
        "n": int(len(X)), "seed": args.seed, "drawn": drawn, "alpha": problem.alpha,
        "spearman_f1_certified": spearman(f1, failed)[0],
        "roc_auc_f1_certified": roc_auc(f1, failed),
        "spearman_f1_invalid_test": spearman(f1, invalid)[0],
        "certified_failures": int(failed.sum()), "invalid_tests": int(invalid.sum()),
        "rejected": int(rejected.sum()), "passes": int((~failed & ~invalid & ~rejected).sum()),
        "certified_rate": float(failed.mean()),
        "top10_n": int(len(top)), "top10_certified_rate": float(failed[top].mean()),
        "top10_invalid_test_rate": float(invalid[top].mean()),
        "risky_n": int(risky.sum()),
        "risky_certified_rate": float(failed[risky].mean()) if risky.any() else None,
        "risky_invalid_test_rate": float(invalid[risky].mean()) if risky.any() else None,
        "f1_percentiles": dict(zip(("p5", "p50", "p95", "max"), np.percentile(f1, [5, 50, 95, 100]).round(4).tolist())),
        "kinds": {k: int(v) for k, v in zip(*np.unique(kinds_arr, return_counts=True))},
        "sample_s": round(sample_s, 3), "execute_s": round(execute_s, 3),
    }
    path = write_result(f"surrogate_rank_{problem.name}_{tag}", figures)
    for key in ("tag", "n", "alpha", "spearman_f1_certified", "roc_auc_f1_certified", "spearman_f1_invalid_test",
                "certified_failures", "invalid_tests", "rejected", "passes", "top10_certified_rate",
                "top10_invalid_test_rate", "risky_n", "risky_certified_rate", "risky_invalid_test_rate"):
        value = figures[key]
        print(f"{key:28s} {value:.4f}" if isinstance(value, float) else f"{key:28s} {value}")
    print(f"wrote {path}")
    return figures


if __name__ == "__main__":
    main()
