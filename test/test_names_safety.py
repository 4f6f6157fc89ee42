"""Identifiers that travel in messages and end up in file names: traversal and control characters.

``run_id`` (generator parameter, every scenario and result) and ``worker_id`` (worker parameter,
heartbeats, results) are refused when they could climb out of a directory or hide in a terminal:
as parameters the node exits with status 2 and one line naming the parameter; in a received
scenario the worker answers INVALID_SCENARIO naming ``meta.run_id`` and never echoes it as is.
"""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from ambiegen_ros.core.attributes import ScenarioError
from ambiegen_ros.problems import get_problem
from ambiegen_ros.ros import conversions, limits
from ambiegen_ros.ros.conversions import ScenarioMeta
from ambiegen_ros.ros.types import get_registry

REPO = Path(__file__).resolve().parents[1]



@pytest.fixture(autouse=True)
def own_domain(ros_domain, monkeypatch) -> None:
    """A ROS domain id no other test holds (test/conftest.py), for the nodes these tests start."""
    monkeypatch.setenv("ROS_DOMAIN_ID", str(ros_domain))


SAFE = ["run-1a2b3c4d", "thermostat-nsga2-s1-abc123", "replay-run-1-ff00aa", "w_a", "thermostat_sim_1234",
        "robot.sim+2@host=1", "A" * limits.MAX_NAME_LENGTH]
UNSAFE = ["", ".", "..", "../x", "a/../../b", "/etc/passwd", "a/b", "a\\b", "run\x00id", "run\nid", "run\rid",
          "run\x1b[31mred", "tab\tid", "space id", ".hidden", "x..y", "é", "run\u202eid", "A" * (limits.MAX_NAME_LENGTH + 1),
          "-", "-rf", "-" * (limits.MAX_NAME_LENGTH + 1)]  # "-": found by test/ros/test_fuzz_handlers.py


@pytest.mark.parametrize("name", SAFE)
def test_safe_names_pass_unchanged(name):
    assert limits.check_name(name, "run_id") == name
    assert conversions.safe_echo(name) == name


@pytest.mark.parametrize("name", UNSAFE)
def test_unsafe_names_are_refused_naming_the_field(name):
    with pytest.raises(limits.UnsafeName, match=r"^worker_id: "):
        limits.check_name(name, "worker_id")
    echoed = conversions.safe_echo(name)
    assert limits.check_name(echoed, "echo", allow_empty=True) == echoed  # what a result may carry
    assert "/" not in echoed and ".." not in echoed


def test_non_strings_are_refused():
    with pytest.raises(limits.UnsafeName, match="must be a string"):
        limits.check_name(b"run", "run_id")


@pytest.mark.parametrize("run_id", ["../../etc/passwd", "run\x00id", "a/b", "run\nid"])
def test_scenario_with_unsafe_run_id_is_invalid_naming_the_field(run_id):
    problem = get_problem("thermostat")
    reg = get_registry()
    scenario = problem.codec.from_row(problem.sample_rows(1, np.random.default_rng(0))[0])
    msg = conversions.scenario_message(reg.new, 0, problem, scenario, ScenarioMeta(run_id, 3))
    msg = reg.deserialize(reg.serialize(msg, "ambiegen_msgs/msg/ThermostatScenario"), "ambiegen_msgs/msg/ThermostatScenario")
    with pytest.raises(ScenarioError) as caught:
        conversions.scenario_from_message(problem, msg)
    assert caught.value.field == "meta.run_id"


def test_json_depth_is_measured_without_recursion():
    assert limits.json_depth('{"a": [1, {"b": "[[[[not nesting]]]]"}]}') == 3
    assert limits.json_depth('"escaped \\" [[[" ') == 0
    assert limits.json_depth("[" * 1_000_000) == 1_000_000  # no RecursionError, linear time


def _start(module: str, *params: str) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONUNBUFFERED="1")  # ROS_DOMAIN_ID: this test's own (own_domain)
    if env.get("AMBIEGEN_TRANSPORT") != "rclpy":
        env["AMBIEGEN_TRANSPORT"] = "dds"
    args = [sys.executable, "-m", module, "--ros-args"]
    for p in params:
        args += ["-p", p]
    return subprocess.run(args, cwd=REPO, env=env, capture_output=True, text=True, timeout=180)


@pytest.mark.parametrize("module, param, value", [
    ("ambiegen_ros.nodes.generator", "run_id", "../../outside"),
    ("sim_nodes.thermostat_sim", "worker_id", "w/../../x"),
])
def test_nodes_refuse_unsafe_ids_as_parameters(module, param, value):
    out = _start(module, f"{param}:={value}", "model:=surrogate" if "sim" in module else "problem:=thermostat")
    assert out.returncode == 2, out.stdout + out.stderr
    assert f"{param}: unsafe name" in out.stderr, out.stderr
