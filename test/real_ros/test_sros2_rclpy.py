"""SROS2 on the rclpy backend: a keystore and enclaves made by ``ros2 security``, then a worker and
a generator complete a run under ROS_SECURITY_ENABLE=true / Enforce; a node whose enclave does not
exist must not start. (The DDS backend's refusal is tested in test/ros/test_sros2.py.)

The test's own domain (``ros_domain``): the keystore's governance names the domain it was created on.
"""
from __future__ import annotations

import shlex

from jazzy_env import require, ros_args, ros_env, ros_run

ENFORCE = {"ROS_SECURITY_ENABLE": "true", "ROS_SECURITY_STRATEGY": "Enforce"}


def test_rclpy_run_under_enforced_sros2(jazzy, workspace, graph, tmp_path, ros_domain):
    require(jazzy, "sros2")
    keystore = shlex.quote(str(tmp_path / "keystore"))
    made = ros_run(f"bash -c 'ros2 security create_keystore {keystore} && "
                   f"ros2 security create_enclave {keystore} /ambiegen/worker && "
                   f"ros2 security create_enclave {keystore} /ambiegen/generator'",
                   env=ros_env(ros_domain), timeout=300)
    assert made.returncode == 0, made.stdout + made.stderr
    secure = ros_env(ros_domain, ROS_SECURITY_KEYSTORE=str(tmp_path / "keystore"), **ENFORCE)

    stranger = ros_run("timeout 60 ros2 run ambiegen_ros thermostat_sim --ros-args --enclave /ambiegen/nowhere "
                       "-p model:=surrogate", workspace, secure, timeout=120)
    assert stranger.returncode != 0, "a node with no enclave ran under Enforce:\n" + stranger.stderr[-2000:]

    g = graph()
    g.ros("worker", "ros2 run ambiegen_ros thermostat_sim --ros-args --enclave /ambiegen/worker "
          + ros_args(worker_id="secure_w", model="surrogate")[len("--ros-args "):], workspace, secure)
    gen = ros_run("ros2 run ambiegen_ros generator --ros-args --enclave /ambiegen/generator " + ros_args(
        problem="thermostat", algorithm="random", evaluations=20, population=10, mode="in_the_loop",
        min_workers=1, subscriber_wait=120.0, seed=1)[len("--ros-args "):], workspace, secure, timeout=360)
    assert gen.returncode == 0, gen.stderr[-3000:] + "\nworker:\n" + g.log("worker")[-2000:]
    assert " done: " in gen.stderr and " 0 timeouts" in gen.stderr, gen.stderr[-2000:]
    assert "secure_w" in gen.stderr, "the secured worker never answered"

