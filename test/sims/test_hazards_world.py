"""The robot's world with what is not in its map (issue 48), and the reference's rules for it.

* the laser sees boxes, posts and people; boxes and posts stop the body as walls do;
* the fault rule: a robot that drives into a person collides (a failure); a person who walks into
  a robot standing still is recorded, not counted;
* the reference: a route with clearance must exist in the true world (unmapped obstacles kept
  clear too), and with people a patient robot that knows their paths must reach the goal; a
  scenario no reference passes is an invalid test.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from ambiegen_ros.sims import robot
from ambiegen_ros.sims.obstacles import Obstacles, Person
from ambiegen_ros.sims.reference.robot import plan_clearance_route
from ambiegen_ros.sims.reference.robot_patient import patient_run, plan_poses
from ambiegen_ros.sims.robot_world import RobotWorld
from helpers.hazards_cases import hazards_case


def room(n: int = 20) -> np.ndarray:
    g = np.zeros((n, n), dtype=bool)
    g[0, :] = g[-1, :] = g[:, 0] = g[:, -1] = True
    return g


def gap_map() -> np.ndarray:
    """Two rooms joined by one 2 m gap (x 1..3) in a wall along y = 8."""
    g = room()
    g[8, 3:] = True
    return g


CFG = robot.RobotSimConfig(laser_noise=0.0)


def test_the_laser_sees_what_the_map_leaves_out():
    post = Obstacles(posts=np.array([[6.0, 5.0, 0.05]]))
    plain = RobotWorld(room(), 1.0, CFG, (3.0, 5.0, 0.0))
    seen = RobotWorld(room(), 1.0, CFG, (3.0, 5.0, 0.0), obstacles=post)
    ahead = int(np.argmin(np.abs(plain.beam_angles)))
    assert plain.scan()[0][ahead] == pytest.approx(10.0)  # nothing within the 10 m range
    assert seen.scan()[0][ahead] == pytest.approx(2.95)  # the 10 cm post 3 m ahead


def test_a_box_stops_the_body_as_a_wall_does():
    box = Obstacles(boxes=np.array([[5.0, 4.0, 6.0, 6.0]]))
    w = RobotWorld(room(), 1.0, CFG, (3.0, 5.0, 0.0), obstacles=box)
    for _ in range(100):
        w.step(0.5, 0.0)
        if w.contact:
            break
    assert w.contact and w.v == 0.0
    front = w.x + 0.22 - 0.04  # the pioneer's nose lies 0.18 m ahead of its rotation centre
    assert front == pytest.approx(5.0, abs=0.01)


def test_a_person_walking_into_a_standing_robot_is_not_its_fault():
    walker = Person(np.array([[8.0, 5.0], [2.0, 5.0]]), speed=1.0, delay=0.0, radius=0.3)
    w = RobotWorld(room(), 1.0, CFG, (5.0, 5.0, 0.0), obstacles=Obstacles(people=(walker,)))
    for _ in range(80):
        w.step(0.0, 0.0)
    assert w.person_contact is None and w.contacts_not_at_fault == 1


def test_driving_into_a_person_is_a_collision():
    stander = Person(np.array([[8.0, 5.0], [8.0, 5.1]]), speed=0.1, delay=1000.0, radius=0.3)
    obstacles = Obstacles(people=(stander,))
    w = RobotWorld(room(), 1.0, CFG, (5.0, 5.0, 0.0), obstacles=obstacles)
    for _ in range(100):
        w.step(0.5, 0.0)
        if w.person_contact:
            break
    assert w.person_contact.startswith("the robot drove into person 0") and w.v == 0.0
    run = robot.drive(room(), 1.0, (3.0, 5.0), (15.0, 5.0), np.array([[3.0, 5.0], [15.0, 5.0]]),
                      robot.RobotSimConfig(planner="gap", laser_noise=0.0, radius=0.01, margin=0.0,
                                           squeeze_margin=0.0), obstacles=obstacles)
    assert run["failure_kind"] in ("collision", "stall", "loiter")  # the gap planner sees it and stops, or hits it
    if run["failure_kind"] == "collision":
        assert "drove into person 0" in run["detail"]


def test_a_contact_reports_both_speeds_along_the_line_of_contact():
    """Head-on: the robot at 0.3 m/s, the person walking at 1.1 m/s towards it. The detail says both
    speeds along the line between their centres, and ``contact_speeds`` reads them back."""
    from ambiegen_ros.sims.obstacles import contact_speeds

    walker = Person(np.array([[9.0, 5.0], [2.0, 5.0]]), speed=1.1, delay=0.0, radius=0.25)
    w = RobotWorld(room(), 1.0, CFG, (5.0, 5.0, 0.0), obstacles=Obstacles(people=(walker,)))
    for _ in range(60):
        w.step(0.3, 0.0)
        if w.person_contact:
            break
    speeds = contact_speeds(w.person_contact)
    assert speeds is not None, w.person_contact
    assert speeds["robot_mps"] == pytest.approx(0.3, abs=0.005)
    assert speeds["robot_along_mps"] == pytest.approx(0.3, abs=0.005)  # head-on: all of it along the line
    assert speeds["person_along_mps"] == pytest.approx(1.1, abs=0.005)
    assert contact_speeds("collision at (1.00, 2.00) (reported on /collision: 'touching a wall, box or post')") is None


def test_a_slow_contact_is_charged_only_above_the_fault_speed():
    """The robot creeping at 0.08 m/s into a person walking at it: charged at the default threshold
    (0.01 m/s, as always), not with ``contact_fault_speed`` 0.1 (then the person walked into it)."""
    import dataclasses

    def creep(cfg):
        walker = Person(np.array([[8.0, 5.0], [2.0, 5.0]]), speed=1.1, delay=0.0, radius=0.25)
        w = RobotWorld(room(), 1.0, cfg, (5.0, 5.0, 0.0), obstacles=Obstacles(people=(walker,)))
        for _ in range(60):
            w.step(0.08, 0.0)
        return w

    strict, lenient = creep(CFG), creep(dataclasses.replace(CFG, contact_fault_speed=0.1))
    assert strict.person_contact is not None and "moving at 0.08 m/s" in strict.person_contact
    assert lenient.person_contact is None and lenient.contacts_not_at_fault == 1


def test_the_true_world_route_keeps_clear_of_unmapped_obstacles():
    """The gap is 2 m wide: on the map a route passes it; a 1 m box in its middle leaves 0.5 m
    on each side, less than the 0.72 m the footprint and margin need: no route in the world."""
    box = Obstacles(boxes=np.array([[1.5, 8.0, 2.5, 9.0]]))
    mapped = plan_clearance_route(gap_map(), 1.0, (10.5, 3.5), (10.5, 14.5), 0.36)
    assert mapped.found
    world = plan_clearance_route(gap_map(), 1.0, (10.5, 3.5), (10.5, 14.5), 0.36, extra=box.static_distance)
    assert not world.found and world.reason == "no route keeps 0.36 m from the walls and obstacles"
    small = Obstacles(boxes=np.array([[1.0, 8.0, 1.3, 8.3]]))  # against the gap's left side
    detour = plan_clearance_route(gap_map(), 1.0, (10.5, 3.5), (10.5, 14.5), 0.36, extra=small.static_distance)
    assert detour.found and detour.min_clearance >= 0.36 - 1e-9
    assert small.static_distance(*detour.waypoints.T).min() >= 0.36 - 1e-9


ROUTE = np.array([[2.0, 5.0], [18.0, 5.0]])


def test_the_patient_reference_waits_for_a_crossing_person():
    crossing = Person(np.array([[10.0, 1.5], [10.0, 8.5]]), speed=0.5, delay=20.0, radius=0.3)
    alone = patient_run(ROUTE, (), 0.0, None, CFG, 300.0)
    run = patient_run(ROUTE, (crossing,), 0.0, None, CFG, 300.0)
    assert alone.passed and alone.waited == 0.0
    assert run.passed and run.waited > 0.0 and run.time == pytest.approx(alone.time + run.waited)
    assert run.contacts_not_at_fault == 0


def test_a_person_standing_on_the_route_for_ever_defeats_the_reference():
    stops_on_it = Person(np.array([[10.0, 1.5], [10.0, 5.0]]), speed=0.5, delay=0.0, radius=0.3)
    run = patient_run(ROUTE, (stops_on_it,), 0.0, None, CFG, 120.0)
    assert not run.passed and "people block the route" in run.reason


def test_a_person_who_walks_into_the_waiting_reference_is_recorded_not_counted():
    head_on = Person(np.array([[17.0, 5.0], [1.5, 5.0]]), speed=0.4, delay=0.0, radius=0.3)
    run = patient_run(ROUTE, (head_on,), 0.0, None, CFG, 300.0)
    assert run.passed and run.contacts_not_at_fault == 1 and run.waited > 0.0


def test_the_reference_turns_on_the_spot_to_each_leg_and_the_goals_yaw():
    poses = plan_poses(np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]]), math.pi, -math.pi / 2, 0.5, math.radians(30), 0.1)
    assert poses[0, 2] == pytest.approx(math.pi)
    assert np.isclose(poses[:, 2] % (2 * math.pi), 0.0).any()  # turned to the first leg (east)
    assert (poses[-1, 2] - (-math.pi / 2)) % (2 * math.pi) == pytest.approx(0.0, abs=1e-9)
    steps = np.hypot(*np.diff(poses[:, :2], axis=0).T)
    assert steps.max() <= 0.05 + 1e-9  # 0.5 m/s x 0.1 s



@pytest.mark.parametrize("why", ["collision with a person", "pass"])
def test_a_give_up_at_the_stacks_own_time_per_goal_counts_only_if_the_reference_makes_it_in_that_time(why):
    """A behaviour tree's Timeout shorter than the scenario's limit (issue 59: the hardened tree gave a
    route the reference drove in 285.6 s only 180 s): the reference gets the stack's time, people or
    not; a route longer than that is the stack's setting, an invalid test, not its failure."""
    from ambiegen_ros.sims import Outcome, reference
    from ambiegen_ros.sims.full_model import sim_config

    problem, scenario = hazards_case(why)
    cfg = sim_config("robot")
    gave_up = Outcome(objectives={"robot_time": 1.0}, failed=True, failure_kind="nav2_aborted",
                      detail="Nav2 aborted its goal after 60.0 s (error 0)", metrics={"time_limit": 300.0})
    plain = reference.after(problem, scenario, cfg, gave_up)
    roomy = reference.after(problem, scenario, cfg, gave_up, budget=290.0)
    assert roomy.passed and roomy.metrics["time_budget_s"] == 290.0
    if why == "pass":  # no people: the route's existence was the whole reference; with a budget it is driven
        assert plain is None
    else:
        assert plain.passed and plain.metrics["patient_time_s"] == pytest.approx(roomy.metrics["patient_time_s"])
    needed = roomy.metrics["patient_time_s"]
    tight = reference.after(problem, scenario, cfg, gave_up, budget=needed - 5.0)
    assert not tight.passed and f"the stack's own {needed - 5.0:.0f} s per goal" in tight.reason
    judged = reference.certify(gave_up, tight)
    assert judged.failure_kind == "invalid_test" and not judged.failed
    assert judged.metrics["sut_failure_kind"] == "nav2_aborted" and judged.metrics["reference_time_budget_s"] == needed - 5.0
    assert reference.certify(gave_up, roomy).failed  # the reference made it in the stack's time: a failure
