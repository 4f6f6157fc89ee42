"""The vehicle's reference check: the competition rules before a drive, a cautious driver after a failure.

Hand-made roads both ways, with outcomes known from geometry: a straight that runs past the map's
margin, a loop whose centre line never crosses but whose lanes overlap, a bend tighter than the
minimum radius, a road the replication builder cut at the map edge; and from driving: the brisk
default driver runs wide in a tight right-hand hairpin after a long straight, the cautious one
(slower in corners, looking further ahead) does not.
"""
from __future__ import annotations

import re

import numpy as np
import pytest
import shapely

from ambiegen_ros.core.attributes import ScenarioError
from ambiegen_ros.problems import get_problem
from ambiegen_ros.problems.vehicle.validity import competition_rules
from ambiegen_ros.sims import car
from ambiegen_ros.sims.full_model import full_model_executor
from ambiegen_ros.sims.reference import vehicle as reference

RULES = {"lane_width": 4.0, "map_size": 200.0, "margin": 4.0, "min_radius": 14.33}
# refined roads (20 m turns, from (100, 100) heading north)
HAIRPIN = [("left", 5, 60), ("straight", 50, 5), ("straight", 10, 5), ("right", 5, 80), ("right", 5, 80)]
GENTLE = [("straight", 30, 5), ("left", 5, 20), ("straight", 30, 5), ("right", 5, 25), ("straight", 20, 5)]
OFF_MAP = [("left", 5, 60), ("straight", 50, 5), ("straight", 30, 5), ("right", 5, 85), ("right", 5, 85)]
LOOP = [("straight", 5, 5)] + [("left", 5, 85)] * 4  # 340 degrees round a 20 m circle: ends 2 m from the start


def arc(centre, radius, start, stop, step=1.0):
    n = max(2, int(abs(stop - start) * radius / step) + 1)
    a = np.linspace(start, stop, n)
    return np.column_stack([centre[0] + radius * np.cos(a), centre[1] + radius * np.sin(a)])


def line(a, b, step=1.0):
    n = max(2, int(np.hypot(b[0] - a[0], b[1] - a[1]) / step) + 1)
    return np.column_stack([np.linspace(a[0], b[0], n), np.linspace(a[1], b[1], n)])


@pytest.fixture(scope="module")
def refined():
    return get_problem("vehicle", {"profile": "refined"})


def road(problem, spec):
    return problem.parse({"problem": problem.name,
                          "elements": [{"type": t, "length": n, "angle": a} for t, n, a in spec]})


# --- the rules on polylines --------------------------------------------------------------------
def test_rules_pass_a_road_well_inside_the_map():
    bend = np.vstack([line((100, 40), (100, 100))[:-1], arc((80, 100), 20, 0, np.pi / 2)])
    assert competition_rules(bend, **RULES) == (True, None)


def test_rules_count_the_lane_edges_against_the_map():
    def north_then_east(y):  # up x = 100, a 20 m bend, then east along y
        return np.vstack([line((100, 40), (100, y - 20))[:-1], arc((120, y - 20), 20, np.pi, np.pi / 2)[:-1],
                          line((120, y), (170, y))])

    ok, reason = competition_rules(north_then_east(193), **RULES)  # centre line 7 m from the edge: its left lane 3 m
    found = re.fullmatch(r"road leaves the map by 1\.0 m at (\d+) m along it \(its 8 m surface must stay "
                         r"4 m inside the 200 m map\)", reason)
    assert not ok and found and 160 <= int(found[1]) <= 215  # in the bend's top or on the eastbound leg
    assert competition_rules(north_then_east(192), **RULES) == (True, None)  # 8 m: the surface just fits
    assert competition_rules(line((100, 100), (100, 196)), **RULES)[0]  # the road's end needs no room beyond it


