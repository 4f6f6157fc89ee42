"""Vehicle (lane keeping) case study, refined profile (paper eqs. 10-13 car, 5 m spine, competition
rules): road geometry, spline == splprep, validity rules, the car's sign convention, windowed ==
global nearest point, both engines, sampler, plot. The replication profile: test_vehicle_replication.py."""
from __future__ import annotations

import math

import numpy as np
import pytest

from ambiegen_ros.core.attributes import ScenarioError
from ambiegen_ros.core.scenario import Scenario
from ambiegen_ros.problems import get_problem
from ambiegen_ros.problems.vehicle import (
    Road,
    VehicleConfig,
    VehicleProblem,
    _kernels,
    build_spines,
    check_roads,
    interpolate,
    interpolate_splprep,
    simulate,
)

HAS_NUMBA = bool(_kernels())


def refined(**overrides) -> VehicleProblem:
    """A refined-profile problem (built from a dict so that profile-dependent defaults resolve)."""
    return VehicleProblem({"profile": "refined", **overrides})


def refined_config(**overrides) -> VehicleConfig:
    return VehicleConfig(profile="refined", **overrides)


def road(*segments) -> Scenario:
    """Elements from ("straight", length) / ("left"|"right", angle) pairs; unused attrs = 5."""
    elements = []
    for kind, value in segments:
        if kind == "straight":
            elements.append({"type": kind, "length": value, "angle": 5})
        else:
            elements.append({"type": kind, "length": 5, "angle": value})
    return Scenario("vehicle", elements)


def split_flat(flat, counts):
    offs = np.concatenate([[0], np.cumsum(counts)])
    return [flat[offs[i]: offs[i + 1]] for i in range(len(counts))]


@pytest.fixture(scope="module")
def problem() -> VehicleProblem:
    return refined()


@pytest.fixture(scope="module")
def sampled(problem):
    """1,500 Markov-sampled roads with their spines, nodes and checks (shared by several tests)."""
    G, L = problem.sample(1500, np.random.default_rng(2024))
    spine, n_spine, nodes, n_nodes = problem.roads(G, L)
    valid, reasons, length, min_radius = check_roads(nodes, n_nodes, problem.config)
    return dict(G=G, L=L, spine=spine, n_spine=n_spine, nodes=nodes, n_nodes=n_nodes,
                valid=valid, reasons=reasons, length=length, min_radius=min_radius)


# --- declaration and config -------------------------------------------------------------------------
def test_declared_shape(problem):
    assert problem.name == "vehicle"
    assert [a.name for a in problem.attributes] == ["type", "length", "angle"]
    t, length, angle = problem.attributes
    assert t.values == ("straight", "left", "right")
    assert (length.low, length.high, length.step, length.tolerance) == (5, 50, 1, 5)
    assert (angle.low, angle.high, angle.step, angle.tolerance) == (5, 85, 5, 5)
    assert (problem.m_min, problem.m_max) == (1, 20)
    assert problem.paper_budget.population == 500 and problem.paper_budget.evaluations == 100000
    assert problem.alpha == 10.0
    assert problem.profile == "refined" and problem.config.v0 == 7.0 and problem.config.turn_radius == 20.0
    assert get_problem("vehicle", {"profile": "refined"}).config == problem.config


def test_config_from_dict_and_errors():
    p = refined(p_from_turn=[0.5, 0.25, 0.25], start=[90, 90])
    assert p.config.p_from_turn == (0.5, 0.25, 0.25) and p.config.start == (90.0, 90.0)
    hash(p.config)  # frozen and hashable after list -> tuple
    with pytest.raises(ScenarioError, match="p_from_straight"):
        refined_config(p_from_straight=(0.5, 0.5, 0.5))
    with pytest.raises(ScenarioError, match="sampling"):
        refined_config(sampling="grid")
    with pytest.raises(ScenarioError, match="window_back"):
        refined_config(window_back=0)
    with pytest.raises(ScenarioError, match="unknown vehicle parameter"):
        VehicleProblem({"speed": 3})
    with pytest.raises(ScenarioError, match="profile"):
        VehicleConfig(profile="paper")


