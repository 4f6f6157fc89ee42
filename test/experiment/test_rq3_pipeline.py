"""RQ3's pipeline: the discrete-event schedule, skipping, failure signatures, invalid tests, the gallery.

Every schedule test runs on a fake clock moved only by the fake search and the fake executor, so
what is asserted are events in virtual time, never the machine's speed.
"""
from __future__ import annotations

import math

import json

import numpy as np
import pytest

from ambiegen_ros.core.search import Search, SearchSettings
from ambiegen_ros.experiment import CandidateQueue, ExperimentSpec, FullModelTally, full_model_run
from ambiegen_ros.problems import get_problem
from ambiegen_ros.sims.outcome import Outcome
from ambiegen_ros.core.scenario import Scenario
from ambiegen_ros.sims.signature import (ENTRIES, DistinctFailures, FailureSignature, failing_bend, same_failure,
                                         signature)


class FakeClock:
    def __init__(self):
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def timed_problem(clock: FakeClock, per_batch: float):
    """The real thermostat problem whose surrogate evaluations take ``per_batch`` fake seconds."""
    problem = get_problem("thermostat")
    evaluate = problem.evaluate_rows

    def evaluate_rows(X):
        clock.now += per_batch
        return evaluate(X)

    problem.evaluate_rows = evaluate_rows
    return problem


class ScriptedExecutor:
    """Takes ``delay`` fake seconds; fails every ``fail_every``-th scenario (0 = never)."""

    def __init__(self, clock: FakeClock, delay: float = 0.0, fail_every: int = 0):
        self.clock, self.delay, self.fail_every = clock, delay, fail_every
        self.calls = 0

    def execute(self, scenario, seed=0):
        self.clock.now += self.delay
        self.calls += 1
        failed = bool(self.fail_every) and self.calls % self.fail_every == 0
        return Outcome(objectives={"x": 1.0}, failed=failed, failure_kind="requirement" if failed else "none",
                       failure_point=(float(self.calls % 24), 20.0) if failed else None)


def fm(budget: float, cost: float = 0.0, executors: int = 1, **extra) -> dict:
    return {"time_budget_s": budget, "clock": "wall", "execution_cost_s": cost, "executors": executors,
            "distinct_distance": 0.0, "signature_radius": None, **extra}


SETTINGS = SearchSettings(algorithm="nsga2", evaluations=20, population=10, offspring=10, seed=1)


def run(budget, cost, per_batch=0.01, delay=0.0, executors=1, settings=SETTINGS, fail_every=0, **extra):
    clock = FakeClock()
    problem = timed_problem(clock, per_batch)
    trace: list = []
    out = full_model_run(problem, settings, ScriptedExecutor(clock, delay, fail_every),
                         fm(budget, cost, executors, **extra), seed=3, clock=clock, trace=trace)
    return out, trace


@pytest.mark.parametrize("algorithm", ["nsga2", "random"])
def test_no_candidate_runs_before_the_search_produced_it_and_the_budget_holds(algorithm):
    settings = SearchSettings(algorithm=algorithm, evaluations=20, population=10, offspring=10, seed=1)
    out, trace = run(budget=30.0, cost=0.7, per_batch=0.5, executors=2, settings=settings)
    assert trace and {t["executor"] for t in trace} == {0, 1}
    for t in trace:
        assert t["start"] >= t["produced"]  # produced at or before its execution starts
    counted = [t for t in trace if t["counted"]]
    assert all(t["end"] <= 30.0 for t in counted)
    assert out["executions"] + out["rejected"] == len(counted)
    assert out["overrun_discarded"] == len(trace) - len(counted) <= 2  # at most one per executor
    for e in (0, 1):  # an executor's executions never overlap on its own clock
        mine = [t for t in trace if t["executor"] == e]
        assert all(a["end"] <= b["start"] + 1e-12 for a, b in zip(mine, mine[1:]))


