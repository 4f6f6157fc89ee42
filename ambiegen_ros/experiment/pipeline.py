"""RQ3's full-model pipeline: search and execution on the full-model simulator share one clock.

Every algorithm gets the same clock budget (``time_budget_s``, default the paper's two hours)
that covers generating AND executing scenarios on the full-model simulator. Random search samples
scenarios and executes the valid ones until the budget ends. GA and NSGA-II work in rounds, as the
paper's RQ3 pipeline did (a fresh short search, then its final population's best scenarios go to
the simulator, again and again): each round is a new surrogate search with the paper's RQ3 round
budget (``spec.RQ3_ROUNDS``) that may use at most ``search_share`` of the time left; then its suite
(10 best / feasible Pareto front: what AmbieGen outputs; ``execute: risky`` adds every risky
scenario, F1 > alpha, that the round evaluated) is executed best first, skipping scenarios invalid
or identical (within the attribute tolerances) to one already executed; then the next round starts.
An execution that ends after the budget does not count. A failure is an execution whose oracle
fails (``Outcome.failed``); it is distinct when its Jaccard distance to every earlier failure of
the run is above ``distinct_distance``.

Kept apart from the runner because this pipeline is to be rewritten ("search and execution at
the same time") without touching the runner, records or report.
"""
from __future__ import annotations

import dataclasses
import time
from typing import Any, Callable

import numpy as np

from ..core.accel import SMALL_BATCH

SAMPLE_CAP = 1000  # executions kept per run for the surrogate-vs-full-model correlation

_WARM: set[tuple[str, bool]] = set()


def make_clock(kind: str) -> Callable[[], float]:
    """The budget clock: wall (as the paper) or cpu (process time, immune to other load)."""
    return time.process_time if kind == "cpu" else time.perf_counter


def warm_up(problem, executor) -> None:
    """Compile/cache once per process outside any budget (numba kernels, lazy imports)."""
    key = (problem.name, executor is not None)
    if key in _WARM:
        return
    rng = np.random.default_rng(12345)
    X = problem.sample_rows(2 * SMALL_BATCH, rng)  # more than SMALL_BATCH: the compiled kernels load
    ev = problem.evaluate_rows(X)
    if executor is not None:
        valid = np.flatnonzero(ev.valid)
        if len(valid):
            executor.execute(problem.codec.from_row(X[valid[0]]), seed=0)
    _WARM.add(key)


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
        from ..core.diversity import nearest_distance

        G, L = self.problem.canonical(*self.problem.codec.split(row[None, :]))
        if not len(self._executed[1]):
            return False
        return bool(nearest_distance(G, L, *self._executed, self.problem.codec.attributes)[0] == 0)

    def execute(self, row: np.ndarray, surrogate_f1: float, start: float) -> None:
        """Run one scenario on the full model and count it, unless it ends after the budget."""
        from ..core.diversity import nearest_distance

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
        from ..core.diversity import mean_pairwise_diversity

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


def full_model_run(problem, settings, executor, fm: dict[str, Any], seed: int) -> dict[str, Any]:
    """RQ3: generation and execution share one clock budget (see the module docstring)."""
    from ..core.search import Search

    clock = make_clock(fm["clock"])
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


def break_even_seconds(a: dict[str, float], r: dict[str, float]) -> float | None:
    """Execution time per scenario above which ``a`` finds more failures per hour than ``r``.

    With failures per execution ``f`` and generation seconds per execution ``g``, an execution
    costing ``c`` seconds gives ``f / (g + c)`` failures per second; the two are equal at
    ``c = (f_r g_a - f_a g_r) / (f_a - f_r)``. None when ``a`` does not fail more often per execution.
    """
    if a["rate"] <= r["rate"]:
        return None
    return max((r["rate"] * a["gen"] - a["rate"] * r["gen"]) / (a["rate"] - r["rate"]), 0.0)


__all__ = ["SAMPLE_CAP", "FullModelTally", "break_even_seconds", "full_model_run", "make_clock", "warm_up"]
