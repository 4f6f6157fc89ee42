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
above which the search finds more failures per hour than random search. A failure is an execution whose oracle fails (``Outcome.failed``);
it is distinct when its Jaccard distance to every earlier failure of the run is above
``--distinct-distance`` (default 0: not the same scenario within the attribute tolerances).
"""
from __future__ import annotations

import argparse
import csv
import dataclasses
import json
import math
import multiprocessing
import os
import signal
import sys
import time
import traceback
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Callable

import numpy as np

from . import __version__
from .core.stats import compare, spearman
from .problems.base import Budget

# Best F1 medians (GA / NSGA-II / random) as printed in the paper and as stored by the authors'
# replication code (30 runs; /work/shared/reference/README.md). Robot: the replication code's
# random runs stopped at 4,100 evaluations.
PAPER_MEDIANS = {
    "thermostat": {"paper": {"ga": 3.0, "nsga2": 3.0, "random": 1.608},
                   "replication_code": {"ga": 3.01, "nsga2": 2.98, "random": 1.62}},
    "robot": {"paper": {"ga": 278.2, "nsga2": 251.6, "random": 158.89},
              "replication_code": {"ga": 205.0, "nsga2": 164.0, "random": 109.0}},
    "vehicle": {"paper": {"ga": 16.0, "nsga2": 17.0, "random": 9.0},
                "replication_code": {"ga": 16.0, "nsga2": 18.7, "random": 8.3}},
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
# One RQ3 search round (population, offspring, evaluations): the paper's RQ3 settings.
RQ3_ROUNDS = {
    "robot": Budget(100, 10, 4100),  # NSGA-II, 10 offspring, at most 400 generations
    "vehicle": Budget(100, 25, 5100),  # "5,100 evaluations (population 100, 200 generations, 25 offspring)"
    "thermostat": Budget(100, 25, 5100),  # no paper RQ3: as the vehicle
}
PAPER_RQ3_BUDGET_S = 7200.0
EXECUTE_MODES = ("suite", "risky")  # what a search round hands to the simulator (module docstring)
CHECKPOINTS = 10
SAMPLE_CAP = 1000  # executions kept per run for the surrogate-vs-full-model correlation
ALGORITHM_LABELS = {"ga": "GA (SO)", "nsga2": "NSGA-II (MO)", "random": "random"}


class ExperimentError(ValueError):
    """A bad experiment request (refused before anything is written or overwritten)."""


# --- what defines an experiment --------------------------------------------------------------
@dataclass
class ExperimentSpec:
    problem: str
    algorithms: tuple[str, ...] = ("ga", "nsga2", "random")
    runs: int = 30
    seed: int = 0
    profile: str | None = None
    evaluations: int | None = None
    time_budget: float | None = None
    full_model: bool = False
    config_file: str | None = None
    sim_options: dict[str, Any] = field(default_factory=dict)
    round_evaluations: int | None = None
    search_share: float = 0.5
    distinct_distance: float = 0.0
    clock: str = "wall"
    execute: str = "suite"

    def check(self) -> None:
        from .core.search import ALGORITHMS

        if not self.algorithms:
            raise ExperimentError("--algorithms: give at least one")
        for alg in self.algorithms:
            if alg not in ALGORITHMS:
                raise ExperimentError(f"--algorithms: unknown {alg!r} (allowed: {','.join(ALGORITHMS)})")
        if len(set(self.algorithms)) != len(self.algorithms):
            raise ExperimentError("--algorithms: an algorithm is listed twice")
        if self.runs < 1:
            raise ExperimentError("--runs: must be >= 1")
        if self.evaluations is not None and self.time_budget is not None:
            raise ExperimentError("--evaluations and --time-budget exclude each other")
        if self.full_model and self.evaluations is not None:
            raise ExperimentError("--full-model runs on a clock budget (--time-budget); "
                                  "a search round's size is --round-evaluations")
        if self.time_budget is not None and not self.time_budget > 0:
            raise ExperimentError("--time-budget: must be > 0 seconds")
        if not 0 < self.search_share <= 1:
            raise ExperimentError("--search-share: must be in (0, 1]")
        if self.distinct_distance < 0 or self.distinct_distance >= 1:
            raise ExperimentError("--distinct-distance: must be in [0, 1)")
        if self.clock not in ("wall", "cpu"):
            raise ExperimentError("--clock: wall|cpu")
        if self.execute not in EXECUTE_MODES:
            raise ExperimentError(f"--execute: {'|'.join(EXECUTE_MODES)}")
        if self.round_evaluations is not None and self.round_evaluations < 2:
            raise ExperimentError("--round-evaluations: must be >= 2")


def _plain_json(value: Any) -> Any:
    """The value as JSON would give it back (tuples -> lists, numpy -> Python), for comparisons."""
    return json.loads(json.dumps(value, default=lambda v: v.item() if hasattr(v, "item") else str(v)))


def resolve(spec: ExperimentSpec) -> dict[str, Any]:
    """The experiment's identity: everything that changes a run's result (checked on --resume)."""
    from .core.config import load_config_file, make_run

    spec.check()
    settings: dict[str, Any] = {}
    problem = None
    file_cfg = load_config_file(spec.config_file)
    for alg in spec.algorithms:
        overrides: dict[str, Any] = {"algorithm": alg, "seed": spec.seed}
        if spec.full_model:
            rnd = RQ3_ROUNDS.get(spec.problem)
            if rnd is None:
                raise ExperimentError(f"--full-model: no RQ3 setting for {spec.problem!r}")
            overrides["evaluations"] = spec.round_evaluations or rnd.evaluations
            for name in ("population", "offspring"):
                if name not in file_cfg:
                    overrides[name] = getattr(rnd, name)
        else:
            overrides["evaluations"] = spec.evaluations
            overrides["time_budget"] = spec.time_budget
        problem, s = make_run(spec.problem, spec.config_file, profile=spec.profile, **overrides)
        entry = dataclasses.asdict(s)
        entry.pop("seed")
        settings[alg] = entry
    assert problem is not None
    identity: dict[str, Any] = {
        "problem": problem.name,
        "profile": problem.profile,
        "problem_config": problem.config_dict(),
        "seed": spec.seed,
        "mode": "rq3_full_model" if spec.full_model else "rq1_rq2_surrogate",
        "settings": settings,
        "ambiegen_ros": __version__,
    }
    if spec.full_model:
        from .sims.full_model import full_model_executor

        executor = full_model_executor(problem, **spec.sim_options)
        identity["full_model"] = {
            "time_budget_s": spec.time_budget or PAPER_RQ3_BUDGET_S,
            "clock": spec.clock,
            "search_share": spec.search_share,
            "distinct_distance": spec.distinct_distance,
            "execute": spec.execute,
            "simulator": executor.config_dict(),
        }
    return _plain_json(identity)


def run_identity(identity: dict[str, Any], algorithm: str) -> dict[str, Any]:
    """What a run file records of the experiment: the shared part plus its algorithm's settings."""
    out = {k: v for k, v in identity.items() if k != "settings"}
    out["algorithm"] = algorithm
    out["settings"] = identity["settings"][algorithm]
    return out


