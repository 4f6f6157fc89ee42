"""`ambiegen robot-profile` and `ambiegen nav2-params --robot` (issue 69): a user's robot from their
Nav2 params (and URDF) to a profile, and from a profile into the params Nav2 starts with.

The params are ``test/data/nav2_jazzy_tb4_robot_keys.yaml``: the few keys of Jazzy's nav2_params.yaml
that describe its TurtleBot 4, restated; the URDF ``test/data/tb4_lidar.urdf`` its laser mount.
"""
from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from ambiegen_ros.sims.robot_profile import load_profile

ROOT = Path(__file__).resolve().parents[1]
JAZZY = ROOT / "test" / "data" / "nav2_jazzy_tb4_robot_keys.yaml"
URDF = ROOT / "test" / "data" / "tb4_lidar.urdf"


def ambiegen(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "ambiegen_ros", *map(str, args)], cwd=ROOT, capture_output=True,
                          text=True, timeout=180)


def read(path: Path) -> dict:
    return yaml.safe_load(path.read_text())


def costmap(params: dict, name: str) -> dict:
    return params[name][name]["ros__parameters"]


def test_nav2_params_writes_the_turtlebot4s_radius_laser_and_limits(tmp_path):
    out = tmp_path / "tb4.yaml"
    run = ambiegen("nav2-params", JAZZY, "--robot", "turtlebot4", "-o", out)
    assert run.returncode == 0, run.stderr
    params = read(out)
    for name in ("local_costmap", "global_costmap"):
        c = costmap(params, name)
        assert c["robot_radius"] == 0.22 and "footprint" not in c  # the overlay's Pioneer footprint is gone
    assert costmap(params, "local_costmap")["voxel_layer"]["scan"]["sensor_frame"] == "rplidar_link"
    smoother = params["velocity_smoother"]["ros__parameters"]
    assert smoother["max_accel"] == [2.5, 0.0, 3.2] and smoother["max_velocity"] == [0.5, 0.0, 2.0]
    mppi = params["controller_server"]["ros__parameters"]["FollowPath"]
    assert (mppi["ax_max"], mppi["az_max"], mppi["vx_max"]) == (2.5, 3.2, 0.5)
    # the overlay checks the Pioneer's box footprint in MPPI's cost critic; a disc needs only its centre's cost
    assert mppi["CostCritic"]["consider_footprint"] is False
    assert "turtlebot4" in run.stdout and "robot_profile:=turtlebot4" in run.stdout
    default = tmp_path / "pioneer.yaml"
    assert ambiegen("nav2-params", JAZZY, "-o", default).returncode == 0  # without --robot: the overlay's Pioneer
    assert costmap(read(default), "local_costmap")["footprint"].startswith("[[0.18, 0.19]")


def test_a_smaller_robots_caps_lower_the_controller_and_never_raise_it(tmp_path):
    out = tmp_path / "tb3.yaml"
    assert ambiegen("nav2-params", JAZZY, "--robot", "turtlebot3_burger", "-o", out).returncode == 0
    params = read(out)
    mppi = params["controller_server"]["ros__parameters"]["FollowPath"]
    assert mppi["vx_max"] == 0.22 and mppi["vx_min"] == -0.22  # the burger's 0.22 m/s
    assert mppi["wz_max"] == 1.9  # the burger could turn at 2.84 rad/s: the user's 1.9 stays
    assert costmap(params, "global_costmap")["robot_radius"] == 0.105
    scan = costmap(params, "local_costmap")["voxel_layer"]["scan"]
    assert scan["raytrace_max_range"] == 3.0 and scan["sensor_frame"] == "base_scan"


