"""The AmbieGen search: GA (SO), NSGA-II (MO) and random search, driven by ask/tell.

``Search.ask()`` hands out genome rows to evaluate and ``Search.tell()`` takes their evaluation,
so the same loop runs with the in-process surrogate (``Search.run``) or with results that arrive
later from simulation nodes (the ROS generator's ``in_the_loop`` mode). pymoo does selection,
survival and bookkeeping; our operators (``core.operators``) do the variation.

Objectives (pymoo minimises, users see positive values): SO minimises -F1; MO minimises
(-F1, -F2) subject to F1 > alpha (``G = alpha - F1 <= 0``). F2 is the Jaccard distance to the
individual's parent (``reference="parent"``, the paper) or to the nearest member of the current
non-dominated front (``reference="front"``). Members of the initial population have no parent:
their F2 is the distance to the nearest other member of that population (written in the docs).

The budget counts every evaluation, the initial population included; the last generation is
truncated so a run never evaluates more than ``evaluations`` scenarios.

Random search draws ``population`` samples per ``ask``; with ``valid_samples`` (a campaign's: a
scenario the problem calls invalid is never executed there) only samples the problem calls valid
(``ValidSampler``), so its budget counts valid scenarios only.

``restarts: R`` splits the budget into R independent searches run one after the other, the first
with the run's seed and each next with a seed derived from it (``restart_seed``). Their suites
interleave, best of each first: one converged population fills a suite with near-copies of one
structure, which a slow system under test then runs over and over (issue 29's Nav2 measurement).
"""
from __future__ import annotations

import time
from collections import deque
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np
from pymoo.algorithms.moo.nsga2 import NSGA2
from pymoo.algorithms.soo.nonconvex.ga import GA
from pymoo.core.evaluator import Evaluator
from pymoo.core.population import Population
from pymoo.core.termination import NoTermination
from pymoo.problems.static import StaticProblem
from pymoo.util.nds.non_dominated_sorting import NonDominatedSorting

from .problem import Evaluation, Problem
from .diversity import jaccard_distance, mean_pairwise_diversity, nearest_distance, pairwise_jaccard
from .operators import (
    CaseStudyProblem,
    OnePointCrossover,
    ScenarioDuplicateElimination,
    ScenarioMutation,
    ScenarioSampling,
)

from .names import ALGORITHMS, REFERENCES  # noqa: F401 (re-exported)
from .settings import SUITES, SearchSettings  # noqa: F401 (re-exported: a run's settings, light on their own)


@dataclass
class SearchResult:
    """What a run leaves: the suite (best scenarios with F1/F2), history rows and totals."""

    settings: SearchSettings
    suite: list[dict[str, Any]]
    history: list[dict[str, float]]
    evaluations: int
    elapsed: float
    best_f1: float
    diversity: float
    extras: dict[str, Any] = field(default_factory=dict)


def non_dominated(f1: np.ndarray, f2: np.ndarray, feasible: np.ndarray) -> np.ndarray:
    """Indices of the feasible points not dominated in (max F1, max F2)."""
    idx = np.flatnonzero(feasible)
    if len(idx) == 0:
        return idx
    front = NonDominatedSorting().do(np.column_stack([-f1[idx], -f2[idx]]), only_non_dominated_front=True)
    return idx[np.sort(front)]


class ValidSampler:
    """Random samples the problem calls valid (``Problem.evaluate(...).valid``, the search's
    constraint), drawn from ``rng`` in batches of ``batch`` and handed out in the order drawn, each
    with its surrogate F1. Random search with ``valid_samples`` draws here, and so does an RQ3
    executor with nothing to run (``experiment.pipeline``: its clock pays the draw)."""

    def __init__(self, problem: Problem, rng: np.random.Generator, batch: int = 64, tries: int = 20):
        self.problem, self.rng, self.batch, self.tries = problem, rng, batch, tries
        self._rows: deque[tuple[np.ndarray, float]] = deque()
        self.drawn = 0

    def draw(self, skip: Callable[[np.ndarray], bool] = lambda row: False) -> tuple[np.ndarray, float] | None:
        """A valid sample ``skip`` does not drop, with its surrogate F1; None when ``tries`` batches held none."""
        for _ in range(self.tries):
            while self._rows:
                row, f1 = self._rows.popleft()
                if not skip(row):
                    self.drawn += 1
                    return row, f1
            X = self.problem.sample_rows(self.batch, self.rng)
            ev = self.problem.evaluate_rows(X)
            f1 = np.nan_to_num(np.asarray(ev.f1, dtype=float), nan=0.0)
            self._rows.extend((X[i], float(f1[i])) for i in np.flatnonzero(ev.valid))
        return None