def test_with_a_large_execution_cost_executions_are_budget_over_cost():
    out, _ = run(budget=300.0, cost=30.0, per_batch=0.01)
    assert abs(out["executions"] - 300.0 / 30.0) <= 1
    # executions measure 0 s on the fake clock; a random sample an idle executor drew is paid too
    assert out["charged_s"] == pytest.approx(out["executions"] * 30.0 + out["execution_s"])
    assert out["execution_s"] == pytest.approx(0.01 * math.ceil(out["random_fill"] / 64), abs=0.05)
    out2, _ = run(budget=300.0, cost=30.0, per_batch=0.01, executors=3)
    assert abs(out2["executions"] - 3 * 300.0 / 30.0) <= 3


def test_the_population_is_carried_on_never_restarted(monkeypatch):
    made = []
    real_init = Search.__init__

    def counting_init(self, *args, **kwargs):
        made.append(1)
        real_init(self, *args, **kwargs)

    monkeypatch.setattr(Search, "__init__", counting_init)
    # cheap executions drain the queue: the search has to keep breeding, one generation per second
    # (executors wait for it here, so that every execution is the search's)
    out, trace = run(budget=40.0, cost=0.05, per_batch=1.0, executor_idle="wait")
    assert len(made) == 1
    evals = [t["evaluations"] for t in trace]
    assert evals == sorted(evals) and evals[-1] > 3 * SETTINGS.evaluations
    assert out["evaluations"] >= evals[-1] and out["search_steps"] * 10 == out["evaluations"]
    assert out["waited_s"] > 0  # the executor waited for the search


@pytest.mark.parametrize("executors", [1, 2])
def test_an_executor_never_waits_for_the_search(executors):
    """The same slow search: by default an executor without a candidate runs a valid random sample
    of its own (produced when it starts), so no simulator idles and nothing waits."""
    waiting, _ = run(budget=40.0, cost=0.05, per_batch=1.0, executors=executors, executor_idle="wait")
    out, trace = run(budget=40.0, cost=0.05, per_batch=1.0, executors=executors)
    assert waiting["waited_s"] > 0 and waiting["random_fill"] == 0
    assert out["waited_s"] == 0 and out["random_fill"] > 0
    assert out["executions"] + out["rejected"] > waiting["executions"] + waiting["rejected"]
    for t in trace:
        assert t["start"] >= t["produced"]
    for e in range(executors):  # back to back on each executor's clock: no gap the search left
        mine = [t for t in trace if t["executor"] == e]
        assert all(b["start"] == pytest.approx(a["end"]) or b["start"] > a["end"] - 1e-12 for a, b in zip(mine, mine[1:]))


def test_the_search_stops_after_its_guaranteed_budget_while_candidates_wait():
    # slow executions of random samples (every valid one is a candidate): the queue never empties,
    # so the sampler stops at its guaranteed evaluations
    random = SearchSettings(algorithm="random", evaluations=100, population=10, seed=1)
    out, trace = run(budget=100.0, cost=10.0, per_batch=0.01, settings=random)
    assert out["evaluations"] == 100 and out["candidates_left"] > 0
    assert out["executions"] == 9 and out["overrun_discarded"] == 1  # the first sample exists at 0.01 s
    assert [t["evaluations"] for t in trace][1:] == [100] * (len(trace) - 1)