# --- road geometry ---------------------------------------------------------------------------------------
def test_spine_follows_straights_and_arcs(problem):
    cfg = problem.config
    for kind, sign in (("left", 1.0), ("right", -1.0)):
        sc = road(("straight", 30), (kind, 85), ("straight", 12))
        G, L = problem.codec.split(problem.codec.to_row(sc))
        spine, n = build_spines(G, L, cfg)
        spacing = np.hypot(*np.diff(spine, axis=0).T)
        assert spacing.max() <= cfg.spine_spacing + 1e-9
        assert np.allclose(spine[0], (100, 100)) and np.allclose(spine[:7, 0], 100)  # straight along +y
        assert np.isclose(spine[6, 1], 130)
        # arc points: on a circle of radius 20 around a pivot 20 m to the left (right) of (100, 130)
        pivot = np.array([100 - sign * 20, 130])
        arc = spine[6: 6 + 1 + math.ceil(20 * math.radians(85) / 5)]
        assert np.allclose(np.hypot(*(arc - pivot).T), 20)
        assert sign * (arc[-1, 0] - 100) < 0  # a left turn bends towards -x when heading +y
        # the final straight leaves along heading 90 +/- 85 degrees
        h = math.radians(90 + sign * 85)
        assert np.allclose(spine[-1] - arc[-1], 12 * np.array([math.cos(h), math.sin(h)]))


def test_batched_spline_matches_splprep(problem, sampled):
    cfg = problem.config
    spines = split_flat(sampled["spine"], sampled["n_spine"])[:200]
    nodes = split_flat(sampled["nodes"], sampled["n_nodes"])[:200]
    for s, n in zip(spines, nodes):
        assert np.abs(interpolate_splprep(s, cfg) - n).max() < 1e-6
    # few points: splprep degree 1, 2, 3 and the smallest not-a-knot systems, in one padded batch
    rng = np.random.default_rng(1)
    small = [np.cumsum(rng.uniform(2, 6, size=(k, 2)), axis=0) + 50 for k in (2, 3, 4, 5, 6, 9)]
    flat, counts = np.concatenate(small), np.array([len(s) for s in small])
    got = split_flat(*interpolate(flat, counts, cfg))
    for s, n in zip(small, got):
        assert len(n) >= cfg.interp_min_nodes
        assert np.abs(interpolate_splprep(s, cfg) - n).max() < 1e-6


def test_about_one_node_per_metre(problem, sampled):
    steps = np.hypot(*np.diff(split_flat(sampled["nodes"], sampled["n_nodes"])[0], axis=0).T)
    assert 0.9 < steps.mean() < 1.05
    assert sampled["n_nodes"].min() >= problem.config.interp_min_nodes


# --- validity -----------------------------------------------------------------------------------------------
def evaluate_one(problem, sc):
    return problem.evaluate_scenarios([sc]).row(0)


def test_self_intersecting_road(problem):
    # a 340 degree loop of radius 20, then a straight back across the first straight
    sc = road(("straight", 30), ("left", 85), ("left", 85), ("left", 85), ("left", 85), ("straight", 50))
    row = evaluate_one(problem, sc)
    assert not row["valid"] and row["reason"] == "self-intersecting" and row["f1"] == 0.0
    env = problem.environment(sc)
    assert env.min_radius >= problem.config.min_radius  # radius 20 arcs: only the crossing is wrong


def test_too_sharp_road():
    # many consecutive 85 degree turns are never too sharp on radius-20 arcs (they self-intersect
    # instead); a tighter arc radius breaks the rule and the reason names the radius
    p = refined(turn_radius=10.0)
    sc = road(("straight", 20), ("left", 85), ("right", 85), ("left", 85), ("straight", 10))
    row = evaluate_one(p, sc)
    assert not row["valid"] and row["reason"].startswith("too sharp: min radius")
    assert row["reason"].endswith("< 14.33 m")
    radius = float(row["reason"].split("min radius ")[1].split(" m")[0])
    assert 5.0 < radius < 10.5
    assert row["f1"] == 0.0


def naive_min_radius(nodes):
    best = math.inf
    for i in range(len(nodes) - 4):
        p, q, s = nodes[i], nodes[i + 2], nodes[i + 4]
        a, b, c = math.dist(p, q), math.dist(q, s), math.dist(p, s)
        area2 = abs((q[0] - p[0]) * (s[1] - p[1]) - (q[1] - p[1]) * (s[0] - p[0]))
        if area2 > 0:
            best = min(best, a * b * c / (2 * area2))
    return best


