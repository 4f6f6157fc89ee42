"""Near misses against Nav2: a PASS that needed Nav2's recovery branch (``nav2_recoveries`` > 0 in
its result, from the action's feedback: ``sim_nodes/nav2_client.py``) is counted apart in the log's
summary and shown in the campaign table; a run without Nav2 has no such count at all."""
from __future__ import annotations

import re

from ambiegen_ros.launch_logic import summary_table
from ambiegen_ros.ros import conversions, qos, topics
from ambiegen_ros.ros.mcap_log import McapLog
from ambiegen_ros.ros.runlog import summarize
from ambiegen_ros.ros.types import get_registry
from ambiegen_ros.sims.outcome import Outcome


def _log(path, outcomes):
    reg = get_registry()
    with McapLog(path) as log:
        channel = log.add_channel(topics.RESULTS, topics.RESULT_TYPE, qos.DEFAULT)
        for i, outcome in enumerate(outcomes):
            msg = conversions.result_message(reg.new, 1000 + i, "run-1", i, "robot", "sut", outcome)
            log.write(channel, reg.serialize(msg, topics.RESULT_TYPE), 1000 + i)
    return path


def test_passes_after_nav2_recoveries_are_near_misses(tmp_path):
    outcomes = [
        Outcome({"x": 1.0}, False, "none", "Nav2 reached the goal after 108.4 s (a near miss: after 1 recovery)",
                {"nav2_status": "succeeded", "nav2_recoveries": 1}),
        Outcome({"x": 1.0}, False, "none", "Nav2 reached the goal after 45.5 s",
                {"nav2_status": "succeeded", "nav2_recoveries": 0}),
        Outcome({"x": 1.0}, True, "nav2_aborted", "Nav2 aborted its goal after 255.1 s (error 105)",
                {"nav2_status": "aborted", "nav2_recoveries": 2}),  # a failure, not a near miss
    ]
    summary = summarize(_log(tmp_path / "nav2.mcap", outcomes), "run-1")
    assert summary["near_misses"] == 1 and summary["failures"] == 1
    table = summary_table({"run_id": "run-1", **summary})
    assert re.search(r"near misses +1  \(passes that needed Nav2's recoveries", table), table


def test_a_run_without_nav2_has_no_near_miss_count(tmp_path):
    summary = summarize(_log(tmp_path / "sim.mcap", [Outcome({"x": 1.0}, False, "none", "ok", {"time": 3.0})]), "run-1")
    assert "near_misses" not in summary and "near misses" not in summary_table({"run_id": "run-1", **summary})