def test_queue_orders_best_first_and_skips_executed_and_near_failures():
    problem = get_problem("thermostat")
    rows = problem.sample_rows(3, np.random.default_rng(4))
    q = CandidateQueue(best_first=True)
    assert q.push(rows[0], 1.0, 0.0) and q.push(rows[1], 3.0, 0.0) and q.push(rows[2], 2.0, 5.0)
    assert not q.push(rows[0], 9.0, 1.0)  # the same scenario once
    assert q.pop(1.0, lambda c: False).f1 == 3.0  # rows[2] is not produced yet at t = 1
    assert q.next_time() == 5.0 and q.pop(6.0, lambda c: False).f1 == 2.0

    tally = FullModelTally(problem, seed=1, distinct_distance=0.0)
    assert not tally.skip(rows[0], 0.0)
    tally.dispatch(rows[0])
    assert tally.seen(rows[0]) and not tally.seen(rows[1])
    failed = Outcome(objectives={"x": 1.0}, failed=True, failure_kind="requirement", failure_point=(1.0, 20.0))
    tally.dispatch(rows[1])
    tally.record(rows[1], 2.0, failed, 7, 0.1, 1.1, end_s=5.0)
    from ambiegen_ros.core.diversity import nearest_distance

    split = [problem.canonical(*problem.codec.split(r[None, :])) for r in (rows[2], rows[1])]
    d = float(nearest_distance(*split[0], *split[1], problem.codec.attributes)[0])
    assert 0 < d <= 1
    near = FullModelTally(problem, seed=1, distinct_distance=d)
    near.record(rows[1], 2.0, failed, 7, 0.1, 1.1, end_s=5.0)
    assert not near.near_failure(rows[2], 4.0)  # the failure had not ended yet
    assert near.near_failure(rows[2], 5.0) and near.skip(rows[2], 6.0)
    farther = FullModelTally(problem, seed=1, distinct_distance=d * 0.999)
    farther.record(rows[1], 2.0, failed, 7, 0.1, 1.1, end_s=5.0)
    assert not farther.skip(rows[2], 6.0)
    strict = FullModelTally(problem, seed=1, distinct_distance=0.0)
    strict.record(rows[1], 2.0, failed, 7, 0.1, 1.1, end_s=5.0)
    assert strict.near_failure(rows[1], 6.0) and not strict.near_failure(rows[2], 6.0)


def test_invalid_tests_are_counted_apart_never_as_failures():
    problem = get_problem("thermostat")
    row = problem.sample_rows(1, np.random.default_rng(5))[0]
    tally = FullModelTally(problem, seed=1)
    after_run = Outcome(objectives={"x": 3.0}, failed=False, failure_kind="invalid_test", detail="no room can follow it",
                        metrics={"sut_failure_kind": "requirement"}, failure_point=(2.0, 20.0))
    tally.record(row, 3.0, after_run, 1, 0.1, 30.1, end_s=30.1)
    screened = Outcome(objectives={}, failed=False, failure_kind="invalid_test", detail="no route keeps 0.39 m")
    tally.record(row, 3.0, screened, 2, 0.1, 0.1, end_s=30.2)
    tally.record(row, 3.0, Outcome.rejected("restriction broken"), 3, 0.0, 0.0, end_s=30.2)
    s = tally.summary(budget=3600)
    assert (s["executions"], s["invalid_tests"], s["screened_out"], s["failures"], s["distinct_failures"],
            s["rejected"]) == (1, 2, 1, 0, 0, 1)
    assert s["failure_kinds"] == {"invalid_test": 2} and s["failure_rate"] == 0.0


def test_execution_cost_is_charged_only_when_the_system_under_test_ran():
    from ambiegen_ros.experiment.pipeline import system_ran

    before = Outcome(objectives={}, failed=False, failure_kind="invalid_test", detail="road leaves the map")
    after = Outcome(objectives={"x": 1.0}, failed=False, failure_kind="invalid_test", detail="the reference fails too",
                    metrics={"sut_failure_kind": "out_of_lane"})
    assert not system_ran(before) and system_ran(after) and not system_ran(Outcome.rejected("no"))

    class HalfInvalid(ScriptedExecutor):
        def execute(self, scenario, seed=0):
            out = super().execute(scenario, seed)
            return before if self.calls % 2 else out

    clock = FakeClock()
    out = full_model_run(timed_problem(clock, 0.01), SETTINGS, HalfInvalid(clock, delay=0.5), fm(100.0, 10.0, executor_idle="wait"),
                         seed=3, clock=clock)
    assert out["invalid_tests"] == out["screened_out"] > 0 and out["executions"] > 0
    assert out["charged_s"] == pytest.approx(0.5 * (out["executions"] + out["screened_out"]) + 10.0 * out["executions"])


def _failed(kind, point=None, **metrics):
    return Outcome(objectives={"x": 1.0}, failed=True, failure_kind=kind, failure_point=point, metrics=metrics)


