"""The vehicle's two-driver surrogate (issue 26): the full model's drivers, coarse, ranking certified failures."""
from __future__ import annotations

import dataclasses
import json
import os
import subprocess
import sys

import numpy as np
import pytest

from ambiegen_ros.experiment.pipeline import Candidate, FullModelTally
from ambiegen_ros.problems import get_problem
from ambiegen_ros.problems.vehicle.drivers import (BRISK, CAP, CAUTIOUS, OUT_OFFSET, certified_score,
                                                   drive_margins)
from ambiegen_ros.problems.vehicle.validity import competition_rules
from ambiegen_ros.sims import car
from ambiegen_ros.sims.outcome import Outcome


def _road(turn_deg: float, radius: float, lead: float = 120.0) -> np.ndarray:
    """A straight of ``lead`` m, a right bend of ``radius`` turning ``turn_deg``, 60 m of straight; 1 m nodes."""
    straight = np.column_stack([np.zeros(int(lead)), np.arange(0.0, lead, 1.0)])
    t = np.linspace(0, np.radians(turn_deg), int(radius * np.radians(turn_deg)) + 2)
    bend = np.column_stack([radius - radius * np.cos(t), lead + radius * np.sin(t)])
    out = bend[-1] + np.outer(np.arange(1.0, 61.0), [np.sin(t[-1]), np.cos(t[-1])])
    return np.concatenate([straight, bend, out]) + [40.0, 20.0]


def test_the_drivers_are_the_full_models():
    full = car.CarSimConfig()
    same = {"wheelbase": "wheelbase", "car_length": "length", "rear_overhang": "rear_overhang",
            "max_steer_deg": "max_steer_deg", "max_steer_rate_deg": "max_steer_rate_deg", "grip": "grip",
            "speed_limit_kmh": "speed_limit_kmh", "accel": "accel", "brake": "brake", "preview_min": "preview_min",
            "speed_gain": "speed_gain", "lookahead_time": "lookahead_time", "lookahead_min": "lookahead_min",
            "timeout_base": "timeout_base", "timeout_speed": "timeout_speed",
            "corner_lat_accel": "corner_lat_accel", "preview_time": "preview_time"}
    for ours, theirs in same.items():
        assert getattr(BRISK, ours) == getattr(full, theirs), ours
    assert (CAUTIOUS.corner_lat_accel, CAUTIOUS.preview_time) == (full.reference_corner_lat_accel,
                                                                  full.reference_preview_time)
    assert full.oob_tolerance == 0.85 and full.width == 1.8  # OUT_OFFSET's numbers
    assert OUT_OFFSET == pytest.approx(4.0 / 2 + (full.oob_tolerance - 0.5) * full.width)


def test_a_hairpin_after_a_long_straight_is_predicted_and_certified_a_gentle_bend_is_not():
    hairpin, gentle = _road(180, 20.0), _road(60, 120.0)
    nodes = np.concatenate([hairpin, gentle])
    counts = [len(hairpin), len(gentle)]
    brisk, arc = drive_margins(nodes, counts, 4.0, BRISK)
    cautious, _ = drive_margins(nodes, counts, 4.0, CAUTIOUS)
    score = certified_score(brisk, cautious)
    assert score[0] > OUT_OFFSET > score[1]
    assert brisk[0] > OUT_OFFSET > cautious[0]
    assert 120.0 <= arc[0] <= 120.0 + np.pi * 20.0 + 30  # in or just after the bend
    # the full model agrees: the brisk driver leaves the lane on the hairpin, the cautious one keeps it
    run = car.drive(hairpin, 4.0, car.CarSimConfig())
    ref = car.drive(hairpin, 4.0, dataclasses.replace(car.CarSimConfig(), corner_lat_accel=4.0, preview_time=1.5))
    assert run["failure_kind"] == "out_of_lane" and ref["failure_kind"] == "none"
    assert car.drive(gentle, 4.0, car.CarSimConfig())["failure_kind"] == "none"