def _differences(a: Any, b: Any, prefix: str = "") -> list[str]:
    """Keys (dotted) whose values differ between two JSON-like documents."""
    if isinstance(a, dict) and isinstance(b, dict):
        out = []
        for key in sorted(set(a) | set(b)):
            out += _differences(a.get(key), b.get(key), f"{prefix}.{key}" if prefix else str(key))
        return out
    return [] if a == b else [prefix or "(root)"]


# --- files ----------------------------------------------------------------------------------------
def write_atomic(path: Path, text: str) -> None:
    """Write then rename: a reader (or a kill) never sees half a file."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


def run_path(out: Path, algorithm: str, run: int) -> Path:
    return Path(out) / "runs" / f"{algorithm}-{run:03d}.json"


# --- one run (in a worker process) -------------------------------------------------------------
_WARM: set[tuple[str, bool]] = set()


def _clock(kind: str) -> Callable[[], float]:
    return time.process_time if kind == "cpu" else time.perf_counter


def _warm_up(problem, executor) -> None:
    """Compile/cache once per process outside any budget (numba kernels, lazy imports)."""
    key = (problem.name, executor is not None)
    if key in _WARM:
        return
    rng = np.random.default_rng(12345)
    X = problem.sample_rows(4, rng)
    ev = problem.evaluate_rows(X)
    if executor is not None:
        valid = np.flatnonzero(ev.valid)
        if len(valid):
            executor.execute(problem.codec.from_row(X[valid[0]]), seed=0)
    _WARM.add(key)


def _settings_for(identity: dict[str, Any], algorithm: str, seed: int):
    from .core.search import SearchSettings

    return SearchSettings(**{**identity["settings"][algorithm], "seed": seed})


def run_task(task: dict[str, Any]) -> dict[str, Any]:
    """Run one (algorithm, k) and write its file at once; returns the record."""
    from .problems import get_problem

    identity = task["identity"]
    algorithm, k = task["algorithm"], task["run"]
    seed = identity["seed"] + k
    problem = get_problem(identity["problem"], identity["problem_config"])
    settings = _settings_for(identity, algorithm, seed)
    executor = None
    if "full_model" in identity:
        from .sims.full_model import FullModelExecutor
        from .sims.full_model import sim_config

        executor = FullModelExecutor(problem, sim_config(problem.name, identity["full_model"]["simulator"]))
    _warm_up(problem, executor)
    record: dict[str, Any] = {
        "problem": problem.name,
        "profile": problem.profile,
        "algorithm": algorithm,
        "run": k,
        "seed": seed,
        "identity": run_identity(identity, algorithm),
    }
    if executor is None:
        record.update(_surrogate_run(problem, settings))
    else:
        record.update(_full_model_run(problem, settings, executor, identity["full_model"], seed))
    record["finished"] = datetime.now(timezone.utc).isoformat(timespec="seconds")
    write_atomic(Path(task["path"]), json.dumps(record, indent=1) + "\n")
    return record


def _run_task_guarded(task: dict[str, Any]) -> dict[str, Any]:
    """A run that raises is reported (and retried by --resume) instead of stopping the others."""
    try:
        return run_task(task)
    except Exception:
        return {"algorithm": task["algorithm"], "run": task["run"], "error": traceback.format_exc()}


def _ignore_sigint() -> None:
    """Pool workers leave Ctrl-C to the parent, which stops them (no half-written results)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _surrogate_run(problem, settings) -> dict[str, Any]:
    """RQ1/RQ2: one search on the surrogate; best F1, diversity, the history for checkpoints."""
    from .core.search import Search

    result = Search(problem, settings).run()
    return {
        "evaluations": result.evaluations,
        "wall_s": round(result.elapsed, 3),
        "best_f1": result.best_f1,
        "diversity": result.diversity,
        "suite_size": len(result.suite),
        "history": {key: [h[key] for h in result.history] for key in ("evaluations", "elapsed_s", "best_f1")},
        "suite": [{"f1": e["f1"], "f2": e["f2"], "scenario": e["scenario"]} for e in result.suite],
    }


