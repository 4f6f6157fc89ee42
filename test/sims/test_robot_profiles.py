"""Robot profiles (issue 69) without ROS: each shipped profile loads; the world moves each drive as
it can (a car never turns in place, an omnidirectional base moves sideways, a differential one
does not), stops each body at the wall, casts each laser from its mount over its field of view;
the references ask each robot's own clearance and a car's turning radius; bad input is one line
naming the field.

Known answers come from geometry: distances to walls a known way off, turning circles.
"""
from __future__ import annotations

import math
import types

import numpy as np
import pytest
import yaml

from ambiegen_ros.sims.reference import robot as reference
from ambiegen_ros.sims.reference.robot_car import car_check, car_path
from ambiegen_ros.sims.robot import RobotSimConfig
from ambiegen_ros.sims.robot_profile import (SHIPPED, ProfileError, check_controller, load_profile, profile_from_dict,
                                             profile_path, profile_to_dict, profiled)
from ambiegen_ros.sims.robot_world import PIONEER2DX, RobotWorld, WallGeometry

CFG = RobotSimConfig(dt=0.1, engine="numpy")


def open_room(n: int = 100) -> np.ndarray:
    """n x n free cells (0.1 m): the only walls are outside the grid."""
    return np.zeros((n, n), dtype=bool)


def raw(name: str) -> dict:
    return yaml.safe_load(profile_path(name).read_text())


def without_noise(name: str, **laser) -> object:
    data = raw(name)
    data["lasers"][0].update(noise=0.0, **laser)
    return profile_from_dict(data)


def drive(world: RobotWorld, steps: int, v: float, w: float, vy: float = 0.0) -> None:
    for _ in range(steps):
        world.step(v, w, vy)


@pytest.mark.parametrize("name", SHIPPED)
def test_each_shipped_profile_loads_and_reads_back_the_same(name):
    p = load_profile(name)
    assert p.name == name and p.lasers and p.max_speed[0] > 0 and p.circumscribed_radius() > 0
    assert "Sources" in profile_path(name).read_text().split("\nname:")[0]  # the header cites its sources
    again = profile_from_dict(yaml.safe_load(yaml.safe_dump(profile_to_dict(p))))
    assert again.footprint() == pytest.approx(p.footprint())
    assert [v for las in again.lasers for v in (las.x, las.y, las.yaw, las.beams)] == \
        pytest.approx([v for las in p.lasers for v in (las.x, las.y, las.yaw, las.beams)])
    assert again.min_turning_radius == p.min_turning_radius and again.drive == p.drive


def test_the_pioneer_profile_is_todays_body_and_laser():
    p = load_profile("pioneer2dx")
    assert np.abs(p.footprint() - PIONEER2DX).max() < 1e-6
    las = p.lasers[0]
    assert (las.fov_deg, las.beams, las.range, las.x, las.y, las.yaw) == (180.0, 181, 10.0, 0.0, 0.0, 0.0)
    assert p.world_config(RobotSimConfig()).max_speed == RobotSimConfig().max_speed


# --- kinematics ------------------------------------------------------------------------------------
def test_a_differential_base_turns_in_place_and_never_moves_sideways():
    world = RobotWorld(open_room(), 0.1, CFG, (5.0, 5.0, 0.0), profile=load_profile("turtlebot4"))
    drive(world, 20, 0.0, 0.0, 0.3)
    assert (world.x, world.y, world.yaw) == (5.0, 5.0, 0.0)
    drive(world, 10, 0.0, 1.0)
    assert (world.x, world.y) == (5.0, 5.0) and world.yaw > 0.5


def test_an_omnidirectional_base_moves_sideways():
    world = RobotWorld(open_room(), 0.1, CFG, (5.0, 5.0, 0.0), profile=load_profile("omni_base"))
    drive(world, 20, 0.0, 0.0, 0.3)
    assert world.x == pytest.approx(5.0) and world.yaw == 0.0 and world.y > 5.4
    assert world.vy == pytest.approx(0.3)
    drive(world, 30, 0.0, 0.0, 2.0)  # capped at its 0.5 m/s
    assert world.vy == pytest.approx(0.5)