def test_robot_signature_is_kind_and_place_within_the_radius():
    robot = get_problem("robot")
    a = signature(robot, None, _failed("stall", (3.0, 4.0)))
    assert a.place == (3.0, 4.0)
    assert same_failure(a, signature(robot, None, _failed("stall", (4.0, 5.0))))  # 1.4 m apart
    assert not same_failure(a, signature(robot, None, _failed("stall", (6.0, 4.0))))  # 3 m apart
    assert not same_failure(a, signature(robot, None, _failed("loiter", (3.0, 4.0))))  # another kind
    assert same_failure(a, signature(robot, None, _failed("stall", (6.0, 4.0))), radius=3.5)
    assert signature(robot, None, Outcome(objectives={}, failed=False, failure_kind="invalid_test")) is None


def _bend_road(turn_deg, radius=20.0, lead=80.0, sign=1):
    """A straight of ``lead`` m, then a bend of ``radius`` turning ``turn_deg`` (sign +1 left), then 40 m straight."""
    straight = np.column_stack([np.arange(-lead, 0.0, 1.0), np.zeros(int(lead))])
    t = np.linspace(0, np.radians(turn_deg), int(radius * np.radians(turn_deg)) + 2)
    bend = np.column_stack([radius * np.sin(t), sign * (radius - radius * np.cos(t))])
    end, heading = bend[-1], t[-1]
    out = end + np.outer(np.arange(1.0, 41.0), [np.cos(heading), sign * np.sin(heading)])
    return np.concatenate([straight, bend, out])


def test_vehicle_signature_is_the_failing_bend_by_shape_wherever_it_lies():
    road = _bend_road(90)
    direction, kappa, turn, entry = failing_bend(road, 80.0 + 25.0)  # the car leaves the lane in the bend
    assert direction == 1 and kappa == pytest.approx(0.05, rel=0.05) and turn == pytest.approx(90, abs=6)
    assert ENTRIES[entry] == "after a long straight"
    assert failing_bend(road * [1, -1], 105.0)[0] == -1  # mirrored: a right bend
    assert failing_bend(road, 20.0)[0] == 0  # on the first straight: no bend
    assert ENTRIES[failing_bend(_bend_road(90, lead=20), 45.0)[3]] == "after a short straight"
    assert failing_bend(_bend_road(180), 140.0)[2] == pytest.approx(180, abs=8)

    def sig(arc, direction, kappa, turn, entry):
        return FailureSignature("vehicle", "out_of_lane", (arc, direction, kappa, turn, entry))

    a = sig(100.0, 1, 0.05, 90.0, 0)
    assert same_failure(a, sig(300.0, 1, 0.045, 110.0, 0))  # elsewhere on another road, the same bend
    assert not same_failure(a, sig(100.0, -1, 0.05, 90.0, 0))  # left vs right
    assert not same_failure(a, sig(100.0, 1, 0.05, 180.0, 0))  # a hairpin is not a right angle
    assert not same_failure(a, sig(100.0, 1, 0.05, 90.0, 2))  # after an opposite bend
    assert not same_failure(a, sig(100.0, 1, 0.03, 90.0, 0))  # R 20 m vs R 33 m
    assert same_failure(a, sig(100.0, 1, 0.05, 180.0, 0), radius=100)

    vehicle = get_problem("vehicle")
    rng = np.random.default_rng(2)
    rows = vehicle.sample_rows(50, rng)
    row = rows[np.flatnonzero(vehicle.evaluate_rows(rows).valid)[0]]
    scenario = vehicle.codec.from_row(row)
    b = signature(vehicle, scenario, _failed("out_of_lane", (0, 0), departure_arc_length=30.0, oob_arc_length=33.0))
    assert b.place[0] == 33.0 and len(b.place) == 5 and b.describe().startswith("out_of_lane")  # where it left
    assert not same_failure(b, FailureSignature("vehicle", "out_of_lane", (30.0, 0.05)))  # an old, shorter place


