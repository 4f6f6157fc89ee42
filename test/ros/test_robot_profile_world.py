"""``robot_world`` with a robot profile (issue 69), a real subprocess on real DDS: the TurtleBot 4's
360-degree lidar on its turned mount (its frames on ``/tf_static``, its beams on ``/scan``), an
omnidirectional base that ``linear.y`` moves sideways (and whose odometry says so), two lasers each
at its own rate, and a car that a turn without speed does not
turn. Waits follow simulated time on the odometry stamps, never the wall clock.
"""
from __future__ import annotations

import math
import os
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]

import numpy as np  # noqa: E402
import pytest  # noqa: E402

from ambiegen_ros.ros import conversions  # noqa: E402
from ambiegen_ros.ros.qos import DEFAULT, LATCHED, Qos  # noqa: E402
from helpers.graph_wait import traced, wait_for  # noqa: E402

pytestmark = pytest.mark.skipif(os.environ.get("AMBIEGEN_TRANSPORT", "auto") == "rclpy",
                                reason="these tests drive the DDS backend")


def world_with(graph, profile: str, x0: float = 15.0):
    """The world on a 30 m box, the robot at (x0, 15) facing +x; what it publishes, collected."""
    procs, node = graph()
    traced(procs).start("world", "sim_nodes.robot_world", time_scale=5.0, cmd_timeout=0.0, robot_profile=profile)
    got: dict[str, list] = {k: [] for k in ("tf_static", "odom", "scan")}
    node.create_subscription("tf2_msgs/msg/TFMessage", "/tf_static", lambda m: got["tf_static"].append(m), LATCHED)
    node.create_subscription("nav_msgs/msg/Odometry", "/odom", lambda m: got["odom"].append(m), Qos(depth=100))
    node.create_subscription("sensor_msgs/msg/LaserScan", "/scan", lambda m: got["scan"].append(m), Qos(depth=100))
    pub_map = node.create_publisher("nav_msgs/msg/OccupancyGrid", "/map", LATCHED)
    pub_pose = node.create_publisher("geometry_msgs/msg/PoseWithCovarianceStamped", "/initialpose", DEFAULT)
    pub_cmd = node.create_publisher("geometry_msgs/msg/Twist", "/cmd_vel", DEFAULT)
    make = node.new_message
    wait_for(node, procs, lambda: pub_cmd.subscription_count() and pub_pose.subscription_count() and got["odom"], 120,
             "odometry from the world, or no match of its /cmd_vel and /initialpose")
    grid = np.zeros((30, 30), dtype=bool)
    grid[0, :] = grid[-1, :] = grid[:, 0] = grid[:, -1] = True
    info = make("nav_msgs/msg/MapMetaData", resolution=1.0, width=30, height=30, origin=conversions.pose(make, 0.0, 0.0))
    pub_map.publish(make("nav_msgs/msg/OccupancyGrid", header=conversions.header(make, node.now_ns()), info=info,
                         data=np.where(grid, 100, 0).astype(np.int8).ravel()))
    pub_pose.publish(make("geometry_msgs/msg/PoseWithCovarianceStamped", header=conversions.header(make, node.now_ns()),
                          pose=make("geometry_msgs/msg/PoseWithCovariance", pose=conversions.pose(make, x0, 15.0))))
    wait_for(node, procs, lambda: any(abs(m.pose.pose.position.x - x0) < 1e-9 for m in got["odom"]), 60,
             "odometry at the initial pose")

    def command(**twist) -> None:
        """Send a command and wait until 3 simulated seconds of odometry have followed it."""
        linear = make("geometry_msgs/msg/Vector3", x=twist.get("x", 0.0), y=twist.get("y", 0.0))
        angular = make("geometry_msgs/msg/Vector3", z=twist.get("w", 0.0))
        start = conversions.stamp_ns(got["odom"][-1].header)
        pub_cmd.publish(make("geometry_msgs/msg/Twist", linear=linear, angular=angular))
        wait_for(node, procs, lambda: conversions.stamp_ns(got["odom"][-1].header) - start > 3e9, 120,
                 "3 simulated seconds of odometry after the command")

    return node, procs, got, command