class FullModelTally:
    """Executions of one RQ3 run: failures, distinct failures, kinds, and a sample for correlations."""

    def __init__(self, problem, executor, clock: Callable[[], float], deadline: float, seed: int,
                 distinct_distance: float):
        self.problem, self.executor = problem, executor
        self.clock, self.deadline = clock, deadline
        self.seed = seed
        self.distinct_distance = distinct_distance
        codec = problem.codec
        shape = (0, codec.m_max, len(codec.attributes))
        self._executed = (np.zeros(shape), np.zeros(0, dtype=int))
        self._failed = (np.zeros(shape), np.zeros(0, dtype=int))
        self.executions = self.rejected = self.overrun = 0
        self.failures = self.distinct = 0
        self.kinds: dict[str, int] = {}
        self.failure_nearest: list[float] = []  # each failure's Jaccard distance to the earlier ones
        self.failure_times: list[float] = []
        self.failure_examples: list[dict[str, Any]] = []
        self.execution_s = 0.0
        self.sample: list[dict[str, Any]] = []
        self._rng = np.random.default_rng([seed, 7])

    def time_left(self) -> bool:
        return self.clock() < self.deadline

    def seen(self, row: np.ndarray) -> bool:
        """Already executed (distance 0 within the attribute tolerances)?"""
        from .core.diversity import nearest_distance

        G, L = self.problem.canonical(*self.problem.codec.split(row[None, :]))
        if not len(self._executed[1]):
            return False
        return bool(nearest_distance(G, L, *self._executed, self.problem.codec.attributes)[0] == 0)

    def execute(self, row: np.ndarray, surrogate_f1: float, start: float) -> None:
        """Run one scenario on the full model and count it, unless it ends after the budget."""
        from .core.diversity import nearest_distance

        codec = self.problem.codec
        t0 = self.clock()
        k = self.executions + self.rejected + self.overrun  # the k-th scenario sent to the simulator
        sim_seed = int(np.random.SeedSequence([self.seed, k]).generate_state(1)[0])
        outcome = self.executor.execute(codec.from_row(row), seed=sim_seed)
        t1 = self.clock()
        if t1 > self.deadline:
            self.overrun += 1
            return
        self.execution_s += t1 - t0
        if outcome.failure_kind == "invalid_scenario":
            self.rejected += 1
            return
        self.executions += 1
        G, L = self.problem.canonical(*codec.split(row[None, :]))
        self._executed = (np.concatenate([self._executed[0], G]), np.concatenate([self._executed[1], L]))
        self.kinds[outcome.failure_kind] = self.kinds.get(outcome.failure_kind, 0) + 1
        if outcome.failed:
            nearest = float(nearest_distance(G, L, *self._failed, codec.attributes)[0])
            self.failures += 1
            self.distinct += nearest > self.distinct_distance
            self.failure_nearest.append(round(min(nearest, 1.0), 6))
            self.failure_times.append(round(t1 - start, 3))
            self._failed = (np.concatenate([self._failed[0], G]), np.concatenate([self._failed[1], L]))
            if len(self.failure_examples) < 20:
                self.failure_examples.append({"surrogate_f1": float(surrogate_f1), "kind": outcome.failure_kind,
                                              "detail": outcome.detail,
                                              "scenario": codec.from_row(row).to_dict()})
        self._keep_sample(surrogate_f1, outcome)

    def _keep_sample(self, surrogate_f1: float, outcome) -> None:
        """Reservoir sample of executions: surrogate F1 next to the full model's numbers."""
        entry = {"surrogate_f1": float(surrogate_f1), "failed": int(bool(outcome.failed)),
                 "kind": outcome.failure_kind,
                 "objective": outcome.f1 if outcome.objectives else None}
        for key, value in outcome.metrics.items():
            if key != "seed" and isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool):
                entry[f"metric.{key}"] = float(value)
        n = self.executions
        if len(self.sample) < SAMPLE_CAP:
            self.sample.append(entry)
        else:
            j = int(self._rng.integers(n))
            if j < SAMPLE_CAP:
                self.sample[j] = entry

    def failure_diversity(self) -> float:
        """Mean pairwise Jaccard distance of the run's failures (a seeded sample of at most 300)."""
        from .core.diversity import mean_pairwise_diversity

        G, L = self._failed
        if len(L) > 300:
            pick = np.sort(self._rng.choice(len(L), 300, replace=False))
            G, L = G[pick], L[pick]
        return mean_pairwise_diversity(G, L, self.problem.codec.attributes)

    def summary(self, budget: float) -> dict[str, Any]:
        keys = sorted({k for e in self.sample for k in e})
        return {
            "executions": self.executions,
            "rejected": self.rejected,
            "overrun_discarded": self.overrun,
            "failures": self.failures,
            "distinct_failures": int(self.distinct),
            "failures_per_hour": self.failures * 3600.0 / budget,
            "distinct_per_hour": int(self.distinct) * 3600.0 / budget,
            "failure_rate": self.failures / self.executions if self.executions else 0.0,
            "failure_kinds": dict(sorted(self.kinds.items())),
            "first_failure_s": self.failure_times[0] if self.failure_times else None,
            "execution_s": round(self.execution_s, 3),
            "diversity": self.failure_diversity(),
            "failure_nearest": self.failure_nearest,
            "failure_times_s": self.failure_times,
            "failure_examples": self.failure_examples,
            "sample": {k: [e.get(k) for e in self.sample] for k in keys},
        }


