"""Issue 28: on the rclpy backend, a node without the ambiegen_msgs classes says in one line what to run.

A plain ``colcon build`` builds only ``ambiegen_ros`` (colcon does not look inside a package's
folder), so ``ambiegen_msgs`` stays unbuilt and ``get_message`` would fail deep inside a node with
"module 'ambiegen_msgs.msg' has no attribute 'ScenarioResult'". Every node on the rclpy backend
checks first (``rclpy_backend.missing_messages``, called by ``nodes.run_node`` before the node is
made) and exits with status 2 and one line naming the command.

rclpy is not installed here. The nodes run as subprocesses with a FAKE ``rclpy`` package on
PYTHONPATH (empty: it only makes ``import rclpy`` succeed, so the rclpy backend is chosen; the check
stops the node before anything of rclpy is used) and, where named, a FAKE ``ambiegen_msgs`` that
lacks the classes. The same check on a real Jazzy build: test/real_ros/test_msgs_unbuilt.py.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from ambiegen_ros.ros.transport import rclpy_backend
from ambiegen_ros.ros.transport.rclpy_backend import message_classes, messages_problem, missing_messages, msgs_build_command

REPO = Path(__file__).resolve().parents[1]
ROS_VARS = ("AMENT_PREFIX_PATH", "RMW_IMPLEMENTATION", "ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_STATIC_PEERS",
            "ROS_LOCALHOST_ONLY", "AMBIEGEN_TRANSPORT", "AMBIEGEN_MSGS_DIR", "PYTHONPATH")


def fake_site(root: Path, msgs: str | None) -> Path:
    """A site folder holding a FAKE rclpy, and a FAKE ambiegen_msgs.msg with ``msgs`` as its code."""
    site = root / "fake_site"
    (site / "rclpy").mkdir(parents=True)
    (site / "rclpy" / "__init__.py").write_text('"""FAKE rclpy (test/test_msgs_missing.py): importable, nothing else."""\n')
    if msgs is not None:
        (site / "ambiegen_msgs" / "msg").mkdir(parents=True)
        (site / "ambiegen_msgs" / "__init__.py").write_text('"""FAKE ambiegen_msgs (test/test_msgs_missing.py)."""\n')
        (site / "ambiegen_msgs" / "msg" / "__init__.py").write_text(msgs)
    return site


def run(args: list[str], site: Path, cwd: Path, timeout: float = 120) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k not in ROS_VARS}
    env.update(AMBIEGEN_TRANSPORT="rclpy", PYTHONPATH=os.pathsep.join([str(site), str(REPO)]))
    return subprocess.run([sys.executable, *args], cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)


LACKING = '"""FAKE ambiegen_msgs.msg: a build of another version, without our classes."""\nclass ScenarioHeader: pass\n'
COMPLETE = "".join(f"class {name}: pass  # FAKE\n" for name in message_classes())


@pytest.mark.parametrize("module", ["ambiegen_ros.nodes.generator", "ambiegen_ros.nodes.recorder",
                                    "sim_nodes.sut_adapter", "sim_nodes.robot_sim", "sim_nodes.robot_world"])
def test_a_node_without_the_message_classes_stops_with_one_line(tmp_path, module):
    site = fake_site(tmp_path, LACKING)
    out = run(["-m", module], site, tmp_path)
    lines = out.stderr.strip().splitlines()
    assert out.returncode == 2 and len(lines) == 1 and "Traceback" not in out.stderr, out.stderr
    line = lines[0]
    assert "ambiegen_msgs.msg" in line and "ScenarioResult" in line and str(site) in line
    assert "colcon build" in line and line.endswith("&& source install/setup.bash"), line
    assert line.endswith(msgs_build_command()), line  # this checkout's own command


def test_the_source_folder_on_the_path_is_named_as_what_it_is(tmp_path):
    """Without a build, the repository's ``ambiegen_msgs/`` folder (only .msg files) imports as a
    namespace package: the error of issue 28 ("has no attribute 'ScenarioResult'"), caught first."""
    out = run(["-m", "ambiegen_ros.nodes.generator"], fake_site(tmp_path, None), REPO)
    assert out.returncode == 2 and len(out.stderr.strip().splitlines()) == 1, out.stderr
    assert f"ambiegen_msgs.msg ({REPO / 'ambiegen_msgs' / 'msg'}) has no" in out.stderr
    assert "ScenarioResult" in out.stderr and "Traceback" not in out.stderr


def test_doctor_reports_the_same_line_on_the_rclpy_backend(tmp_path):
    out = run(["-m", "ambiegen_ros.doctor", "--json"], fake_site(tmp_path, LACKING), tmp_path)
    checks = {c["name"]: c for c in json.loads(out.stdout)["checks"]}
    assert out.returncode == 1
    assert checks["ambiegen_msgs_python"]["status"] == "fail"
    assert checks["ambiegen_msgs_python"]["detail"].startswith("ambiegen_msgs is not built or not sourced")


def test_complete_classes_pass_and_a_missing_module_is_named(tmp_path, monkeypatch):
    site = fake_site(tmp_path, COMPLETE)
    probe = "from ambiegen_ros.ros.transport.rclpy_backend import missing_messages; print(repr(missing_messages()))"
    out = run(["-c", probe], site, tmp_path)
    assert out.returncode == 0 and out.stdout.strip() == "''", out.stderr
    monkeypatch.setitem(sys.modules, "ambiegen_msgs", None)  # import raises ModuleNotFoundError
    monkeypatch.delitem(sys.modules, "ambiegen_msgs.msg", raising=False)
    assert messages_problem().startswith("ModuleNotFoundError")
    assert missing_messages().startswith("ambiegen_msgs is not built or not sourced (ModuleNotFoundError")


def test_run_node_checks_before_the_node_exists_and_only_on_rclpy(monkeypatch, capsys):
    from ambiegen_ros import nodes

    made = []
    monkeypatch.setattr(rclpy_backend, "is_available", lambda: True)
    monkeypatch.setattr(rclpy_backend, "missing_messages", lambda: "ambiegen_msgs is not built or not sourced (x)")
    monkeypatch.setenv("AMBIEGEN_TRANSPORT", "rclpy")
    assert nodes.run_node("generator", lambda: made.append(1)) == 2 and made == []
    assert capsys.readouterr().err == "generator: error: ambiegen_msgs is not built or not sourced (x)\n"
    monkeypatch.setenv("AMBIEGEN_TRANSPORT", "dds")  # the DDS backend reads the .msg files: nothing to build
    assert nodes.unusable_messages() == ""


def module_file(root: Path) -> Path:
    return root / "ambiegen_ros" / "ros" / "transport" / "rclpy_backend.py"


def package(path: Path) -> Path:
    path.mkdir(parents=True)
    (path / "package.xml").write_text("<package/>")
    return path


@pytest.mark.parametrize("install", ["install/ambiegen_ros/lib/python3.12/site-packages",  # isolated install
                                     "install/lib/python3.12/site-packages",  # --merge-install
                                     "build/ambiegen_ros"])  # --symlink-install
def test_build_command_names_the_workspace_and_the_clone(tmp_path, install):
    ws = tmp_path / "my ws"
    package(ws / "src" / "ambiegen-ros" / "ambiegen_msgs")
    package(ws / "src" / "other_pkg")
    assert msgs_build_command(module_file(ws / install)) == (
        f"cd '{ws}' && colcon build --base-paths src src/ambiegen-ros/ambiegen_msgs && source install/setup.bash")


def test_build_command_from_a_checkout(tmp_path):
    in_src = tmp_path / "ws" / "src" / "clone"
    package(in_src / "ambiegen_msgs")
    assert msgs_build_command(module_file(in_src)) == (
        f"cd {tmp_path / 'ws'} && colcon build --base-paths src src/clone/ambiegen_msgs && source install/setup.bash")
    alone = tmp_path / "checkout"
    package(alone / "ambiegen_msgs")
    assert msgs_build_command(module_file(alone)) == (
        f"cd {alone} && colcon build --paths . ambiegen_msgs && source install/setup.bash")
    assert msgs_build_command(module_file(tmp_path / "site-packages")) == (
        "in your workspace: colcon build --base-paths src src/<repository folder>/ambiegen_msgs "
        "&& source install/setup.bash")
