"""Verdicts decided by stamps on rclpy (issue 28): the 20 maps of ``bench/nd_stack.py``'s failing
setting through ``robot_world`` + ``nd_driver`` + ``sut_adapter`` under ``ros2 run`` (rclpy, Cyclone
DDS RMW), with three busy loops beside them. Every verdict, its time and its path equal the
in-process full model's fed the wire's number formats, as on the DDS backend
(``test/ros/test_robot_world.py``). Skips with the reason where no Jazzy build is found.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from jazzy_env import REPO, ros_args, ros_env

for extra in (REPO, REPO / "test", REPO / "test" / "sims"):
    if str(extra) not in sys.path:
        sys.path.insert(0, str(extra))

from ambiegen_ros.problems import get_problem  # noqa: E402
from ambiegen_ros.ros.transport import create_node  # noqa: E402
from ambiegen_ros.sims.full_model import full_model_executor  # noqa: E402
from helpers.nd_maps import FAILING_SAFETY_DIST, busy_loops, certified_maps  # noqa: E402
from helpers.sut_graph import Driver  # noqa: E402
from helpers.wire import wire_emulation  # noqa: E402

LOCKSTEP = dict(lockstep=True, time_scale=0.0, scan_rate=10.0, cmd_vel_stamped=True, paired_start=True,
                **{"sim.dt": 0.1})


def test_the_nd_stack_on_rclpy_gives_the_in_process_verdicts_on_a_loaded_machine(workspace, graph, monkeypatch,
                                                                                  ros_domain):
    p = get_problem("robot", {"profile": "refined"})
    full = full_model_executor(p, safety_dist=FAILING_SAFETY_DIST)
    maps = certified_maps(p, full, 20)
    with wire_emulation():
        wires = [full.execute(sc, seed=0) for sc in maps]
    g, env = graph(), ros_env(ros_domain)
    g.ros("world", f"ros2 run ambiegen_ros robot_world {ros_args(**LOCKSTEP)}", workspace, env)
    g.ros("nd", "ros2 run ambiegen_ros nd_driver " + ros_args(cmd_vel_stamped=True, paired_start=True,
                                                                **{"sim.safety_dist": FAILING_SAFETY_DIST}),
          workspace, env)
    g.ros("adapter", "ros2 run ambiegen_ros sut_adapter " + ros_args(
        problem="robot", worker_id="sut", profile="refined", stall_topic="/nd_driver/stall", plan_topic="/plan",
        settle_time=0.1), workspace, env)
    monkeypatch.setenv("ROS_DOMAIN_ID", str(ros_domain))
    monkeypatch.delenv("AMBIEGEN_TRANSPORT", raising=False)
    node = create_node("rclpy_stamp_order_driver", argv=[], backend="dds")  # the scenarios' sender
    try:
        driver = Driver(node, p)
        driver.wait_matched()
        with busy_loops(3):
            driver.send("nd", maps)
            got = driver.wait("nd", len(maps), 1800)  # a safety net: the wait ends with the last result
    finally:
        node.shutdown()
    assert all(got), g.logs()
    for i, (res, wire) in enumerate(zip(got, wires)):
        assert res.failure_kind == wire.failure_kind, (i, res.detail, wire.detail)
        assert np.array_equal(np.asarray(res.trajectory), wire.trajectory), i
        assert float(res.metrics["time"]) == pytest.approx(wire.metrics["time"], abs=1e-6), i