def _full_model_run(problem, settings, executor, fm: dict[str, Any], seed: int) -> dict[str, Any]:
    """RQ3: generation and execution share one clock budget (see the module docstring)."""
    from .core.search import Search

    clock = _clock(fm["clock"])
    budget = float(fm["time_budget_s"])
    start = clock()
    tally = FullModelTally(problem, executor, clock, start + budget, seed, fm["distinct_distance"])
    best_f1, evaluations, rounds, search_s = 0.0, 0, 0, 0.0
    if settings.algorithm == "random":
        rng = np.random.default_rng(seed)
        while tally.time_left():
            t0 = clock()
            X = problem.sample_rows(10, rng)
            ev = problem.evaluate_rows(X)
            search_s += clock() - t0
            evaluations += len(X)
            f1 = np.where(ev.valid, np.nan_to_num(ev.f1, nan=0.0), 0.0)
            best_f1 = max(best_f1, float(f1.max(initial=0.0)))
            for i in np.flatnonzero(ev.valid):
                if not tally.time_left():
                    break
                tally.execute(X[i], f1[i], start)
    else:
        while tally.time_left():
            left = tally.deadline - clock()
            round_seed = int(np.random.SeedSequence([seed, rounds]).generate_state(1)[0] % 2**31)
            s = dataclasses.replace(settings, seed=round_seed, time_budget=max(fm["search_share"] * left, 1e-3))
            t0 = clock()
            search = Search(problem, s)
            found: list[tuple[np.ndarray, np.ndarray]] = []  # risky rows seen by this round (--execute risky)
            while (X := search.ask()) is not None:
                ev = problem.evaluate_rows(X)
                search.tell(ev)
                f1 = np.where(ev.valid, np.nan_to_num(ev.f1, nan=0.0), 0.0)
                risky = f1 > problem.alpha
                if fm["execute"] == "risky" and risky.any():
                    found.append((X[risky], f1[risky]))
            search_s += clock() - t0
            evaluations += search.evaluations
            best_f1 = max(best_f1, search.best_f1)
            rounds += 1
            pop = search.suite_population()
            valid = np.array([bool(ind.get("info")["valid"]) for ind in pop], dtype=bool)
            found.append((pop.get("X")[valid], pop.get("f1").astype(float)[valid]))
            X = np.concatenate([x for x, _ in found])
            f1 = np.concatenate([f for _, f in found])
            for i in np.argsort(-f1, kind="stable"):  # best first; the same scenario only once
                if not tally.time_left():
                    break
                if not tally.seen(X[i]):
                    tally.execute(X[i], f1[i], start)
    out = {"evaluations": evaluations, "wall_s": round(clock() - start, 3), "best_f1": best_f1,
           "rounds": rounds, "search_s": round(search_s, 3), "time_budget_s": budget}
    out.update(tally.summary(budget))
    return out


# --- orchestration ---------------------------------------------------------------------------------
def default_jobs() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


