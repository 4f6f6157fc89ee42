"""RQ3's full-model pipeline: the search and the executions run at the same time, on measured clocks.

One run is one process (``--jobs`` already runs runs in parallel on the machine's cores; more real
processes per run would only fight for them), so the pipeline is an honest discrete-event schedule
of measured times:

* **The search** has its own clock. It advances by the measured time of each generation (one
  ``Search.ask`` / surrogate evaluation / ``tell``). It keeps ONE population carried on for the
  whole run (``core.search.Search``, never restarted). Every generation produces candidates at the
  search clock's new time: every valid risky scenario it evaluated (F1 > alpha) plus the valid
  members of the current suite (10 best / feasible Pareto front). Random search is the same
  process: it samples a batch per step and every valid sample is a candidate.
* **E executors** (``--executors``, default 1) each have their own clock. An executor that is
  free at time t takes the best waiting candidate produced at or before t: highest surrogate F1
  first (random: in the order sampled), skipping any already executed (Jaccard distance 0 within the attribute
  tolerances) or within ``--distinct-distance`` of a failure that had ended by t. Its clock
  advances by the measured execution time plus ``--execution-cost`` S (charged, never slept: a
  0.04 s car and a 30 s simulator are both honest settings) whenever the system under test ran: a
  scenario the restrictions reject, or an invalid test decided by the reference's static check
  before anything runs (the vehicle's competition rules, the robot's clearance route), costs only
  its measured time, as a tester checks a road before starting the simulator. An executor with
  nothing available runs a valid random sample that it draws itself (its clock pays the draw), so a
  simulator never idles while the search thinks and the search can only add to what random search
  would have found (``executor_idle`` "random", the default); with "wait" its clock jumps to the
  moment the search produces the next candidate (``waited_s``).
* **Novelty** (a search's executor only; ``novelty`` in the identity, ``--no-novelty``): when the
  surrogate says where it predicts a failure (``PREDICTED_PLACE``, the certified objectives), a
  candidate whose predicted failure has the same signature as a failure certified by then is
  skipped (``predicted_repeats``). Random search never skips one: it stays plain sampling.
* **The budget** (``--time-budget``) is on the executors' clocks: an execution that would end after
  it does not count (``overrun_discarded``). The search runs at least until it has used the
  problem's RQ3 round budget of evaluations (``spec.RQ3_ROUNDS``, the paper's evaluations per
  search); after that, only when the executors have no candidate left. Stopping the search early
  can only disadvantage the search (it would only add candidates), and it keeps experiments
  affordable: with a 30 s simulator one hour is ~120 executions, which the first searches feed.

Events are processed in time order (always the executor with the earliest clock), so a candidate
is never executed before the search produced it and a failure is never used to skip a candidate
before it ended. Outcomes are counted by ``FullModelTally``: certified failures (``Outcome.failed``
after the full model's reference check), ``invalid_tests`` (scenarios no reference passes; never
failures), and distinct failures by what failed (``sims.signature``), not by genome.
"""
from __future__ import annotations

import dataclasses
import heapq
import itertools
import math
import time
from collections import deque
from typing import Any, Callable

import numpy as np

from ..core.accel import SMALL_BATCH
from ..sims.signature import DistinctFailures, predicted_signature, same_failure, signature

SAMPLE_CAP = 1000  # executions kept per run for the surrogate-vs-full-model correlation
DISTINCT_KEPT = 24  # distinct failures kept per run (scenario, seed) for the failure gallery
UNBOUNDED = 10**12  # the carried-on search has no evaluation budget of its own
PREDICTED_PLACE = ("failure_arc", "failure_hour")  # surrogate metrics that place a predicted failure (``predicted_signature``)

_WARM: set[tuple[str, bool]] = set()


def make_clock(kind: str) -> Callable[[], float]:
    """The measuring clock: wall (as the paper) or cpu (process time, immune to other load)."""
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


@dataclasses.dataclass
class Candidate:
    """A scenario waiting for an executor: produced at ``produced_s`` on the search clock."""

    row: np.ndarray
    f1: float
    produced_s: float
    order: int
    predicted: dict | None = None  # the surrogate's metrics that say where it predicts a failure