def test_min_radius_matches_naive_circumradius(problem, sampled):
    nodes = split_flat(sampled["nodes"], sampled["n_nodes"])
    sharp = [i for i, r in enumerate(sampled["reasons"]) if r and r.startswith("too sharp")]
    assert sharp, "the sampler should produce a few too-sharp roads (spline between uneven spine gaps)"
    for i in sharp[:5] + list(range(5)):
        assert math.isclose(sampled["min_radius"][i], naive_min_radius(nodes[i]), rel_tol=1e-9)
    assert all(naive_min_radius(nodes[i]) < problem.config.min_radius for i in sharp[:5])


def test_out_of_map_and_too_short(problem):
    row = evaluate_one(problem, road(("straight", 50), ("straight", 50), ("straight", 50)))
    assert not row["valid"] and row["reason"].startswith("leaves the map") and "196" in row["reason"]
    row = evaluate_one(problem, road(("straight", 12)))
    assert not row["valid"] and row["reason"].startswith("too short") and row["f1"] == 0.0
    row = evaluate_one(problem, road(("straight", 50), ("straight", 40)))
    assert row["valid"] and row["reason"] is None


def test_domain_violation_is_invalid(problem):
    X = problem.codec.to_row(road(("straight", 30), ("left", 40)))[None].copy()
    X[0, 1 + 3 + 2] = 42  # angle of element 1: not a multiple of 5
    ev = problem.evaluate_rows(X)
    assert not ev.valid[0] and ev.f1[0] == 0 and ev.reasons[0].startswith("domain: elements[1].angle")


# --- surrogate car --------------------------------------------------------------------------------------------
def test_straight_road_gives_zero_deviation(problem):
    env = problem.environment(road(("straight", 50), ("straight", 40)))
    assert env.valid and env.max_deviation < 1e-9
    # drives until just before passing the last road point (not counted: d would be longitudinal)
    end_y = env.nodes[-1, 1]
    step = problem.config.v0 * problem.config.dt * 2
    assert end_y - step <= env.path[-1, 1] <= end_y
    # Euler steps on the centre line: y_k = y_(k-1) + v_(k-1) dt, v_k = v_(k-1) + beta_v dt
    cfg = problem.config
    y, v, expected = 100.0, cfg.v0, []
    while y <= end_y:
        expected.append(y)
        y, v = y + v * cfg.dt, v + cfg.beta_v * cfg.dt
    assert np.allclose(env.path[:, 1], expected)