class ExperimentProgress:
    """``[#####     ] 12/90 runs  4m10s elapsed, ~20m left`` on stderr (a terminal only)."""

    def __init__(self, total: int, done: int, enabled: bool | None = None, label: str = "",
                 run_seconds: float | None = None, jobs: int = 1):
        self.total, self.done, self.start_done = total, done, done
        self.label = label
        self.run_seconds, self.jobs = run_seconds, jobs  # a clock budget per run gives an early estimate
        self.enabled = sys.stderr.isatty() if enabled is None else enabled
        self.t0 = time.monotonic()

    @staticmethod
    def _fmt(seconds: float) -> str:
        seconds = int(round(seconds))
        h, rem = divmod(seconds, 3600)
        m, s = divmod(rem, 60)
        return f"{h}h{m:02d}m" if h else (f"{m}m{s:02d}s" if m else f"{s}s")

    def eta(self) -> float | None:
        finished = self.done - self.start_done
        if finished <= 0:
            if self.run_seconds is None:
                return None
            waves = math.ceil((self.total - self.done) / self.jobs)
            return max(waves * self.run_seconds - (time.monotonic() - self.t0), 0.0)
        return (time.monotonic() - self.t0) / finished * (self.total - self.done)

    def update(self, done: int | None = None) -> None:
        if done is not None:
            self.done = done
        if not self.enabled:
            return
        frac = self.done / self.total if self.total else 1.0
        eta = self.eta()
        left = f", ~{self._fmt(eta)} left" if eta is not None else ""
        sys.stderr.write(f"\r{self.label}[{'#' * int(frac * 30):<30}] {self.done}/{self.total} runs  "
                         f"{self._fmt(time.monotonic() - self.t0)} elapsed{left}   ")
        sys.stderr.flush()

    def close(self) -> None:
        if self.enabled:
            sys.stderr.write("\n")
            sys.stderr.flush()


def _load_record(path: Path) -> dict[str, Any] | None:
    try:
        return json.loads(path.read_text())
    except (OSError, json.JSONDecodeError):
        return None  # a damaged file counts as not done (re-run)


def prepare(spec: ExperimentSpec, out: Path, resume: bool, jobs: int) -> tuple[dict[str, Any], list[dict], list[dict]]:
    """Check DIR, write config.json; returns (config, runs already done, tasks to run)."""
    out = Path(out)
    identity = resolve(spec)
    existing = out / "config.json"
    if out.exists() and any(out.iterdir()):
        if not resume:
            raise ExperimentError(f"--out {out}: directory exists and is not empty (use --resume to continue "
                                  "that experiment, or choose a new directory)")
        if not existing.exists():
            raise ExperimentError(f"--out {out}: not an experiment directory (no config.json); refusing to write into it")
        old = json.loads(existing.read_text()).get("identity") or {}
        shared = {k: v for k, v in identity.items() if k != "settings"}
        diff = _differences({k: v for k, v in old.items() if k != "settings"}, shared)
        for alg, settings in identity["settings"].items():  # an algorithm may join or stay out
            if alg in (old.get("settings") or {}):
                diff += _differences(old["settings"][alg], settings, f"settings.{alg}")
        if diff:
            raise ExperimentError(f"--resume: {out} holds an experiment with a different config "
                                  f"({', '.join(diff[:5])}); use the same options or a new --out")
        identity = {**identity, "settings": {**old.get("settings", {}), **identity["settings"]}}
    done, tasks = [], []
    for k in range(spec.runs):  # interleaved: a stopped experiment leaves balanced algorithms
        for alg in spec.algorithms:
            path = run_path(out, alg, k)
            rec = _load_record(path) if path.exists() else None
            if rec is not None:
                diff = _differences(rec.get("identity"), run_identity(identity, alg))
                if diff:
                    raise ExperimentError(f"--resume: {path} was made with a different config ({', '.join(diff[:5])})")
                done.append(rec)
            else:
                tasks.append({"identity": identity, "algorithm": alg, "run": k, "path": str(path)})
    from .core.runs import versions

    config = {
        "identity": identity,
        "problem": identity["problem"],
        "profile": identity["profile"],
        "seed": spec.seed,
        "algorithms": list(spec.algorithms),
        "runs": spec.runs,
        "jobs": jobs,
        "cpus": os.cpu_count(),
        "versions": versions(),
        "command": sys.argv,
        "written": datetime.now(timezone.utc).isoformat(timespec="seconds"),
    }
    write_atomic(existing, json.dumps(config, indent=2) + "\n")
    return config, done, tasks


