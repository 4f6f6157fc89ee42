"""`ambiegen experiment`: the paper's RQ1-RQ3 in one command.

``ambiegen experiment --problem P --algorithms ga,nsga2,random --runs 30 --out DIR`` runs every
algorithm ``--runs`` times (run k with seed ``seed + k``) on a process pool and writes, under DIR:
``config.json`` (what defines the experiment), ``runs/<algorithm>-<k>.json`` (one file per finished
run, written atomically the moment it ends), ``results.csv`` (one row per run), ``checkpoints.csv``
(best F1 over the budget), ``stats.json`` (Mann-Whitney + Cliff's delta for every pair of
algorithms and every metric), ``report.md`` (the paper's tables next to ours) and the plots.

RQ1 / RQ2 (default): every algorithm gets the same budget of surrogate evaluations (the paper's
budgets unless ``--evaluations``/``--time-budget``). Best F1 and the diversity are what the engine
reports: the mean pairwise Jaccard distance of the 10 best (GA, random) or of the final feasible
Pareto front (NSGA-II).

RQ3 (``--full-model``): every algorithm gets the same clock budget (``--time-budget``, default
the paper's two hours) on the executors' clocks. The search (one population carried on for the
whole run) and ``--executors`` full-model executors run at the same time, as a discrete-event
schedule on measured times (``pipeline``; docs/rq3_pipeline.md): candidates (risky scenarios and
the current suite; random search: every valid sample) are executed best first, skipping any
already executed or within ``--distinct-distance`` of an executed failure; ``--execution-cost S``
charges S seconds per execution on top of the measured time. Failures are certified (the full
model's reference check); scenarios no reference passes are ``invalid_tests``, never failures;
distinct failures are counted by what failed (``sims.signature``, ``--signature-radius``), and the
report shows one picture per distinct failure (``gallery/``).
"""
from __future__ import annotations

# One module per concern: spec (request, identity), runner (pool, resume, progress), records (run
# files), pipeline (RQ3 full-model search + execution), summary (tables, statistics), report (text).
# Names load on first use, so that the command line starts without numpy or pymoo.
from importlib import import_module
from typing import Any

_HOMES = {
    "pipeline": ("SAMPLE_CAP", "CandidateQueue", "FullModelTally", "SearchProcess", "full_model_run"),
    "records": ("run_path", "write_atomic"),
    "report": ("ALGORITHM_LABELS", "PAPER_MEDIANS", "PAPER_RQ3", "PAPER_TESTS", "median", "report",
               "too_few_runs"),
    "runner": ("ExperimentProgress", "default_jobs", "prepare", "run_experiment", "run_task"),
    "spec": ("PAPER_RQ3_BUDGET_S", "RQ3_ROUNDS", "ExperimentError", "ExperimentSpec", "resolve",
             "run_identity"),
    "summary": ("CHECKPOINTS", "checkpoint_table", "correlations", "statistics", "summarize"),
}
_WHERE = {name: module for module, names in _HOMES.items() for name in names}


def __getattr__(name: str) -> Any:
    if name in _WHERE:
        return getattr(import_module(f".{_WHERE[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = sorted(_WHERE)