def test_rules_find_lanes_that_overlap_where_the_centre_line_does_not_cross():
    loop = arc((100, 100), 15, np.pi, np.pi + np.radians(330))  # ends 7.8 m apart: the lanes overlap
    assert shapely.is_simple(shapely.LineString(loop))
    ok, reason = competition_rules(loop, **RULES)
    assert not ok and "road overlaps itself at 0 m and 86 m along it (centre lines 7.8 m apart" in reason
    wider = arc((100, 100), 17, np.pi, np.pi + np.radians(330))  # 8.8 m apart: clear
    assert competition_rules(wider, **RULES) == (True, None)
    assert competition_rules(loop, **RULES, gap=4.0)[0]  # only a lane width of clearance asked


def test_rules_tell_neighbours_along_the_arc_from_a_road_coming_back():
    hairpin = np.vstack([line((100, 40), (100, 100))[:-1], arc((115, 100), 15, np.pi, 0)[:-1],
                         line((130, 100), (130, 40))])  # legs 30 m apart, tightest legal radius
    assert competition_rules(hairpin, **RULES) == (True, None)
    legs_close = np.vstack([line((100, 40), (100, 120))[:-1], line((100, 120), (106, 120))[:-1],
                            line((106, 120), (106, 40))])  # 6 m apart: the surfaces overlap
    ok, reason = competition_rules(legs_close, **RULES, radius=np.inf)
    assert not ok and "road overlaps itself" in reason and "6.0 m apart" in reason


def test_rules_find_a_bend_too_sharp_and_an_edge_folding_over():
    corner = np.vstack([line((100, 60), (100, 100))[:-1], arc((98, 100), 2, 0, np.pi / 2)[:-1],
                        line((98, 102), (60, 102))])  # a 2 m corner: the inner edge folds over
    ok, reason = competition_rules(corner, **RULES)
    assert not ok
    fold, sharp = reason.split("; ")
    assert fold.startswith("road's left edge crosses itself at")
    assert sharp.startswith("road too sharp: radius 2.")  # the 2 m arc, sampled every metre
    ok, reason = competition_rules(arc((100, 100), 12, 0, np.pi / 2), **RULES)
    assert not ok and reason.startswith("road too sharp: radius 12.0 m")
    assert competition_rules(arc((100, 100), 15, 0, np.pi / 2), **RULES)[0]
    assert competition_rules(arc((100, 100), 15, 0, np.pi / 2), **RULES, radius=14.0)[0] is False  # measured elsewhere
    # the replication car drives nodes ~8 m apart: a legal bend turns 36 degrees per node, and its
    # edges, offset at the nodes as the car's lane is, do not fold
    coarse = arc((100, 100), 15, 0, np.pi, step=8.0)
    assert len(coarse) == 6 and competition_rules(coarse, **RULES) == (True, None)


# --- the reference in the full-model executor ---------------------------------------------------
def test_valid_road_passes_the_rules_and_is_driven(refined):
    out = full_model_executor(refined).execute(road(refined, GENTLE))
    assert out.verdict == "PASS" and out.metrics["outcome"] == "success"
    assert out.reference == {"check": "competition_rules", "passed": True, "reason": ""}


@pytest.mark.parametrize("spec, why", [
    (OFF_MAP, "road leaves the map by 2.6 m at 153 m along it"),
    (LOOP, "road overlaps itself at 0 m and 124 m along it (centre lines 2.2 m apart"),
])
def test_rule_breaking_roads_are_invalid_tests_without_a_drive(refined, spec, why):
    sc = road(refined, spec)
    assert car.road_check(refined, sc).valid  # the problem's own rules let both through
    out = full_model_executor(refined).execute(sc)
    assert out.failure_kind == "invalid_test" and not out.failed
    assert out.detail.startswith(why) and out.verdict == f"INVALID_TEST({out.detail})"
    assert out.trajectory is None and "max_oob" not in out.metrics  # nothing was driven
    assert out.reference["check"] == "competition_rules" and not out.reference["passed"]
    old = full_model_executor(refined, reference=False).execute(sc)  # the old, unchecked verdict
    assert old.reference is None and old.failure_kind != "invalid_test" and "max_oob" in old.metrics


