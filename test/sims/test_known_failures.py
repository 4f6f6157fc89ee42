"""Known failures (``sims.known_failures``): NavFn's path cap and MPPI's stop at an unmapped
obstacle, as shipped, name exactly the failures that show them, and a bad file is one clear line."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ambiegen_ros.sims import known_failures, oracles
from ambiegen_ros.sims.outcome import Outcome

SHIPPED = Path(__file__).resolve().parents[2] / "config" / "nav2" / "known_failures.yaml"


def shipped(name: str) -> known_failures.KnownFailure:
    (entry,) = [k for k in known_failures.load(SHIPPED) if k.name == name]
    return entry


def failure(kind="nav2_aborted", plans=0, route=120.0, side=50.0, failed=True) -> Outcome:
    return Outcome(objectives={}, failed=failed, failure_kind=kind, detail="Nav2 aborted its goal (error 208)",
                   metrics={"plans": plans, "route_length_m": route, "map_side_m": side})


def test_the_navfn_cap_names_a_planless_failure_past_twice_the_maps_side():
    cap = shipped("navfn_path_cap")
    assert cap.name == "navfn_path_cap" and "4655" in cap.reference
    marked = known_failures.mark(failure(route=106.0), [cap])
    assert marked.metrics["known_failure"] == "navfn_path_cap" and "known: navfn_path_cap" in marked.detail
    assert known_failures.is_known(marked)
    # the measured boundary: a 96 m route is inside the cap; a plan, a pass or another kind is not it
    for other in (failure(route=96.0), failure(plans=3), failure(plans="2"), failure(failed=False, kind="none"),
                  failure(kind="collision"), failure(route=None)):
        assert not known_failures.is_known(known_failures.mark(other, [cap])), other
    assert known_failures.is_known(known_failures.mark(failure(plans="0", kind="stall", route=425.5), [cap]))
    logged = failure(plans="0", route="106.0", side="50.0")  # metrics as a logged result carries them: text
    assert known_failures.is_known(known_failures.mark(logged, [cap]))


def test_mppis_stop_at_an_unmapped_obstacle_needs_error_105_next_to_a_box_or_post():
    """The hazards search's abort (docs/results/nav2/mppi_no_progress.md): Nav2 aborted with 105
    (no progress), or with none (0) on a tree that gives up by time, the robot 0.63 m from a box not
    in the map. Another code, a stop far from any
    unmapped obstacle, a run without that evidence or a person's collision is not it."""
    stop = shipped("mppi_unmapped_obstacle_no_progress")
    assert "6091" in stop.reference and stop.nav2_error_codes == (105, 0)

    def aborted(code="105", near="0.52", kind="nav2_aborted"):
        return Outcome(objectives={}, failed=True, failure_kind=kind, detail=f"Nav2 aborted its goal (error {code})",
                       metrics={"nav2_error_code": code, "unmapped_obstacle_m": near})

    assert known_failures.is_known(known_failures.mark(aborted(), [stop]))
    assert known_failures.is_known(known_failures.mark(aborted(code=105, near=1.0), [stop]))
    # a tree that gives up by time (the hardened stack) ends the same stop without a code
    assert known_failures.is_known(known_failures.mark(aborted(code="0", near="0.76"), [stop]))
    assert not known_failures.is_known(known_failures.mark(aborted(code="0", near="1.2"), [stop]))
    for other in (aborted(code="104"), aborted(near="1.01"), aborted(near=None), aborted(near="None"),
                  aborted(kind="collision"), aborted(code="")):
        assert not known_failures.is_known(known_failures.mark(other, [stop])), other.metrics


def test_the_adapter_measures_the_stop_against_the_scenarios_unmapped_obstacles():
    """The recorded abort (runs.jsonl, key 6d1e25f877cb689d) stopped 0.63 m from the box in its way,
    the evidence the adapter records (``known_failures.unmapped_obstacle_m``); people do not count,
    no point or a scenario without hazards is no evidence."""
    import json

    from ambiegen_ros.problems import get_problem
    from ambiegen_ros.sims.obstacles import Obstacles

    runs = SHIPPED.parents[2] / "docs" / "results" / "nav2" / "runs.jsonl"
    (row,) = [r for r in map(json.loads, runs.read_text().splitlines()) if r["key"] == "6d1e25f877cb689d"]
    problem = get_problem("robot", row["problem_config"])
    scenario = problem.parse(row["scenario"])
    near = known_failures.unmapped_obstacle_m(problem, scenario, row["failure_point"])
    assert 0.3 < near < 1.0  # within the known failure's reach, yet not inside the box
    assert known_failures.unmapped_obstacle_m(problem, scenario, None) is None
    assert known_failures.unmapped_obstacle_m(problem, scenario, (0.0, 15.9)) > 1.0
    walls_only = get_problem("robot", {"profile": "refined"})
    assert known_failures.unmapped_obstacle_m(walls_only, None, (1.0, 1.0)) is None
    people = problem.environment(scenario).unmapped["people"]
    assert Obstacles.from_dict({"people": people}).nearest_static_m((0.0, 0.0)) is None


