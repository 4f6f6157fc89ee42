"""``--robot`` of ``ambiegen rerun``, ``compare`` and ``stack-search`` (issue 69), without a stack.

The option reaches the trials' settings as the nodes take it (a shipped name, or a file as an
absolute path: ``launch_logic.node_robot``, as the Nav2 campaign launch resolves it); every
configuration's params get the robot's body and limits once the params' controller can drive it;
the world and the adapter of each stack kind get ``robot_profile``, no other node does; a robot
the stack cannot drive is refused in one line naming the configuration and the field, before any
file is written or any process started. The real run is ``test/ros/test_trials_robot.py``.
"""
from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from ambiegen_ros.cli import build_parser
from ambiegen_ros.cli.common import BadInput
from ambiegen_ros.cli.trials import _settings
from ambiegen_ros.nav2_params import OVERLAY_FILE, package_file
from ambiegen_ros.sims.robot_profile import profile_path
from ambiegen_ros.trials import configs
from ambiegen_ros.trials.session import stack_nodes

PIONEER_DWB = Path(package_file("config", "nav2", "pioneer_navfn_dwb.yaml"))
OVERLAY = str(package_file(*OVERLAY_FILE))
COMMANDS = {"rerun": ["suite.json"], "compare": ["suite.json"], "stack-search": ["--hours", "1"]}


def settings_of(command: str, *extra: str, tmp_path: Path):
    args = build_parser().parse_args([command, *COMMANDS[command], "--stack", "nd", "--results",
                                      str(tmp_path / "r.jsonl"), *extra])
    return _settings(args, tmp_path / "r.jsonl")


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_the_option_reaches_the_settings_as_the_nodes_take_it(command, tmp_path, monkeypatch):
    assert settings_of(command, tmp_path=tmp_path).robot == ""  # the Pioneer, as before
    assert settings_of(command, "--robot", "turtlebot4", tmp_path=tmp_path).robot == "turtlebot4"
    mine = tmp_path / "mine.yaml"
    shutil.copy(profile_path("turtlebot3_burger"), mine)
    monkeypatch.chdir(tmp_path)
    given = settings_of(command, "--robot", "mine.yaml", tmp_path=tmp_path).robot
    assert Path(given).is_absolute() and Path(given).read_text() == mine.read_text()  # any node's cwd reads it
    with pytest.raises(BadInput) as bad:
        settings_of(command, "--robot", "roomba", tmp_path=tmp_path)
    assert "--robot roomba: robot_profile: no shipped profile 'roomba'" in str(bad.value)
    assert "\n" not in str(bad.value)


def nodes_of(stack: str, prepared: configs.Prepared, robot: str, tmp_path: Path) -> dict:
    from ambiegen_ros.trials.runner import TrialSettings

    settings = TrialSettings(stack=stack, results=tmp_path / "r.jsonl", bags=tmp_path, robot=robot)
    return {n.name: n for n in stack_nodes(settings, prepared, tmp_path / "problem.yaml", tmp_path / "b.mcap", "abc")}


def test_the_nd_stack_gives_the_robot_to_the_world_and_the_adapter_only(tmp_path):
    prepared = configs.prepare(configs.StackConfig("nd", ()), "nd", None, 1.0, tmp_path, "turtlebot4")
    nodes = nodes_of("nd", prepared, "turtlebot4", tmp_path)
    given = {name for name, n in nodes.items() if "robot_profile" in n.parameters}
    assert given == {"robot_world", "sut_adapter"} and set(nodes) - given == {"recorder", "nd_driver"}
    assert {nodes[n].parameters["robot_profile"] for n in given} == {"turtlebot4"}
    pioneer = configs.prepare(configs.StackConfig("nd", ()), "nd", None, 1.0, tmp_path)
    assert not any("robot_profile" in n.parameters for n in nodes_of("nd", pioneer, "", tmp_path).values())
    assert prepared.digest != pioneer.digest  # a label's rows on one robot are never resumed on another


@pytest.mark.parametrize("stack", ["ours", "bringup"])
def test_a_nav2_stack_gets_the_robot_in_its_params_world_and_adapter(stack, tmp_path):
    config = configs.StackConfig("jazzy", (str(PIONEER_DWB),))
    pioneer = configs.prepare(config, stack, OVERLAY, 1.0, tmp_path / "p")
    burger = configs.prepare(config, stack, OVERLAY, 1.0, tmp_path / "b", "turtlebot3_burger")
    for costmap in ("local_costmap", "global_costmap"):
        section = burger.params[costmap][costmap]["ros__parameters"]
        assert section["robot_radius"] == pytest.approx(0.105) and "footprint" not in section
        assert "footprint" in pioneer.params[costmap][costmap]["ros__parameters"]
    assert burger.speed == pytest.approx(0.22) and pioneer.speed > 0.22  # the time limit follows the slower base
    assert "robot_radius: 0.105" in burger.path.read_text()  # the file the stack's nodes read
    nodes = nodes_of(stack, burger, "turtlebot3_burger", tmp_path)
    given = {name for name, n in nodes.items() if "robot_profile" in n.parameters}
    assert given == {"robot_world", "sut_adapter"}, sorted(nodes)
    assert all(nodes[n].parameters["robot_profile"] == "turtlebot3_burger" for n in given)
    if stack == "ours":
        assert "controller_server" in nodes and burger.path and str(burger.path) in nodes["controller_server"].params_files


def test_a_car_under_a_controller_without_a_car_like_model_is_refused_in_one_line(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    with pytest.raises(BadInput) as bad:
        configs.prepare(configs.StackConfig("jazzy", (str(PIONEER_DWB),)), "bringup", OVERLAY, 1.0, out,
                        "ackermann_car")
    said = str(bad.value)
    assert said.startswith("--params jazzy with --robot ackermann_car: controller_server.FollowPath.plugin: ")
    assert "no car-like model" in said and "\n" not in said
    assert list(out.iterdir()) == []  # nothing written, nothing to start
    with pytest.raises(BadInput) as nd:
        configs.prepare(configs.StackConfig("nd", ()), "nd", None, 1.0, out, "ackermann_car")
    assert str(nd.value).startswith("--params nd with --robot ackermann_car: drive.kind: ") and "\n" not in str(nd.value)
    omni = configs.prepare(configs.StackConfig("nd", ()), "nd", None, 1.0, out, "omni_base")  # ND drives it
    assert omni.params == {}


def test_stack_search_refuses_a_car_on_the_nd_stack_before_its_settings_are_written(tmp_path):
    """The command's own words, one line, exit status 2: no settings file, no results, no bag."""
    import subprocess
    import sys

    repo = Path(__file__).resolve().parents[1]
    results = tmp_path / "found.jsonl"
    run = subprocess.run([sys.executable, "-m", "ambiegen_ros", "stack-search", "--stack", "nd", "--hours", "1",
                          "--config", str(repo / "config" / "robot_hazards.yaml"), "--results", str(results),
                          "--robot", "ackermann_car"], capture_output=True, text=True, cwd=repo, timeout=300)
    assert run.returncode == 2, run.stdout[-2000:] + run.stderr[-2000:]
    said = run.stderr.strip()
    assert said.startswith("ambiegen stack-search: error: --params nd with --robot ackermann_car: drive.kind: ")
    assert "\n" not in said
    assert not results.exists() and not results.with_name("found.search.json").exists()
    assert not any(p.is_file() for p in tmp_path.rglob("*"))
