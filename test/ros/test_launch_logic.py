"""The campaign launch file's logic (ambiegen_ros/launch_logic.py), tested without ROS (issue 9).

launch/campaign.launch.py wraps this plan in launch actions: the node set and its parameters, the
log name (run id + UTC time, never the same twice), when the launch ends (the generator's exit;
``keep_workers``) and the summary it prints. The plan's node set is run here as real node
processes over DDS (the test's own ROS_DOMAIN_ID, ``ros_domain``) and ended by the plan's own rules, as the launch file does.
"""
from __future__ import annotations

import ast
import json
import re
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
if str(HERE) not in sys.path:
    sys.path.insert(0, str(HERE))

import pytest  # noqa: E402
from mcap.reader import make_reader  # noqa: E402

from ambiegen_ros import launch_logic  # noqa: E402
from ambiegen_ros.launch_logic import (  # noqa: E402
    LAUNCH_ARGUMENTS,
    SIM_EXECUTABLES,
    plan_campaign,
    plan_summary,
    summary_table,
)
from ambiegen_ros.ros.runlog import read_metadata, summarize  # noqa: E402
from test_nodes import REPO, nodes_factory  # noqa: E402,F401  (the fixture is used by name)

LAUNCH_FILE = REPO / "launch" / "campaign.launch.py"
# setup.py's console scripts: the executable a launch_ros Node names -> the module it runs
MODULES = {"recorder": "ambiegen_ros.nodes.recorder", "generator": "ambiegen_ros.nodes.generator",
           "robot_sim": "sim_nodes.robot_sim", "car_sim": "sim_nodes.car_sim", "thermostat_sim": "sim_nodes.thermostat_sim"}


def plan(tmp_path: Path, **args: str):
    values = {"problem": "thermostat", "algorithm": "ga", "seed": "5", "workers": "2", "output_dir": str(tmp_path)}
    values.update(args)
    return plan_campaign(values, share_dir="/opt/share/ambiegen_ros")


# --- the plan -------------------------------------------------------------------------------------
def test_plan_node_set_and_parameters(tmp_path):
    p = plan(tmp_path)
    assert [(n.name, n.executable) for n in p.nodes] == [
        ("recorder", "recorder"), ("thermostat_sim_0", "thermostat_sim"), ("thermostat_sim_1", "thermostat_sim"),
        ("generator", "generator")]
    generator = p.node("generator").parameters
    assert generator["run_id"] == p.run_id and generator["seed"] == 5 and generator["min_subscribers"] == 3
    assert generator["config_file"] == "/opt/share/ambiegen_ros/config/thermostat.yaml"
    worker_ids = [p.node(f"thermostat_sim_{k}").parameters["worker_id"] for k in range(2)]
    assert len(set(worker_ids)) == 2 and all(w.endswith(p.run_id[-6:]) for w in worker_ids)  # unique per run
    assert p.node("recorder").parameters["overwrite"] is False


def test_profile_argument_reaches_the_sims_and_the_generator(tmp_path):
    p = plan(tmp_path, profile="refined")
    handed = {n.name: n.parameters.get("profile") for n in p.nodes}
    assert handed == {"recorder": None, "thermostat_sim_0": "refined", "thermostat_sim_1": "refined", "generator": "refined"}
    assert "profile" in LAUNCH_ARGUMENTS


def test_log_name_carries_run_id_and_utc_time_and_never_repeats(tmp_path):
    first, second = plan(tmp_path), plan(tmp_path)  # the same arguments twice
    for p in (first, second):
        assert re.fullmatch(r"thermostat-ga-s5-[0-9a-f]{6}", p.run_id)
        output = Path(p.node("recorder").parameters["output"])
        assert output == p.mcap and output.parent == tmp_path
        assert re.fullmatch(re.escape(p.run_id) + r"_\d{8}T\d{6}Z\.mcap", output.name)
    assert first.run_id != second.run_id and first.mcap != second.mcap


def test_drawn_seed_is_drawn_once_and_named(tmp_path):
    p = plan(tmp_path, seed="-1")
    assert p.seed >= 0 and p.node("generator").parameters["seed"] == p.seed and f"-s{p.seed}-" in p.run_id