def test_a_car_cannot_turn_in_place_and_turns_no_tighter_than_its_radius():
    car = load_profile("ackermann_car")
    world = RobotWorld(open_room(), 0.1, CFG, (5.0, 5.0, 0.0), profile=car)
    drive(world, 20, 0.0, 1.0)
    assert (world.x, world.y, world.yaw) == (5.0, 5.0, 0.0)
    drive(world, 60, 0.5, 5.0)  # asks for a 0.1 m radius
    assert abs(world.w) <= abs(world.v) / car.min_turning_radius + 1e-12 and world.w > 0
    assert world.v / world.w == pytest.approx(car.min_turning_radius)


def test_todays_world_is_unchanged_without_a_profile():
    """No profile: the Pioneer as before (reverse uncapped, no turn-rate cap), a sideways command ignored."""
    a = RobotWorld(open_room(), 0.1, CFG, (5.0, 5.0, 0.3))
    b = RobotWorld(open_room(), 0.1, CFG, (5.0, 5.0, 0.3))
    for k in range(30):
        a.step(0.4 - 0.05 * k, 3.0 * math.sin(k))
        b.step(0.4 - 0.05 * k, 3.0 * math.sin(k), 0.7)
    assert a.pose == b.pose
    drive(a, 30, 0.0, 3.0)
    assert a.w == 3.0  # today's world has no turn-rate cap; the Pioneer profile's is 90 deg/s
    capped = RobotWorld(open_room(), 0.1, CFG, (5.0, 5.0, 0.3), profile=load_profile("pioneer2dx"))
    drive(capped, 30, 0.0, 3.0)
    assert capped.w == pytest.approx(math.pi / 2, abs=1e-6)


# --- footprint contact -----------------------------------------------------------------------------
def wall_east(n: int = 100) -> np.ndarray:
    g = open_room(n)
    g[:, 80:] = True  # a wall from x = 8.0 m
    return g


def test_a_round_body_touches_the_wall_at_its_radius():
    tb3 = load_profile("turtlebot3_burger")
    walls = WallGeometry(wall_east(), 0.1, 3, footprint=tb3.footprint(), engine="numpy")
    for yaw in np.linspace(0, 2 * math.pi, 7):  # round: the same at any heading, within 0.5 % of the radius
        assert walls.clearance_at(7.8, 5.0, yaw) == pytest.approx(0.2 - 0.105, abs=0.001)
    assert walls.clearance_at(7.9, 5.0, 0.0) < 0.0
    world = RobotWorld(wall_east(), 0.1, CFG, (7.0, 5.0, 0.0), profile=tb3)
    drive(world, 100, 0.22, 0.0)
    assert world.contact and 8.0 - 0.106 < world.x < 8.0 - 0.104 + 0.001


def test_a_square_body_touches_the_wall_with_its_corner_when_turned():
    omni = load_profile("omni_base")
    walls = WallGeometry(wall_east(), 0.1, 5, footprint=omni.footprint(), engine="numpy")
    assert walls.clearance_at(7.5, 5.0, 0.0) == pytest.approx(0.25)
    assert walls.clearance_at(7.5, 5.0, math.pi / 4) == pytest.approx(0.5 - math.sqrt(2) * 0.25)
    world = RobotWorld(wall_east(), 0.1, CFG, (7.0, 5.0, 0.0), profile=omni)
    drive(world, 100, 0.5, 0.0)
    assert world.contact and world.x == pytest.approx(8.0 - 0.25, abs=1e-3)


# --- lasers ----------------------------------------------------------------------------------------
def wall_behind() -> np.ndarray:
    g = open_room()
    g[:, :30] = True  # a wall up to x = 3 m; the robot at x = 5 faces +x, away from it
    return g


def test_a_360_degree_lidar_sees_behind_and_the_pioneers_180_does_not():
    """Both lasers cut to 3 m, so only the wall 2 m behind is within range."""
    tb4 = RobotWorld(wall_behind(), 0.1, CFG, (5.0, 5.0, 0.0), profile=without_noise("turtlebot4", range=3.0))
    ranges, hits = tb4.scan()
    assert len(ranges) == 360 and hits.any()
    # the lidar is turned 90 deg on its mount: its beam at -90 deg looks ahead, +90 deg behind
    angles = tb4.lasers[0][3]
    behind = np.argmin(np.abs(angles - math.pi / 2))
    assert hits[behind] and ranges[behind] == pytest.approx(2.0 - 0.04, abs=1e-9)
    pioneer = RobotWorld(wall_behind(), 0.1, CFG, (5.0, 5.0, 0.0), profile=without_noise("pioneer2dx", range=3.0))
    assert not pioneer.scan()[1].any()
    today = RobotWorld(wall_behind(), 0.1, RobotSimConfig(dt=0.1, engine="numpy", laser_noise=0.0, laser_range=3.0),
                       (5.0, 5.0, 0.0))
    assert not today.scan()[1].any()


