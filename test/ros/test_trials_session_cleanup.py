"""A stack session leaves no process behind when it fails after its processes started.

The session (``trials.session.StackSession``) starts our ND stack for real: recorder,
``robot_world``, ``nd_driver`` and ``sut_adapter`` as subprocesses over Cyclone DDS, and its driver
node in this process. A failure right after they start (in the constructor, or in the runner's
first line about the session) must stop every one of them, process group included: a leaked stack
keeps taking scenarios on the domain and holds the machine's cores.
"""
from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
CASES = json.loads((REPO / "test" / "data" / "robot_hazards_nd.json").read_text())

pytestmark = pytest.mark.skipif(os.environ.get("AMBIEGEN_TRANSPORT", "auto") == "rclpy",
                                reason="the session's driver runs on the DDS backend here")


@pytest.fixture
def started(monkeypatch) -> dict[str, subprocess.Popen]:
    """Every process a ``ProcessGroup`` starts during the test, by name."""
    from ambiegen_ros import campaign

    procs: dict[str, subprocess.Popen] = {}
    original = campaign.ProcessGroup.start_argv

    def recording(self, name, argv):
        procs[name] = original(self, name, argv)
        return procs[name]

    monkeypatch.setattr(campaign.ProcessGroup, "start_argv", recording)
    yield procs
    for proc in procs.values():  # a failed test leaves nothing either
        if proc.poll() is None:
            os.killpg(proc.pid, 9)
            proc.wait()


@pytest.fixture
def nd_session(tmp_path, monkeypatch, ros_domain):
    """(suite, prepared, settings) of a one-scenario rerun on our ND stack, on the test's domain."""
    from ambiegen_ros.trials.configs import StackConfig, prepare
    from ambiegen_ros.trials.runner import TrialSettings
    from ambiegen_ros.trials.suite import load_suite

    monkeypatch.setenv("ROS_DOMAIN_ID", str(ros_domain))  # the session sets it for its driver: restored after
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    monkeypatch.delenv("AMBIEGEN_TRANSPORT", raising=False)
    (tmp_path / "suite.json").write_text(json.dumps({"suite": [{"scenario": CASES["cases"][0]["scenario"]}]}))
    suite = load_suite([str(tmp_path / "suite.json")], str(REPO / CASES["config"]))
    settings = TrialSettings(stack="nd", results=tmp_path / "r.jsonl", bags=tmp_path / "bags", repeat=1,
                             domain_id=ros_domain)
    settings.bags.mkdir()
    return suite, prepare(StackConfig("nd", ()), "nd", None, 1.0, settings.bags), settings


STACK = {"recorder", "robot_world", "nd_driver", "sut_adapter"}


def running(procs: dict[str, subprocess.Popen]) -> bool:
    """The whole ND stack was started and every process of it runs."""
    return set(procs) == STACK and all(p.poll() is None for p in procs.values())


def assert_none_left(procs: dict[str, subprocess.Popen]) -> None:
    assert set(procs) == STACK, sorted(procs)
    for name, proc in procs.items():
        assert proc.poll() is not None, f"{name} still runs"
        with pytest.raises(ProcessLookupError):  # nothing it started is left in its process group either
            os.killpg(proc.pid, 0)


def test_a_constructor_that_fails_after_its_processes_started_stops_them(nd_session, started, monkeypatch):
    from ambiegen_ros.trials import session as session_module

    suite, prepared, settings = nd_session
    nodes = []

    def announce_fails(self, run_id, config):  # the constructor's step after the processes start
        nodes.append(self.node)
        assert running(started)
        raise RuntimeError("announce failed")

    monkeypatch.setattr(session_module.SuiteDriver, "announce", announce_fails)
    with pytest.raises(RuntimeError, match="announce failed"):
        session_module.StackSession(settings, suite, prepared, lambda line: None)
    assert nodes and not nodes[0].ok(), "the driver's node is shut down too"
    assert_none_left(started)


def test_an_interrupt_right_after_the_session_started_leaves_no_process(nd_session, started):
    """The runner's first line about the session comes before any run: a Ctrl-C there (or any error)
    goes through the session's ``with``."""
    from ambiegen_ros.trials.runner import run_trials

    suite, prepared, settings = nd_session
    said = []

    def say(line: str) -> None:
        said.append(line)
        if "stack nd, params" in line:
            assert running(started)
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_trials(suite, [prepared], settings, say=say)
    assert any("stack nd, params" in line for line in said), said
    assert_none_left(started)
    assert not settings.results.exists(), "no run was made"
