"""``Nav2Client`` against rclpy's own servers on rmw_cyclonedds_cpp, from both backends.

``nav2_services_server.py`` (ROS python, rclpy, nav2_msgs of the Jazzy build) serves
navigate_to_pose, two lifecycle ``get_state`` services and a costmap clearing service. The same
driver (``drive`` below) runs the client side twice, each in its own process: on the DDS backend
(the venv's python, PyPI Cyclone DDS: ``transport/dds_services.py`` speaking rmw_cyclonedds_cpp's
request/reply format and client ids) and on rclpy (the ROS python). Both must see the same things:
readiness, GetState, a cleared costmap, a goal succeeded after 2 recoveries, one aborted with
Nav2's error 102 and message, one rejected, one cancelled while feedback streams at 100 Hz.
Skipped, naming the reason, unless ``$AMBIEGEN_ROS_SETUP`` (or /opt/ros/jazzy) has rclpy,
nav2_msgs and rmw_cyclonedds_cpp (jazzy_env.py).
"""
from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

from jazzy_env import REPO, require, ros_command, ros_env, venv_env

HERE = Path(__file__).resolve().parent

SERVER = HERE / "nav2_services_server.py"
SUCCEEDED, CANCELED = 4, 5


def drive(backend: str) -> dict:
    """Run Nav2Client through every case on ``backend``; what it saw, as JSON-able values."""
    import os

    from ambiegen_ros.ros.transport import create_node
    from sim_nodes.nav2_client import Nav2Client

    node = create_node("dds_nav2_client_test", argv=[], backend=backend)
    lines: list[str] = []

    class Log:
        def info(self, m):
            lines.append(str(m))

        warning = info

    out: dict = {"backend": node.backend_name, "domain": os.environ.get("ROS_DOMAIN_ID")}
    try:
        nav2 = Nav2Client(node, "navigate_to_pose", ["controller_server", "planner_server"],
                          ["/global_costmap/clear_entirely_global_costmap"], Log())
        feedback = [0]  # counted on the way to Nav2Client's own callback (either backend)
        send = nav2.action.send_goal_async

        def counting(goal, feedback_callback=None):
            def count(message):
                feedback[0] += 1
                feedback_callback(message)
            return send(goal, feedback_callback=count)

        nav2.action.send_goal_async = counting
        t0 = time.monotonic()
        node.spin_until(lambda: nav2.missing() == ["Nav2 node planner_server is not active"], 30)
        out["ready_s"], out["missing"], out["active"] = time.monotonic() - t0, nav2.missing(), sorted(nav2.active)
        nav2.clear_costmaps()

        def pose(x: float):
            make = node.new_message
            return make("geometry_msgs/msg/PoseStamped", header=make("std_msgs/msg/Header", frame_id="map"),
                        pose=make("geometry_msgs/msg/Pose", position=make("geometry_msgs/msg/Point", x=float(x))))

        for x in (1, 2, -1):
            nav2.send(pose(x))
            node.spin_until(lambda: nav2.result is not None, 15)
            out[f"goal{x:g}"] = {"result": nav2.result, "recoveries": nav2.recoveries,
                                 "status": None if nav2.handle is None else int(nav2.handle.status)}
        nav2.send(pose(3))
        node.spin_until(lambda: nav2.handle is not None and int(nav2.handle.status) == 2, 15)
        handle = nav2.handle
        node.spin_until(lambda: False, 0.3)
        fed, cpu, wall = feedback[0], time.process_time(), time.monotonic()
        node.spin_until(lambda: False, 2.0)  # Nav2's 100 Hz feedback of the running goal
        out["feedback_per_s"] = (feedback[0] - fed) / (time.monotonic() - wall)
        out["cpu_us_per_feedback"] = 1e6 * (time.process_time() - cpu) / max(1, feedback[0] - fed)
        out["running_result"] = nav2.result
        nav2.cancel()
        node.spin_until(lambda: int(handle.status) == CANCELED, 15)
        node.spin_until(lambda: any("canceled" in m for m in lines), 15)
        out["cancelled_status"], out["log"] = int(handle.status), lines
    finally:
        node.shutdown()
    return out


def test_nav2_client_drives_rclpy_servers_on_rmw_cyclonedds_from_both_backends(jazzy, graph, ros_domain):
    require(jazzy, "nav2_msgs", "rmw_cyclonedds_cpp")
    g = graph()
    g.start("server", ros_command(f"{jazzy['executable']} {SERVER}", venv=False), ros_env(ros_domain))
    g.wait_for("server", "ready", 60)
    runs = {
        "dds": subprocess.run([sys.executable, __file__, "dds"], cwd=REPO, env=venv_env(ros_domain),
                              capture_output=True, text=True, timeout=180),
        "rclpy": subprocess.run(ros_command(f"{jazzy['executable']} {__file__} rclpy"), cwd=REPO,
                                env=ros_env(ros_domain), capture_output=True, text=True, timeout=180),
    }
    seen = {}
    for backend, run in runs.items():
        assert run.returncode == 0, f"{backend}:\n{run.stdout[-3000:]}\n{run.stderr[-3000:]}\n{g.logs()}"
        seen[backend] = json.loads(run.stdout.strip().splitlines()[-1])
    server_log = g.log("server")
    for backend, got in seen.items():
        where = f"{backend}: {got}\n{server_log[-2000:]}"
        assert got["backend"] == backend and got["domain"] == str(ros_domain), where
        assert got["missing"] == ["Nav2 node planner_server is not active"], where
        assert got["active"] == ["controller_server"], where
        assert got["goal1"] == {"result": {"status": "succeeded", "error_code": 0, "error_msg": ""},
                                "recoveries": 2, "status": SUCCEEDED}, where
        assert got["goal2"]["result"] == {"status": "aborted", "error_code": 102,
                                          "error_msg": "fake: the controller failed to make progress"}, where
        assert got["goal2"]["recoveries"] == 1, where
        assert got["goal-1"] == {"result": {"status": "rejected", "error_code": 0, "error_msg": "goal rejected"},
                                 "recoveries": 0, "status": None}, where
        assert got["running_result"] is None and got["feedback_per_s"] > 40, where
        assert got["cancelled_status"] == CANCELED, where
        assert any("canceled" in m and "after its scenario was decided" in m for m in got["log"]), where
        print(f"{backend}: ready in {got['ready_s']:.2f} s; {got['feedback_per_s']:.0f} feedback/s, "
              f"{got['cpu_us_per_feedback']:.0f} us of the client's CPU per feedback message")
    assert server_log.count("cleared") == 2 and server_log.count("canceled") == 2, server_log
    assert server_log.count("goal 1 map") == 2 and server_log.count("goal -1 map") == 2, server_log


if __name__ == "__main__":  # one client run: python test_dds_nav2_client.py dds|rclpy
    sys.path.insert(0, str(REPO))  # the script's own folder is on the path, not the repository
    print(json.dumps(drive(sys.argv[1])))
