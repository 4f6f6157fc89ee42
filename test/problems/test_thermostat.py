"""Thermostat case study, refined profile (the paper's text) and what both profiles share:
restrictions, simulation semantics, vectorised == reference, sampler, plot. The replication
profile's fidelity to the authors' code is pinned in test_thermostat_replication.py."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ambiegen_ros.core.attributes import ScenarioError
from ambiegen_ros.core.scenario import Scenario
from ambiegen_ros.problems.thermostat import (
    ROOM_MODELS,
    ThermostatConfig,
    ThermostatProblem,
    schedule_steps,
    simulate_batch,
    simulate_schedule,
)


def scenario(temps, durations, models) -> Scenario:
    elements = [
        {"temperature": t, "duration": d, "model": m} for t, d, m in zip(temps, durations, models)
    ]
    return Scenario("thermostat", elements)


@pytest.fixture(scope="module")
def problem() -> ThermostatProblem:
    return ThermostatProblem(profile="refined")


PROFILES = ("replication", "refined")


def test_declared_shape(problem):
    assert problem.name == "thermostat"
    assert [a.name for a in problem.attributes] == ["temperature", "duration", "model"]
    assert (problem.m_min, problem.m_max) == (1, 24)
    assert problem.alpha == 1.5
    assert problem.paper_budget.evaluations == 50000


# --- restrictions ------------------------------------------------------------------------------
def test_r1_too_long_is_invalid(problem):
    ev = problem.evaluate_scenarios([scenario([20] * 7, [240] * 7, [1] * 7)])  # 28 h
    assert not ev.valid[0]
    assert ev.f1[0] == 0.0
    assert ev.reasons[0].startswith("R1")
    assert "1680" in ev.reasons[0]
    assert ev.metrics["duration_min"][0] == 1680


def test_r1_exactly_24h_is_valid(problem):
    ev = problem.evaluate_scenarios([scenario([20] * 6, [240] * 6, [1] * 6)])
    assert ev.valid[0] and ev.reasons[0] is None and ev.f1[0] > 0


def test_r2_jump_is_invalid_and_names_the_elements(problem):
    ev = problem.evaluate_scenarios(
        [
            scenario([18, 19, 20, 25, 21], [60] * 5, [1] * 5),  # |25-20| = 5 between 2 and 3
            scenario([18, 22, 18, 22], [60] * 4, [1] * 4),  # jumps of 4 are allowed
        ]
    )
    assert not ev.valid[0] and ev.f1[0] == 0.0
    assert ev.reasons[0].startswith("R2")
    assert "elements[2] and elements[3]" in ev.reasons[0]
    assert "|20-25|" in ev.reasons[0]
    assert ev.valid[1] and ev.f1[1] > 0


def test_out_of_domain_cell_is_invalid_not_a_crash(problem):
    row = problem.codec.to_row(scenario([20, 21], [120, 120], [1, 2]))
    row[1 + 1 * 3 + 2] = 9  # model 9 of element 1
    ev = problem.evaluate_rows(row[None])
    assert not ev.valid[0] and ev.f1[0] == 0.0
    assert "elements[1].model" in ev.reasons[0]


def test_invalid_rows_do_not_change_valid_results(problem):
    good = scenario([20, 23, 19], [120, 240, 180], [3, 1, 5])
    bad = scenario([16, 25], [60, 60], [1, 1])
    alone = problem.evaluate_scenarios([good])
    mixed = problem.evaluate_scenarios([bad, good, bad])
    assert list(mixed.valid) == [False, True, False]
    assert list(mixed.f1) == [0.0, alone.f1[0], 0.0]


# --- simulation semantics ----------------------------------------------------------------------
def test_first_steps_follow_the_paper_formulas():
    """Start at the first goal with the heater ON; the first sample is after the first step."""
    k_on1, k_on2, k_off1, k_off2 = ROOM_MODELS[0]
    config = ThermostatConfig(profile="refined")
    temps, errors, heater = simulate_schedule([20.0] * 4, [1] * 4, config, return_heater=True)
    t1 = 20.0 + k_on1 * (1 - math.exp(-k_on2))
    assert temps[0] == pytest.approx(t1, abs=1e-12)
    # t1 >= 20.1, so the heater switches OFF and a new phase starts from t1 with n = 1, 2
    assert temps[1] == pytest.approx(t1 + k_off1 * math.exp(-k_off2) - k_off1, abs=1e-12)
    assert temps[2] == pytest.approx(t1 + k_off1 * math.exp(-2 * k_off2) - k_off1, abs=1e-12)
    assert list(heater[:3]) == [True, False, False]
    np.testing.assert_array_equal(errors, temps - 20.0)  # refined: sampled after each step


def test_curve_restarts_at_every_element_boundary():
    """Both profiles: a new element restarts the curve (T0 = T, n = 1, its room model), with or
    without a heater switch; refined keeps the heater state, replication re-decides it."""
    goals = [16.0, 25.0, 25.0, 25.0]
    models = [1, 1, 1, 2]
    starts = [True, True, False, True]  # elements: step 0 | steps 1-2 | step 3 (same goal, model 2)
    k1, k2 = ROOM_MODELS[0][:2]
    k1b, k2b = ROOM_MODELS[1][:2]
    for profile in PROFILES:
        config = ThermostatConfig(profile=profile)
        temps, _ = simulate_schedule(goals, models, config, starts=starts)
        assert temps[0] == pytest.approx(16 + k1 * (1 - math.exp(-k2)), abs=1e-12)
        # step 1 starts element 2 (goal 25): the curve restarts from temps[0] with n = 1, 2
        assert temps[1] == pytest.approx(temps[0] + k1 * (1 - math.exp(-k2)), abs=1e-12)
        assert temps[2] == pytest.approx(temps[0] + k1 * (1 - math.exp(-2 * k2)), abs=1e-12)
        # step 3 starts element 3 without a switch: restart with model 2, n = 1
        assert temps[3] == pytest.approx(temps[2] + k1b * (1 - math.exp(-k2b)), abs=1e-12)
    G = np.zeros((1, 24, 3))
    G[0, :3] = [[16, 3, 1], [25, 6, 1], [25, 3, 2]]  # 3 + 6 + 3 minutes at step 3 min
    for profile in PROFILES:
        config = ThermostatConfig(profile=profile)
        run = simulate_batch(G, np.array([3]), config, record=True)
        temps, _ = simulate_schedule(goals, models, config, starts=starts)
        np.testing.assert_array_equal(run.temperature[0, :4], temps)


def test_replication_redecides_the_heater_at_an_element_boundary():
    """Cooling towards 20 (OFF), then an element with goal 20 again at T within the band:
    refined stays OFF (hysteresis), replication turns ON since T < goal + h."""
    goals = [20.0] * 12
    starts = [s in (0, 6) for s in range(12)]
    k = ThermostatConfig(profile="refined")
    t_ref, _, h_ref = simulate_schedule(goals, [1] * 12, k, starts=starts, return_heater=True)
    t_rep, _, h_rep = simulate_schedule(goals, [1] * 12, ThermostatConfig(), starts=starts, return_heater=True)
    np.testing.assert_array_equal(t_ref[:6], t_rep[:6])
    assert not h_ref[5] and not h_rep[5]  # cooling before the boundary in both
    assert h_rep[6] and not h_ref[6]


def test_schedule_steps_maps_minutes_to_elements():
    goals, models, starts = schedule_steps([20, 22], [60, 75], [3, 4])
    assert len(goals) == (60 + 75) // 3
    assert list(np.flatnonzero(starts)) == [0, 20]
    assert list(goals[:20]) == [20] * 20 and list(goals[20:]) == [22] * 25
    assert list(models[19:21]) == [3, 4]


@pytest.mark.parametrize("model", range(1, 8))
def test_trackable_schedules_have_small_rmse(problem, model):
    constant = scenario([20] * 6, [240] * 6, [model] * 6)
    gentle = scenario([20, 21, 22, 21, 20, 21, 22, 21], [180] * 8, [model] * 8)
    ev = problem.evaluate_scenarios([constant, gentle])
    assert ev.valid.all()
    assert 0 < ev.f1[0] < 0.5 and 0 < ev.f1[1] < 0.5
    assert np.all(ev.metrics["max_error"] >= ev.f1)


def test_harsh_schedule_breaks_the_requirement(problem):
    gentle = scenario([20, 21, 22, 21, 20, 21, 22, 21], [180] * 8, [1] * 8)
    harsh = scenario([25, 21, 25, 21, 25, 21, 25, 21], [180] * 8, [1] * 8)  # slow cooling room
    ev = problem.evaluate_scenarios([gentle, harsh])
    assert ev.f1[1] > problem.config.requirement_rmse
    assert ev.f1[1] > 3 * ev.f1[0]


# --- vectorised == reference ---------------------------------------------------------------------
def _reference_run(G, lengths, config):
    out = []
    for row, m in zip(G, lengths):
        goals, models, starts = schedule_steps(row[:m, 0], row[:m, 1], row[:m, 2], config)
        out.append((goals, models, *simulate_schedule(goals, models, config, starts=starts)))
    return out


@pytest.mark.parametrize("sampling, profile", [("markov", "refined"), ("uniform", "refined"), ("markov", "replication")])
def test_vectorised_matches_reference(sampling, profile):
    """Same temperatures and errors bit for bit: both read one curve table."""
    problem = ThermostatProblem(sampling=sampling, profile=profile)
    G, lengths = problem.sample(50, np.random.default_rng(7))
    # a few short schedules so rows end at different steps within one batch
    G[:5, 3:] = 0.0
    lengths[:5] = 3
    G[5, 0, 1], lengths[5] = 60, 1
    run = simulate_batch(G, lengths, problem.config, record=True)
    for i, (goals, models, temps, err) in enumerate(_reference_run(G, lengths, problem.config)):
        n = len(goals)
        assert run.n_steps[i] == n
        np.testing.assert_array_equal(run.goal[i, :n], goals)
        np.testing.assert_array_equal(run.model[i, :n], models)
        np.testing.assert_array_equal(run.temperature[i, :n], temps)
        assert run.rmse[i] == pytest.approx(np.sqrt(np.mean(err**2)), abs=1e-10)
        assert run.max_error[i] == pytest.approx(np.abs(err).max(), abs=1e-10)


def test_evaluate_matches_reference_rmse(problem):
    G, lengths = problem.sample(50, np.random.default_rng(11))
    ev = problem.evaluate(G, lengths)
    assert ev.valid.all()
    for i, (goals, _, temps, err) in enumerate(_reference_run(G, lengths, problem.config)):
        np.testing.assert_array_equal(err, temps - goals)
        assert ev.f1[i] == pytest.approx(np.sqrt(np.mean((temps - goals) ** 2)), abs=1e-10)


# --- sampler -----------------------------------------------------------------------------------
@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), sampling=st.sampled_from(["markov", "uniform"]))
def test_sampler_is_domain_valid_and_fills_the_day(seed, sampling):
    problem = ThermostatProblem(sampling=sampling, profile="refined")
    G, lengths = problem.sample(64, np.random.default_rng(seed))
    assert problem.codec.in_domain(G, lengths).all()
    used = np.arange(problem.m_max)[None, :] < lengths[:, None]
    assert np.all(G[~used] == 0)
    total = np.where(used, G[:, :, 1], 0).sum(axis=1)
    assert np.all(total <= 1440)
    assert np.all(total > 1440 - 60)  # otherwise one more (shortened) element would have fitted
    if sampling == "markov":
        jumps = np.abs(np.diff(G[:, :, 0], axis=1))[used[:, 1:]]
        assert np.all(jumps <= problem.config.markov_max_step)
        assert problem.evaluate(G, lengths).valid.all()


@pytest.mark.parametrize("profile", PROFILES)
def test_markov_chain_mostly_switches_direction(profile):
    problem = ThermostatProblem(profile=profile)
    G, lengths = problem.sample(2000, np.random.default_rng(3))
    d = np.diff(G[:, :, 0], axis=1)
    used = np.arange(1, problem.m_max)[None, :] < lengths[:, None]
    d = np.where(used, d, 0)
    # strict rises followed by strict falls (or vice versa) need a switch: P(switch) = 0.7
    a, b = d[:, :-1], d[:, 1:]
    both = (a != 0) & (b != 0) & used[:, 1:]
    assert 0.5 < np.mean(np.sign(a[both]) != np.sign(b[both])) < 0.9


def test_sampling_is_reproducible(problem):
    a = problem.sample(20, np.random.default_rng(5))
    b = problem.sample(20, np.random.default_rng(5))
    np.testing.assert_array_equal(a[0], b[0])
    np.testing.assert_array_equal(a[1], b[1])


# --- environment, config, plot -----------------------------------------------------------------
def test_environment_rmse_equals_f1(problem):
    X = problem.sample_rows(10, np.random.default_rng(13))
    ev = problem.evaluate_rows(X)
    for i, sc in enumerate(problem.codec.from_rows(X)):
        env = problem.environment(sc)
        assert env.valid
        assert env.rmse == pytest.approx(ev.f1[i], abs=1e-12)
        assert env.max_error == pytest.approx(ev.metrics["max_error"][i], abs=1e-12)
        assert env.minutes[-1] == sum(env.durations)
        assert len(env.goal) == len(env.temperature) == len(env.heater) == len(env.model)
        assert env.initial_temperature == env.setpoints[0]


def test_environment_reports_invalid_schedules(problem):
    env = problem.environment(scenario([16, 25], [60, 60], [1, 1]))
    assert not env.valid and env.reason.startswith("R2")
    assert env.rmse > 0  # still simulated, for inspection


def test_config_from_dict_and_bad_values():
    p = ThermostatProblem({"alpha": 2.0, "room_models": [list(r) for r in ROOM_MODELS]})
    assert p.alpha == 2.0 and p.config.room_models == ROOM_MODELS
    with pytest.raises(ScenarioError):
        ThermostatProblem({"nope": 1})
    with pytest.raises(ScenarioError):
        ThermostatProblem(sampling="gaussian")
    with pytest.raises(ScenarioError):
        ThermostatProblem(room_models=ROOM_MODELS[:3])
    with pytest.raises(ScenarioError, match="profile"):
        ThermostatProblem(profile="paper")


def test_plot_renders_png(problem, tmp_path):
    from ambiegen_ros.viz.thermostat import plot_scenario

    sc = scenario([25, 21, 24, 20], [240, 180, 240, 240], [1, 2, 7, 4])
    fig = plot_scenario(problem, sc, title="harsh")
    path = tmp_path / "thermostat.png"
    fig.savefig(path)
    assert path.stat().st_size > 5000
    assert "RMSE" in fig.axes[0].get_title()
    import matplotlib.pyplot as plt

    plt.close(fig)


@pytest.mark.parametrize("profile", PROFILES)
def test_small_batches_use_the_scalar_path_with_identical_results(profile):
    """evaluate() switches to the plain simulator for a few schedules; F1 must not depend on it,
    not even in the last bit (a campaign's workers batch scenarios as they arrive)."""
    from ambiegen_ros.problems import thermostat as module

    problem = ThermostatProblem(profile=profile)
    G, lengths = problem.sample(40, np.random.default_rng(11))
    big = problem.evaluate(G, lengths)  # 40 > SCALAR_BATCH: vectorised
    assert len(G) > module.SCALAR_BATCH
    for i in range(0, 40, 5):
        small = problem.evaluate(G[i : i + 5], lengths[i : i + 5])  # scalar path
        np.testing.assert_array_equal(small.f1, big.f1[i : i + 5])
        np.testing.assert_array_equal(small.metrics["max_error"], big.metrics["max_error"][i : i + 5])


@pytest.mark.parametrize("profile", PROFILES)
def test_compiled_and_numpy_engines_agree_bit_for_bit(profile):
    """The numba loop (default when numba imports) and the numpy paths give the same bits."""
    from ambiegen_ros.core.accel import numba_module

    if not numba_module():
        pytest.skip("numba is not importable here: only the numpy paths exist")
    compiled = ThermostatProblem(profile=profile)
    plain = ThermostatProblem(profile=profile, engine="numpy")
    G, lengths = compiled.sample(300, np.random.default_rng(17))
    a, b = compiled.evaluate(G, lengths), plain.evaluate(G, lengths)
    np.testing.assert_array_equal(a.f1, b.f1)
    np.testing.assert_array_equal(a.metrics["max_error"], b.metrics["max_error"])
    assert a.reasons == b.reasons
    small = plain.evaluate(G[:7], lengths[:7])  # the plain scalar loop
    np.testing.assert_array_equal(small.f1, a.f1[:7])
