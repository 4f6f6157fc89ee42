"""`ambiegen replay`: re-execute a recorded run and compare, and re-publish it byte for byte.

Real processes over DDS, each test on its own ROS_DOMAIN_ID (``ros_domain``). The recorded run is
shared read-only: a test that needs files beside it works on a copy, so any order passes.
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest
from mcap.reader import make_reader

from ambiegen_ros.ros import topics
from ambiegen_ros.ros.qos import STREAM
from ambiegen_ros.ros.runlog import read_metadata, summarize

REPO = Path(__file__).resolve().parents[2]


def ambiegen(domain: int, *args: str, timeout: float = 150) -> subprocess.CompletedProcess:
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain), PYTHONUNBUFFERED="1")
    return subprocess.run([sys.executable, "-m", "ambiegen_ros", *args], cwd=REPO, env=env,
                          capture_output=True, text=True, timeout=timeout)


@pytest.fixture(scope="module")
def recorded(tmp_path_factory, module_domains) -> Path:
    out = tmp_path_factory.mktemp("recorded")
    domain = module_domains()
    run = ambiegen(domain, "campaign", "--problem", "thermostat", "--algorithm", "ga", "--evaluations", "200",
                   "--population", "20", "--offspring", "20", "--seed", "4", "--sim-model", "surrogate",
                   "--domain-id", str(domain), "--out", str(out))
    assert run.returncode == 0, run.stdout[-2000:] + run.stderr[-2000:]
    return next(out.glob("*.mcap"))


def test_replay_execute_reruns_every_scenario_and_reports_no_change(recorded, tmp_path, ros_domain):
    report_path, new_log = tmp_path / "report.json", tmp_path / "new.mcap"
    run = ambiegen(ros_domain, "replay", str(recorded), "--execute", "--workers", "1", "--sim-model", "surrogate",
                   "--record", str(new_log), "--report", str(report_path), "--domain-id", str(ros_domain))
    assert run.returncode == 0, run.stdout[-2000:] + run.stderr[-2000:]
    report = json.loads(report_path.read_text())
    old = summarize(recorded)
    assert report["scenarios"] == report["settled"] == old["scenarios_published"] == 10
    # same surrogate, same scenarios: every verdict and objective is reproduced
    assert report["changes"] == {"none": 10}, report["changes"]
    assert report["new_failures"] == report["fixed_failures"] == []
    # the full models' noise is seeded from the run's seed: a replay runs with the recorded one
    assert report["seed"] == 4 == int(read_metadata(recorded)["ambiegen_run"]["seed"])
    # the new results were recorded under the replay's run id, one per scenario
    new = summarize(new_log, report["replay_run_id"])
    assert new["results_received"] == 10 and new["unresolved"] == []


def test_replay_execute_with_another_model_reports_the_changes(recorded, tmp_path, ros_domain):
    """A 'new SUT version': the full-model thermostat instead of the surrogate."""
    report_path = tmp_path / "report.json"
    run = ambiegen(ros_domain, "replay", str(recorded), "--execute", "--workers", "1", "--sim-model", "full",
                   "--report", str(report_path), "--domain-id", str(ros_domain))
    assert run.returncode == 0, run.stderr[-2000:]
    report = json.loads(report_path.read_text())
    assert report["settled"] == 10
    # objectives are named differently by the full model, so every entry shows a change
    assert report["changes"].get("none", 0) < 10
    for entry in report["entries"].values():
        assert entry["old"] is not None and entry["new"]["objectives"]


def test_replay_publish_sends_the_recorded_bytes(recorded, monkeypatch, ros_domain):
    """Mode publish: a subscriber receives each recorded scenario message byte for byte."""
    from ambiegen_ros.ros.transport import create_node

    with open(recorded, "rb") as fh:
        expected = [m.data for _, _, m in make_reader(fh).iter_messages(topics=[topics.scenarios("thermostat")])]
    env = dict(os.environ, ROS_DOMAIN_ID=str(ros_domain))
    monkeypatch.setenv("ROS_DOMAIN_ID", str(ros_domain))  # undone after the test (no leftover for others)
    node = create_node("replay_listener", argv=[])
    received: list[bytes] = []
    node.create_subscription(topics.SCENARIO_TYPES["thermostat"], topics.scenarios("thermostat"),
                             lambda data, _t: received.append(bytes(data)), STREAM, raw=True)
    proc = subprocess.Popen([sys.executable, "-m", "ambiegen_ros", "replay", str(recorded), "--rate", "0"],
                            cwd=REPO, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 300  # a safety net: the loop ends when every message is in
        while len(received) < len(expected) and time.monotonic() < deadline:
            node.spin_once(0.05)
        assert proc.wait(timeout=120) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
        node.shutdown()
    assert received == expected


def test_replay_never_overwrites_a_report(recorded, tmp_path, ros_domain):
    """An explicit --report that exists is refused before anything starts; the default name moves aside."""
    existing = tmp_path / "kept.json"
    existing.write_text("an earlier report\n")
    recorded = Path(shutil.copy2(recorded, tmp_path / recorded.name))  # its default report goes beside it
    run = ambiegen(ros_domain, "replay", str(recorded), "--execute", "--report", str(existing),
                   "--domain-id", str(ros_domain))
    assert run.returncode == 2 and "already exists" in run.stderr, run.stderr[-2000:]
    assert existing.read_text() == "an earlier report\n"

    default = recorded.with_suffix(".replay.json")
    default.write_text("the first replay's report\n")
    run = ambiegen(ros_domain, "replay", str(recorded), "--execute", "--workers", "1", "--sim-model", "surrogate",
                   "--domain-id", str(ros_domain))
    assert run.returncode == 0, run.stderr[-2000:]
    assert default.read_text() == "the first replay's report\n"
    (moved,) = recorded.parent.glob(recorded.stem + ".replay-*.json")
    assert json.loads(moved.read_text())["settled"] == 10
    assert json.loads(run.stdout)["report"] == str(moved)
    moved.unlink()
