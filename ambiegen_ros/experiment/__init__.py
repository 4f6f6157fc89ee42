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
the paper's two hours) that covers generating AND executing scenarios on the full-model
simulator. Random search samples scenarios and executes the valid ones until the budget ends.
GA and NSGA-II work in rounds, as the paper's RQ3 pipeline did (a fresh short search, then its
final population's best scenarios go to the simulator, again and again): each round is a new
surrogate search with the paper's RQ3 round budget (robot: population 100, 10 offspring, 4,100
evaluations; vehicle: 100 / 25 / 5,100; thermostat, not in the paper's RQ3: as the vehicle) that
may use at most ``--search-share`` of the time left; then its suite (10 best / feasible Pareto
front: what AmbieGen outputs; ``--execute risky`` adds every risky scenario, F1 > alpha, that the
round evaluated) is executed best first, skipping scenarios invalid or identical (within the
attribute tolerances) to one already executed; then the next round starts. An execution that ends
after the budget does not count. Our full models run in milliseconds to seconds where the paper's
took minutes, so the report also gives the failure rate per execution and the execution time
above which the search finds more failures per hour than random search. A failure is an
execution whose oracle fails (``Outcome.failed``); it is distinct when its Jaccard distance to
every earlier failure of the run is above ``--distinct-distance`` (default 0: not the same
scenario within the attribute tolerances).
"""
from __future__ import annotations

# One module per concern: spec (request, identity), runner (pool, resume, progress), records (run
# files), pipeline (RQ3 full-model search + execution), summary (tables, statistics), report (text).
# Names load on first use, so that the command line can read ``spec.EXECUTE_MODES`` cheaply.
from importlib import import_module
from typing import Any

_HOMES = {
    "pipeline": ("SAMPLE_CAP", "FullModelTally", "break_even_seconds"),
    "records": ("run_path", "write_atomic"),
    "report": ("ALGORITHM_LABELS", "PAPER_MEDIANS", "PAPER_RQ3", "PAPER_TESTS", "median", "report"),
    "runner": ("ExperimentProgress", "default_jobs", "prepare", "run_experiment", "run_task"),
    "spec": ("EXECUTE_MODES", "PAPER_RQ3_BUDGET_S", "RQ3_ROUNDS", "ExperimentError", "ExperimentSpec", "resolve",
             "run_identity"),
    "summary": ("CHECKPOINTS", "checkpoint_table", "correlations", "statistics", "summarize"),
}
_WHERE = {name: module for module, names in _HOMES.items() for name in names}


def __getattr__(name: str) -> Any:
    if name in _WHERE:
        return getattr(import_module(f".{_WHERE[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = sorted(_WHERE)