def test_too_sharp_road_forced_through_is_an_invalid_test():
    tight = get_problem("vehicle", {"profile": "refined", "turn_radius": 8})
    sc = road(tight, [("straight", 20, 5), ("left", 5, 60), ("straight", 20, 5)])
    assert full_model_executor(tight).execute(sc).failure_kind == "invalid_scenario"  # the problem's rule
    out = full_model_executor(tight, run_invalid=True).execute(sc)
    assert out.failure_kind == "invalid_test" and out.detail.startswith("road too sharp: radius 6.8 m < 14.33 m")


def test_a_road_the_replication_builder_cut_is_never_driven():
    problem = get_problem("vehicle")  # replication: heads south from (100, 100); 100 m of straight leave the map
    sc = road(problem, [("straight", 50, 5)] * 3)
    check = car.road_check(problem, sc)
    assert check.valid and check.cut and (check.elements, check.elements_built) == (3, 1)  # scored all the same
    assert problem.evaluate_scenarios([sc]).valid[0]
    out = full_model_executor(problem).execute(sc)
    assert out.failure_kind == "invalid_test" and "max_oob" not in out.metrics
    assert out.detail == "road leaves the map: the road builder cut it after 1 of 3 elements, 56 m along it"
    assert out.metrics["reference_road_cut"] is True
    whole = road(problem, [("straight", 40, 5)])
    assert full_model_executor(problem).execute(whole).verdict == "PASS"


def test_a_failure_the_cautious_driver_avoids_stays_a_failure(refined):
    sc = road(refined, HAIRPIN)
    assert reference.before(refined, sc, car.CarSimConfig()).passed
    out = full_model_executor(refined).execute(sc)
    assert out.verdict == "FAIL(out_of_lane)" and out.metrics["max_oob"] > 0.85
    assert out.reference == {"check": "reference_driver", "passed": True, "reason": ""}
    assert out.metrics["reference_driver_outcome"] == "success" and out.metrics["reference_driver_max_oob"] < 0.85


def test_a_failure_the_reference_driver_shares_is_an_invalid_test(refined):
    sc = road(refined, HAIRPIN)
    brisk_reference = {"reference_corner_lat_accel": 6.5, "reference_preview_time": 0.5}  # the SUT's own driver
    out = full_model_executor(refined, **brisk_reference).execute(sc, seed=2)
    assert out.failure_kind == "invalid_test" and not out.failed
    assert out.detail.startswith("a cautious driver (6.5 m/s^2 corners, 0.5 s preview) also leaves the lane at ")
    assert out.metrics["sut_failure_kind"] == "out_of_lane" and out.trajectory is not None  # what the SUT did stays
    verdict = reference.after(refined, sc, car.CarSimConfig(**brisk_reference), out, 2)
    assert not verdict.passed and verdict.reason == out.detail


def test_cautious_driver_is_the_sut_config_with_two_numbers_changed():
    sut = car.CarSimConfig(grip=6.0, controller="stanley", reference_preview_time=2.0)
    ref = reference.cautious(sut)
    assert (ref.corner_lat_accel, ref.preview_time) == (4.0, 2.0)
    assert (ref.grip, ref.controller, ref.oob_tolerance) == (6.0, "stanley", sut.oob_tolerance)


@pytest.mark.parametrize("options, field", [
    ({"reference_corner_lat_accel": 0.0}, "option.reference_corner_lat_accel"),
    ({"reference_preview_time": -1.0}, "option.reference_preview_time"),
    ({"reference": 1}, "option.reference"),
])
def test_reference_options_are_checked(refined, options, field):
    with pytest.raises(ScenarioError, match=field):
        full_model_executor(refined, **options)