def test_certified_score_caps_the_failure_and_charges_the_references_near_miss():
    brisk = np.array([1.0, OUT_OFFSET + 2.0, OUT_OFFSET + 2.0, OUT_OFFSET + 0.2])
    cautious = np.array([0.5, 1.0, OUT_OFFSET, 1.0])
    s = certified_score(brisk, cautious)
    assert s[0] == 1.0 and s[1] == pytest.approx(OUT_OFFSET + CAP)  # deeper is not more certain
    assert s[2] == pytest.approx(OUT_OFFSET)  # the reference fails too: no longer above the rest
    assert s[3] > OUT_OFFSET and s[1] > s[3] > s[0]


def test_certified_vehicle_validity_is_the_competition_rules_and_f1_the_drivers():
    problem = get_problem("vehicle", {"profile": "refined", "objective": "certified"})
    assert problem.alpha == 2.5
    X = problem.sample_rows(120, np.random.default_rng(3))
    ev = problem.evaluate_rows(X)
    plain = get_problem("vehicle", {"profile": "refined"}).evaluate_rows(X)
    assert not (ev.valid & ~plain.valid).any() and (plain.valid & ~ev.valid).any()  # stricter: the rules
    cfg = problem.config
    for i in np.flatnonzero(plain.valid & ~ev.valid)[:5]:
        road = car.road_of(problem, problem.codec.from_row(X[i]))[0]
        assert not competition_rules(road, cfg.lane_width, cfg.map_size, cfg.margin, cfg.min_radius)[0]
    valid = np.flatnonzero(ev.valid)
    assert np.all(ev.f1[valid] >= 0) and np.all(ev.f1[~ev.valid] == 0)
    assert np.isfinite(ev.metrics["failure_arc"][valid]).all()
    assert np.allclose(ev.f1[valid], np.maximum(certified_score(ev.metrics["brisk_offset"][valid],
                                                                ev.metrics["cautious_offset"][valid]), 0))


def test_the_compiled_and_the_plain_python_drivers_agree():
    pytest.importorskip("numba")
    roads = [_road(180, 20.0), _road(75, 30.0, lead=40.0)]
    code = ("import json, sys, numpy as np\n"
            "from ambiegen_ros.problems.vehicle.drivers import drive_margins, BRISK\n"
            "r = [np.array(x) for x in json.loads(sys.stdin.read())]\n"
            "w, a = drive_margins(np.concatenate(r), [len(x) for x in r], 4.0, BRISK)\n"
            "print(json.dumps([w.tolist(), a.tolist()]))\n")
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    out = []
    for disable in ("0", "1"):
        env = {**os.environ, "NUMBA_DISABLE_JIT": disable}
        done = subprocess.run([sys.executable, "-c", code], cwd=root, env=env, capture_output=True, text=True,
                              check=True, input=json.dumps([r.tolist() for r in roads]))
        out.append(json.loads(done.stdout))
    assert np.allclose(out[0], out[1], rtol=1e-9, atol=1e-9)


def test_a_search_skips_a_candidate_predicted_to_repeat_a_certified_failure():
    problem = get_problem("vehicle", {"profile": "refined", "objective": "certified"})
    X = problem.sample_rows(400, np.random.default_rng(11))
    ev = problem.evaluate_rows(X)
    risky = [i for i in np.flatnonzero(ev.valid & (ev.f1 > OUT_OFFSET))]
    assert len(risky) >= 2
    tally = FullModelTally(problem, seed=1)
    i = risky[0]
    arc = float(ev.metrics["failure_arc"][i])
    failed = Outcome(objectives={"vehicle_max_oob": 1.0}, failed=True, failure_kind="out_of_lane",
                     metrics={"departure_arc_length": arc})
    tally.dispatch(X[i])
    tally.record(X[i], float(ev.f1[i]), failed, 0, 0.1, 30.1, end_s=30.1)
    same = Candidate(X[i], float(ev.f1[i]), 0.0, 0, {"failure_arc": arc})
    assert not tally.predicted_repeat(same, now=30.0)  # not certified yet
    assert tally.predicted_repeat(same, now=31.0)
    assert not tally.predicted_repeat(Candidate(X[i], 1.0, 0.0, 1, None), now=31.0)  # no prediction
    straight = Candidate(X[i], 1.0, 0.0, 2, {"failure_arc": 0.5})  # at the start: another place
    assert tally.predicted_repeat(straight, now=31.0) == (tally.distinct.seen[0].place[1] == 0)
    assert tally.predicted_repeats >= 1