def test_explicit_output_and_overwrite_reach_the_recorder(tmp_path):
    p = plan(tmp_path, output=str(tmp_path / "mine.mcap"), overwrite="true", workers="0")
    assert p.node("recorder").parameters == {"output": str(tmp_path / "mine.mcap"), "overwrite": True}
    assert [n.name for n in p.nodes] == ["recorder", "generator"] and p.node("generator").parameters["min_subscribers"] == 1


@pytest.mark.parametrize("name, value", [("problem", "plane"), ("workers", "two"), ("workers", "-1"),
                                         ("overwrite", "yes"), ("keep_workers", "maybe"), ("evaluations", "-5"),
                                         ("time_budget", "soon"), ("seed", "1.5")])
def test_bad_arguments_name_themselves(tmp_path, name, value):
    with pytest.raises(ValueError, match=f"^{name}: "):
        plan(tmp_path, **{name: value})


def test_the_launch_ends_with_the_generator_unless_workers_are_kept(tmp_path):
    ends = plan(tmp_path)
    assert ends.after_generator_exit() == "shutdown"
    assert ends.after_recorder_exit(generator_done=True) and ends.after_recorder_exit(generator_done=False)
    kept = plan(tmp_path, keep_workers="true")
    assert kept.after_generator_exit() == "stop_recorder"
    assert not kept.after_recorder_exit(generator_done=True)
    assert kept.after_recorder_exit(generator_done=False)  # a recorder lost mid-run ends the launch anyway


def test_a_refused_recorder_is_reported_not_summarised_from_someone_elses_file(tmp_path):
    p = plan(tmp_path, output=str(tmp_path / "old.mcap"))
    (tmp_path / "old.mcap").write_bytes(b"an earlier log")
    summary = plan_summary(p, 3.0, {"recorder": 2})
    assert "scenarios_published" not in summary and "did not start" in summary["log_error"]
    table = summary_table(summary)
    assert "log error" in table and str(tmp_path / "old.mcap") in table and "recorder 2" in table


def test_summary_says_how_evaluations_became_published_scenarios():
    """2000 evaluations next to 3 published scenarios is not lost work: surrogate mode publishes
    only the final suite, and the table says so (issue 18)."""
    counts = {"scenarios_published": 3, "results_received": 3, "unresolved": [], "failures": 1, "timeouts": 0,
              "errors": 0, "outcomes": {"none": 2, "collision": 1}, "evaluations": 2000, "best_f1": 4.25,
              "final_state": "done"}
    table = summary_table({"run_id": "r", "problem": "robot", "algorithm": "nsga2", "mode": "surrogate", **counts})
    assert "search     2000 evaluations -> suite of 3 scenarios published, best F1 4.25, state done" in table
    loop = summary_table({"run_id": "r", "mode": "in_the_loop", **counts, "scenarios_published": 1})
    assert "2000 evaluations -> 1 scenario published (in the loop: the sims give every F1)" in loop
    # the scenarios the problem calls invalid were never sent (issue 47): counted apart, with their rules
    unsent = summary_table({"run_id": "r", "mode": "in_the_loop", **counts, "scenarios_published": 1,
                            "not_sent": 5, "not_sent_rules": {"leaves the map": 4, "too sharp": 1}})
    assert re.search(r"^  not sent +5  \(the problem calls them invalid, never executed; logged with the rule they "
                     r"break: leaves the map 4, too sharp 1\)$", unsent, re.M), unsent
    assert "1 scenario published (in the loop: the sims give every F1), 5 not sent (invalid)" in unsent
    assert "not sent" not in loop


# --- the launch file uses the plan ------------------------------------------------------------------
def test_launch_file_takes_its_logic_from_the_plan():
    tree = ast.parse(LAUNCH_FILE.read_text())
    imported = [a.name for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)
                and node.module == "ambiegen_ros.launch_logic" for a in node.names]
    assert {"LAUNCH_ARGUMENTS", "plan_campaign", "plan_summary", "summary_table"} <= set(imported)
    assert all(hasattr(launch_logic, name) for name in imported)
    for needed in ("keep_workers", "overwrite", "output"):
        assert needed in LAUNCH_ARGUMENTS


