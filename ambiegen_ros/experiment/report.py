"""report.md: our medians and tests next to the paper's tables and the replication code's numbers.

The RQ3 report counts certified failures (after the full model's reference check), distinct
failures by what failed (``sims.signature``) and invalid tests apart; it compares each search's
executions per hour with random's (the pipeline must keep the executors as busy as random does)
and shows the failure gallery (one picture per distinct failure).
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from ..core.stats import smallest_p
from .pipeline import SAMPLE_CAP

# Best F1 medians (GA / NSGA-II / random) as printed in the paper, and (median, runs) of the runs the
# authors' replication code stored (github.com/dgumenyuk/Environment_generation, RQ1_RQ2, commit
# 092fbec; ``bench/three_seed_check.py --authors`` recomputes them). Our notes once gave that code's
# *means* here (vehicle 16.0 / 18.7 / 8.3): the medians differ. Robot: its random runs stopped at
# 4,100 evaluations.
PAPER_MEDIANS = {
    "thermostat": {"paper": {"ga": 3.0, "nsga2": 3.0, "random": 1.608},
                   "replication_code": {"ga": (3.024, 30), "nsga2": (2.971, 30), "random": (1.606, 30)}},
    "robot": {"paper": {"ga": 278.2, "nsga2": 251.6, "random": 158.89},
              "replication_code": {"ga": (198.9, 30), "nsga2": (159.9, 30), "random": (107.6, 30)}},
    "vehicle": {"paper": {"ga": 16.0, "nsga2": 17.0, "random": 9.0},
                "replication_code": {"ga": (16.30, 16), "nsga2": (17.84, 20), "random": (7.874, 30)}},
}
# The paper's Tables (Mann-Whitney p, Cliff's delta): RQ1 best F1 and RQ2 diversity (GA vs NSGA-II).
PAPER_TESTS = {
    "thermostat": {"best_f1": {("ga", "nsga2"): ("0.378", 0.133), ("ga", "random"): ("< 0.01", 1.0),
                               ("nsga2", "random"): ("< 0.01", 1.0)},
                   "diversity": {("ga", "nsga2"): ("< 0.01", 0.852)}},
    "robot": {"best_f1": {("ga", "nsga2"): ("< 0.01", 0.772), ("ga", "random"): ("< 0.01", 1.0),
                          ("nsga2", "random"): ("< 0.01", 0.978)},
              "diversity": {("ga", "nsga2"): ("< 0.01", 1.0)}},
    "vehicle": {"best_f1": {("ga", "nsga2"): ("0.0501", 0.295), ("ga", "random"): ("< 0.01", 0.877),
                            ("nsga2", "random"): ("< 0.01", 0.886)},
                "diversity": {("ga", "nsga2"): ("0.0109", 0.383)}},
}
# The paper's RQ3 (failures in two hours, mean of 30 runs; AmbieGen = NSGA-II on the surrogate).
PAPER_RQ3 = {
    "robot": {"nsga2": 9.0, "random": 2.0, "test": ("< 0.01", 1.0)},
    "vehicle": {"nsga2": 14.0, "random": 8.0, "test": ("< 0.01", 0.653)},
}
ALGORITHM_LABELS = {"ga": "GA (SO)", "nsga2": "NSGA-II (MO)", "random": "random"}
NEAREST_LEVELS = (0.0, 0.25, 0.5)


def median(values: list) -> float:
    v = np.asarray([x for x in values if x is not None], dtype=float)
    return float(np.median(v)) if len(v) else math.nan


def _iqr(values: list) -> str:
    v = np.asarray([x for x in values if x is not None], dtype=float)
    if not len(v):
        return "-"
    q1, q3 = np.percentile(v, [25, 75])
    return f"{q1:.3g}-{q3:.3g}"


def _p(p: float | None) -> str:
    if p is None:
        return "n/a"
    return "< 0.01" if p < 0.01 else f"{p:.3g}"


def _num(x: Any, digits: int = 3) -> str:
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "-"
    return f"{x:.{digits}g}" if isinstance(x, float) else str(x)


def _stored(entry: tuple[float, int] | None) -> str:
    return "-" if entry is None else f"{_num(float(entry[0]), 4)} ({entry[1]})"


def too_few_runs(n_a: int, n_b: int) -> str | None:
    """Why runs this few cannot show a difference whatever their values (None when they can). Issue
    17: a user who ran three seeds per algorithm read a verdict from three draws."""
    floor = smallest_p(n_a, n_b)
    if floor < 0.05:
        return None
    return (f"with {n_a} and {n_b} runs the two-sided Mann-Whitney p cannot fall below {floor:.3g}, whatever "
            "the values, so no difference can be significant at 0.05")


def _too_few_runs_note(tests: list[dict], metric: str) -> list[str]:
    sizes = [(t["n_a"], t["n_b"]) for t in tests if t["metric"] == metric]
    why = too_few_runs(*max(sizes, key=lambda n: smallest_p(*n))) if sizes else None
    if why is None:
        return []
    return ["", f"**Too few runs to decide:** {why}. A median of a few runs also moves a lot from one set of "
            "seeds to the next; the paper ran 30 per algorithm (docs/reproducing_the_paper.md gives ours)."]


def _tests_table(tests: list[dict], metric: str, paper: dict | None) -> list[str]:
    lines = ["| A vs B | p (ours) | Cliff's delta (ours) | paper: p | paper: delta |", "|---|---|---|---|---|"]
    for t in tests:
        if t["metric"] != metric:
            continue
        ref = None
        if paper:
            ref = paper.get((t["a"], t["b"])) or paper.get((t["b"], t["a"]))
        ref_p, ref_d = (ref[0], f"{ref[1]:g}, {_magnitude(ref[1])}") if ref else ("-", "-")
        delta = "n/a" if t["cliffs_delta"] is None else f"{t['cliffs_delta']:+.3f}, {t['magnitude']}"
        lines.append(f"| {ALGORITHM_LABELS.get(t['a'], t['a'])} vs {ALGORITHM_LABELS.get(t['b'], t['b'])} "
                     f"| {_p(t['p_value'])} | {delta} | {ref_p} | {ref_d} |")
    return lines


def _magnitude(d: float) -> str:
    from ..core.stats import magnitude

    return magnitude(d)


def _rq3_comparison(by_alg: dict[str, list[dict]], algorithms: list[str]) -> list[str]:
    """Pooled over runs: executions and failure rate next to random's (is the executor kept busy?)."""
    if "random" not in by_alg or len(algorithms) < 2:
        return []
    totals = {}
    for a in algorithms:
        rs = by_alg[a]
        execs = sum(r.get("executions") or 0 for r in rs)
        totals[a] = {"execs": execs, "rate": sum(r.get("failures") or 0 for r in rs) / execs if execs else 0.0,
                     "waited": sum(r.get("waited_s") or 0.0 for r in rs), "steps": sum(r.get("search_steps") or 0 for r in rs)}
    rnd = totals["random"]
    L = ["| algorithm | executions | x random | certified failures per execution | x random "
         "| executor waiting for the search [s] | search generations |", "|---|---|---|---|---|---|---|"]
    for a in algorithms:
        t = totals[a]
        x_exec = f"{t['execs'] / rnd['execs']:.2f}" if rnd["execs"] else "-"
        x_rate = f"{t['rate'] / rnd['rate']:.2f}" if rnd["rate"] > 0 else "-"
        L.append(f"| {ALGORITHM_LABELS.get(a, a)} | {t['execs']} | {x_exec} | {t['rate']:.3g} | {x_rate} "
                 f"| {t['waited']:.3g} | {t['steps']} |")
    return ["Pooled over runs:", ""] + L + [""]


