"""A starved stack is never a failure (issue 70), end to end on real DDS: ``run_trials`` starts our
world, adapter and recorder and a FAKE Nav2 (test/helpers/fake_nav2_dds.py, not Nav2) whose
controller says on /rosout, each cycle while a goal runs, that it missed its desired rate (navigation2
jazzy's own words) and whose navigator aborts the goal (105) once the controller holds the robot.

Nav2 answered "aborted", yet every run is an error record of the kind ``starved``, its timing figures
in the row, run again at once, never counted as a run of the stack; ``max_errors`` starved runs in a
row stop the configuration saying this machine does not give the stack its computer.
"""
from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
for extra in (REPO, REPO / "test", REPO / "test" / "ros"):
    if str(extra) not in sys.path:
        sys.path.insert(0, str(extra))

from ambiegen_ros.nav2_params import OVERLAY_FILE, package_file  # noqa: E402
from ambiegen_ros.ros.transport import dds_backend  # noqa: E402
from ambiegen_ros.trials import tables  # noqa: E402
from ambiegen_ros.trials.configs import StackConfig, prepare  # noqa: E402
from ambiegen_ros.trials.reruns import starved  # noqa: E402
from ambiegen_ros.trials.rows import TrialLog  # noqa: E402
from ambiegen_ros.trials.runner import TrialSettings, run_trials  # noqa: E402
from ambiegen_ros.trials.session import StackStopped  # noqa: E402
from ambiegen_ros.trials.suite import load_suite  # noqa: E402
from test_trials_hang import CASES, CONFIG, FAKE_ROS2, HANG_AFTER, PARAMS  # noqa: E402

pytestmark = pytest.mark.skipif(os.environ.get("AMBIEGEN_TRANSPORT", "auto") == "rclpy"
                                or not dds_backend.is_available(), reason="these tests drive the DDS backend")


def test_a_starved_fake_nav2_abort_is_rerun_as_starved_and_never_a_failure(tmp_path, ros_domain, session_env):
    suite_file = tmp_path / "suite.json"
    suite_file.write_text(json.dumps({"suite": [{"scenario": CASES["cases"][0]["scenario"], "name": "case0"}]}))
    results, bags = tmp_path / "trials.jsonl", tmp_path / "bags"
    bags.mkdir()
    env = {"PATH": f"{FAKE_ROS2}{os.pathsep}{os.environ['PATH']}", "FAKE_ROS2_PYTHON": sys.executable,
           "FAKE_NAV2_CONTROLLER": "hold", "FAKE_NAV2_PATIENCE_S": "1.0", "FAKE_NAV2_STARVED": "1",
           "AMBIEGEN_TRANSPORT": "dds"}
    settings = TrialSettings(stack="bringup", results=results, bags=bags, repeat=1, domain_id=ros_domain,
                             hang_after=HANG_AFTER, start_timeout=120.0, ready_timeout=120.0, max_errors=2,
                             extra_env=env)
    prepared = prepare(StackConfig("fake", (str(PARAMS),)), "bringup", str(package_file(*OVERLAY_FILE)), 1.0, bags)
    said: list[str] = []
    with pytest.raises(StackStopped, match="does not give the stack its computer"):
        run_trials(load_suite([str(suite_file)], CONFIG), [prepared], settings, say=said.append)
    rows = TrialLog(results).rows()
    assert len(rows) == 2, "\n".join(said)  # the first, and its rerun at once
    for row in rows:
        assert starved(row) and not row["failed"] and row["failure_kind"] == "error", row["detail"]
        m = row["metrics"]
        assert m["sut_failure_kind"] == "nav2_aborted" and row["nav2_error_code"] == 105, row["detail"]
        assert "missed" in m["starved"] and int(m["timing.missed_loops"]) > 0 and float(m["timing.ack_s"]) >= 0
    md, data = tables.rerun_table(rows, "fake", {rows[0]["key"]: "case0"})
    assert data["starved"] == 2 and data["runs"] == 0 and data["failures"] == 0, md