def test_thermostat_signature_is_the_kind_of_element_that_broke_not_its_index():
    thermostat = get_problem("thermostat", {"profile": "refined"})

    def day(elements):
        return Scenario("thermostat", [{"temperature": t, "duration": d, "model": m} for t, d, m in elements])

    a = day([(20, 120, 1), (24, 180, 3), (22, 240, 2)])
    shifted = day([(21, 60, 4), (20, 120, 1), (23, 180, 3), (22, 240, 2)])  # one element later, a 3 degC step
    hour = lambda start_min: _failed("requirement", ((start_min + 30) / 60.0, 20.0))  # noqa: E731
    in_second = signature(thermostat, a, hour(120))
    assert in_second.place == (1.0, 1.0, 4.0, 3.0, 1.0)  # element 1: +4 degC, model 3, 2-3 h
    assert in_second.describe().startswith("requirement in an element after a 4 degC step up, room model 3")
    same_kind = signature(thermostat, shifted, hour(180))
    assert same_kind.place[0] == 2 and same_failure(in_second, same_kind)  # the index does not matter
    assert not same_failure(in_second, same_kind, radius=0.5)  # 4 vs 3 degC with a 0.5 degC tolerance
    in_third = signature(thermostat, a, hour(300))  # a step down into model 2, over 3 h
    assert in_third.place[1:] == (-1.0, 2.0, 2.0, 2.0) and not same_failure(in_second, in_third)
    first = signature(thermostat, a, hour(0))
    assert first.place[1] == 0 and not same_failure(first, in_second)
    distinct = DistinctFailures()
    assert [distinct.add(s) for s in (in_second, same_kind, in_third)] == [True, False, True] and len(distinct) == 2


def test_gallery_writes_a_picture_and_the_scenario_per_distinct_failure(tmp_path):
    from ambiegen_ros.experiment.report import report
    from ambiegen_ros.experiment.spec import resolve
    from ambiegen_ros.viz.experiment import _gallery_picks, plot_gallery

    spec = ExperimentSpec(problem="thermostat", algorithms=("nsga2",), runs=1, full_model=True, time_budget=60,
                          execution_cost=30)
    identity = resolve(spec)
    config = {"identity": identity, "algorithms": ["nsga2"], "problem": "thermostat", "profile": identity["profile"],
              "runs": 1}
    problem = get_problem("thermostat")
    rows = problem.sample_rows(2, np.random.default_rng(8))  # two distinct failures and a repeat
    examples = []
    for i, row in enumerate(rows):
        sig = FailureSignature("thermostat", "requirement", (float(i), 1.0, 2.0 + 3 * i, 1.0, 0.0))
        examples.append({"signature": sig.to_dict(), "describe": sig.describe(), "kind": "requirement",
                         "verdict": "FAIL(requirement)", "detail": "", "surrogate_f1": 2.0, "time_s": 30.0 * (i + 1),
                         "sim_seed": 11 + i, "scenario": problem.codec.from_row(row).to_dict()})
    records = [{"algorithm": "nsga2", "run": 0, "distinct_examples": examples[:1]},
               {"algorithm": "nsga2", "run": 1, "distinct_examples": examples[::-1]}]  # run 1 repeats run 0's
    picks = _gallery_picks(records, "nsga2", None, 12)
    assert [(rec["run"], e["sim_seed"]) for rec, e in picks] == [(0, 11), (1, 12)]
    gallery = plot_gallery(tmp_path, config, records, per_algorithm=1)  # one picture: matplotlib is slow
    assert [g["png"].name for g in gallery] == ["nsga2-01.png"]
    for g in gallery:
        assert g["png"].stat().st_size > 1000
        doc = json.loads(g["json"].read_text())
        assert doc["scenario"] == examples[0]["scenario"] and doc["sim_seed"] == 11
    rec = {"algorithm": "nsga2", "run": 0, "executions": 2, "failures": 2, "distinct_failures": 2, "invalid_tests": 0,
           "failures_per_hour": 120.0, "distinct_per_hour": 120.0, "failure_rate": 1.0}
    text = report(config, [rec], {"runs": {"nsga2": 1}, "tests": []}, [], gallery)
    assert "## Failure gallery" in text and "(gallery/nsga2-01.png)" in text and "gallery/nsga2-01.json" in text

