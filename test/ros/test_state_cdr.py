"""The world's per-step messages written straight to CDR are the bytes the message objects give."""
from __future__ import annotations

import math

import numpy as np
import pytest

from ambiegen_ros.ros import conversions, state_cdr
from ambiegen_ros.ros.types import TypeRegistry


@pytest.fixture(scope="module")
def reg():
    return TypeRegistry()


def cases(n: int = 300):
    rng = np.random.default_rng(58)
    frames = ["odom", "map", "a", "ab", "abc", "abcd", "abcde", "base_link", "robot_1/odom"]
    for _ in range(n):
        x, y, yaw, v, w = rng.uniform(-50, 50, 5)
        yield (int(rng.integers(0, 10**13)), float(x), float(y), float(yaw), float(v), float(w),
               str(rng.choice(frames)), str(rng.choice(frames)))


def test_odometry_is_the_registrys_bytes(reg):
    for i, (stamp, x, y, yaw, v, w, frame, child) in enumerate(cases()):
        vy = 0.0 if i % 2 else v / 3  # an omnidirectional base's sideways speed, every other case
        msg = conversions.odometry(reg.new, stamp, x, y, yaw, v, w, frame, child, vy)
        fast = state_cdr.odometry(stamp, x, y, yaw, v, w, frame, child, vy)
        assert fast == reg.serialize(msg, "nav_msgs/msg/Odometry")


def test_tf_and_clock_are_the_registrys_bytes(reg):
    for stamp, x, y, yaw, _, _, parent, child in cases():
        msg = reg.new("tf2_msgs/msg/TFMessage", transforms=[
            conversions.transform(reg.new, stamp, "map", parent),
            conversions.transform(reg.new, stamp, parent, child, x, y, yaw)])
        fast = state_cdr.tf_message(stamp, [("map", parent, 0.0, 0.0, 0.0), (parent, child, x, y, yaw)])
        assert fast == reg.serialize(msg, "tf2_msgs/msg/TFMessage")
        clock = reg.new("rosgraph_msgs/msg/Clock", clock=conversions.stamp(reg.new, stamp))
        assert state_cdr.clock(stamp) == reg.serialize(clock, "rosgraph_msgs/msg/Clock")


def test_odometry_reads_back_as_written(reg):
    """Decoded by the registry (rosbags' decoder): the pose, the heading and the twist."""
    data = state_cdr.odometry(1_500_000_123, 3.0, -4.0, 1.2, 0.4, -0.3, "odom", "base_link")
    msg = reg.deserialize(data, "nav_msgs/msg/Odometry")
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (1, 500_000_123)
    assert (msg.header.frame_id, msg.child_frame_id) == ("odom", "base_link")
    p, q = msg.pose.pose.position, msg.pose.pose.orientation
    assert (p.x, p.y) == (3.0, -4.0) and math.isclose(2 * math.atan2(q.z, q.w), 1.2)
    assert (msg.twist.twist.linear.x, msg.twist.twist.linear.y, msg.twist.twist.angular.z) == (0.4, 0.0, -0.3)
    assert not msg.pose.covariance.any() and not msg.twist.covariance.any()
    sideways = reg.deserialize(state_cdr.odometry(0, 0.0, 0.0, 0.0, 0.1, 0.0, "odom", "base_link", -0.25),
                               "nav_msgs/msg/Odometry")
    assert (sideways.twist.twist.linear.x, sideways.twist.twist.linear.y) == (0.1, -0.25)