def test_a_bad_file_is_one_clear_error(tmp_path):
    bad = tmp_path / "known.yaml"
    bad.write_text("- name: x\n  reference: y\n  colour: red\n")
    with pytest.raises(ValueError, match="unknown field.*colour"):
        known_failures.load(bad)
    bad.write_text("- name: x\n")
    with pytest.raises(ValueError, match="needs a name and a reference"):
        known_failures.load(bad)
    with pytest.raises(ValueError, match="cannot read"):
        known_failures.load(tmp_path / "none.yaml")


def test_the_robot_oracle_records_the_route_and_the_map_side():
    grid = np.zeros((60, 80), dtype=bool)
    grid[0, :] = grid[-1, :] = grid[:, 0] = grid[:, -1] = True
    judge = oracles.RobotJudge(grid, 0.5, (30.25, 15.25))
    judge.start(5.25, 15.25)
    judge.fail("nav2_aborted", "Nav2 aborted")
    m = judge.outcome().metrics
    assert m["map_side_m"] == 40.0 and m["route_length_m"] == pytest.approx(25.0, abs=0.5)


def test_an_in_the_loop_search_is_not_rewarded_for_a_known_failure():
    """``nodes.generator.loop_evaluation``: a known failure stays a valid test with F1 0 (the time
    limit it would otherwise score is the highest F1 there is); a new failure keeps its F1, an
    invalid test is invalid."""
    from ambiegen_ros.nodes.generator import loop_evaluation

    cap = shipped("navfn_path_cap")
    known = known_failures.mark(failure(route=120.0), [cap])
    known.objectives = {"robot_time": 300.0}
    new = failure(kind="collision")
    new.objectives = {"robot_time": 300.0}
    passed = Outcome(objectives={"robot_time": 61.5}, failed=False, failure_kind="none", detail="goal reached")
    invalid = Outcome(objectives={"robot_time": 300.0}, failed=False, failure_kind="invalid_test", detail="no route")
    ev = loop_evaluation([known, new, passed, invalid])
    assert ev.valid.tolist() == [True, True, True, False]
    assert ev.f1.tolist() == [0.0, 300.0, 61.5, 0.0]


def test_the_pace_in_the_loop_ranks_a_struggle_over_a_long_easy_route():
    """``loop_objective: pace``: a pass of 120 s on a 25 m route (a near miss: 4.8 s/m) ranks above
    a pass of 150 s on a 60 m route (a long, easy one: 2.5 s/m), which the time alone ranks first;
    a failure scores its time limit's pace (300 s on 25 m: 12), a known one still 0, a run with no
    route on record 0."""
    from ambiegen_ros.core.attributes import ScenarioError
    from ambiegen_ros.nodes.generator import loop_evaluation
    from ambiegen_ros.problems.robot import RobotProblem

    def passed(time, route):
        return Outcome(objectives={"robot_time": time}, failed=False, failure_kind="none", detail="goal reached",
                       metrics={"time": time, "time_limit": 300.0, "route_length_m": route})

    cap = shipped("navfn_path_cap")
    known = known_failures.mark(failure(route=120.0), [cap])
    new = failure(kind="collision", route=25.0)
    new.metrics["time_limit"] = 300.0
    runs = [passed(120.0, 25.0), passed(150.0, 60.0), new, known, passed(80.0, None)]
    by_time = loop_evaluation(runs, RobotProblem(profile="refined").loop_f1)
    assert by_time.f1[1] > by_time.f1[0]
    pace = loop_evaluation(runs, RobotProblem(profile="refined", loop_objective="pace").loop_f1)
    assert pace.f1.tolist() == pytest.approx([4.8, 2.5, 12.0, 0.0, 0.0])
    share = loop_evaluation(runs, RobotProblem(profile="refined", loop_objective="time_share").loop_f1)
    assert share.f1.tolist() == pytest.approx([0.4, 0.5, 1.0, 0.0, 80.0 / 300.0])  # the time, over a floor
    ours = Outcome(objectives={"robot_time": 60.0}, failed=False, failure_kind="none", detail="goal reached",
                   metrics={"time": 60.0, "time_limit": 300.0, "route_length": 20.0})  # our full model's name
    assert RobotProblem(profile="refined", loop_objective="pace").loop_f1(ours) == pytest.approx(3.0)
    with pytest.raises(ScenarioError, match="loop_objective"):
        RobotProblem(profile="refined", loop_objective="recoveries")
