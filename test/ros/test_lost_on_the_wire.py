"""A scenario lost on the wire is sent again, and a scenario sent twice is run once.

A reliable, volatile message reaches only the readers that have finished their side of discovery:
one published before the adapter was on the graph is lost for good (the CI run of 2026-12-07 lost
five hazards scenarios that way and waited out its safety net). The driver (``SuiteDriver``, also
the runner's) sends again what every worker's heartbeat shows it does not hold; the adapter answers
a scenario it has already run from its record, and never runs it twice.

Real parts: the adapter is a subprocess on real DDS (its own ROS_DOMAIN_ID); with no system under
test behind it, each run ends quickly as an error record ("no odometry within 1 s"), which is all
the bookkeeping here needs.
"""
from __future__ import annotations

import os
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
for extra in (REPO, REPO / "test"):
    if str(extra) not in sys.path:
        sys.path.insert(0, str(extra))

import pytest  # noqa: E402

from ambiegen_ros.problems import get_problem  # noqa: E402
from helpers.sut_graph import Driver  # noqa: E402

pytestmark = pytest.mark.skipif(os.environ.get("AMBIEGEN_TRANSPORT", "auto") == "rclpy",
                                reason="these tests drive the DDS backend")
ROAD = [("straight", 30, 5), ("left", 5, 20), ("straight", 30, 5)]  # a gentle road of the refined profile


def test_a_scenario_sent_before_the_adapter_existed_is_sent_again_and_a_repeat_is_answered_from_record(graph):
    problem = get_problem("vehicle", {"profile": "refined"})
    scenario = problem.parse({"problem": "vehicle", "elements": [{"type": t, "length": n, "angle": a}
                                                                 for t, n, a in ROAD]})
    procs, node = graph()
    driver = Driver(node, problem)
    driver.send("early", [scenario])  # nobody subscribes yet: this one is lost for sure
    assert driver.pub.subscription_count() == 1  # only the driver's own reader took it
    procs.start("adapter", "sim_nodes.sut_adapter", problem="vehicle", worker_id="sut", start_timeout=1.0,
                profile="refined")
    (res,) = driver.wait("early", 1, 120)  # a safety net: the wait ends on the answer
    assert res is not None, procs.logs()
    assert res.failure_kind == "error" and "no odometry within 1 s" in res.detail
    assert driver.suite_driver.resent >= 1

    # the same scenario once more, as a driver that missed its result would: answered, not run again
    first = driver.results.pop(("early", 0))
    driver.suite_driver.send("early", 0, scenario)
    again = driver.wait("early", 1, 120)[0]
    assert again is not None, procs.logs()
    assert (again.failure_kind, again.detail) == (first.failure_kind, first.detail)
    node.spin_until(lambda: "came again" in procs.log("adapter"), 30)
    log = procs.log("adapter")
    assert "scenario 0 of run early came again" in log, log
    assert log.count("scenario 0: error") == 1, log  # one run, one finish line
