"""A Nav2 user's own params file, made ready for our world (``ambiegen_ros.nav2_params``,
``ambiegen nav2-params``): the overlay reaches their layers and controller by what they contain,
not by name, rates follow the time scale, and nothing of theirs is lost or overwritten."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from ambiegen_ros import nav2_params
from ambiegen_ros.nav2_params import merge_overlay, merged_params, top_speed

REPO = Path(__file__).resolve().parents[1]
OVERLAY = REPO / "config" / "nav2" / "ambiegen_overlay.yaml"
# the shape of a Jazzy params file (MPPI, a voxel layer named by the user), written here, not copied
THEIRS = {
    "controller_server": {"ros__parameters": {
        "controller_frequency": 20.0, "controller_plugins": ["FollowPath"],
        "FollowPath": {"plugin": "nav2_mppi_controller::MPPIController", "vx_max": 0.5, "vx_min": -0.35,
                       "ax_max": 3.0, "ax_min": -3.0, "az_max": 3.5, "batch_size": 2000,
                       "CostCritic": {"enabled": True, "consider_footprint": False, "cost_weight": 3.81}}}},
    "local_costmap": {"local_costmap": {"ros__parameters": {
        "update_frequency": 5.0, "robot_radius": 0.22, "global_frame": "odom", "robot_base_frame": "base_link",
        "plugins": ["my_voxels", "inflation_layer"],
        "my_voxels": {"plugin": "nav2_costmap_2d::VoxelLayer", "observation_sources": "scan",
                      "scan": {"topic": "/scan", "data_type": "LaserScan"}},
        "inflation_layer": {"plugin": "nav2_costmap_2d::InflationLayer", "inflation_radius": 0.7}}}},
    "collision_monitor": {"ros__parameters": {"base_frame_id": "base_footprint", "cmd_vel_in_topic": "cmd_vel_smoothed"}},
    "bt_navigator": {"ros__parameters": {"bt_loop_duration": 10, "default_server_timeout": 20,
                                         "action_server_result_timeout": 900.0}},
}


def test_the_overlay_reaches_layers_and_controllers_by_content():
    got = merge_overlay(THEIRS, yaml.safe_load(OVERLAY.read_text()))
    follow = got["controller_server"]["ros__parameters"]["FollowPath"]
    assert (follow["ax_max"], follow["ax_min"], follow["az_max"]) == (0.5, -0.5, 2.0)  # the world's base
    assert follow["CostCritic"] == {"enabled": True, "consider_footprint": True, "cost_weight": 3.81}
    assert follow["vx_max"] == 0.5 and follow["batch_size"] == 2000  # theirs, untouched
    assert "acc_lim_x" not in follow  # the DWB pattern did not reach an MPPI controller
    local = got["local_costmap"]["local_costmap"]["ros__parameters"]
    assert local["my_voxels"]["scan"] == {"topic": "/scan", "data_type": "LaserScan", "inf_is_valid": True}
    assert "scan" not in local["inflation_layer"]  # a pattern never adds a section a layer lacks
    assert local["footprint"].startswith("[[0.18, 0.19]")
    assert got["collision_monitor"]["ros__parameters"] == {"base_frame_id": "base_link", "odom_frame_id": "odom",
                                                           "cmd_vel_in_topic": "cmd_vel_smoothed"}
    assert THEIRS["controller_server"]["ros__parameters"]["FollowPath"]["ax_max"] == 3.0  # the input is not changed
    assert not any(str(k).startswith("*") for k in yaml.safe_dump(got).split())  # no pattern key left in the output


def test_rates_scale_with_the_time_scale_and_the_top_speed_is_the_controllers(tmp_path):
    theirs = tmp_path / "theirs.yaml"
    theirs.write_text(yaml.safe_dump(THEIRS))
    got = merged_params(theirs, OVERLAY, 2.0)
    assert got["controller_server"]["ros__parameters"]["controller_frequency"] == 40.0
    assert got["local_costmap"]["local_costmap"]["ros__parameters"]["update_frequency"] == 10.0
    assert got["bt_navigator"]["ros__parameters"]["bt_loop_duration"] == 5
    bt = got["bt_navigator"]["ros__parameters"]
    assert bt["default_server_timeout"] == 1000  # the overlay's (Jazzy's 20 ms aborts goals on a loaded host), unscaled
    assert bt["action_server_result_timeout"] == 900.0  # a timeout of theirs: not a rate, left alone
    assert top_speed(got) == 0.5
    dwb = yaml.safe_load((REPO / "config" / "nav2" / "pioneer_navfn_dwb.yaml").read_text())
    assert top_speed(dwb) == 0.3 and top_speed({}) is None
    with pytest.raises(ValueError, match="pattern"):
        merge_overlay({"a": {}}, {"*x": 1})


def test_the_command_writes_once_and_says_how_to_start_nav2(tmp_path):
    theirs, out = tmp_path / "theirs.yaml", tmp_path / "merged.yaml"
    theirs.write_text(yaml.safe_dump(THEIRS))
    run = lambda *extra: subprocess.run(  # noqa: E731
        [sys.executable, "-m", "ambiegen_ros.cli", "nav2-params", str(theirs), "-o", str(out), *extra],
        capture_output=True, text=True, timeout=120)
    first = run("--time-scale", "2")
    assert first.returncode == 0, first.stderr
    assert f"params_file:={out}" in first.stdout and "MPPIController" in first.stdout and "0.5 m/s" in first.stdout
    written = out.read_text()
    assert yaml.safe_load(written)["controller_server"]["ros__parameters"]["controller_frequency"] == 40.0
    again = run()
    assert again.returncode == 2 and len(again.stderr.strip().splitlines()) == 1 and "exists" in again.stderr
    assert out.read_text() == written  # the user's file is never overwritten silently
    missing = subprocess.run([sys.executable, "-m", "ambiegen_ros.cli", "nav2-params", str(tmp_path / "none.yaml"),
                              "-o", str(tmp_path / "x.yaml")], capture_output=True, text=True, timeout=120)
    assert missing.returncode == 2 and "params_file: cannot read" in missing.stderr
    assert nav2_params.package_file(*nav2_params.OVERLAY_FILE) is not None


def test_the_command_writes_the_hardened_stack_with_its_tree(tmp_path):
    """``PARAMS+fix:hardened`` (issue 59): the params file and the derived tree a Nav2 user's bringup takes."""
    folder = tmp_path / "prefix" / "share" / "nav2_bt_navigator" / "behavior_trees"
    folder.mkdir(parents=True)  # a stand-in for Jazzy's installed tree (no Nav2 here)
    (folder / "navigate_to_pose_w_replanning_and_recovery.xml").write_text(
        '<root BTCPP_format="4"><BehaviorTree ID="MainTree"><RecoveryNode number_of_retries="6" '
        'name="NavigateRecovery"><FollowPath/></RecoveryNode></BehaviorTree></root>')
    theirs, out = tmp_path / "theirs.yaml", tmp_path / "hardened.yaml"
    theirs.write_text(yaml.safe_dump(THEIRS))
    env = {**os.environ, "AMENT_PREFIX_PATH": str(tmp_path / "prefix")}
    run = lambda: subprocess.run(  # noqa: E731
        [sys.executable, "-m", "ambiegen_ros.cli", "nav2-params", f"{theirs}+fix:hardened", "-o", str(out)],
        capture_output=True, text=True, timeout=120, env=env)
    first = run()
    assert first.returncode == 0, first.stderr
    written = yaml.safe_load(out.read_text())
    tree = Path(written["bt_navigator"]["ros__parameters"]["default_nav_to_pose_bt_xml"])
    assert tree.parent == tmp_path and f"behaviour tree: {tree}" in first.stdout
    assert 'number_of_retries="1000"' in tree.read_text() and "<Timeout" in tree.read_text()
    assert written["local_costmap"]["local_costmap"]["ros__parameters"]["plugins"][0] == "static_layer"
    assert "fix:hardened" in out.read_text().splitlines()[0]  # the header says what was merged
    trees_before = sorted(tmp_path.glob("*.xml"))
    again = run()
    assert again.returncode == 2 and "exists" in again.stderr and sorted(tmp_path.glob("*.xml")) == trees_before
