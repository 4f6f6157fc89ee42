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

from ambiegen_ros.run_config import load_config_file, _build_problem  # noqa: E402
from ambiegen_ros.sims.full_model import full_model_executor, scenario_seed  # noqa: E402


def average_ranks(x) -> np.ndarray:
    """1-based ranks with ties given their mean rank (scipy's ``rankdata``; numpy only, as scipy is optional)."""
    x = np.asarray(x, dtype=float)
    order = np.argsort(x, kind="mergesort")
    ranks = np.empty(len(x))
    sx = x[order]
    start = 0
    for end in range(1, len(x) + 1):
        if end == len(x) or sx[end] != sx[start]:
            ranks[order[start:end]] = 0.5 * (start + end - 1) + 1.0
            start = end
    return ranks


def spearman(x, y) -> float:
    """Spearman's rho (Pearson on average ranks); nan when either side is constant."""
    rx, ry = average_ranks(x), average_ranks(y)
    if rx.std() == 0 or ry.std() == 0:
        return float("nan")
    return float(np.corrcoef(rx, ry)[0, 1])


def roc_auc(score, label) -> float:
    """P(score of a random positive > that of a random negative), ties half (Mann-Whitney U / n1 n0)."""
    label = np.asarray(label, dtype=bool)
    n1, n0 = int(label.sum()), int((~label).sum())
    if n1 == 0 or n0 == 0:
        return float("nan")
    r = average_ranks(score)
    return float((r[label].sum() - n1 * (n1 + 1) / 2.0) / (n1 * n0))


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


def parse_sets(items) -> dict:
    """``key=value`` pairs, values read as JSON when they parse (numbers, true/false), else text."""
    out = {}
    for item in items or ():
        key, _, value = item.partition("=")
        try:
            out[key] = json.loads(value)
        except json.JSONDecodeError:
            out[key] = value
    return out


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
    file_cfg["problem_config"] = {**(file_cfg.get("problem_config") or {}), **parse_sets(args.set)}
    problem = _build_problem(args.problem, file_cfg, args.profile)
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
        "problem": problem.name, "tag": tag, "config_file": args.config, "overrides": parse_sets(args.set),
        "problem_config": {k: v for k, v in dataclasses.asdict(cfg).items()
                           if isinstance(v, (int, float, str, bool, type(None)))} if dataclasses.is_dataclass(cfg) else None,
        "n": int(len(X)), "seed": args.seed, "drawn": drawn, "alpha": problem.alpha,
        "spearman_f1_certified": spearman(f1, failed),
        "roc_auc_f1_certified": roc_auc(f1, failed),
        "spearman_f1_invalid_test": spearman(f1, invalid),
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
