"""Node subprocesses on a test's own ROS domain, and a driver that publishes scenarios like the
generator and collects every result: the harness of the tests that put a system under test
behind ``sut_adapter`` (``test/ros/test_adapter.py``, ``test/ros/test_robot_world.py``)."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from ambiegen_ros.ros import conversions

REPO = Path(__file__).resolve().parents[2]


class Procs:
    """Node subprocesses of one test, stopped by pid at the end."""

    def __init__(self, domain: int, log_dir: Path):
        self.env = dict(os.environ, ROS_DOMAIN_ID=str(domain), PYTHONUNBUFFERED="1")
        self.env.pop("AMBIEGEN_TRANSPORT", None)
        self.log_dir = log_dir
        self.procs: dict[str, subprocess.Popen] = {}

    def start(self, name: str, module: str, **params: Any) -> subprocess.Popen:
        args = [sys.executable, "-m", module, "--ros-args", "-r", f"__node:={name}"]
        for key, value in params.items():
            value = ("true" if value else "false") if isinstance(value, bool) else value
            args += ["-p", f"{key}:={value}"]
        self.log_dir.mkdir(parents=True, exist_ok=True)
        with open(self.log_dir / f"{name}.log", "wb") as log:
            self.procs[name] = subprocess.Popen(args, cwd=REPO, env=self.env, stdout=log, stderr=subprocess.STDOUT)
        return self.procs[name]

    def log(self, name: str) -> str:
        return (self.log_dir / f"{name}.log").read_text(errors="replace")

    def exited(self) -> list[str]:
        """The processes that ended (a crash ends a wait on them at once, not at its safety net)."""
        return [name for name, proc in self.procs.items() if proc.poll() is not None]

    def logs(self) -> str:
        return "\n".join(f"--- {n}\n{self.log(n)[-2500:]}" for n in self.procs)

    def stop_all(self) -> None:
        for proc in self.procs.values():
            if proc.poll() is None:
                proc.send_signal(signal.SIGINT)
        for proc in self.procs.values():
            try:
                proc.wait(5)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()


@pytest.fixture
def graph(tmp_path, monkeypatch, ros_domain):
    """make() -> (Procs, driver node in this process), on the test's own domain."""
    made = []

    def make(domain: int = ros_domain):
        from ambiegen_ros.ros.transport import create_node

        monkeypatch.setenv("ROS_DOMAIN_ID", str(domain))
        monkeypatch.delenv("AMBIEGEN_TRANSPORT", raising=False)
        procs = Procs(domain, tmp_path / f"logs{domain}")
        node = create_node("adapter_test_driver", argv=[])
        made.append((procs, node))
        return procs, node

    yield make
    for procs, node in made:
        node.shutdown()
        procs.stop_all()


class Driver:
    """Publishes scenario messages like the generator and collects every result (the runner's
    ``trials.session.SuiteDriver``, sending a batch at once)."""

    def __init__(self, node, problem):
        from ambiegen_ros.ros import topics
        from ambiegen_ros.ros.qos import STREAM
        from ambiegen_ros.trials.session import SuiteDriver

        self.suite_driver = SuiteDriver(node, problem)
        self.node, self.problem, self.conv = node, problem, conversions
        self.pub = self.suite_driver.pub
        self.results = self.suite_driver.results
        self.workers = self.suite_driver.workers
        self.scenarios: dict[tuple[str, int], Any] = {}
        node.create_subscription(topics.SCENARIO_TYPES[problem.name], topics.scenarios(problem.name),
                                 self.on_scenario, STREAM)

    def on_scenario(self, msg) -> None:
        scenario, _ = self.conv.scenario_from_message(self.problem, msg)
        self.scenarios[(msg.meta.run_id, int(msg.meta.scenario_id))] = scenario

    def wait_matched(self, count: int = 1, timeout: float = 120.0) -> None:  # a safety net
        assert self.suite_driver.wait_matched(count + 1, timeout), "adapter not matched"

    def send(self, run_id: str, scenarios: list) -> None:
        for i, sc in enumerate(scenarios):
            self.suite_driver.send(run_id, i, sc)

    def wait(self, run_id: str, count: int, timeout: float, procs: "Procs | None" = None) -> list:
        """The results of ``run_id``'s first ``count`` scenarios (None where none came); a process of
        ``procs`` that exits ends the wait at once."""
        done = lambda: (self.suite_driver.resend_lost() or sum(k[0] == run_id for k in self.results) >= count  # noqa: E731
                        or bool(procs and procs.exited()))
        self.node.spin_until(done, timeout)
        return [self.results.get((run_id, i)) for i in range(count)]