def run_experiment(spec: ExperimentSpec, out: Path, jobs: int | None = None, resume: bool = False,
                   progress: bool | None = None) -> dict[str, Any]:
    """Run what is missing, then write the tables, statistics, report and plots."""
    out = Path(out)
    jobs = max(1, jobs or default_jobs())
    config, records, tasks = prepare(spec, out, resume, jobs)
    identity = config["identity"]
    run_seconds = (identity["full_model"]["time_budget_s"] if "full_model" in identity
                   else next(iter(identity["settings"].values()))["time_budget"])
    bar = ExperimentProgress(len(records) + len(tasks), len(records), enabled=progress,
                             label=f"{config['problem']} ({config['profile']}) ", run_seconds=run_seconds, jobs=jobs)
    bar.update()
    errors: list[dict[str, Any]] = []

    def take(rec: dict[str, Any]) -> None:
        if "error" in rec:
            errors.append(rec)
            print(f"\nambiegen experiment: run {rec['algorithm']}-{rec['run']:03d} failed (--resume retries it):\n"
                  f"{rec['error']}", file=sys.stderr)
        else:
            records.append(rec)
        bar.update(len(records) + len(errors))

    try:
        if jobs == 1 or len(tasks) <= 1:
            for task in tasks:
                take(_run_task_guarded(task))
        elif tasks:
            pool = multiprocessing.get_context("spawn").Pool(min(jobs, len(tasks)), initializer=_ignore_sigint)
            try:
                results = pool.imap_unordered(_run_task_guarded, tasks)
                for _ in tasks:
                    while True:
                        try:
                            rec = results.next(timeout=1.0)
                            break
                        except multiprocessing.TimeoutError:
                            bar.update()
                    take(rec)
                pool.close()
            finally:
                pool.terminate()  # on Ctrl-C or an error: the runs in flight stop (their files were never written)
                pool.join()
    finally:
        bar.close()
        if records:
            summarize(out, config, records)
    return {"config": config, "records": records, "errors": errors}


# --- tables, statistics, report ----------------------------------------------------------------
SURROGATE_METRICS = ("best_f1", "diversity")
FULL_MODEL_METRICS = ("failures_per_hour", "distinct_per_hour", "failures", "distinct_failures", "failure_rate",
                      "executions", "best_f1", "diversity")