class CandidateQueue:
    """Waiting candidates: available ones in a heap (best first, or in production order), future
    ones in a deque (the search clock only moves forward, so production times are sorted)."""

    def __init__(self, best_first: bool):
        self.best_first = best_first
        self._future: deque[Candidate] = deque()
        self._ready: list[tuple[float, int, Candidate]] = []
        self._keys: set[bytes] = set()
        self._order = itertools.count()

    def push(self, row: np.ndarray, f1: float, produced_s: float, predicted: dict | None = None) -> bool:
        """Add a candidate once (a scenario already queued or executed is not added again)."""
        key = np.asarray(row, dtype=float).tobytes()
        if key in self._keys:
            return False
        self._keys.add(key)
        self._future.append(Candidate(np.array(row, dtype=float), float(f1), produced_s, next(self._order), predicted))
        return True

    def _priority(self, c: Candidate) -> float:
        return -c.f1 if self.best_first else float(c.order)

    def _release(self, now: float) -> None:
        while self._future and self._future[0].produced_s <= now:
            c = self._future.popleft()
            heapq.heappush(self._ready, (self._priority(c), c.order, c))

    def pop(self, now: float, skip: Callable[[Candidate], bool]) -> Candidate | None:
        """The best candidate available at ``now`` that ``skip`` does not drop (dropped ones are gone)."""
        self._release(now)
        while self._ready:
            c = heapq.heappop(self._ready)[2]
            if not skip(c):
                return c
        return None

    def next_time(self) -> float | None:
        """When the next not-yet-available candidate becomes available (None: none waiting)."""
        return self._future[0].produced_s if self._future else None

    def __len__(self) -> int:
        return len(self._future) + len(self._ready)


class SearchProcess:
    """The search on its own clock: one population carried on (ask/tell), feeding the queue."""

    def __init__(self, problem, settings, queue: CandidateQueue, clock: Callable[[], float]):
        from ..core.search import Search

        self.problem, self.queue, self.clock = problem, queue, clock
        self.random = settings.algorithm == "random"
        self.min_evaluations = int(settings.evaluations or 0)
        self.search = Search(problem, dataclasses.replace(settings, evaluations=UNBOUNDED, time_budget=None))
        self.t = 0.0  # the search clock (jumps forward when an idle search is asked for more)
        self.busy = 0.0  # the measured time of its generations
        self.steps = 0
        self.exhausted = False  # nothing new can be bred

    @property
    def evaluations(self) -> int:
        return self.search.evaluations

    def wanted(self) -> bool:
        """Below its guaranteed budget the search always runs; above it, only when asked."""
        return not self.exhausted and self.evaluations < self.min_evaluations

    def step(self) -> int:
        """One generation; its candidates are produced when it ends. Returns how many were new."""
        t0 = self.clock()
        X = self.search.ask()
        if X is None:
            self.exhausted = True
            return 0
        ev = self.problem.evaluate_rows(X)
        self.search.tell(ev)
        f1 = np.where(ev.valid, np.nan_to_num(ev.f1, nan=0.0), 0.0).astype(float)
        pick = np.asarray(ev.valid, dtype=bool) if self.random else (np.asarray(ev.valid, dtype=bool)
                                                                      & (f1 > self.problem.alpha))
        place = {k: ev.metrics[k] for k in PREDICTED_PLACE if k in ev.metrics}
        rows = [(X[i], f1[i], {k: float(v[i]) for k, v in place.items()} or None) for i in np.flatnonzero(pick)]
        if not self.random:
            pop = self.search.suite_population()
            for ind in pop:
                info = ind.get("info")
                if info is not None and info.get("valid"):
                    rows.append((ind.get("X"), float(ind.get("f1")),
                                 {k: float(info[k]) for k in PREDICTED_PLACE if k in info} or None))
        spent = self.clock() - t0
        self.t += spent
        self.busy += spent
        self.steps += 1
        return sum(self.queue.push(row, f, self.t, pred) for row, f, pred in rows)