def test_the_mount_offset_shifts_the_ranges():
    ahead = wall_east()
    mounted = RobotWorld(ahead, 0.1, CFG, (5.0, 5.0, 0.0), profile=without_noise("turtlebot3_burger", range=10.0))
    centred = RobotWorld(ahead, 0.1, CFG, (5.0, 5.0, 0.0), profile=without_noise("turtlebot3_burger", x=0.0,
                                                                                   range=10.0))
    front = int(np.argmin(np.abs(mounted.lasers[0][3])))
    assert mounted.scan()[0][front] == pytest.approx(3.0 + 0.032)
    assert centred.scan()[0][front] == pytest.approx(3.0)
    assert mounted.laser_pose() == pytest.approx((5.0 - 0.032, 5.0, 0.0))


# --- the references on each robot ------------------------------------------------------------------
def gap_map(gap_cells: int = 6) -> np.ndarray:
    """40 x 40 cells of 0.1 m, a wall across the middle with a gap of ``gap_cells``."""
    g = np.zeros((40, 40), dtype=bool)
    g[19:21, :] = True
    g[19:21, 17:17 + gap_cells] = False
    return g


def problem_on(grid: np.ndarray, start: tuple, goal: tuple, start_yaw: float = 0.0):
    env = types.SimpleNamespace(grid=grid, resolution=0.1, start=start, goal=goal, start_yaw=start_yaw, goal_yaw=None,
                                unmapped=None)
    return types.SimpleNamespace(environment=lambda scenario: env, hazards=False)


def test_the_small_turtlebot3_passes_a_gap_the_pioneers_clearance_refuses():
    problem = problem_on(gap_map(), (20, 5), (20, 35), math.pi / 2)
    pioneer = reference.before(problem, None, RobotSimConfig())
    tb3 = reference.before(problem, None, profiled(RobotSimConfig(), "turtlebot3_burger"))
    assert not pioneer.passed and "0.36" in pioneer.reason
    assert tb3.passed and tb3.metrics["footprint_radius_m"] == 0.105 and tb3.metrics["clearance_m"] == \
        pytest.approx(0.205)


def u_bend_map() -> np.ndarray:
    """Two 2 m corridors side by side (0.1 m cells) on either side of a 0.4 m wall, joined by a
    1.5 m bend above its end: a U-turn 2.4 m across, wide enough for the car's 1.56 m circle."""
    g = np.ones((70, 50), dtype=bool)
    g[2:66, 2:48] = False
    g[:51, 22:26] = True
    return g


def test_the_car_drives_a_u_bend_wide_enough_for_its_turning_circle():
    problem = problem_on(u_bend_map(), (12, 15), (36, 15), math.pi / 2)
    assert reference.before(problem, None, profiled(RobotSimConfig(), "ackermann_car")).passed


def test_the_car_refuses_a_hairpin_that_a_differential_robot_drives():
    """A 1.5 m corridor, the goal behind the start: a turn on the spot for a TurtleBot 4, a U-turn
    1.56 m across (twice the car's minimum radius) that does not fit for the car."""
    grid = np.ones((60, 19), dtype=bool)
    grid[2:58, 2:17] = False
    problem = problem_on(grid, (9, 40), (9, 10), math.pi / 2)
    assert reference.before(problem, None, profiled(RobotSimConfig(), "turtlebot4")).passed
    car = reference.before(problem, None, profiled(RobotSimConfig(), "ackermann_car"))
    assert not car.passed and car.reason.startswith("no car-like robot drives it"), car.reason
    assert car.metrics["min_turning_radius_m"] == pytest.approx(0.779, abs=1e-3)