def test_launch_file_declares_every_argument_with_ros_launch():
    # (the repo's launch/ folder is a namespace package named `launch`: ask for the real modules)
    pytest.importorskip("launch_ros.actions", reason="ROS 2 launch_ros is not installed here (source /opt/ros/jazzy)")
    sources = pytest.importorskip("launch.launch_description_sources", reason="ROS 2 launch is not installed here")
    get_launch_description_from_python_launch_file = sources.get_launch_description_from_python_launch_file

    description = get_launch_description_from_python_launch_file(str(LAUNCH_FILE))
    assert {a.name for a in description.get_launch_arguments()} == set(LAUNCH_ARGUMENTS)


# --- Nav2 as the system under test: nav2_campaign.launch.py's plan --------------------------------------
def test_a_tree_with_a_timeout_at_its_root_gives_the_adapter_the_stacks_time_per_goal(tmp_path):
    """The user's tree gives each goal 90 wall seconds (BT.CPP's Timeout, as fix:doorway_patient wraps
    Jazzy's): at time_scale 4 that is 360 simulated seconds, the adapter's goal_time_budget."""
    tree = tmp_path / "patient.xml"
    tree.write_text('<root BTCPP_format="4" main_tree_to_execute="Main"><BehaviorTree ID="Other"><Wait/></BehaviorTree>'
                    '<BehaviorTree ID="Main"><Timeout msec="90000"><FollowPath/></Timeout></BehaviorTree></root>')
    params = tmp_path / "mine.yaml"
    params.write_text(f"bt_navigator:\n  ros__parameters:\n    default_nav_to_pose_bt_xml: {tree}\n")
    plan = launch_logic.plan_nav2_campaign({"output_dir": str(tmp_path / "a"), "time_scale": "4",
                                            "params_file": str(params)}, share_dir=str(REPO))
    assert plan.node("sut_adapter").parameters["goal_time_budget"] == pytest.approx(360.0)
    tree.write_text('<root main_tree_to_execute="Main"><BehaviorTree ID="Main"><Sequence><Timeout msec="90000">'
                    '<FollowPath/></Timeout><Wait/></Sequence></BehaviorTree></root>')  # a Timeout inside: not the goal's
    plan = launch_logic.plan_nav2_campaign({"output_dir": str(tmp_path / "b"), "time_scale": "4",
                                            "params_file": str(params)}, share_dir=str(REPO))
    assert plan.node("sut_adapter").parameters["goal_time_budget"] == 0.0


def test_nav2_plan_starts_world_nav2_adapter_and_scales_nav2s_rates(tmp_path):
    import yaml

    p = launch_logic.plan_nav2_campaign({"seed": "3", "output_dir": str(tmp_path), "time_scale": "4"},
                                        share_dir=str(REPO))  # the repo's config/ stands in for the share dir
    assert [(n.name, n.package) for n in p.nodes] == [
        ("recorder", "ambiegen_ros"), ("robot_world", "ambiegen_ros"), ("controller_server", "nav2_controller"),
        ("planner_server", "nav2_planner"), ("behavior_server", "nav2_behaviors"), ("bt_navigator", "nav2_bt_navigator"),
        ("lifecycle_manager_navigation", "nav2_lifecycle_manager"), ("sut_adapter", "ambiegen_ros"),
        ("generator", "ambiegen_ros")]
    adapter, generator, world = p.node("sut_adapter").parameters, p.node("generator").parameters, p.node("robot_world")
    assert adapter["goal_mode"] == "action" and adapter["time_scale"] == 4.0 and adapter["collision_topic"] == "/collision"
    assert world.parameters["time_scale"] == 4.0 and world.parameters["seed"] == 3 == p.seed
    assert generator["min_workers"] == 1 and generator["max_in_flight"] == 1
    # the adapter's guard for a 500 m route at the controller's 0.3 m/s (2 x route / speed + 60 s), + 60 s
    assert generator["result_timeout"] == pytest.approx(2 * (2 * 500 / 0.3 + 60) / 4 + 120 + 60)
    assert adapter["early_verdicts"] is False and adapter["time_limit_speed"] == 0.3  # DWB's max_vel_x
    assert adapter["ours_error_codes"] == "102,107,202" and adapter["goal_time_budget"] == 0.0  # Jazzy's tree: no Timeout
    assert "/scan" in p.node("recorder").parameters["extra_topics"].split(",")
    (scaled,) = {f for n in p.nodes for f in n.params_files}
    assert Path(scaled).parent == tmp_path and p.run_id in Path(scaled).name
    ours = yaml.safe_load((REPO / "config" / "nav2" / "pioneer_navfn_dwb.yaml").read_text())
    got = yaml.safe_load(Path(scaled).read_text())
    cs, ours_cs = got["controller_server"]["ros__parameters"], ours["controller_server"]["ros__parameters"]
    assert cs["controller_frequency"] == 4 * ours_cs["controller_frequency"]
    assert cs["progress_checker"]["movement_time_allowance"] == ours_cs["progress_checker"]["movement_time_allowance"]
    local = got["local_costmap"]["local_costmap"]["ros__parameters"]
    assert local["update_frequency"] == 4 * ours["local_costmap"]["local_costmap"]["ros__parameters"]["update_frequency"]
    assert got["bt_navigator"]["ros__parameters"]["bt_loop_duration"] == round(
        ours["bt_navigator"]["ros__parameters"]["bt_loop_duration"] / 4)
    assert got["lifecycle_manager_navigation"] == ours["lifecycle_manager_navigation"]  # nothing else changes