def test_every_laser_of_a_profile_is_a_scan_source_of_each_costmap(tmp_path):
    sys.path.insert(0, str(ROOT / "test" / "sims"))
    from test_hosted_world import TWO_LASERS

    robot = tmp_path / "two_lasers.yaml"
    robot.write_text(TWO_LASERS)
    out = tmp_path / "two.yaml"
    run = ambiegen("nav2-params", JAZZY, "--robot", robot, "-o", out)
    assert run.returncode == 0, run.stderr
    params = read(out)
    for name in ("local_costmap", "global_costmap"):
        layers = [layer for layer in costmap(params, name).values() if isinstance(layer, dict) and "scan" in layer]
        assert layers, name
        for layer in layers:
            front, rear = layer["scan"], layer["scan_rear"]
            assert layer["observation_sources"].split() == ["scan", "scan_rear"]
            assert (front["sensor_frame"], rear["sensor_frame"], rear["topic"]) == ("front_laser", "rear_laser",
                                                                                  "/scan_rear")
            # the rear laser reaches 5 m: its ranges no farther; the rest of its settings the first source's
            assert rear["raytrace_max_range"] <= 5.0 and rear["obstacle_max_range"] <= 5.0
            assert {k: v for k, v in rear.items() if "range" not in k and k not in ("topic", "sensor_frame")} == \
                {k: v for k, v in front.items() if "range" not in k and k not in ("topic", "sensor_frame")}


def test_a_polygon_robot_gets_its_footprint(tmp_path):
    out = tmp_path / "omni.yaml"
    run = ambiegen("nav2-params", JAZZY, "--robot", "omni_base", "-o", out)
    assert run.returncode == 0, run.stderr
    c = costmap(read(out), "local_costmap")
    assert yaml.safe_load(c["footprint"]) == [[0.25, 0.25], [-0.25, 0.25], [-0.25, -0.25], [0.25, -0.25]]
    assert "robot_radius" not in c
    assert read(out)["controller_server"]["ros__parameters"]["FollowPath"]["CostCritic"]["consider_footprint"] is True
    assert "never moves sideways" in run.stdout  # Jazzy's MPPI is DiffDrive: allowed, said


def test_a_car_under_a_controller_without_a_car_like_model_is_one_line_and_nothing_written(tmp_path):
    out = tmp_path / "car.yaml"
    run = ambiegen("nav2-params", JAZZY, "--robot", "ackermann_car", "-o", out)
    assert run.returncode == 2 and not out.exists()
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and "controller_server.FollowPath.motion_model" in lines[0]


def test_a_car_under_mppis_ackermann_model_gets_its_turning_radius(tmp_path):
    params = read(JAZZY)
    params["controller_server"]["ros__parameters"]["FollowPath"]["motion_model"] = "Ackermann"
    mine = tmp_path / "mine.yaml"
    mine.write_text(yaml.safe_dump(params))
    out = tmp_path / "car.yaml"
    run = ambiegen("nav2-params", mine, "--robot", "ackermann_car", "-o", out)
    assert run.returncode == 0, run.stderr
    mppi = read(out)["controller_server"]["ros__parameters"]["FollowPath"]
    assert mppi["AckermannConstraints"]["min_turning_r"] == pytest.approx(load_profile("ackermann_car").min_turning_radius)


def test_the_shipped_car_set_up_drives_the_car_with_its_turning_radius(tmp_path):
    """``config/nav2/robots/ackermann_car.yaml`` over Jazzy's params: Smac Hybrid-A* and MPPI's
    Ackermann model, both at the profile's radius, accepted for the car; the TurtleBot 4's params alone
    are refused for it (above)."""
    out = tmp_path / "car.yaml"
    run = ambiegen("nav2-params", f"{JAZZY}+{ROOT / 'config' / 'nav2' / 'robots' / 'ackermann_car.yaml'}",
                   "--robot", "ackermann_car", "-o", out)
    assert run.returncode == 0, run.stderr
    params = read(out)
    radius = load_profile("ackermann_car").min_turning_radius
    planner = params["planner_server"]["ros__parameters"]["GridBased"]
    assert planner["plugin"] == "nav2_smac_planner::SmacPlannerHybrid" and planner["motion_model_for_search"] == "DUBIN"
    assert planner["minimum_turning_radius"] == pytest.approx(radius)
    mppi = params["controller_server"]["ros__parameters"]["FollowPath"]
    assert mppi["motion_model"] == "Ackermann" and mppi["AckermannConstraints"]["min_turning_r"] == pytest.approx(radius)
    assert mppi["vx_min"] == -0.35  # the rest of Jazzy's MPPI as it was
    assert yaml.safe_load(costmap(params, "local_costmap")["footprint"])  # the car's body, not the radius