def test_the_car_drives_an_open_route_within_its_turning_radius():
    grid = np.zeros((100, 100), dtype=bool)
    problem = problem_on(grid, (40, 50), (80, 60), math.pi)  # starts facing away from the goal
    verdict = reference.before(problem, None, profiled(RobotSimConfig(), "ackermann_car"))
    assert verdict.passed, verdict.reason
    route = reference.route_for(grid, 0.1, (40, 50), (80, 60), RobotSimConfig())
    r = load_profile("ackermann_car").min_turning_radius
    path = car_check(grid, 0.1, route.waypoints, math.pi, r, 0.622)
    assert path.found
    seg = np.diff(path.points, axis=0)
    seg = seg[np.hypot(seg[:, 0], seg[:, 1]) > 1e-9]  # the joins repeat a point
    heading = np.unwrap(np.arctan2(seg[:, 1], seg[:, 0]))
    length = np.hypot(seg[:, 0], seg[:, 1])
    curvature = np.abs(np.diff(heading)) / np.minimum(length[:-1], length[1:])
    assert curvature.max() <= 1 / r * 1.01  # never tighter than the minimum radius
    assert heading[0] == pytest.approx(math.pi, abs=0.02)  # it leaves as it stands: no turn on the spot


def test_a_goal_inside_the_cars_turning_circle_is_refused_with_its_reason():
    path = car_path(np.array([[0.0, 0.0], [0.0, 0.5]]), 0.0, 0.78)  # 0.5 m to its left
    assert not path.found and "turning circle" in path.reason


def test_the_judge_measures_the_profiles_body():
    from ambiegen_ros.sims.oracles import RobotJudge

    judge = RobotJudge(open_room(), 0.1, (8.0, 8.0), profiled(RobotSimConfig(), "turtlebot3_burger"))
    assert judge.walls.footprint == pytest.approx(load_profile("turtlebot3_burger").footprint())
    assert RobotJudge(open_room(), 0.1, (8.0, 8.0), RobotSimConfig()).walls.footprint == pytest.approx(PIONEER2DX)


# --- bad input: one line naming the field ----------------------------------------------------------
def broken(change) -> dict:
    data = raw("turtlebot4")
    change(data)
    return data


BAD = [
    ("footprint.polygon", lambda d: d.update(footprint={"polygon": [[0.2, 0.2], [-0.2, -0.2], [0.2, -0.2],
                                                                   [-0.2, 0.2]]})),  # a bow tie
    ("lasers[0].parent", lambda d: d["lasers"][0].update(parent="camera_link")),
    ("frames.shell_link.parent", lambda d: d["frames"]["shell_link"].update(parent="odom")),
    ("limits.max_speed.x", lambda d: d["limits"]["max_speed"].update(x=0.0)),
    ("limits.max_accel.theta", lambda d: d["limits"]["max_accel"].update(theta=-1.0)),
    ("limits.max_speed.y", lambda d: d["limits"]["max_speed"].update(y=0.3)),
    ("drive.kind", lambda d: d.update(drive={"kind": "tank"})),
    ("drive.min_turning_radius", lambda d: d.update(drive={"kind": "ackermann"})),
    ("lasers[0].beams", lambda d: d["lasers"][0].update(beams=0)),
    ("lasers[0].x", lambda d: d["lasers"][0].update(x=1.0)),
    ("footprint", lambda d: d.update(footprint={"radius": 0.2, "polygon": [[1, 1], [0, 1], [0, 0]]})),
]


@pytest.mark.parametrize("field,change", BAD, ids=[b[0] for b in BAD])
def test_a_bad_profile_is_one_line_naming_the_field(field, change):
    with pytest.raises(ProfileError) as err:
        profile_from_dict(broken(change))
    assert err.value.field == field and str(err.value).startswith(f"{field}: ") and "\n" not in str(err.value)


def params_with(plugin: str, **section) -> dict:
    return {"controller_server": {"ros__parameters": {"controller_plugins": ["FollowPath"],
                                                      "FollowPath": {"plugin": plugin, **section}}}}


MPPI, RPP, DWB = ("nav2_mppi_controller::MPPIController",
                  "nav2_regulated_pure_pursuit_controller::RegulatedPurePursuitController", "dwb_core::DWBLocalPlanner")


@pytest.mark.parametrize("params,field", [
    (params_with(DWB), "controller_server.FollowPath.plugin"),
    (params_with(MPPI, motion_model="DiffDrive"), "controller_server.FollowPath.motion_model"),
    (params_with(RPP), "controller_server.FollowPath.use_rotate_to_heading"),
    (params_with("nav2_rotation_shim_controller::RotationShimController"), "controller_server.FollowPath.plugin"),
])
def test_a_car_under_a_controller_without_a_car_like_model_is_refused(params, field):
    with pytest.raises(ProfileError) as err:
        check_controller(load_profile("ackermann_car"), params)
    assert err.value.field == field and "\n" not in str(err.value)