def test_nav2_plan_takes_the_users_params_file_and_names_a_bad_one(tmp_path):
    theirs = tmp_path / "theirs.yaml"
    theirs.write_text("controller_server:\n  ros__parameters:\n    controller_frequency: 10.0\n")
    p = launch_logic.plan_nav2_campaign({"output_dir": str(tmp_path), "params_file": str(theirs), "seed": "1"},
                                        share_dir=str(REPO))
    (scaled,) = {f for n in p.nodes for f in n.params_files}
    assert "controller_frequency: 10.0" in Path(scaled).read_text()
    with pytest.raises(ValueError, match="params_file"):
        launch_logic.plan_nav2_campaign({"output_dir": str(tmp_path), "params_file": str(tmp_path / "none.yaml")},
                                        share_dir=str(REPO))
    with pytest.raises(ValueError, match="time_scale"):
        launch_logic.plan_nav2_campaign({"output_dir": str(tmp_path), "time_scale": "0"}, share_dir=str(REPO))


def test_nav2_external_starts_only_our_side_and_bringup_includes_navigation_launch(tmp_path):
    import yaml

    theirs = tmp_path / "theirs.yaml"
    theirs.write_text("controller_server:\n  ros__parameters:\n    controller_frequency: 20.0\n"
                      "    controller_plugins: [FollowPath]\n    FollowPath:\n"
                      "      plugin: nav2_mppi_controller::MPPIController\n      vx_max: 0.5\n      ax_max: 3.0\n"
                      "      ax_min: -3.0\n      az_max: 3.5\n")
    common = {"output_dir": str(tmp_path), "params_file": str(theirs), "seed": "2", "time_scale": "2"}
    external = launch_logic.plan_nav2_campaign({**common, "nav2": "external"}, share_dir=str(REPO))
    assert [n.name for n in external.nodes] == ["recorder", "robot_world", "sut_adapter", "generator"]
    assert not external.includes
    adapter = external.node("sut_adapter").parameters
    assert adapter["start_timeout"] == launch_logic.EXTERNAL_START_TIMEOUT and adapter["time_limit_speed"] == 0.5
    assert adapter["early_verdicts"] is False
    assert adapter["nav2_lifecycle_manager"] == ""  # a user's own bringup is theirs to restart
    merged = yaml.safe_load(external.nav2_params.read_text())
    follow = merged["controller_server"]["ros__parameters"]["FollowPath"]
    assert follow["ax_max"] == 0.5 and merged["controller_server"]["ros__parameters"]["controller_frequency"] == 40.0
    assert any(f"params_file:={external.nav2_params}" in note for note in external.notes)
    bringup = launch_logic.plan_nav2_campaign({**common, "nav2": "bringup", "early_verdicts": "true"},
                                              share_dir=str(REPO))
    assert [n.name for n in bringup.nodes] == ["recorder", "robot_world", "sut_adapter", "generator"]
    assert bringup.node("sut_adapter").parameters["nav2_lifecycle_manager"] == "lifecycle_manager_navigation"
    (include,) = bringup.includes
    assert (include.package, include.launch_file) == ("nav2_bringup", "launch/navigation_launch.py")
    assert include.arguments["params_file"] == str(bringup.nav2_params) and include.arguments["use_sim_time"] == "true"
    assert bringup.node("sut_adapter").parameters["early_verdicts"] is True
    plain = launch_logic.plan_nav2_campaign({**common, "params_overlay": "none"}, share_dir=str(REPO))
    assert "ax_max: 3.0" in plain.nav2_params.read_text()  # no overlay: theirs as it is
    with pytest.raises(ValueError, match="nav2: unknown"):
        launch_logic.plan_nav2_campaign({**common, "nav2": "mine"}, share_dir=str(REPO))
    with pytest.raises(ValueError, match="early_verdicts"):
        launch_logic.plan_nav2_campaign({**common, "early_verdicts": "maybe"}, share_dir=str(REPO))