def test_the_jazzy_params_and_urdf_give_the_turtlebot4_profile(tmp_path):
    out = tmp_path / "my_robot.yaml"
    run = ambiegen("robot-profile", "--from-params", JAZZY, "--urdf", URDF, "-o", out)
    assert run.returncode == 0, run.stderr
    mine, tb4 = load_profile(out), load_profile("turtlebot4")
    assert mine.name == "my_robot" and mine.radius == tb4.radius and mine.drive == tb4.drive == "differential"
    assert mine.max_speed == tb4.max_speed and mine.max_accel == tb4.max_accel
    a, b = mine.lasers[0], tb4.lasers[0]
    assert (a.frame, a.fov_deg, a.beams, a.range, a.rate) == (b.frame, b.fov_deg, b.beams, b.range, b.rate)
    assert (a.x, a.y) == pytest.approx((b.x, b.y)) and a.yaw == pytest.approx(math.pi / 2)
    not_found = [line for line in run.stdout.splitlines() if line.startswith("not found:")]
    assert len(not_found) == 1 and "noise" in not_found[0]  # the one thing neither file says
    assert "# Not found there" in out.read_text()
    # and the second command takes it
    merged = tmp_path / "merged.yaml"
    again = ambiegen("nav2-params", JAZZY, "--robot", out, "-o", merged)
    assert again.returncode == 0, again.stderr
    assert costmap(read(merged), "global_costmap")["robot_radius"] == 0.22


def test_without_a_urdf_it_says_what_it_could_not_find(tmp_path):
    out = tmp_path / "bare.yaml"
    run = ambiegen("robot-profile", "--from-params", JAZZY, "-o", out)
    assert run.returncode == 0, run.stderr
    text = run.stdout
    for field in ("lasers[0] mount", "lasers[0].frame", "lasers[0].fov_deg", "lasers[0].beams", "lasers[0].range",
                  "lasers[0].rate"):
        assert f"not found: {field}" in text
    assert "not found: footprint" not in text and "not found: limits" not in text
    assert load_profile(out).lasers[0].x == 0.0


def test_a_self_intersecting_footprint_in_the_params_is_one_line_naming_the_field(tmp_path):
    params = read(JAZZY)
    costmap(params, "local_costmap")["footprint"] = "[[0.2, 0.2], [-0.2, -0.2], [0.2, -0.2], [-0.2, 0.2]]"
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump(params))
    run = ambiegen("robot-profile", "--from-params", bad, "-o", tmp_path / "out.yaml")
    lines = run.stderr.strip().splitlines()
    assert run.returncode == 2 and len(lines) == 1 and "footprint.polygon" in lines[0]
    assert not (tmp_path / "out.yaml").exists()


def test_the_nav2_campaign_plan_gives_the_world_and_the_params_the_robot(tmp_path):
    from ambiegen_ros.launch_logic import plan_nav2_campaign

    plan = plan_nav2_campaign({"output_dir": str(tmp_path), "robot_profile": "turtlebot4", "params_file": str(JAZZY)},
                              share_dir=str(ROOT))
    (world,) = [n for n in plan.nodes if n.name == "robot_world"]
    assert world.parameters["robot_profile"] == plan.node("sut_adapter").parameters["robot_profile"] == "turtlebot4"
    (written,) = tmp_path.rglob("*.nav2_params.yaml")
    assert costmap(read(written), "local_costmap")["robot_radius"] == 0.22
    plain = plan_nav2_campaign({"output_dir": str(tmp_path / "plain"), "params_file": str(JAZZY)}, share_dir=str(ROOT))
    assert all("robot_profile" not in n.parameters for n in plain.nodes)  # today's plan, unchanged
    with pytest.raises(ValueError, match="^controller_server.FollowPath.motion_model: "):
        plan_nav2_campaign({"output_dir": str(tmp_path / "car"), "robot_profile": "ackermann_car",
                            "params_file": str(JAZZY)}, share_dir=str(ROOT))
    omni = plan_nav2_campaign({"output_dir": str(tmp_path / "omni"), "robot_profile": "omni_base",
                               "params_file": str(JAZZY)}, share_dir=str(ROOT))
    assert omni.node("sut_adapter").parameters["robot_profile"] == "omni_base"  # judged as itself, not refused
