"""What the node tests share (``test/ros/test_nodes*.py``, and the ROS tests that start nodes the
same way): node subprocesses of one test on its own ROS domain (``Nodes``; the fixtures
``nodes_factory`` and ``test_node``, registered in test/ros/conftest.py), and a run read back from
its MCAP log (``_read_run``) and from its generator's "done" line (``_done_line``).
"""
from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from rosbags.highlevel import AnyReader

from ambiegen_ros.ros import topics

REPO = Path(__file__).resolve().parents[2]
DONE = re.compile(
    r"run (\S+) done: (\d+) scenarios, (\d+) settled, (\d+) failures, (\d+) invalid tests, (\d+) timeouts, "
    r"(\d+) errors, (\d+) invalid"
)


def _env(domain: int) -> dict[str, str]:
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain), PYTHONUNBUFFERED="1")
    env.pop("AMBIEGEN_TRANSPORT", None)
    return env


def _value(v: Any) -> str:
    return ("true" if v else "false") if isinstance(v, bool) else str(v)


class Nodes:
    """Node subprocesses of one test; whatever is still running at teardown is stopped by pid."""

    def __init__(self, domain: int, log_dir: Path):
        self.domain = domain
        self.log_dir = log_dir
        self.procs: dict[str, subprocess.Popen] = {}

    def start(self, name: str, module: str, **params: Any) -> subprocess.Popen:
        args = [sys.executable, "-m", module, "--ros-args", "-r", f"__node:={name}"]
        for key, value in params.items():
            args += ["-p", f"{key}:={_value(value)}"]
        self.log_dir.mkdir(parents=True, exist_ok=True)
        with open(self.log_dir / f"{name}.log", "wb") as log:
            proc = subprocess.Popen(args, cwd=REPO, env=_env(self.domain), stdout=log, stderr=subprocess.STDOUT)
        self.procs[name] = proc
        return proc

    def log(self, name: str) -> str:
        return (self.log_dir / f"{name}.log").read_text(errors="replace")

    def wait(self, name: str, timeout: float) -> int:
        try:
            return self.procs[name].wait(timeout)
        except subprocess.TimeoutExpired:
            pytest.fail(f"{name} still running after {timeout} s; log:\n{self.log(name)[-3000:]}")

    def stop(self, name: str, timeout: float = 10.0) -> int:
        proc = self.procs[name]
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
            try:
                proc.wait(timeout)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
                pytest.fail(f"{name} ignored SIGINT for {timeout} s")
        return proc.returncode

    def cleanup(self) -> None:
        for proc in self.procs.values():
            if proc.poll() is None:
                proc.kill()
                proc.wait()


@pytest.fixture
def nodes_factory(tmp_path):
    made: list[Nodes] = []

    def make(domain: int) -> Nodes:
        nodes = Nodes(domain, tmp_path / f"logs{domain}")
        made.append(nodes)
        return nodes

    yield make
    for nodes in made:
        nodes.cleanup()


@pytest.fixture
def test_node(monkeypatch):
    """A node in this process on a given domain (DDS backend, as AMBIEGEN_TRANSPORT defaults)."""
    from ambiegen_ros.ros.transport import create_node

    created = []

    def make(name: str, domain: int):
        monkeypatch.setenv("ROS_DOMAIN_ID", str(domain))
        node = create_node(name, argv=[])
        created.append(node)
        return node

    yield make
    for node in created:
        node.shutdown()


def _read_run(mcap: Path) -> dict[str, Any]:
    """Everything of a run as rosbags decodes it from the schema text stored in the file."""
    run: dict[str, Any] = {"scenarios": [], "not_sent": [], "results": [], "status": [], "config": [], "connections": {}}
    with AnyReader([mcap]) as reader:
        run["connections"] = {c.topic: c for c in reader.connections}
        for conn, stamp, raw in reader.messages():
            msg = reader.deserialize(raw, conn.msgtype)
            if conn.topic.endswith("/scenarios"):
                m = msg.meta
                run["scenarios"].append((int(m.scenario_id), m.assigned_worker, int(m.attempt), m.run_id, m.problem))
            elif conn.topic.endswith("/not_sent"):
                m = msg.meta
                run["not_sent"].append((int(m.scenario_id), m.scenario_json, bool(m.surrogate_valid), m.invalid_reason,
                                        int(m.attempt), m.run_id))
            elif conn.topic == topics.RESULTS:
                run["results"].append((int(msg.scenario_id), msg.worker, int(msg.failure_kind), msg.run_id, msg.detail))
            elif conn.topic == topics.STATUS:
                run["status"].append(msg)
            elif conn.topic == topics.RUN_CONFIG:
                run["config"].append(msg)
    return run


def _done_line(log: str) -> dict[str, Any]:
    match = DONE.search(log)
    assert match, f"no 'done' line in the generator log:\n{log[-2000:]}"
    keys = ("run_id", "scenarios", "settled", "failures", "invalid_tests", "timeouts", "errors", "invalid")
    done = {k: (v if k == "run_id" else int(v)) for k, v in zip(keys, match.groups())}
    unsent = re.search(r"; (\d+) not sent \(the problem calls them invalid\)", log[match.end():].split("\n", 1)[0])
    done["not_sent"] = int(unsent.group(1)) if unsent else 0
    return done