def system_ran(outcome) -> bool:
    """Did the system under test run (what ``--execution-cost`` charges)? Not for a restriction
    reject nor for an invalid test decided before the run (no ``sut_failure_kind`` recorded)."""
    if outcome.failure_kind == "invalid_scenario":
        return False
    return not (outcome.failure_kind == "invalid_test" and "sut_failure_kind" not in (outcome.metrics or {}))


class FullModelTally:
    """Executions of one RQ3 run: certified failures, distinct failures by signature, invalid tests.

    ``executions`` are runs of the system under test (what ``--execution-cost`` charges);
    ``invalid_tests`` counts every INVALID_TEST, ``screened_out`` those decided before anything ran
    (not executions); ``rejected`` scenarios broke the problem's restrictions (never simulated).
    """

    def __init__(self, problem, seed: int, distinct_distance: float = 0.0, signature_radius: float | None = None):
        self.problem, self.seed = problem, seed
        self.distinct_distance = distinct_distance
        self.signature_radius = signature_radius
        codec = problem.codec
        shape = (0, codec.m_max, len(codec.attributes))
        # sent to an executor: a buffer grown by doubling (a run may screen out tens of thousands of
        # roads, and copying the whole history per dispatch made it quadratic, charged to the clock)
        self._sent_G = np.zeros((64, *shape[1:]))
        self._sent_L = np.zeros(64, dtype=int)
        self._sent_active = np.zeros(64, dtype=bool)  # screened-out rows are dropped: nothing ran
        self._sent_at: dict[bytes, int] = {}
        self._failed = (np.zeros(shape), np.zeros(0, dtype=int))
        self._failed_end = np.zeros(0)
        self.dispatched = 0
        self.executions = self.rejected = self.overrun = self.invalid_tests = self.screened_out = 0
        self.failures = 0
        self.distinct = DistinctFailures(signature_radius)
        self._sig_end: list[float] = []  # when each of ``distinct.seen`` was certified
        self.predicted_repeats = 0  # candidates skipped as predicted repeats of a found failure
        self.kinds: dict[str, int] = {}
        self.failure_nearest: list[float] = []  # each failure's Jaccard distance to the earlier ones
        self.failure_times: list[float] = []
        self.distinct_examples: list[dict[str, Any]] = []
        self.execution_s = self.charged_s = 0.0
        self.sample: list[dict[str, Any]] = []
        self._rng = np.random.default_rng([seed, 7])

    def _canonical(self, row: np.ndarray):
        return self.problem.canonical(*self.problem.codec.split(np.asarray(row, dtype=float)[None, :]))

    def seen(self, row: np.ndarray) -> bool:
        """Already sent to an executor (distance 0 within the attribute tolerances: the same length
        and every element the same)? Scenarios screened out before anything ran do not count."""
        from ..core.diversity import jaccard_distance

        G, L = self._canonical(row)
        n = self.dispatched
        ref = np.flatnonzero(self._sent_active[:n] & (self._sent_L[:n] == L[0]))  # distance 0 needs equal lengths
        if not len(ref):
            return False
        k = len(ref)
        d = jaccard_distance(np.repeat(G, k, axis=0), np.repeat(L, k), self._sent_G[ref], self._sent_L[ref],
                             self.problem.codec.attributes)
        return bool((d == 0).any())

    def near_failure(self, row: np.ndarray, now: float) -> bool:
        """Within ``distinct_distance`` of a failure that had ended by ``now``?"""
        from ..core.diversity import nearest_distance

        known = self._failed_end <= now
        if not known.any():
            return False
        G, L = self._canonical(row)
        d = nearest_distance(G, L, self._failed[0][known], self._failed[1][known], self.problem.codec.attributes)[0]
        return bool(d <= self.distinct_distance)

    def skip(self, row: np.ndarray, now: float) -> bool:
        return self.seen(row) or self.near_failure(row, now)

    def predicted_repeat(self, cand: Candidate, now: float) -> bool:
        """Does the surrogate predict the same failure (``sims.signature``) as one certified by ``now``?
        A search's executor skips it: a tester wants failures unlike the ones found."""
        known = [sig for sig, end in zip(self.distinct.seen, self._sig_end) if end <= now]
        if not cand.predicted or not known:
            return False
        guess = predicted_signature(self.problem, self.problem.codec.from_row(cand.row), cand.predicted)
        if guess is None:
            return False
        if any(same_failure(guess, sig, self.signature_radius) for sig in known):
            self.predicted_repeats += 1
            return True
        return False

    def dispatch(self, row: np.ndarray) -> int:
        """Mark a scenario as sent to an executor; returns its index k in the run (its simulator seed's)."""
        G, L = self._canonical(row)
        k = self.dispatched
        if k == len(self._sent_L):
            grow = lambda a: np.concatenate([a, np.zeros_like(a)])  # noqa: E731
            self._sent_G, self._sent_L, self._sent_active = map(grow, (self._sent_G, self._sent_L, self._sent_active))
        self._sent_G[k], self._sent_L[k], self._sent_active[k] = G[0], L[0], True
        self._sent_at[np.asarray(row, dtype=float).tobytes()] = k
        self.dispatched += 1
        return k

    def record(self, row: np.ndarray, surrogate_f1: float, outcome, sim_seed: int, measured_s: float,
               charged_s: float, end_s: float) -> None:
        """Count one execution that ended within the budget at ``end_s`` on its executor's clock."""
        from ..core.diversity import nearest_distance

        self.execution_s += measured_s
        self.charged_s += charged_s
        if outcome.failure_kind == "invalid_scenario":
            self.rejected += 1
            return
        self.kinds[outcome.failure_kind] = self.kinds.get(outcome.failure_kind, 0) + 1
        self.invalid_tests += outcome.failure_kind == "invalid_test"
        if not system_ran(outcome):  # an invalid test screened out before the system under test ran
            self.screened_out += 1
            k = self._sent_at.pop(np.asarray(row, dtype=float).tobytes(), None)
            if k is not None:
                self._sent_active[k] = False
            return
        self.executions += 1
        if outcome.failed:
            codec = self.problem.codec
            scenario = codec.from_row(row)
            G, L = self._canonical(row)
            nearest = float(nearest_distance(G, L, *self._failed, codec.attributes)[0])
            self.failures += 1
            self.failure_nearest.append(round(min(nearest, 1.0), 6))
            self.failure_times.append(round(end_s, 3))
            self._failed = (np.concatenate([self._failed[0], G]), np.concatenate([self._failed[1], L]))
            self._failed_end = np.append(self._failed_end, end_s)
            sig = signature(self.problem, scenario, outcome, self.signature_radius)
            self._sig_end.append(end_s)
            if self.distinct.add(sig) and len(self.distinct_examples) < DISTINCT_KEPT:
                self.distinct_examples.append({
                    "signature": sig.to_dict(), "describe": sig.describe(), "kind": outcome.failure_kind,
                    "verdict": outcome.verdict, "detail": outcome.detail, "reference": outcome.reference,
                    "surrogate_f1": float(surrogate_f1), "time_s": round(end_s, 3), "sim_seed": int(sim_seed),
                    "scenario": scenario.to_dict()})
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
        distinct = len(self.distinct)
        return {
            "executions": self.executions,
            "failures": self.failures,
            "distinct_failures": distinct,
            "invalid_tests": self.invalid_tests,
            "screened_out": self.screened_out,
            "rejected": self.rejected,
            "overrun_discarded": self.overrun,
            "failures_per_hour": self.failures * 3600.0 / budget,
            "distinct_per_hour": distinct * 3600.0 / budget,
            "failure_rate": self.failures / self.executions if self.executions else 0.0,
            "failure_kinds": dict(sorted(self.kinds.items())),
            "first_failure_s": self.failure_times[0] if self.failure_times else None,
            "predicted_repeats": self.predicted_repeats,
            "execution_s": round(self.execution_s, 3),
            "charged_s": round(self.charged_s, 3),
            "diversity": self.failure_diversity(),
            "failure_nearest": self.failure_nearest,
            "failure_times_s": self.failure_times,
            "distinct_examples": self.distinct_examples,
            "sample": {k: [e.get(k) for e in self.sample] for k in keys},
        }