def test_nav2_stacks_each_get_a_namespace_a_clock_and_params_of_their_own(tmp_path):
    import yaml

    p = launch_logic.plan_nav2_campaign({"output_dir": str(tmp_path), "seed": "4", "stacks": "2", "time_scale": "2"},
                                        share_dir=str(REPO))
    assert p.workers == 2
    generator = p.node("generator").parameters
    assert (generator["min_workers"], generator["min_subscribers"], generator["max_in_flight"]) == (2, 3, 1)
    for i in (0, 1):
        ns = f"stack{i}"
        world = p.node(f"{ns}/robot_world")
        assert world.namespace == ns and world.parameters["clock_topic"] == f"/{ns}/clock"
        assert world.parameters["scan_topic"] == f"/{ns}/scan" and world.parameters["odom_topic"] == f"/{ns}/odom"
        controller = p.node(f"{ns}/controller_server")
        assert ("/clock", f"/{ns}/clock") in controller.remappings and ("/tf", "tf") in controller.remappings
        (params_file,) = controller.params_files
        params = yaml.safe_load(Path(params_file).read_text())[ns]
        global_costmap = params["global_costmap"]["global_costmap"]["ros__parameters"]
        assert global_costmap["obstacle_layer"]["scan"]["topic"] == f"/{ns}/scan"
        assert global_costmap["static_layer"]["map_topic"] == f"/{ns}/map"
        assert params["bt_navigator"]["ros__parameters"]["odom_topic"] == f"/{ns}/odom"
        adapter = p.node(f"sut_adapter_{ns}").parameters
        assert adapter["action_name"] == f"/{ns}/navigate_to_pose" and adapter["map_topic"] == f"/{ns}/map"
        assert adapter["nav2_lifecycle_nodes"].split(",")[0] == f"{ns}/planner_server"
        assert adapter["nav2_lifecycle_manager"] == f"{ns}/lifecycle_manager_navigation"
        assert adapter["nav2_clear_costmaps"].startswith(f"/{ns}/global_costmap/")
        assert (adapter["timing_scan_topic"], adapter["timing_clock_topic"]) == (f"/{ns}/scan", f"/{ns}/clock")
    workers = [n.parameters["worker_id"] for n in p.nodes if n.executable == "sut_adapter"]
    assert len(set(workers)) == 2
    assert "/stack1/scan" in p.node("recorder").parameters["extra_topics"].split(",")
    with pytest.raises(ValueError, match="stacks"):
        launch_logic.plan_nav2_campaign({"output_dir": str(tmp_path), "stacks": "2", "nav2": "bringup"},
                                        share_dir=str(REPO))