def test_controllers_that_can_drive_each_base_pass():
    car = load_profile("ackermann_car")
    assert check_controller(car, params_with(MPPI, motion_model="Ackermann")) == []
    assert check_controller(car, params_with(RPP, use_rotate_to_heading=False)) == []
    assert check_controller(load_profile("turtlebot4"), params_with(MPPI, motion_model="DiffDrive")) == []
    notes = check_controller(load_profile("omni_base"), params_with(DWB, max_vel_y=0.0))
    assert notes and "never moves sideways" in notes[0]
    with pytest.raises(ProfileError, match="sideways"):
        check_controller(load_profile("turtlebot4"), params_with(MPPI, motion_model="Omni"))


def test_the_patient_reference_drives_the_profiles_body_within_its_limits():
    """No people: the patient reference just drives. The burger no faster than its 0.22 m/s (the
    config's cruise speed is 0.3); the car along its rounded path, never turning on the spot."""
    grid = np.zeros((100, 100), dtype=bool)
    env = types.SimpleNamespace(grid=grid, resolution=0.1, start=(20, 50), goal=(80, 50), start_yaw=0.0,
                                goal_yaw=None, unmapped=None)
    route = reference.route_for(grid, 0.1, env.start, env.goal, RobotSimConfig())
    tb3 = reference._patient(route, (), env, profiled(RobotSimConfig(), "turtlebot3_burger"), 600.0)
    assert tb3.passed and tb3.time >= route.length / 0.22
    steps = np.hypot(*np.diff(tb3.poses[:, :2], axis=0).T)
    assert steps.max() <= 0.22 * RobotSimConfig().dt + 1e-9
    env.start_yaw = math.pi / 2  # the car starts facing across the route: it curves onto it
    car = reference._patient(route, (), env, profiled(RobotSimConfig(), "ackermann_car"), 600.0)
    assert car.passed
    moved = np.hypot(*np.diff(car.poses[:, :2], axis=0).T)
    turned = np.abs(np.diff(np.unwrap(car.poses[:, 2])))
    assert (turned[moved < 1e-9] < 1e-9).all()  # no turn without moving
    assert (turned <= moved / load_profile("ackermann_car").min_turning_radius * 1.05 + 1e-9).all()


# --- every shipped profile, the same questions -------------------------------------------------------
@pytest.mark.parametrize("name", SHIPPED)
def test_each_profile_drives_stops_at_its_front_sees_its_field_and_gets_a_route(name):
    p = load_profile(name)
    world = RobotWorld(wall_east(), 0.1, CFG, (4.0, 5.0, 0.0), profile=p)
    drive(world, 200, 5.0, 0.0)  # asks for more than any base can: the world gives its top speed, then the wall
    front = float(p.footprint()[:, 0].max())
    assert world.contact and world.x == pytest.approx(8.0 - front, abs=2e-3) and world.yaw == 0.0
    world = RobotWorld(open_room(), 0.1, CFG, (2.0, 5.0, 0.0), profile=p)
    drive(world, 40, 5.0, 0.0)  # 4 s: every base reaches its top speed within 2 s, well short of the far wall
    assert world.v == pytest.approx(p.max_speed[0]) and not world.contact
    box = np.ones((40, 40), dtype=bool)
    box[5:35, 5:35] = False  # a closed 3 m room: every wall within every laser's range
    world = RobotWorld(box, 0.1, CFG, (2.0, 2.0, 0.0), profile=p)
    for k, laser in enumerate(p.lasers):
        ranges, hits = world.scan(k)
        angles = world.lasers[k][3]
        assert len(ranges) == laser.beams and hits.all()
        span = math.degrees(angles[-1] - angles[0]) * (1 if laser.fov_deg < 360 else laser.beams / (laser.beams - 1))
        assert span == pytest.approx(laser.fov_deg)
    problem = problem_on(np.zeros((60, 60), dtype=bool), (10, 30), (50, 30), 0.0)
    verdict = reference.before(problem, None, profiled(RobotSimConfig(), name))
    assert verdict.passed and verdict.metrics["clearance_m"] == pytest.approx(p.circumscribed_radius() + 0.1)


def test_a_repeated_waypoint_is_no_leg_for_the_car():
    route = np.array([[1.0, 1.0], [1.0, 1.0], [4.0, 1.0], [4.0, 1.0], [6.0, 3.0]])
    path = car_path(route, 0.0, 0.78)
    assert path.found and path.points[0] == pytest.approx([1.0, 1.0]) and path.points[-1] == pytest.approx([6.0, 3.0])