BASE_COLUMNS = ("problem", "profile", "algorithm", "run", "seed", "evaluations", "wall_s", "best_f1", "diversity")
FULL_MODEL_COLUMNS = ("executions", "failures", "distinct_failures", "failures_per_hour", "distinct_per_hour",
                      "failure_rate", "rejected", "overrun_discarded", "rounds", "search_s", "execution_s",
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
    from .viz.experiment import plot_experiment

    try:
        plots = plot_experiment(out, config, records, checkpoints)
    except Exception as exc:  # pictures must never cost the tables
        print(f"ambiegen experiment: plots skipped ({exc})", file=sys.stderr)
        plots = []
    write_atomic(paths["report.md"], report(config, records, doc, plots))
    return paths


def _median(values: list) -> float:
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
    from .core.stats import magnitude

    return magnitude(d)


NEAREST_LEVELS = (0.0, 0.25, 0.5)


def break_even_seconds(a: dict[str, float], r: dict[str, float]) -> float | None:
    """Execution time per scenario above which ``a`` finds more failures per hour than ``r``.

    With failures per execution ``f`` and generation seconds per execution ``g``, an execution
    costing ``c`` seconds gives ``f / (g + c)`` failures per second; the two are equal at
    ``c = (f_r g_a - f_a g_r) / (f_a - f_r)``. None when ``a`` does not fail more often per execution.
    """
    if a["rate"] <= r["rate"]:
        return None
    return max((r["rate"] * a["gen"] - a["rate"] * r["gen"]) / (a["rate"] - r["rate"]), 0.0)


def _rq3_comparison(by_alg: dict[str, list[dict]], algorithms: list[str]) -> list[str]:
    """Failure rate against random's, and the execution cost from which searching pays off per hour."""
    if "random" not in by_alg or len(algorithms) < 2:
        return []
    totals = {}
    for a in algorithms:
        execs = sum(r.get("executions") or 0 for r in by_alg[a])
        totals[a] = {"rate": sum(r.get("failures") or 0 for r in by_alg[a]) / execs if execs else 0.0,
                     "gen": sum(r.get("search_s") or 0.0 for r in by_alg[a]) / execs if execs else math.inf,
                     "exec": sum(r.get("execution_s") or 0.0 for r in by_alg[a]) / execs if execs else math.nan}
    rnd = totals["random"]
    L = ["| algorithm | failures per execution | x random | generation s per execution | full-model s per "
         "execution | more failures per hour than random if every execution took more than |",
         "|---|---|---|---|---|---|"]
    for a in algorithms:
        t = totals[a]
        ratio = f"{t['rate'] / rnd['rate']:.2f}" if rnd["rate"] > 0 else "-"
        if a == "random":
            even = "-"
        else:
            c = break_even_seconds(t, rnd)
            even = "never (not a higher failure rate)" if c is None else f"{c:.3g} s"
        L.append(f"| {ALGORITHM_LABELS.get(a, a)} | {t['rate']:.3g} | {ratio} | {t['gen']:.3g} | {t['exec']:.3g} | {even} |")
    return ["Pooled over runs:", ""] + L + [""]


def report(config: dict[str, Any], records: list[dict], doc: dict[str, Any], plots: list[Path]) -> str:
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
              "| algorithm | runs | median best F1 (ours) | IQR | paper | replication code (stored) |",
              "|---|---|---|---|---|---|"]
        for a in algorithms:
            vals = [r["best_f1"] for r in by_alg[a]]
            L.append(f"| {ALGORITHM_LABELS.get(a, a)} | {len(vals)} | {_median(vals):.4g} | {_iqr(vals)} "
                     f"| {_num(ref.get('paper', {}).get(a))} | {_num(ref.get('replication_code', {}).get(a))} |")
        L.append("")
        if problem == "robot":
            L += ["The replication code's stored robot random runs stopped at 4,100 evaluations.", ""]
        L += ["Mann-Whitney U (two-sided) and Cliff's delta(A, B) = P(A > B) - P(A < B):", ""]
        L += _tests_table(doc["tests"], "best_f1", PAPER_TESTS.get(problem, {}).get("best_f1"))
        L += ["", "## RQ2: diversity of the delivered scenarios", "",
              "Mean pairwise Jaccard distance of the 10 best scenarios (GA, random) or of the final feasible "
              "Pareto front (NSGA-II).", "",
              "| algorithm | median diversity | IQR | median suite size |", "|---|---|---|---|"]
        for a in algorithms:
            vals = [r["diversity"] for r in by_alg[a]]
            L.append(f"| {ALGORITHM_LABELS.get(a, a)} | {_median(vals):.3f} | {_iqr(vals)} "
                     f"| {_median([r.get('suite_size') for r in by_alg[a]]):g} |")
        L.append("")
        L += _tests_table(doc["tests"], "diversity", PAPER_TESTS.get(problem, {}).get("diversity"))
        L.append("")
    else:
        fm = identity["full_model"]
        hours = fm["time_budget_s"] / 3600
        L += ["## RQ3: failures of the full model in the same time", "",
              f"Budget per run: {fm['time_budget_s']:g} s ({fm['clock']} clock), generation and execution together; "
              f"search rounds use at most {fm['search_share']:g} of the time left; a failure is distinct when its "
              f"Jaccard distance to every earlier failure is > {fm['distinct_distance']:g}.", "",
              "| algorithm | runs | executions | failures | distinct | failures / hour | distinct / hour "
              "| failure rate | search rounds | paper (failures / hour) |", "|---|---|---|---|---|---|---|---|---|---|"]
        paper = PAPER_RQ3.get(problem, {})
        for a in algorithms:
            rs = by_alg[a]
            med = {k: _median([r.get(k) for r in rs]) for k in
                   ("executions", "failures", "distinct_failures", "failures_per_hour", "distinct_per_hour",
                    "failure_rate", "rounds")}
            ref = f"{paper[a] / 2:g} ({paper[a]:g} in 2 h)" if a in paper else "-"
            L.append(f"| {ALGORITHM_LABELS.get(a, a)} | {len(rs)} | {med['executions']:g} | {med['failures']:g} "
                     f"| {med['distinct_failures']:g} | {med['failures_per_hour']:.3g} | {med['distinct_per_hour']:.3g} "
                     f"| {med['failure_rate']:.3g} | {med['rounds']:g} | {ref} |")
        L += ["", f"Medians over runs of {hours:.3g} h each."]
        if paper:
            L.append(f"The paper's figures are means of 30 two-hour runs (AmbieGen = NSGA-II); its test "
                     f"(AmbieGen vs random failures): p {paper['test'][0]}, delta {paper['test'][1]:g}, large.")
        L.append("")
        L += _rq3_comparison(by_alg, algorithms)
        L += ["Failures far from every earlier failure of the same run (medians over runs; the distance is the "
              "Jaccard distance of the diversity code):", "",
              "| algorithm | " + " | ".join(f"> {d:g}" for d in NEAREST_LEVELS) + " | median distance to the nearest earlier failure |",
              "|---|" + "---|" * (len(NEAREST_LEVELS) + 1)]
        for a in algorithms:
            nearest = [r.get("failure_nearest") or [] for r in by_alg[a]]
            counts = [_median([sum(d > level for d in n) for n in nearest]) for level in NEAREST_LEVELS]
            pooled = [d for n in nearest for d in n[1:]]
            L.append(f"| {ALGORITHM_LABELS.get(a, a)} | " + " | ".join(f"{c:g}" for c in counts)
                     + f" | {_num(_median(pooled))} |")
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
        for metric in ("failures_per_hour", "distinct_per_hour", "failure_rate"):
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
    L += ["Files: `results.csv` (one row per run), `checkpoints.csv`, `stats.json`, `runs/*.json`, `config.json`.", ""]
    return "\n".join(L)


# --- command line ----------------------------------------------------------------------------------
def _spec_from_args(args: argparse.Namespace) -> ExperimentSpec:
    from .sims.cli import parse_options

    algorithms = tuple(a.strip() for a in args.algorithms.split(",") if a.strip())
    return ExperimentSpec(
        problem=args.problem, algorithms=algorithms, runs=args.runs, seed=args.seed, profile=args.profile,
        evaluations=args.evaluations, time_budget=args.time_budget, full_model=args.full_model,
        config_file=args.config, sim_options=parse_options(args.set), round_evaluations=args.round_evaluations,
        search_share=args.search_share, distinct_distance=args.distinct_distance, clock=args.clock,
        execute=args.execute,
    )


