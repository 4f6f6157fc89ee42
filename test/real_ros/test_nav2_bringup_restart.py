"""A Nav2 bringup that gave up is started again by ``Nav2Client``, on Jazzy's own nodes.

The race a loaded machine showed in a search hour: the controller's costmap activated before our
world published TF, the lifecycle manager gave up the bringup, and every scenario of the hour
became an error record. Here Jazzy's ``planner_server`` (its global costmap waits 1 s for TF) and
``lifecycle_manager`` (autostart) start with no TF at all, so the bringup gives up for real; then a
``static_transform_publisher`` supplies map -> base_link, and the adapter's client, on the DDS
backend (PyPI Cyclone DDS speaking rmw_cyclonedds_cpp's services), must find the manager not
active, ask it to clean up and start again, and see the planner active. Skipped, naming the
reason, unless ``$AMBIEGEN_ROS_SETUP`` (or /opt/ros/jazzy) has nav2_planner, nav2_lifecycle_manager
and rmw_cyclonedds_cpp (jazzy_env.py).
"""
from __future__ import annotations

from jazzy_env import require, ros_args, ros_command, ros_env


def test_a_real_bringup_that_gave_up_for_want_of_tf_is_started_again_once_tf_is_there(jazzy, graph, ros_domain,
                                                                                      monkeypatch, tmp_path):
    require(jazzy, "nav2_planner", "nav2_lifecycle_manager", "rmw_cyclonedds_cpp")  # tf2_ros: in every Jazzy
    params = tmp_path / "planner.yaml"
    params.write_text("planner_server:\n  ros__parameters:\n    use_sim_time: false\n"
                      "    planner_plugins: [GridBased]\n    GridBased:\n      plugin: nav2_navfn_planner::NavfnPlanner\n"
                      "global_costmap:\n  global_costmap:\n    ros__parameters:\n      use_sim_time: false\n"
                      "      initial_transform_timeout: 1.0\n      global_frame: map\n"
                      "      robot_base_frame: base_link\n")
    env = ros_env(ros_domain)
    g = graph()
    g.start("planner", ros_command(f"ros2 run nav2_planner planner_server --ros-args --params-file {params}",
                                   venv=False), env)
    g.start("manager", ros_command("ros2 run nav2_lifecycle_manager lifecycle_manager "
                                   + ros_args("lifecycle_manager_navigation", autostart=True, use_sim_time=False)
                                   + " -p 'node_names:=[planner_server]'", venv=False), env)
    g.wait_for("manager", "Aborting bringup", 90)  # no TF: the costmap gave up, and the manager with it
    assert "did not become available before timeout" in g.log("planner")
    g.start("tf", ros_command("ros2 run tf2_ros static_transform_publisher --frame-id map --child-frame-id base_link",
                              venv=False), env)

    from ambiegen_ros.ros.transport import create_node
    from sim_nodes.nav2_client import Nav2Client

    monkeypatch.setenv("ROS_DOMAIN_ID", str(ros_domain))
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", env["ROS_AUTOMATIC_DISCOVERY_RANGE"])
    node = create_node("bringup_restart_test", argv=[], backend="dds")
    lines: list[str] = []

    class Log:
        def info(self, m):
            lines.append(str(m))

        warning = info

    try:
        nav2 = Nav2Client(node, "navigate_to_pose", ["planner_server"], [], Log(),
                          manager="lifecycle_manager_navigation", restarts=2, restart_after=1.0)
        assert node.spin_until(lambda: [m for m in nav2.missing() if "action server" not in m] == [], 120), \
            f"{nav2.missing()}\n{lines}\n{g.logs()}"
        assert "planner_server" in nav2.active and nav2.restarts == 1, lines
        assert any("bringup gave up" in m for m in lines), lines
        # the manager answers STARTUP after its bonds are made, which may be after the node's own state
        assert node.spin_until(lambda: any("new bringup succeeded" in m for m in lines), 60), lines
    finally:
        node.shutdown()
    manager_log = g.log("manager")
    assert "Cleaning up planner_server" in manager_log and "Managed nodes are active" in manager_log, manager_log
