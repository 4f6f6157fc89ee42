"""Sim workers started alike get distinct node names (issue 9): the name follows ``worker_id``.

Real worker subprocesses on the DDS backend (each test its own ROS_DOMAIN_ID: ``ros_domain``); an
observer node in this process reads the node names from the ``ros_discovery_info`` the workers
publish (``publishers_info``) and the worker ids from their heartbeats.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from ambiegen_ros.ros import topics  # noqa: E402
from ambiegen_ros.ros.qos import DEFAULT  # noqa: E402
from sim_nodes.worker import node_name_for, worker_node  # noqa: E402

pytestmark = pytest.mark.skipif(
    os.environ.get("AMBIEGEN_TRANSPORT", "auto") == "rclpy", reason="these tests drive the DDS backend"
)


@pytest.fixture
def workers(tmp_path, ros_domain):
    """Start worker subprocesses (``python -m sim_nodes.robot_sim``); SIGINT, then kill, at teardown."""
    procs: dict[str, subprocess.Popen] = {}

    def start(label: str, *ros_args: str) -> subprocess.Popen:
        env = dict(os.environ, ROS_DOMAIN_ID=str(ros_domain), PYTHONUNBUFFERED="1")
        env.pop("AMBIEGEN_TRANSPORT", None)
        args = [sys.executable, "-m", "sim_nodes.robot_sim", "--ros-args", "-p", "model:=surrogate",
                "-p", "min_result_subscribers:=0", "-p", "heartbeat_period:=0.2", *ros_args]
        with open(tmp_path / f"{label}.log", "wb") as log:
            procs[label] = subprocess.Popen(args, cwd=REPO, env=env, stdout=log, stderr=subprocess.STDOUT)
        return procs[label]

    start.log = lambda label: (tmp_path / f"{label}.log").read_text(errors="replace")  # type: ignore[attr-defined]
    start.procs = procs  # type: ignore[attr-defined]
    yield start
    for proc in procs.values():
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
            try:
                proc.wait(10)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()


def test_name_rule_and_sanitizing():
    assert node_name_for("robot-worker.1") == "robot_worker_1"
    assert node_name_for("7up") == "w_7up"  # ROS node names cannot start with a digit
    assert node_name_for("w_ok") == "w_ok"


def test_params_file_keyed_by_the_executable_name_still_applies(tmp_path, monkeypatch, ros_domain):
    monkeypatch.setenv("ROS_DOMAIN_ID", str(ros_domain))
    params = tmp_path / "p.yaml"
    params.write_text("robot_sim:\n  ros__parameters:\n    worker_id: from-file\n    model: surrogate\n")
    node, default_id = worker_node("robot_sim", ["robot_sim", "--ros-args", "--params-file", str(params)])
    try:
        assert node.name == "from_file"
        assert default_id == f"robot_sim_{os.getpid()}"
        assert node.declare_parameter("worker_id", default_id) == "from-file"
        assert node.declare_parameter("model", "full") == "surrogate"
    finally:
        node.shutdown()


def test_sut_adapter_follows_the_same_rule(monkeypatch, ros_domain):
    from sim_nodes.sut_adapter import SutAdapter

    monkeypatch.setenv("ROS_DOMAIN_ID", str(ros_domain))
    for ros_args, name, worker_id in (
        (["-p", "worker_id:=nav-2"], "nav_2", "nav-2"),
        ([], f"sut_adapter_{os.getpid()}", f"sut_adapter_{os.getpid()}"),
        (["-r", "__node:=sut", "-p", "worker_id:=nav-3"], "sut", "nav-3"),
    ):
        adapter = SutAdapter(["sut_adapter", "--ros-args", "-p", "problem:=robot", *ros_args])
        try:
            assert (adapter.node.name, adapter.worker_id) == (name, worker_id)
        finally:
            adapter.endpoint.stop()
            adapter.node.shutdown()


def test_two_plain_workers_have_distinct_names_and_remap_wins(workers, test_node_names_observer):
    a = workers("a")
    b = workers("b")
    workers("c", "-p", "worker_id:=robot-worker.c")
    workers("d", "-r", "__node:=remapped", "-p", "worker_id:=dee")
    observer = test_node_names_observer
    beats: set[str] = set()
    observer.create_subscription(topics.WORKERS_TYPE, topics.WORKERS, lambda m: beats.add(m.name), DEFAULT)
    want_names = {f"robot_sim_{a.pid}", f"robot_sim_{b.pid}", "robot_worker_c", "remapped"}
    want_ids = {f"robot_sim_{a.pid}", f"robot_sim_{b.pid}", "robot-worker.c", "dee"}
    names: set[str] = set()

    def seen() -> bool:
        names.update(ep.node_name for ep in observer.publishers_info(topics.WORKERS) if ep.node_name)
        return names >= want_names and beats >= want_ids

    deadline = time.monotonic() + 120.0  # a safety net: the wait ends when all four are seen
    while time.monotonic() < deadline and not seen():
        dead = [k for k, p in workers.procs.items() if p.poll() is not None]
        assert not dead, f"worker {dead[0]} exited:\n{workers.log(dead[0])[-3000:]}"
        observer.spin_until(lambda: False, 0.5)
    assert names == want_names, names
    assert beats == want_ids, beats
    for label, proc in workers.procs.items():
        proc.send_signal(signal.SIGINT)
        assert proc.wait(20) == 0, workers.log(label)[-3000:]


@pytest.fixture
def test_node_names_observer(monkeypatch, ros_domain):
    from ambiegen_ros.ros.transport import create_node

    monkeypatch.setenv("ROS_DOMAIN_ID", str(ros_domain))
    node = create_node("names_observer", backend="dds", argv=["observer"])
    yield node
    node.shutdown()