def test_the_turtlebot4s_lidar_sees_all_around_from_its_turned_mount(graph):
    node, procs, got, _ = world_with(graph, "turtlebot4", x0=4.0)  # the west wall's face 3 m behind
    there = min(conversions.stamp_ns(m.header) for m in got["odom"] if abs(m.pose.pose.position.x - 4.0) < 1e-9)
    placed = lambda: [m for m in got["scan"] if conversions.stamp_ns(m.header) >= there]  # noqa: E731
    wait_for(node, procs, lambda: placed() and got["tf_static"], 60, "a scan at the start and the static frames")
    scan = placed()[-1]
    ranges = np.asarray(scan.ranges, dtype=float)
    assert scan.header.frame_id == "rplidar_link" and len(ranges) == 360 and scan.range_max == pytest.approx(12.0)
    assert scan.angle_min == pytest.approx(-math.pi) and scan.angle_increment == pytest.approx(2 * math.pi / 360)
    # its beam at +90 deg looks behind (the mount turns it 90 deg): the wall 3 m behind, less the 4 cm mount
    assert ranges[270] == pytest.approx(3.0 - 0.04, abs=0.05)
    assert np.isinf(ranges[90])  # ahead: 25 m of room, beyond its 12 m
    static = {(t.header.frame_id, t.child_frame_id): t.transform for m in got["tf_static"] for t in m.transforms}
    assert set(static) == {("base_link", "shell_link"), ("shell_link", "rplidar_link")}
    lidar = static[("shell_link", "rplidar_link")]
    assert lidar.translation.x == pytest.approx(-0.04) and lidar.rotation.z == pytest.approx(math.sin(math.pi / 4))


def test_an_omnidirectional_base_moves_sideways_on_linear_y(graph):
    _, _, got, command = world_with(graph, "omni_base")
    command(y=0.4)
    odom = got["odom"][-1]
    pose = odom.pose.pose
    assert pose.position.y > 15.5 and pose.position.x == pytest.approx(15.0, abs=1e-6)
    # the sideways speed is in the odometry's twist, as a base's odometry gives it to Nav2
    assert odom.twist.twist.linear.y == pytest.approx(0.4) and odom.twist.twist.linear.x == 0.0


def test_each_laser_scans_at_its_own_rate_on_its_own_topic(graph, tmp_path):
    """A profile with a 10 Hz front laser and a 4 Hz rear one (every 12 steps of 0.02 s: 0.24 s)."""
    sys.path.insert(0, str(REPO / "test" / "sims"))
    from test_hosted_world import TWO_LASERS

    path = tmp_path / "two_lasers.yaml"
    path.write_text(TWO_LASERS)
    node, procs, got, _ = world_with(graph, str(path))
    rear: list = []
    node.create_subscription("sensor_msgs/msg/LaserScan", "/scan_rear", rear.append, Qos(depth=100))
    wait_for(node, procs, lambda: len(rear) >= 5, 120, "five scans of the rear laser")
    front = [m for m in got["scan"] if conversions.stamp_ns(m.header) >= conversions.stamp_ns(rear[0].header)]
    assert {m.header.frame_id for m in rear} == {"rear_laser"} and {m.header.frame_id for m in front} == {"front_laser"}
    assert {len(m.ranges) for m in rear} == {91} and rear[0].range_max == pytest.approx(5.0)
    assert rear[0].scan_time == pytest.approx(0.24) and front[0].scan_time == pytest.approx(0.1)
    for scans, period in ((rear, 0.24), (front, 0.1)):
        # best effort may drop a scan on a loaded machine: every gap a whole number of periods, most one
        gaps = np.diff([conversions.stamp_ns(m.header) for m in scans]) / 1e9 / period
        assert gaps == pytest.approx(np.round(gaps), abs=1e-6) and np.median(gaps) == 1.0, (period, gaps)


def test_a_car_does_not_turn_on_the_spot(graph):
    _, _, got, command = world_with(graph, "ackermann_car")
    command(w=1.0)
    pose = got["odom"][-1].pose.pose
    assert (pose.position.x, pose.position.y, pose.orientation.z) == (15.0, 15.0, 0.0)
    command(x=0.5, w=1.0)
    pose = got["odom"][-1].pose.pose
    assert pose.orientation.z > 0.1 and pose.position.x > 15.5  # turning as it rolls


def test_a_bad_profile_is_one_line_naming_the_field_and_no_world(tmp_path, ros_domain):
    import subprocess

    bad = tmp_path / "bad.yaml"
    bad.write_text("name: bad\nfootprint: {radius: 0.2}\ndrive: {kind: differential}\nlimits:\n"
                   "  max_speed: {x: 0.0, theta: 1.0}\n  max_accel: {x: 1.0, theta: 1.0}\n"
                   "lasers: [{frame: laser, fov_deg: 360, beams: 360, range: 5, rate: 10}]\n")
    run = subprocess.run([sys.executable, "-m", "sim_nodes.robot_world", "--ros-args", "-p", f"robot_profile:={bad}"],
                         cwd=REPO, capture_output=True, text=True, timeout=120,
                         env={**os.environ, "ROS_DOMAIN_ID": str(ros_domain)})
    lines = (run.stdout + run.stderr).strip().splitlines()
    assert run.returncode == 2 and len(lines) == 1 and "limits.max_speed.x" in lines[0]