def restart_seed(seed: int, restart: int) -> int:
    """The seed of restart ``restart`` of a run seeded ``seed``: the run's own for the first, so a run
    of R restarts begins as a run without any; independent streams after (numpy's SeedSequence)."""
    if restart == 0:
        return int(seed)
    return int(np.random.SeedSequence([int(seed), int(restart)]).generate_state(1)[0] % 2**31)


def interleave(suites: list[Population]) -> Population:
    """Round robin over suites, each in its own order: the best of every restart first."""
    rows = [pop[i] for i in range(max((len(p) for p in suites), default=0)) for pop in suites if i < len(pop)]
    return Population.create(*rows) if rows else Population.empty()


class Search:
    """One run of one algorithm on one problem; ask/tell or ``run()`` with the surrogate.

    ``valid_samples``: random search draws only samples the problem calls valid (module docstring);
    GA and NSGA-II are not affected (they learn from invalid scenarios as constraint violations)."""

    def __init__(self, problem: Problem, settings: SearchSettings, valid_samples: bool = False):
        self.problem = problem
        self.settings = settings.resolved(problem)
        self.codec = problem.codec
        self.evaluations = 0
        self.history: list[dict[str, float]] = []
        self.best_f1 = 0.0
        self._start = time.perf_counter()
        self._pending: Population | np.ndarray | None = None
        s = self.settings
        if s.algorithm == "random":  # samples are independent already: restarts change nothing
            self._rng = np.random.default_rng(s.seed)
            self._valid = ValidSampler(problem, self._rng) if valid_samples else None
            self._archive = Population.empty()
            self._algorithm = None
            return
        mo = s.algorithm == "nsga2"
        self._pymoo_problem = CaseStudyProblem(problem, n_obj=2 if mo else 1, n_ieq_constr=1 if mo else 0)
        self._restart = 0
        self._finished: list[Population] = []  # the suites of the restarts done
        self._begin_restart()

    def _begin_restart(self) -> None:
        s = self.settings
        self._restart_evaluations, self._restart_start = self.evaluations, time.perf_counter()
        operators = dict(
            pop_size=s.population,
            n_offsprings=s.offspring,
            sampling=ScenarioSampling(),
            crossover=OnePointCrossover(prob=s.crossover_rate),
            mutation=ScenarioMutation(prob=s.mutation_rate),
            eliminate_duplicates=ScenarioDuplicateElimination(self.problem),
        )
        # a case study may replace some for its profile (the vehicle's replication profile compares
        # duplicates road by road)
        operators.update(self.problem.search_operators(s))
        algorithm = NSGA2 if self._pymoo_problem.n_obj == 2 else GA
        self._algorithm = algorithm(**operators)
        seed = restart_seed(s.seed, self._restart)
        self._algorithm.setup(self._pymoo_problem, termination=NoTermination(), seed=seed, verbose=False)

    # --- budget --------------------------------------------------------------------------
    @property
    def elapsed(self) -> float:
        return time.perf_counter() - self._start

    def remaining(self) -> int | None:
        """Evaluations left (None when only a time budget is set)."""
        if self.settings.evaluations is None:
            return None
        return max(self.settings.evaluations - self.evaluations, 0)

    def _restart_left(self) -> int | None:
        """Evaluations left in the current restart's share (None when only a time budget is set)."""
        s = self.settings
        if s.evaluations is None:
            return None
        share = s.evaluations // s.restarts + (self._restart < s.evaluations % s.restarts)
        return share - (self.evaluations - self._restart_evaluations)

    def _restart_spent(self) -> bool:
        """Has the current restart used its share (evaluations or time) of the budget?"""
        left, s = self._restart_left(), self.settings
        if left is not None and left <= 0:
            return True
        return s.time_budget is not None and time.perf_counter() - self._restart_start >= s.time_budget / s.restarts

    def _next_restart(self) -> bool:
        """Close the current restart and begin the next; False when it was the last."""
        if self._algorithm is None or self._restart + 1 >= self.settings.restarts:
            return False
        self._finished.append(self.suite_population(this_restart=True))
        self._restart += 1
        self._begin_restart()
        return True

    def done(self) -> bool:
        s = self.settings
        if s.evaluations is not None and self.evaluations >= s.evaluations:
            return True
        if s.time_budget is not None and self.elapsed >= s.time_budget:
            return True
        return False

    # --- ask / tell ----------------------------------------------------------------------
    def ask(self) -> np.ndarray | None:
        """Genome rows to evaluate next (None when the budget is spent or nothing new can be bred)."""
        if self._pending is not None:
            raise RuntimeError("ask() called twice without tell()")
        if self.done():
            return None
        if self._algorithm is not None and self._restart_spent():
            self._next_restart()
        remaining = self.remaining()
        if self._algorithm is None:
            n = self.settings.population if remaining is None else min(self.settings.population, remaining)
            rows = self.problem.sample_rows(n, self._rng) if self._valid is None else self._valid_rows(n)
            if len(rows) == 0:  # the problem passed no sample of many batches: nothing to ask
                return None
            self._pending = Population.new("X", rows)
        else:
            pop = self._algorithm.ask()
            if pop is None or len(pop) == 0:  # nothing new can be bred: the next restart, if any
                return self.ask() if self._next_restart() else None
            if remaining is not None:
                remaining = min(remaining, self._restart_left())
            if remaining is not None and len(pop) > remaining:
                pop = pop[:remaining]
            self._pending = pop
        return self._pending.get("X")

    def tell(self, evaluation: Evaluation) -> None:
        """Record the evaluation of the rows from the last ``ask()`` (same order)."""
        pop = self._pending
        if pop is None:
            raise RuntimeError("tell() without ask()")
        if len(evaluation.f1) != len(pop):
            raise ValueError(f"tell(): {len(evaluation.f1)} results for {len(pop)} scenarios")
        self._pending = None
        f1 = np.where(evaluation.valid, np.nan_to_num(evaluation.f1, nan=0.0), 0.0).astype(float)
        f2 = self._f2(pop)
        for i, ind in enumerate(pop):
            ind.set("f1", f1[i])
            ind.set("f2", f2[i])
            ind.set("info", evaluation.row(i))
        self.evaluations += len(pop)
        self.best_f1 = max(self.best_f1, float(f1.max(initial=0.0)))
        if self._algorithm is None:
            merged = Population.merge(self._archive, pop)
            order = np.argsort(-merged.get("f1"), kind="stable")[: self.settings.suite_size]
            self._archive = merged[order]
            self._record(pop)
            return
        if self._pymoo_problem.n_obj == 2:
            F = np.column_stack([-f1, -f2])
            G = (self.problem.alpha - f1)[:, None]
            Evaluator().eval(StaticProblem(self._pymoo_problem, F=F, G=G), pop)
        else:
            Evaluator().eval(StaticProblem(self._pymoo_problem, F=-f1[:, None]), pop)
        self._algorithm.tell(infills=pop)
        self._record(self._algorithm.pop)

    def step(self) -> bool:
        """One ask / surrogate-evaluate / tell cycle; False when the run is over."""
        X = self.ask()
        if X is None:
            return False
        self.tell(self.problem.evaluate_rows(X))
        return True

    def run(self, progress: Callable[["Search"], None] | None = None) -> SearchResult:
        while self.step():
            if progress is not None:
                progress(self)
        return self.result()

    # --- internals -----------------------------------------------------------------------
    def _valid_rows(self, n: int) -> np.ndarray:
        """Up to ``n`` valid samples (fewer only when the sampler gives up)."""
        rows = []
        while len(rows) < n and (drawn := self._valid.draw()) is not None:
            rows.append(drawn[0])
        return np.array(rows).reshape(len(rows), self.codec.n_var)

    def _split(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Canonical ``(G, lengths)`` of genome rows: diversity counts what the environment sees."""
        return self.problem.canonical(*self.codec.split(X))

    def _f2(self, pop: Population) -> np.ndarray:
        attrs = self.codec.attributes
        G, lengths = self._split(pop.get("X"))
        f2 = np.empty(len(pop))
        refs = [ind.get("ref") for ind in pop]
        has_ref = np.array([r is not None for r in refs])
        if self.settings.reference == "front" and self._algorithm is not None and self._algorithm.pop is not None:
            front = self._current_front(self._algorithm.pop)
            Gf, lf = self._split(front.get("X")) if len(front) else (G[:0], lengths[:0])
            return nearest_distance(G, lengths, Gf, lf, attrs)
        if has_ref.any():
            Gr, lr = self._split(np.stack([r for r in refs if r is not None]))
            f2[has_ref] = jaccard_distance(G[has_ref], lengths[has_ref], Gr, lr, attrs)
        orphans = np.flatnonzero(~has_ref)
        if len(orphans) == 1:
            f2[orphans] = 1.0
        elif len(orphans) > 1:  # initial population / random samples: nearest other orphan
            D = pairwise_jaccard(G[orphans], lengths[orphans], attrs)
            np.fill_diagonal(D, np.inf)
            f2[orphans] = D.min(axis=1)
        return f2

    def _current_front(self, pop: Population) -> Population:
        f1, f2 = pop.get("f1").astype(float), pop.get("f2").astype(float)
        feasible = f1 > self.problem.alpha
        return pop[non_dominated(f1, f2, feasible)]

    def _record(self, pop: Population) -> None:
        f1 = pop.get("f1").astype(float)
        self.history.append(
            {
                "evaluations": self.evaluations,
                "elapsed_s": round(self.elapsed, 4),
                "best_f1": self.best_f1,
                "mean_f1": float(f1.mean()) if len(f1) else 0.0,
                "front_size": len(self._current_front(pop)),
                "risky": int(np.sum(f1 > self.problem.alpha)),
            }
        )

    def suite_population(self, this_restart: bool = False) -> Population:
        """SO: the 10 best; MO: the feasible Pareto front (F1 > alpha); random: the 10 best samples.

        ``suite: population``: the whole final population above alpha (MO) or valid (SO), best F1
        first. For a slow system under test that can run more maps than a front holds: a front of
        3 leaves most of an hour of Nav2 unused, while NSGA-II's population stays spread by F2.
        With restarts, the restarts' suites interleave (``this_restart``: the current one's only)."""
        if self._algorithm is None:
            return self._archive
        if not this_restart and self._finished:
            return interleave([*self._finished, self.suite_population(this_restart=True)])
        pop = self._algorithm.pop
        if self.settings.suite == "population":
            f1 = pop.get("f1").astype(float)
            keep = f1 > (self.problem.alpha if self._pymoo_problem.n_obj == 2 else 0.0)
            order = np.argsort(-f1, kind="stable")
            return pop[order[keep[order]]]
        if self._pymoo_problem.n_obj == 2:
            front = self._current_front(pop)
            if len(front) == 0:  # nothing beat alpha yet: the unconstrained front (entries say feasible: false)
                f1, f2 = pop.get("f1").astype(float), pop.get("f2").astype(float)
                front = pop[non_dominated(f1, f2, np.ones(len(pop), dtype=bool))]
            return front
        order = np.argsort(-pop.get("f1").astype(float), kind="stable")
        return pop[order[: self.settings.suite_size]]

    def result(self) -> SearchResult:
        suite_pop = self.suite_population()
        X = suite_pop.get("X") if len(suite_pop) else np.zeros((0, self.codec.n_var))
        suite = []
        for rank, ind in enumerate(suite_pop):
            info = dict(ind.get("info"))
            entry = {
                "rank": rank,
                "f1": float(ind.get("f1")),
                "f2": float(ind.get("f2")),
                "feasible": bool(float(ind.get("f1")) > self.problem.alpha),
                "valid": info.pop("valid"),
                "reason": info.pop("reason"),
                "metrics": {k: v for k, v in info.items() if k != "f1"},
                "scenario": self.codec.from_row(ind.get("X")).to_dict(),
            }
            suite.append(entry)
        G, lengths = self._split(X)
        return SearchResult(
            settings=self.settings,
            suite=suite,
            history=list(self.history),
            evaluations=self.evaluations,
            elapsed=self.elapsed,
            best_f1=self.best_f1,
            diversity=mean_pairwise_diversity(G, lengths, self.codec.attributes),
        )