def full_model_run(problem, settings, executor, fm: dict[str, Any], seed: int,
                   clock: Callable[[], float] | None = None, trace: list | None = None) -> dict[str, Any]:
    """RQ3: one run of the schedule in the module docstring; ``clock`` measures (default ``fm['clock']``);
    ``trace`` (a list) receives one event per execution: executor, start, end, produced, counted,
    the search's evaluations and clock at the start."""
    clock = clock or make_clock(fm["clock"])
    real_start = time.perf_counter()
    budget = float(fm["time_budget_s"])
    cost = float(fm.get("execution_cost_s", 0.0))
    queue = CandidateQueue(best_first=settings.algorithm != "random")
    search = SearchProcess(problem, settings, queue, clock)
    tally = FullModelTally(problem, seed, fm.get("distinct_distance", 0.0), fm.get("signature_radius"))
    novelty = settings.algorithm != "random" and fm.get("novelty", True)  # random search stays plain sampling
    free = [0.0] * max(1, int(fm.get("executors", 1)))  # each executor's clock
    waited = 0.0
    from ..core.search import ValidSampler  # an executor's random fill: valid samples, as random search's

    fill = ValidSampler(problem, np.random.default_rng([seed, 11])) if fm.get("executor_idle", "random") == "random" \
        else None
    while True:
        e = int(np.argmin(free))
        now = free[e]
        if now >= budget:
            break
        while search.wanted() and search.t <= now:  # everything the search has produced by `now`
            search.step()
        t0 = clock()
        if novelty:
            cand = queue.pop(now, lambda c: tally.skip(c.row, now) or tally.predicted_repeat(c, now))
        else:
            cand = queue.pop(now, lambda c: tally.skip(c.row, now))
        if cand is None and fill is not None and (queue.next_time() is not None or search.exhausted):
            drawn = fill.draw(lambda row: tally.skip(row, now))  # the search is busy: never idle
            if drawn is not None:
                cand = Candidate(drawn[0], drawn[1], now, -1)
        if cand is None:
            nxt = queue.next_time()
            if nxt is None and not search.exhausted:  # nothing left: the (idle) search runs now
                search.t = max(search.t, now)
                if search.step():
                    continue
                # it bred nothing worth executing (a system it cannot find a failure of): the executor
                # runs a random sample, or waits out the step; either way its clock moves on
                drawn = None if fill is None else fill.draw(lambda row: tally.skip(row, now))
                if drawn is None:
                    waited += search.t - now
                    free[e] = search.t
                    continue
                cand = Candidate(drawn[0], drawn[1], now, -1)
            elif nxt is None:
                free[e] = math.inf  # the search can breed nothing new: this executor is done
                continue
            else:
                waited += nxt - now
                free[e] = nxt
                continue
        k = tally.dispatch(cand.row)
        sim_seed = int(np.random.SeedSequence([seed, k]).generate_state(1)[0])
        outcome = executor.execute(problem.codec.from_row(cand.row), seed=sim_seed)
        measured = clock() - t0
        charged = measured + (cost if system_ran(outcome) else 0.0)
        end = now + charged
        free[e] = end
        if trace is not None:
            trace.append({"executor": e, "start": now, "end": end, "produced": cand.produced_s, "counted": end <= budget,
                          "evaluations": search.evaluations, "search_t": search.t, "kind": outcome.failure_kind})
        if end > budget:
            tally.overrun += 1
            continue
        tally.record(cand.row, cand.f1, outcome, sim_seed, measured, charged, end)
    out = {"evaluations": search.evaluations, "search_steps": search.steps, "search_s": round(search.busy, 3),
           "best_f1": search.search.best_f1, "time_budget_s": budget, "executors": len(free),
           "execution_cost_s": cost, "waited_s": round(waited, 3),
           "random_fill": 0 if fill is None else fill.drawn, "candidates_left": len(queue),
           "wall_s": round(time.perf_counter() - real_start, 3)}
    out.update(tally.summary(budget))
    return out


__all__ = ["DISTINCT_KEPT", "SAMPLE_CAP", "Candidate", "CandidateQueue", "FullModelTally", "SearchProcess",
           "full_model_run", "make_clock", "system_ran", "warm_up"]