def test_sign_convention_car_steers_back(problem):
    # road along +y: left of the direction of travel is -x; a car started 3 m left has d = +3
    sc = road(("straight", 50), ("straight", 40))
    left = problem.environment(sc, start_offset=3.0)
    assert math.isclose(left.deviations[0], 3.0, abs_tol=1e-9)
    assert math.isclose(left.path[0, 0], 97.0, abs_tol=1e-9)
    # it turns right, towards the road (x grows), and reaches the band around the centre line
    assert np.all(np.diff(left.path[:6, 0]) >= 0) and left.path[5, 0] > left.path[1, 0]
    assert np.all(np.diff(left.deviations[1:10]) < 0)
    assert np.abs(left.deviations[: len(left.deviations) // 3]).min() < problem.config.band
    # started on the right, the run is the exact mirror image
    right = problem.environment(sc, start_offset=-3.0)
    assert np.allclose(right.deviations, -left.deviations, atol=1e-9)
    assert np.allclose(right.path[:, 0] - 100, 100 - left.path[:, 0], atol=1e-9)
    assert left.max_deviation == pytest.approx(np.abs(left.deviations).max())


def global_signed_distance(nodes, pts):
    a, dv = nodes[:-1], np.diff(nodes, axis=0)
    r = pts[:, None, :] - a[None]
    t = np.clip((r * dv[None]).sum(-1) / (dv * dv).sum(-1)[None], 0, 1)
    d2 = ((r - t[..., None] * dv[None]) ** 2).sum(-1)
    am, rows = d2.argmin(1), np.arange(len(pts))
    cross = dv[am, 0] * r[rows, am, 1] - dv[am, 1] * r[rows, am, 0]
    dist = np.sqrt(d2[rows, am])
    return np.where(cross > 0, dist, -dist)


def test_windowed_nearest_matches_global(problem, sampled):
    v = sampled["valid"]
    idx = np.flatnonzero(v)[:150]
    nodes = split_flat(sampled["nodes"], sampled["n_nodes"])
    flat = np.concatenate([nodes[i] for i in idx])
    f1, traces = simulate(flat, sampled["n_nodes"][idx], sampled["length"][idx], problem.config, record=True)
    assert np.allclose(f1, [np.abs(tr[:, 2]).max() for tr in traces])
    total = mismatched = 0
    for i, tr in zip(idx, traces):
        g = global_signed_distance(nodes[i], tr[:, :2])
        mismatched += int((np.abs(g - tr[:, 2]) > 1e-9).sum())
        total += len(tr)
    assert total > 20000
    assert mismatched / total < 1e-3  # only where another leg of the road comes closer


def test_window_size_does_not_matter_on_sampled_roads(problem, sampled):
    v = np.flatnonzero(sampled["valid"])[:100]
    nodes = split_flat(sampled["nodes"], sampled["n_nodes"])
    flat = np.concatenate([nodes[i] for i in v])
    args = (flat, sampled["n_nodes"][v], sampled["length"][v])
    small = simulate(*args, refined_config(window_back=1, window_ahead=1))
    wide = simulate(*args, refined_config(window_back=12, window_ahead=25))
    assert np.array_equal(small, wide)


@pytest.mark.skipif(not HAS_NUMBA, reason="numba not installed")
def test_numba_and_numpy_engines_agree(sampled):
    """Bit for bit: the kernels do the numpy twins' operations in the same order, without FMA
    contraction (no fastmath), and both take sin/cos/atan2 from the C library (issue 18)."""
    idx = np.arange(120)
    nodes = split_flat(sampled["nodes"], sampled["n_nodes"])
    flat = np.concatenate([nodes[i] for i in idx])
    n, length = sampled["n_nodes"][idx], sampled["length"][idx]
    fast, slow = refined_config(engine="numba"), refined_config(engine="numpy")
    assert np.array_equal(simulate(flat, n, length, fast), simulate(flat, n, length, slow))
    spine = np.concatenate(split_flat(sampled["spine"], sampled["n_spine"])[:120])
    ns = sampled["n_spine"][idx]
    a, na = interpolate(spine, ns, fast)
    b, nb = interpolate(spine, ns, slow)
    assert np.array_equal(na, nb) and np.array_equal(a, b)
    ca, cb = check_roads(a, na, fast), check_roads(a, na, slow)
    assert ca[1] == cb[1] and np.array_equal(ca[2], cb[2]) and np.array_equal(ca[3], cb[3])
    _, tf = simulate(flat[: n[0]], n[:1], length[:1], fast, record=True)
    _, ts = simulate(flat[: n[0]], n[:1], length[:1], slow, record=True)
    assert np.array_equal(tf[0], ts[0])


@pytest.mark.skipif(not HAS_NUMBA, reason="numba not installed")
def test_engines_agree_whatever_numpy_trig_returns(sampled, monkeypatch):
    """numpy's float64 sin/cos/arctan2 are Intel SVML on AVX-512 CPUs, a last bit away from the C
    library the kernels call; moved by one ulp here on every CPU, the numpy car must not see it."""
    for name in ("sin", "cos", "arctan2"):
        fn = getattr(np, name)
        monkeypatch.setattr(np, name, lambda *a, _fn=fn, **k: np.nextafter(_fn(*a, **k), np.inf))
    idx = np.arange(60)
    flat = np.concatenate([split_flat(sampled["nodes"], sampled["n_nodes"])[i] for i in idx])
    n, length = sampled["n_nodes"][idx], sampled["length"][idx]
    fast, slow = refined_config(engine="numba"), refined_config(engine="numpy")
    assert np.array_equal(simulate(flat, n, length, fast), simulate(flat, n, length, slow))



@pytest.mark.parametrize("profile", ["replication", "refined"])
def test_a_few_roads_skip_numba_and_score_the_same_bits(profile, monkeypatch):
    """Up to SMALL_BATCH roads take the numpy engine while numba is not loaded (start-up of
    `ambiegen evaluate`); a batch of them must score the same bits as the compiled engine."""
    from ambiegen_ros.problems.vehicle import kernels, problem as module

    case = get_problem("vehicle", {"profile": profile})
    G, L = case.sample(module.SMALL_BATCH, np.random.default_rng(8))
    compiled = get_problem("vehicle", {"profile": profile, "engine": "numba" if HAS_NUMBA else "numpy"}).evaluate(G, L)
    monkeypatch.setattr(kernels, "_KERNELS", None)  # as in a fresh process
    monkeypatch.setattr(kernels, "_kernels", lambda: pytest.fail("a few roads must not load numba"))
    monkeypatch.setattr(module, "kernels_loaded", lambda: False)
    few = case.evaluate(G, L)
    assert np.array_equal(few.f1, compiled.f1) and np.array_equal(few.valid, compiled.valid)
    assert few.valid.any()


# --- evaluate / environment / sampler -------------------------------------------------------------------
def test_evaluate_and_environment_agree(problem, sampled):
    G, L = sampled["G"][:40], sampled["L"][:40]
    ev = problem.evaluate(G, L)
    assert set(ev.metrics) == {"max_deviation", "road_length"}
    assert np.array_equal(ev.valid, sampled["valid"][:40])
    assert np.all(ev.f1[~ev.valid] == 0) and np.all(ev.f1[ev.valid] > 0)
    assert np.allclose(ev.metrics["road_length"], sampled["length"][:40])
    for i in (int(np.argmax(ev.f1)), int(np.flatnonzero(~ev.valid)[0]) if (~ev.valid).any() else 0):
        env = problem.environment(problem.codec.from_row(problem.codec.join(G[i: i + 1], L[i: i + 1])[0]))
        assert isinstance(env, Road)
        assert env.valid == ev.valid[i] and env.reason == ev.reasons[i]
        assert env.f1 == pytest.approx(ev.f1[i], abs=1e-9)
        assert np.allclose(env.path[0], env.nodes[0]) and env.lane_width == 4.0


def test_sampler_domain_and_valid_fraction(problem, sampled):
    G, L = sampled["G"], sampled["L"]
    assert problem.codec.in_domain(G, L).all()
    assert np.all(G[:, 0, 0] == 0)  # Markov chain starts with a straight
    assert np.all(G[np.arange(20)[None, :] >= L[:, None]] == 0)
    lo, hi = problem.config.margin, problem.config.map_size - problem.config.margin
    assert np.all((sampled["spine"] >= lo) & (sampled["spine"] <= hi))
    frac = sampled["valid"].mean()
    assert 0.84 < frac < 0.95, frac  # spec: about 90 % valid with the 5 m spine
    T = G[:, :, 0].astype(int)
    used = np.arange(1, 20)[None, :] < L[:, None]
    prev, nxt = T[:, :-1][used], T[:, 1:][used]
    assert np.bincount(nxt[prev == 0], minlength=3)[0] / (prev == 0).sum() == pytest.approx(0.1, abs=0.03)
    assert np.bincount(nxt[prev != 0], minlength=3)[0] / (prev != 0).sum() == pytest.approx(0.2, abs=0.03)


def test_uniform_sampling():
    p = refined(sampling="uniform")
    G, L = p.sample(600, np.random.default_rng(3))
    assert p.codec.in_domain(G, L).all()
    types = G[:, :, 0][np.arange(20)[None, :] < L[:, None]].astype(int)
    assert np.allclose(np.bincount(types, minlength=3) / len(types), 1 / 3, atol=0.05)


# --- plot -----------------------------------------------------------------------------------------------------
def test_plot_renders_png(problem, tmp_path):
    from ambiegen_ros.viz import save_scenario_plot

    good = road(("straight", 30), ("left", 60), ("straight", 20), ("right", 45), ("straight", 30))
    bad = road(("straight", 30), ("left", 85), ("left", 85), ("left", 85), ("left", 85), ("straight", 50))
    for name, sc in (("good", good), ("bad", bad)):
        path = save_scenario_plot(problem, sc, tmp_path / f"{name}.png", title=name)
        data = path.read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10_000
