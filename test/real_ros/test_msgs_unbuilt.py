"""Issue 28 on a real Jazzy: after a plain `colcon build`, every node names in one line what to run.

The repository root is the ``ambiegen_ros`` package and ``ambiegen_msgs`` sits inside its folder,
where colcon's discovery never looks, so a plain ``colcon build`` in the workspace builds
``ambiegen_ros`` alone. Each node then stops (exit status 2, one line, no traceback) with the
command that builds both; that command, run as printed, makes ``ambiegen_msgs`` importable.
Skipped without a Jazzy install (conftest.py); the same check without ROS: test/test_msgs_missing.py.
"""
from __future__ import annotations

import shlex

from jazzy_env import copy_working_tree, probe, ros_env, ros_run

NODES = ("generator", "recorder", "sut_adapter", "robot_sim")


def test_a_plain_colcon_build_leaves_ambiegen_msgs_out_and_the_nodes_say_what_to_run(jazzy, tmp_path):
    ws = tmp_path / "ws"
    copy_working_tree(ws / "src" / "ambiegen")
    plain = ros_run("colcon build --event-handlers console_direct-", env=ros_env(), timeout=600, venv=False, cwd=ws)
    assert plain.returncode == 0, plain.stdout[-3000:] + plain.stderr[-3000:]
    assert (ws / "install" / "ambiegen_ros").is_dir() and not (ws / "install" / "ambiegen_msgs").exists()

    command = (f"cd {shlex.quote(str(ws))} && colcon build --base-paths src src/ambiegen/ambiegen_msgs "
               "&& source install/setup.bash")
    for node in NODES:
        run = ros_run(f"ros2 run ambiegen_ros {node}", ws / "install", env=ros_env(), timeout=120, cwd=tmp_path)
        lines = run.stderr.strip().splitlines()
        assert run.returncode == 2 and "Traceback" not in run.stderr, f"{node}:\n{run.stdout}\n{run.stderr}"
        assert len(lines) == 1 and lines[0].startswith(f"{node}: error: ambiegen_msgs is not built"), run.stderr
        assert lines[0].endswith(f"run: {command}"), lines[0]

    # the printed command, with the suite's cmake arguments (no tests, the ROS python)
    cmake = f" --cmake-args -DBUILD_TESTING=OFF -DPython3_EXECUTABLE={shlex.quote(probe()['executable'])}"
    both = command.replace(" && source install/setup.bash", cmake + " && source install/setup.bash")
    built = ros_run(f"bash -c {shlex.quote(both)}", env=ros_env(), timeout=600, venv=False, cwd=ws)
    assert built.returncode == 0, built.stdout[-3000:] + built.stderr[-3000:]
    check = ("from ambiegen_ros.ros.transport.rclpy_backend import missing_messages; "
             "assert missing_messages() == '', missing_messages(); print('ok')")
    shown = ros_run(f"{jazzy['executable']} -c {shlex.quote(check)}", ws / "install", env=ros_env(), cwd=tmp_path)
    assert shown.returncode == 0 and shown.stdout.strip() == "ok", shown.stderr