def cmd_experiment(args: argparse.Namespace) -> int:
    from .cli import BadInput

    if args.jobs is not None and args.jobs < 1:
        raise BadInput("--jobs: must be >= 1")
    try:
        spec = _spec_from_args(args)
        result = run_experiment(spec, Path(args.out), jobs=args.jobs, resume=args.resume,
                                progress=False if args.quiet else None)
    except ExperimentError as exc:
        raise BadInput(str(exc))
    config, records, errors = result["config"], result["records"], result["errors"]
    print(f"{config['problem']} ({config['profile']} profile): {len(records)} runs -> {args.out}")
    for alg in config["algorithms"]:
        rs = [r for r in records if r["algorithm"] == alg]
        line = f"  {ALGORITHM_LABELS.get(alg, alg):<13} median best F1 {_median([r['best_f1'] for r in rs]):.4g}"
        if spec.full_model:
            line += (f", failures/h {_median([r['failures_per_hour'] for r in rs]):.3g}"
                     f", failure rate {_median([r['failure_rate'] for r in rs]):.3g}")
        else:
            line += f", diversity {_median([r['diversity'] for r in rs]):.3f}"
        print(line)
    print(f"  report: {Path(args.out) / 'report.md'}")
    if errors:
        print(f"ambiegen experiment: {len(errors)} run(s) failed; see above; --resume re-runs them", file=sys.stderr)
        return 1
    return 0


def register_cli(sub) -> None:
    """Add ``experiment`` to ``ambiegen``'s subparsers."""
    from .problems import PROBLEM_NAMES, PROFILES

    p = sub.add_parser("experiment", help="the paper's RQ1-RQ3: repeated runs, statistics, report and plots",
                       description="Run every algorithm --runs times (run k with seed SEED + k) on a process pool and "
                                   "write results.csv, stats.json, report.md and plots. RQ1/RQ2 on the surrogate "
                                   "(same evaluation budget); RQ3 with --full-model (same clock budget for generating "
                                   "and executing scenarios on the full-model simulators).")
    p.add_argument("--problem", required=True, choices=PROBLEM_NAMES)
    p.add_argument("--algorithms", default="ga,nsga2,random", help="comma-separated (default ga,nsga2,random)")
    p.add_argument("--runs", type=int, default=30, help="runs per algorithm (default 30, as the paper)")
    p.add_argument("--jobs", type=int, help="parallel runs (default: all cores)")
    p.add_argument("--out", required=True, metavar="DIR", help="experiment directory (must be new or empty, "
                                                                 "or an earlier experiment with --resume)")
    budget = p.add_mutually_exclusive_group()
    budget.add_argument("--evaluations", type=int, help="surrogate evaluations per run (default: the paper's budget)")
    budget.add_argument("--time-budget", type=float, metavar="S",
                        help="seconds per run (RQ1/RQ2: of search; --full-model: of search + execution, default 7200)")
    p.add_argument("--full-model", action="store_true", help="RQ3: execute scenarios on the full-model simulators")
    p.add_argument("--profile", choices=PROFILES, help="fidelity profile of the problem (default: replication)")
    p.add_argument("--seed", type=int, default=0, help="base seed; run k uses seed + k (default 0)")
    p.add_argument("--resume", action="store_true", help="continue an experiment in --out: skip runs already done")
    p.add_argument("--config", metavar="FILE.yaml", help="search settings and problem_config overrides")
    p.add_argument("--set", action="append", default=[], metavar="OPTION=VALUE",
                   help="--full-model: simulator option (repeatable), as for `ambiegen execute`")
    p.add_argument("--round-evaluations", type=int,
                   help="--full-model: evaluations of one search round (default: the paper's RQ3 setting)")
    p.add_argument("--search-share", type=float, default=0.5,
                   help="--full-model: most of the time left one search round may use (default 0.5)")
    p.add_argument("--distinct-distance", type=float, default=0.0,
                   help="--full-model: a failure is distinct when its Jaccard distance to every earlier failure "
                        "is above this (default 0: not the same scenario within the attribute tolerances)")
    p.add_argument("--clock", choices=("wall", "cpu"), default="wall",
                   help="--full-model: budget clock (default wall, as the paper; cpu = process time, "
                        "immune to other load on the machine)")
    p.add_argument("--execute", choices=EXECUTE_MODES, default="suite",
                   help="--full-model: what a GA/NSGA-II round executes, best first: its suite (10 best / Pareto "
                        "front, the paper's output; default) or every risky scenario it evaluated (F1 > alpha)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_experiment)


__all__ = ["ExperimentError", "ExperimentSpec", "FullModelTally", "PAPER_MEDIANS", "RQ3_ROUNDS", "register_cli",
           "resolve", "run_experiment", "run_task", "summarize"]
