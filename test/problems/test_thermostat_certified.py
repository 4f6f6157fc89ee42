"""The thermostat's ``certified`` objective (issue 26): the surrogate scores a schedule as the full
model and its reference would judge it, so that RQ3's search climbs towards certified failures
(the full model fails, an ideal controller passes) and not towards invalid tests. Also the
rank statistics of bench/surrogate_rank.py, which measure that."""
from __future__ import annotations

import numpy as np
import pytest

from ambiegen_ros.core.attributes import ScenarioError
from ambiegen_ros.core.scenario import Scenario
from ambiegen_ros.problems.thermostat import ThermostatConfig, ThermostatProblem
from ambiegen_ros.problems.thermostat_model import simulate_room
from ambiegen_ros.sims import room
from ambiegen_ros.sims.full_model import full_model_executor
from ambiegen_ros.core.stats import roc_auc, spearman

# a descending staircase: the on/off thermostat (60 s period, 0.1 degC hysteresis) stays OFF and the
# full model's room cannot cool more than k_off1 below the temperature of its last switch; the ideal
# controller re-anchors every 10 s and follows (measured: full RMSE 2.41, ideal 0.34 degC)
STAIRCASE = [(25, 105, 5), (22, 60, 3), (20, 135, 2), (19, 195, 5), (19, 180, 7), (18, 210, 4), (17, 210, 2),
             (17, 150, 6), (18, 195, 1)]


def scenario(elements) -> Scenario:
    return Scenario("thermostat", [{"temperature": t, "duration": d, "model": m} for t, d, m in elements])


@pytest.fixture(scope="module")
def certified() -> ThermostatProblem:
    return ThermostatProblem(profile="refined", objective="certified")


def sampled(problem, n=40, seed=3):
    X = problem.sample_rows(n, np.random.default_rng(seed))
    return X, problem.evaluate_rows(X)


def test_rq3_searches_for_certified_failures_with_the_refined_profile():
    case = ThermostatProblem(ThermostatProblem.certified_search)
    assert (case.config.profile, case.config.objective, case.config.certified_cap) == ("refined", "certified", 0.1)


def test_defaults_are_unchanged():
    cfg = ThermostatConfig()
    assert (cfg.objective, cfg.alpha, cfg.profile, cfg.step_minutes) == ("rmse", 1.5, "replication", 3.0)
    assert cfg.certified_cap is None


def test_alpha_defaults_to_the_requirement(certified):
    assert certified.alpha == 1.0
    assert ThermostatProblem(objective="certified", requirement_rmse=1.2).alpha == 1.2
    assert "ideal" in certified.f1_label


@pytest.mark.parametrize("ideal", [False, True])
def test_surrogate_room_is_the_full_model_without_noise(certified, ideal):
    """Same room, controller period, hysteresis and error sampling as sims.room.heat."""
    X, ev = sampled(certified, 12)
    G, L = certified.codec.split(X)
    rmse, top, hour = simulate_room(G, L, certified.config, ideal=ideal)
    sim = room.RoomSimConfig(sensor_noise=0.0, sensor_resolution=0.0)
    if ideal:
        sim = room.ideal_config(sim)
    for i in range(len(X)):
        m = int(L[i])
        full = room.heat(G[i, :m, 0], G[i, :m, 1], G[i, :m, 2].astype(int), certified.config.room_models, sim)
        assert rmse[i] == pytest.approx(full["rmse"], abs=1e-9)
        assert top[i] == pytest.approx(full["max_error"], abs=1e-9)
        assert hour[i] == pytest.approx(full["worst_time_s"] / 3600.0)


def test_numpy_engine_gives_the_compiled_results(certified):
    X, ev = sampled(certified, 20)
    slow = ThermostatProblem(profile="refined", objective="certified", engine="numpy").evaluate_rows(X)
    np.testing.assert_allclose(slow.f1, ev.f1, rtol=0, atol=1e-12)


def test_f1_is_the_smaller_certified_margin(certified):
    X, ev = sampled(certified, 60)
    S, R = ev.metrics["rmse"], ev.metrics["reference_rmse"]
    expected = np.where(ev.valid, np.maximum(np.minimum(S, 2.0 - R), 0.0), 0.0)
    np.testing.assert_allclose(ev.f1, expected)
    risky = ev.f1 > certified.alpha
    np.testing.assert_array_equal(risky, ev.valid & (S > 1.0) & (R < 1.0))


def test_a_schedule_the_reference_also_fails_scores_below_alpha(certified):
    """A 16 -> 20 degC day of 1 h elements: no controller heats that fast, so both fail."""
    sc = scenario([(16, 60, 7), (20, 60, 7), (16, 60, 7), (20, 60, 7)])
    ev = certified.evaluate_scenarios([sc])
    assert ev.metrics["reference_rmse"][0] > 1.0 and ev.metrics["rmse"][0] > 1.0
    assert ev.f1[0] < certified.alpha
    out = full_model_executor(certified).execute(sc, seed=1)
    assert out.failure_kind == "invalid_test"


def test_a_surrogate_certified_failure_is_certified_by_the_full_model(certified):
    sc = scenario(STAIRCASE)
    ev = certified.evaluate_scenarios([sc])
    assert ev.valid[0] and ev.f1[0] > certified.alpha
    out = full_model_executor(certified).execute(sc, seed=7)
    assert out.failed and out.reference["passed"]


def test_cap_flattens_clear_failures_only():
    capped = ThermostatProblem(profile="refined", objective="certified", certified_cap=0.1)
    plain = ThermostatProblem(profile="refined", objective="certified")
    sc = scenario(STAIRCASE)
    assert plain.evaluate_scenarios([sc]).f1[0] > 1.1
    assert capped.evaluate_scenarios([sc]).f1[0] == pytest.approx(1.1)
    X = plain.sample_rows(60, np.random.default_rng(5))
    a, b = plain.evaluate_rows(X).f1, capped.evaluate_rows(X).f1
    np.testing.assert_allclose(b, np.minimum(a, 1.1))


def test_invalid_schedules_score_zero(certified):
    sc = scenario([(16, 60, 1), (22, 60, 1)])  # R2: a 6 degC jump
    ev = certified.evaluate_scenarios([sc])
    assert not ev.valid[0] and ev.f1[0] == 0.0


@pytest.mark.parametrize("bad", [{"control_seconds": 25.0}, {"sample_seconds": 0.0}, {"certified_cap": 0.0}])
def test_bad_settings_are_refused(bad):
    with pytest.raises(ScenarioError):
        ThermostatConfig(objective="certified", **bad)


# --- the rank statistics bench/surrogate_rank.py reports (core.stats) -----------------------------------
def test_roc_auc_and_spearman():
    assert roc_auc([0.1, 0.2, 0.8, 0.9], [0, 0, 1, 1]) == 1.0
    assert roc_auc([0.9, 0.8, 0.2, 0.1], [0, 0, 1, 1]) == 0.0
    assert roc_auc([0.5, 0.5, 0.5, 0.5], [0, 1, 0, 1]) == 0.5
    assert np.isnan(roc_auc([1.0, 2.0], [1, 1]))
    assert spearman([1, 2, 3, 4], [10, 20, 30, 40])[0] == pytest.approx(1.0)
    scipy_stats = pytest.importorskip("scipy.stats")
    rng = np.random.default_rng(0)
    x, y = rng.integers(0, 5, 50), rng.integers(0, 2, 50)
    assert spearman(x, y)[0] == pytest.approx(scipy_stats.spearmanr(x, y)[0])