def _gallery(gallery: list[dict[str, Any]], out_name: str = "gallery") -> list[str]:
    if not gallery:
        return []
    L = ["## Failure gallery", "",
         "One picture per distinct certified failure (up to 12 per algorithm, taken in turn from the runs; "
         "each executed again with its recorded simulator seed). The scenario JSON is next to each picture.", ""]
    for g in gallery:
        name = Path(g["png"]).name
        L += [f"**{ALGORITHM_LABELS.get(g['algorithm'], g['algorithm'])}, run {g['run']}: {g['failure']}** "
              f"({g['verdict']}; [{Path(g['json']).name}]({out_name}/{Path(g['json']).name}))", "",
              f"![{name}]({out_name}/{name})", ""]
    return L


def report(config: dict[str, Any], records: list[dict], doc: dict[str, Any], plots: list[Path],
           gallery: list[dict[str, Any]] | None = None) -> str:
    """report.md: our medians and tests next to the paper's and the replication code's."""
    identity = config["identity"]
    problem, profile = config["problem"], config["profile"]
    algorithms = list(doc["runs"])
    full = "full_model" in identity
    by_alg = {a: [r for r in records if r["algorithm"] == a] for a in algorithms}
    L = [f"# AmbieGen experiment: {problem}, profile `{profile}`", ""]
    L.append(f"Every number below was made with the **`{profile}` profile** of the {problem} case study "
             f"(ambiegen_ros {identity['ambiegen_ros']}, seed {identity['seed']}: run k uses seed {identity['seed']} + k).")
    L.append("")
    L.append("Command: `" + " ".join(["ambiegen", *config.get("command", [])[1:]]) + "`")
    L.append("")
    runs = ", ".join(f"{ALGORITHM_LABELS.get(a, a)} {n}" for a, n in doc["runs"].items())
    L.append(f"Runs done: {runs} (of {config['runs']} each).")
    s0 = identity["settings"][algorithms[0]] if algorithms else {}
    if not full:
        budget = (f"{s0.get('evaluations')} surrogate evaluations" if s0.get("evaluations") is not None
                  else f"{s0.get('time_budget')} s of search")
        L.append(f"Budget per run: {budget}; population {s0.get('population')}, offspring {s0.get('offspring')} "
                 "(GA / NSGA-II).")
    L.append("")
    if not full:
        ref = PAPER_MEDIANS.get(problem, {})
        L += ["## RQ1: best F1 at the same budget", "",
              "| algorithm | runs | median best F1 (ours) | IQR | paper | replication code (stored median, runs) |",
              "|---|---|---|---|---|---|"]
        for a in algorithms:
            vals = [r["best_f1"] for r in by_alg[a]]
            L.append(f"| {ALGORITHM_LABELS.get(a, a)} | {len(vals)} | {median(vals):.4g} | {_iqr(vals)} "
                     f"| {_num(ref.get('paper', {}).get(a))} | {_stored(ref.get('replication_code', {}).get(a))} |")
        L.append("")
        if problem == "robot":
            L += ["The replication code's stored robot random runs stopped at 4,100 evaluations.", ""]
        L += ["Mann-Whitney U (two-sided) and Cliff's delta(A, B) = P(A > B) - P(A < B):", ""]
        L += _tests_table(doc["tests"], "best_f1", PAPER_TESTS.get(problem, {}).get("best_f1"))
        L += _too_few_runs_note(doc["tests"], "best_f1")
        L += ["", "## RQ2: diversity of the delivered scenarios", "",
              "Mean pairwise Jaccard distance of the 10 best scenarios (GA, random) or of the final feasible "
              "Pareto front (NSGA-II).", "",
              "| algorithm | median diversity | IQR | median suite size |", "|---|---|---|---|"]
        for a in algorithms:
            vals = [r["diversity"] for r in by_alg[a]]
            L.append(f"| {ALGORITHM_LABELS.get(a, a)} | {median(vals):.3f} | {_iqr(vals)} "
                     f"| {median([r.get('suite_size') for r in by_alg[a]]):g} |")
        L.append("")
        L += _tests_table(doc["tests"], "diversity", PAPER_TESTS.get(problem, {}).get("diversity"))
        L.append("")
    else:
        fm = identity["full_model"]
        hours = fm["time_budget_s"] / 3600
        L += ["## RQ3: certified failures of the full model in the same time", "",
              f"Budget per run: {fm['time_budget_s']:g} s on the executors' clocks ({fm['clock']} clock measures; "
              f"{fm.get('executors', 1)} executor(s) beside the search, each execution charged its measured time "
              f"+ {fm.get('execution_cost_s', 0):g} s). The search carries one population on and runs at the same "
              f"time (docs/rq3_pipeline.md). Candidates are ordered by surrogate F1; a candidate "
              f"within Jaccard distance {fm['distinct_distance']:g} of an executed failure is skipped. A failure "
              "counts once the problem's reference passes (certified); scenarios no reference passes are invalid "
              f"tests, never failures. Distinct = different signature (signature radius {fm.get('signature_radius')}).",
              "", "Executions are runs of the system under test; invalid tests screened out by a static reference "
              "check (in brackets) ran nothing and are not executions.",
              "", "| algorithm | runs | executions | certified failures | distinct failures | invalid tests (screened out) "
              "| distinct / hour | failures / hour | failure rate | paper (failures / hour) |",
              "|---|---|---|---|---|---|---|---|---|---|"]
        paper = PAPER_RQ3.get(problem, {})
        for a in algorithms:
            rs = by_alg[a]
            med = {k: median([r.get(k) for r in rs]) for k in
                   ("executions", "failures", "distinct_failures", "invalid_tests", "screened_out",
                    "failures_per_hour", "distinct_per_hour", "failure_rate")}
            ref = f"{paper[a] / 2:g} ({paper[a]:g} in 2 h)" if a in paper else "-"
            L.append(f"| {ALGORITHM_LABELS.get(a, a)} | {len(rs)} | {med['executions']:g} | {med['failures']:g} "
                     f"| {med['distinct_failures']:g} | {med['invalid_tests']:g} ({med['screened_out']:g}) "
                     f"| {med['distinct_per_hour']:.3g} "
                     f"| {med['failures_per_hour']:.3g} | {med['failure_rate']:.3g} | {ref} |")
        L += ["", f"Medians over runs of {hours:.3g} h each."]
        if paper:
            L.append(f"The paper's figures are means of 30 two-hour runs (AmbieGen = NSGA-II) and counted every "
                     f"oracle failure; its test (AmbieGen vs random failures): p {paper['test'][0]}, "
                     f"delta {paper['test'][1]:g}, large.")
        L.append("")
        L += _rq3_comparison(by_alg, algorithms)
        L += ["Failures far from every earlier failure of the same run (medians over runs; the distance is the "
              "Jaccard distance of the diversity code):", "",
              "| algorithm | " + " | ".join(f"> {d:g}" for d in NEAREST_LEVELS) + " | median distance to the nearest earlier failure |",
              "|---|" + "---|" * (len(NEAREST_LEVELS) + 1)]
        for a in algorithms:
            nearest = [r.get("failure_nearest") or [] for r in by_alg[a]]
            counts = [median([sum(d > level for d in n) for n in nearest]) for level in NEAREST_LEVELS]
            pooled = [d for n in nearest for d in n[1:]]
            L.append(f"| {ALGORITHM_LABELS.get(a, a)} | " + " | ".join(f"{c:g}" for c in counts)
                     + f" | {_num(median(pooled))} |")
        L.append("")
        kinds: dict[str, dict[str, int]] = {}
        for a in algorithms:
            for r in by_alg[a]:
                for k, n in (r.get("failure_kinds") or {}).items():
                    kinds.setdefault(k, {}).setdefault(a, 0)
                    kinds[k][a] += n
        L += ["### Outcomes of all executions (summed over runs)", "",
              "| outcome | " + " | ".join(ALGORITHM_LABELS.get(a, a) for a in algorithms) + " |",
              "|---|" + "---|" * len(algorithms)]
        for k in sorted(kinds):
            L.append(f"| {k} | " + " | ".join(str(kinds[k].get(a, 0)) for a in algorithms) + " |")
        L += ["", "### Tests", ""]
        for metric in ("distinct_per_hour", "failures_per_hour", "invalid_tests", "failure_rate"):
            L += [f"`{metric}`:", ""]
            L += _tests_table(doc["tests"], metric, None)
            L.append("")
        L += ["### Surrogate F1 against the full model (Spearman)", "",
              f"Over a reservoir sample of at most {SAMPLE_CAP} executions per run, pooled.", "",
              "| group | full-model number | rho | p | n |", "|---|---|---|---|---|"]
        for row in doc.get("spearman", []):  # per algorithm: the headline numbers only (all in stats.json)
            if row["group"] != "all" and row["metric"] not in ("objective", "failed"):
                continue
            L.append(f"| {row['group']} | {row['metric']} | {row['rho']:+.3f} | {_p(row['p_value'])} | {row['n']} |")
        L.append("")
    if plots:
        L += ["## Plots", ""] + [f"![{p.stem}]({p.name})" for p in plots] + [""]
    L += _gallery(gallery or [])
    L += ["Files: `results.csv` (one row per run), `checkpoints.csv`, `stats.json`, `runs/*.json`, `config.json`"
          + (", `gallery/`." if gallery else "."), ""]
    return "\n".join(L)


__all__ = ["ALGORITHM_LABELS", "PAPER_MEDIANS", "PAPER_RQ3", "PAPER_TESTS", "median", "report", "too_few_runs"]
