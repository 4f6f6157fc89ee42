"""The thermostat's replication profile reproduces the authors' replication code.

Pinned on a copy of its verdicts (test/data/replication/thermostat.jsonl: scenarios drawn by our
sampler and by the replication code's own generator, including days that run past 24 h).
"""
from __future__ import annotations

import numpy as np
import pytest
from replication_reference import agreement, load

from ambiegen_ros.core.scenario import Scenario
from ambiegen_ros.problems.thermostat import ThermostatProblem


@pytest.fixture(scope="module")
def problem() -> ThermostatProblem:
    return ThermostatProblem()  # replication is the default profile


def schedule(temps, durations, models) -> Scenario:
    return Scenario("thermostat", [{"temperature": t, "duration": d, "model": m} for t, d, m in zip(temps, durations, models)])


def test_replication_is_the_default(problem):
    assert problem.profile == "replication"
    assert problem.config_dict()["profile"] == "replication"


@pytest.mark.parametrize("sampler", ["project", "replication"])
def test_verdicts_match_the_replication_code(problem, sampler):
    rows = [r for r in load("thermostat") if r["sampler"] == sampler]
    assert len(rows) >= 75
    result = agreement(problem, rows)
    assert result.validity_rate >= 0.99, result.mismatches[:5]
    assert result.both_valid >= 25
    assert result.f1_rate >= 0.99, result.mismatches[:5]


def test_the_refined_profile_is_a_different_model(problem):
    """The reference pins the replication profile only: refined scores the same days differently."""
    rows = [r for r in load("thermostat") if r["replication"]["valid"]][:40]
    refined = agreement(ThermostatProblem(profile="refined"), rows)
    assert refined.f1_rate < 0.5


def test_days_past_24h_are_cut_as_the_replication_code_does(problem):
    rows = [r for r in load("thermostat") if sum(e["duration"] for e in r["scenario"]["elements"]) > 1440]
    assert rows, "the reference copy keeps the generator's over-long days"
    for row in rows:
        sc = problem.parse(row["scenario"])
        total, kept = 0, []
        for e in sc.elements:
            total += e["duration"]
            if total > 1440:
                break
            kept.append(e)
        ev = problem.evaluate_scenarios([sc, Scenario("thermostat", kept)])
        assert ev.valid[0] == ev.valid[1] == row["replication"]["valid"]
        assert ev.f1[0] == ev.f1[1] == pytest.approx(row["replication"]["f1"], abs=1e-6)
        assert ev.metrics["scored_elements"][0] == len(kept) < len(sc.elements)
        env = problem.environment(sc)  # what is plotted and executed is what was scored
        assert env.durations == [e["duration"] for e in kept]
        assert env.minutes[-1] == sum(env.durations) <= 1440


def test_validity_is_the_span_of_the_whole_day(problem):
    ok = schedule([16, 21, 16, 21], [240] * 4, [1] * 4)  # adjacent jumps of 5 are fine; span 5
    bad = schedule([16, 19, 21, 22], [240] * 4, [1] * 4)  # small steps, but a span of 6
    ev = problem.evaluate_scenarios([ok, bad])
    assert ev.valid[0] and ev.f1[0] > 0
    assert not ev.valid[1] and ev.f1[1] == 0 and "span" in ev.reasons[1]
    refined = ThermostatProblem(profile="refined").evaluate_scenarios([ok, bad])
    assert not refined.valid[0] and refined.valid[1]


def test_error_is_sampled_at_the_start_of_each_step(problem):
    """One-step lag: a constant day at the room's start temperature begins with error 0."""
    day = schedule([20] * 6, [240] * 6, [1] * 6)
    rep = problem.evaluate_scenarios([day])
    ref = ThermostatProblem(profile="refined").evaluate_scenarios([day])
    assert rep.f1[0] != ref.f1[0]
    env = problem.environment(day)
    errors = np.concatenate([[env.initial_temperature], env.temperature[:-1]]) - env.goal
    assert rep.f1[0] == pytest.approx(np.sqrt(np.mean(errors**2)), abs=1e-12)


def test_replication_sampler_follows_the_replication_generator(problem):
    G, lengths = problem.sample(3000, np.random.default_rng(2024))
    assert problem.codec.in_domain(G, lengths).all()
    used = np.arange(problem.m_max)[None, :] < lengths[:, None]
    dur = np.where(used, G[:, :, 1], 0)
    total = dur.sum(axis=1)
    assert np.all(total <= 1440)
    assert 0.95 < np.mean(total == 1440) < 0.99  # the rest of the day closes it; ~3.5 % over-long draws are cut
    assert dur.max() > 240  # a short rest is merged into the last element
    jumps = np.abs(np.diff(G[:, :, 0], axis=1))[used[:, 1:]]
    assert jumps.max() == 5  # next temperature within t..t+5 / t-5..t
    valid = problem.evaluate(G, lengths).valid.mean()
    reference = np.mean([r["replication"]["valid"] for r in load("thermostat") if r["sampler"] == "replication"])
    assert abs(valid - reference) < 0.1  # ~38 % of the generator's days are valid (span <= 5)