def test_a_campaign_across_hosts_splits_into_a_generator_part_and_one_part_per_stack(tmp_path):
    common = {"output_dir": str(tmp_path), "seed": "4", "stacks": "2"}
    head = launch_logic.plan_nav2_campaign({**common, "part": "generator"}, share_dir=str(REPO))
    assert sorted(n.name for n in head.nodes) == ["generator", "recorder"]
    generator = head.node("generator").parameters
    assert (generator["min_workers"], generator["min_subscribers"]) == (2, 3)  # the stacks elsewhere
    assert "/stack1/scan" in head.node("recorder").parameters["extra_topics"].split(",")
    stack = launch_logic.plan_nav2_campaign({**common, "part": "stack1"}, share_dir=str(REPO))
    assert not any(n.name in ("generator", "recorder") for n in stack.nodes)
    assert {n.namespace for n in stack.nodes if n.executable != "sut_adapter"} == {"stack1"}
    assert stack.node("stack1/robot_world").parameters["clock_topic"] == "/stack1/clock"
    assert stack.node("sut_adapter_stack1").parameters["action_name"] == "/stack1/navigate_to_pose"
    assert stack.workers == 1 and any("Ctrl-C" in note for note in stack.notes)
    lifecycle = stack.node("stack1/lifecycle_manager_navigation").parameters
    assert lifecycle["node_names"] == list(launch_logic.NAV2_MANAGED)  # whatever the user's params file says
    for bad in ("stack", "stack01", "host2", "stack-1"):
        with pytest.raises(ValueError, match="part"):
            launch_logic.plan_nav2_campaign({**common, "part": bad}, share_dir=str(REPO))
    with pytest.raises(ValueError, match="nav2:=ours"):
        launch_logic.plan_nav2_campaign({**common, "stacks": "1", "part": "stack0", "nav2": "bringup"},
                                        share_dir=str(REPO))


def test_nav2_launch_file_takes_its_logic_from_the_plan():
    tree = ast.parse((REPO / "launch" / "nav2_campaign.launch.py").read_text())
    imported = [a.name for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)
                and node.module == "ambiegen_ros.launch_logic" for a in node.names]
    assert {"NAV2_LAUNCH_ARGUMENTS", "plan_nav2_campaign"} <= set(imported)
    for needed in ("params_file", "time_scale", "overwrite", "output", "nav2", "params_overlay", "early_verdicts"):
        assert needed in launch_logic.NAV2_LAUNCH_ARGUMENTS


def test_every_planned_generator_waits_for_the_recorder_of_its_plan(tmp_path):
    """No scenario before the recorder reads every topic it records (``min_recorders``, as ``ambiegen
    campaign``): the generator of each plan with a recorder waits for it; a stack's part has neither."""
    assert plan(tmp_path).node("generator").parameters["min_recorders"] == 1
    for args in ({}, {"stacks": "2"}, {"stacks": "2", "part": "generator"}):
        p = launch_logic.plan_nav2_campaign({"output_dir": str(tmp_path), **args}, share_dir=str(REPO))
        assert [n.executable for n in p.nodes].count("recorder") == 1, args
        assert p.node("generator").parameters["min_recorders"] == 1, args
    stack = launch_logic.plan_nav2_campaign({"output_dir": str(tmp_path), "stacks": "2", "part": "stack0"},
                                            share_dir=str(REPO))
    assert not any(n.executable in ("generator", "recorder") for n in stack.nodes)


@pytest.mark.parametrize("args", [{}, {"stacks": "2"}, {"stacks": "2", "part": "stack1"}])
def test_contact_fault_speed_goes_to_each_world_and_its_adapter_never_to_the_recorder(tmp_path, args):
    p = launch_logic.plan_nav2_campaign({"output_dir": str(tmp_path), "contact_fault_speed": "0.05", **args},
                                        share_dir=str(REPO))
    worlds = [n for n in p.nodes if n.executable == "robot_world"]
    adapters = [n for n in p.nodes if n.executable == "sut_adapter"]
    assert len(worlds) == len(adapters) == (1 if args.get("part") else int(args.get("stacks", "1")))
    assert all(w.parameters["sim.contact_fault_speed"] == 0.05 for w in worlds)
    assert all(a.parameters["oracle.contact_fault_speed"] == 0.05 for a in adapters)
    charged = {n.name for n in p.nodes if any("contact_fault_speed" in k for k in n.parameters)}
    assert charged == {n.name for n in worlds + adapters}  # the recorder, Nav2 and the generator get nothing


MPPI_ACKERMANN = ("controller_server:\n  ros__parameters:\n    controller_plugins: [FollowPath]\n    FollowPath:\n"
                  "      plugin: nav2_mppi_controller::MPPIController\n      motion_model: Ackermann\n")


