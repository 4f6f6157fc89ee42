"""``ambiegen rerun --stack nd --robot turtlebot4`` for real (no ROS needed; issue 69).

A real subprocess starts our ND stack over Cyclone DDS with the TurtleBot 4's profile: the run ends
with a verdict, its row names the robot, and the bag shows the world drove that robot (its laser's
frame, ``rplidar_link``, on ``/tf_static``: the Pioneer has no such frame).
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from mcap.reader import make_reader

REPO = Path(__file__).resolve().parents[2]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from ambiegen_ros.trials.rows import TrialLog  # noqa: E402

pytestmark = pytest.mark.skipif(os.environ.get("AMBIEGEN_TRANSPORT", "auto") == "rclpy",
                                reason="these tests drive the DDS backend")
CASES = json.loads((REPO / "test" / "data" / "robot_hazards_nd.json").read_text())
CONFIG = str(REPO / CASES["config"])


def test_rerun_on_the_nd_stack_drives_and_records_the_robot_given(tmp_path, ros_domain):
    suite = tmp_path / "one_suite.json"
    suite.write_text(json.dumps({"suite": [{"scenario": CASES["cases"][0]["scenario"], "name": "case0"}]}))
    results = tmp_path / "trials.jsonl"
    env = {k: v for k, v in os.environ.items() if k != "AMBIEGEN_TRANSPORT"}
    run = subprocess.run([sys.executable, "-m", "ambiegen_ros", "rerun", str(suite), "--stack", "nd", "--config",
                          CONFIG, "--results", str(results), "--repeat", "1", "--robot", "turtlebot4",
                          "--domain-id", str(ros_domain)], capture_output=True, text=True, cwd=REPO, env=env,
                         timeout=600)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    rows = TrialLog(results).rows()
    assert len(rows) == 1, [r.get("detail") for r in rows]
    row = rows[0]
    assert row["robot"] == "turtlebot4" and row["stack"] == "nd" and row["scenario_name"] == "case0"
    assert row["verdict"] == "PASS" or row["verdict"].startswith("FAIL("), row["detail"]
    assert f"case0 run 1/1: {row['verdict']}" in run.stdout and "[nd] stack nd, robot turtlebot4, params" in run.stdout
    frames = set()
    with open(row["bag"], "rb") as fh:
        for _, channel, message in make_reader(fh).iter_messages(topics=["/tf_static"]):
            frames |= {name for name in (b"rplidar_link", b"shell_link", b"laser") if name in message.data}
    assert b"rplidar_link" in frames, frames


def test_stack_search_records_the_robot_in_its_settings_and_rows(tmp_path, ros_domain):
    """One scenario asked of the search on the ND stack with a TurtleBot 3 Burger: the search's
    settings file and its row both name the robot; the run ends with a verdict."""
    results = tmp_path / "found.jsonl"
    env = {k: v for k, v in os.environ.items() if k != "AMBIEGEN_TRANSPORT"}
    run = subprocess.run([sys.executable, "-m", "ambiegen_ros", "stack-search", "--stack", "nd", "--hours", "1",
                          "--evaluations", "1", "--config", CONFIG, "--results", str(results), "--robot",
                          "turtlebot3_burger", "--domain-id", str(ros_domain)], capture_output=True, text=True,
                         cwd=REPO, env=env, timeout=600)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    assert json.loads(results.with_name("found.search.json").read_text())["robot"] == "turtlebot3_burger"
    rows = TrialLog(results).rows()
    assert rows and all(r["robot"] == "turtlebot3_burger" for r in rows)
    assert all(r["verdict"] == "PASS" or r["verdict"].startswith(("FAIL(", "INVALID")) for r in rows), rows
