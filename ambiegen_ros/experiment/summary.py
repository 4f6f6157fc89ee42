"""The experiment's tables: results.csv, checkpoints.csv, stats.json, then report.md and plots.

Everything here is computed from the run files alone, so ``--resume`` and a finished experiment
write the same tables.
"""
from __future__ import annotations

import csv
import json
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np

from ..core.stats import compare, spearman
from .records import write_atomic
from .report import report

CHECKPOINTS = 10
SURROGATE_METRICS = ("best_f1", "diversity")
FULL_MODEL_METRICS = ("distinct_per_hour", "failures_per_hour", "distinct_failures", "failures", "invalid_tests",
                      "failure_rate", "executions", "best_f1", "diversity")
BASE_COLUMNS = ("problem", "profile", "algorithm", "run", "seed", "evaluations", "wall_s", "best_f1", "diversity")
FULL_MODEL_COLUMNS = ("executions", "failures", "distinct_failures", "invalid_tests", "screened_out", "failures_per_hour",
                      "distinct_per_hour", "failure_rate", "rejected", "overrun_discarded", "execution_cost_s",
                      "executors", "search_steps", "search_s", "execution_s", "charged_s", "waited_s", "random_fill",
                      "first_failure_s", "failure_kinds")


def _ordered(records: list[dict], algorithms: list[str]) -> list[dict]:
    rank = {a: i for i, a in enumerate(algorithms)}
    return sorted(records, key=lambda r: (rank.get(r["algorithm"], len(rank)), r["run"]))


def checkpoint_table(records: list[dict], identity: dict[str, Any]) -> list[dict[str, Any]]:
    """Best F1 at CHECKPOINTS evenly spaced points of the budget (evaluations, or seconds with a
    time budget), from each run's history: the data of the paper's convergence boxplots."""
    rows = []
    for rec in records:
        hist = rec.get("history")
        if not hist or not hist["best_f1"]:
            continue
        s = identity["settings"][rec["algorithm"]]
        by_time = s.get("evaluations") is None
        axis = np.asarray(hist["elapsed_s" if by_time else "evaluations"], dtype=float)
        best = np.asarray(hist["best_f1"], dtype=float)
        total = float(s["time_budget"] if by_time else s["evaluations"])
        for c in range(1, CHECKPOINTS + 1):
            mark = total * c / CHECKPOINTS
            idx = np.searchsorted(axis, mark + 1e-9, side="right") - 1
            rows.append({"algorithm": rec["algorithm"], "run": rec["run"], "axis": "seconds" if by_time else "evaluations",
                         "checkpoint": round(mark, 3), "best_f1": float(best[idx]) if idx >= 0 else None})
    return rows


def statistics(records: list[dict], algorithms: list[str], metrics: tuple[str, ...]) -> list[dict[str, Any]]:
    values = {a: {m: [r.get(m) for r in records if r["algorithm"] == a] for m in metrics} for a in algorithms}
    tests = []
    for metric in metrics:
        for i, a in enumerate(algorithms):
            for b in algorithms[i + 1:]:
                tests.append(compare(metric, a, values[a][metric], b, values[b][metric]))
    return tests


def correlations(records: list[dict]) -> list[dict[str, Any]]:
    """Spearman of surrogate F1 with each full-model number, pooled per algorithm and over all."""
    groups: dict[str, list[dict]] = {"all": records}
    for rec in records:
        groups.setdefault(rec["algorithm"], []).append(rec)
    rows = []
    for group, recs in groups.items():
        samples = [rec.get("sample") or {} for rec in recs]
        keys = sorted({k for sample in samples for k in sample} - {"surrogate_f1", "kind"})
        f1: list = []
        pooled: dict[str, list] = {k: [] for k in keys}
        for sample in samples:
            n = len(sample.get("surrogate_f1", []))
            f1.extend(sample.get("surrogate_f1", []))
            for key in keys:
                pooled[key].extend(sample.get(key, [None] * n))
        for key in keys:
            rho, p, n = spearman(f1, pooled[key])
            if not math.isnan(rho):
                rows.append({"group": group, "metric": key.replace("metric.", ""), "rho": rho, "p_value": p, "n": n})
    return rows


def _csv_value(value: Any) -> Any:
    if isinstance(value, dict):
        return ";".join(f"{k}:{v}" for k, v in value.items())
    if isinstance(value, float):
        return f"{value:.6g}"
    return "" if value is None else value


def summarize(out: Path, config: dict[str, Any], records: list[dict]) -> dict[str, Path]:
    """Write results.csv, checkpoints.csv, stats.json, report.md and the plots from the run files."""
    out = Path(out)
    identity = config["identity"]
    algorithms = [a for a in config["algorithms"] if any(r["algorithm"] == a for r in records)]
    records = _ordered([r for r in records if r["algorithm"] in algorithms and r["run"] < config["runs"]], algorithms)
    full = "full_model" in identity
    columns = BASE_COLUMNS + (FULL_MODEL_COLUMNS if full else ("suite_size",))
    paths = {name: out / name for name in ("results.csv", "checkpoints.csv", "stats.json", "report.md")}
    with paths["results.csv"].open("w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(columns)
        for rec in records:
            writer.writerow([_csv_value(rec.get(c)) for c in columns])
    checkpoints = checkpoint_table(records, identity)
    with paths["checkpoints.csv"].open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=("algorithm", "run", "axis", "checkpoint", "best_f1"))
        writer.writeheader()
        writer.writerows({k: _csv_value(v) for k, v in row.items()} for row in checkpoints)
    metrics = FULL_MODEL_METRICS if full else SURROGATE_METRICS
    doc: dict[str, Any] = {"problem": config["problem"], "profile": config["profile"],
                           "runs": {a: sum(r["algorithm"] == a for r in records) for a in algorithms},
                           "tests": statistics(records, algorithms, metrics)}
    if full:
        doc["spearman"] = correlations(records)
    write_atomic(paths["stats.json"], json.dumps(doc, indent=2) + "\n")
    from ..viz.experiment import plot_experiment, plot_gallery

    try:
        plots = plot_experiment(out, config, records, checkpoints)
    except Exception as exc:  # pictures must never cost the tables
        print(f"ambiegen experiment: plots skipped ({exc})", file=sys.stderr)
        plots = []
    gallery: list[dict[str, Any]] = []
    if full:
        try:
            gallery = plot_gallery(out, config, records)
        except Exception as exc:
            print(f"ambiegen experiment: failure gallery skipped ({exc})", file=sys.stderr)
    write_atomic(paths["report.md"], report(config, records, doc, plots, gallery))
    return paths


__all__ = ["CHECKPOINTS", "checkpoint_table", "correlations", "statistics", "summarize"]