def test_the_adapter_judges_the_robot_the_world_drives(tmp_path, monkeypatch):
    """robot_profile reaches each stack's world and adapter alike: a robot bigger than the Pioneer
    or a car is judged as itself (its radius, its turning radius), so the plan takes it."""
    for robot, args in (("omni_base", {}), ("turtlebot4", {"stacks": "2"})):
        p = launch_logic.plan_nav2_campaign({"output_dir": str(tmp_path), "robot_profile": robot, **args},
                                            share_dir=str(REPO))
        handed = {(n.namespace, n.name): n.parameters.get("robot_profile") for n in p.nodes
                  if n.executable in ("robot_world", "sut_adapter")}
        assert len(handed) == 2 * int(args.get("stacks", "1")) and set(handed.values()) == {robot}
    params = tmp_path / "mppi.yaml"
    params.write_text(MPPI_ACKERMANN)
    car = launch_logic.plan_nav2_campaign({"output_dir": str(tmp_path), "robot_profile": "ackermann_car",
                                           "params_file": str(params)}, share_dir=str(REPO))
    assert car.node("sut_adapter").parameters["robot_profile"] == "ackermann_car"
    # a file is handed on as an absolute path: each node reads the file the plan checked, wherever it runs
    (tmp_path / "robots").mkdir()
    (tmp_path / "robots" / "mine.yaml").write_text((REPO / "config" / "robots" / "turtlebot4.yaml").read_text())
    monkeypatch.chdir(tmp_path)
    mine = launch_logic.plan_nav2_campaign({"output_dir": str(tmp_path), "robot_profile": "robots/mine.yaml"},
                                           share_dir=str(REPO))
    expected = str(tmp_path / "robots" / "mine.yaml")
    assert mine.node("robot_world").parameters["robot_profile"] == expected
    assert mine.node("sut_adapter").parameters["robot_profile"] == expected
    plain = launch_logic.plan_nav2_campaign({"output_dir": str(tmp_path)}, share_dir=str(REPO))
    assert all("robot_profile" not in n.parameters for n in plain.nodes)  # '' = today's plan, unchanged
    with pytest.raises(ValueError, match="^robot_profile: no shipped profile 'roomba'"):
        launch_logic.plan_nav2_campaign({"output_dir": str(tmp_path), "robot_profile": "roomba"}, share_dir=str(REPO))


# --- the plan's node set, run as real processes ---------------------------------------------------------
def test_plan_node_set_runs_a_campaign_and_keep_workers_leaves_them_running(nodes_factory, tmp_path, ros_domain):
    """The launch file's sequence with ``keep_workers:=true``: generator exits -> SIGINT to the
    recorder only (it finalises the MCAP) -> summary from the log; the sim node still runs."""
    p = plan_campaign({"problem": "thermostat", "algorithm": "ga", "seed": "3", "workers": "1", "evaluations": "60",
                       "output_dir": str(tmp_path), "keep_workers": "true"}, share_dir=str(REPO))
    assert set(SIM_EXECUTABLES.values()) <= set(MODULES)
    nodes = nodes_factory(ros_domain)
    started = time.monotonic()
    for spec in p.nodes:
        nodes.start(spec.name, MODULES[spec.executable], **spec.parameters)
    exit_codes = {"generator": nodes.wait("generator", 240)}
    assert exit_codes["generator"] == 0, nodes.log("generator")[-3000:]
    assert p.after_generator_exit() == "stop_recorder"
    exit_codes["recorder"] = nodes.stop("recorder", timeout=30)
    assert not p.after_recorder_exit(generator_done=True)
    # kept: still running after the recorder's stop, and it ends cleanly on its own Ctrl-C below
    assert nodes.procs["thermostat_sim_0"].poll() is None, nodes.log("thermostat_sim_0")[-2000:]

    summary = plan_summary(p, time.monotonic() - started, exit_codes)
    assert summary == {**summary, **summarize(p.mcap, p.run_id)} and "log_error" not in summary
    assert summary["scenarios_published"] > 0 and summary["unresolved"] == [] and summary["evaluations"] == 60
    assert read_metadata(p.mcap)["ambiegen_run"]["run_id"] == p.run_id
    with open(p.mcap, "rb") as fh:
        assert make_reader(fh).get_summary() is not None  # finalised by SIGINT
    table = summary_table(summary)
    assert f"{summary['scenarios_published']} published, {summary['results_received']} results, 0 unresolved" in table
    assert str(p.mcap) in table and "generator 0, recorder 0" in table
    assert nodes.stop("thermostat_sim_0", timeout=30) == 0  # Ctrl-C ends the kept workers
    json.dumps(summary)  # what `ambiegen campaign --json` would print
