"""Hazards scenarios (issue 48) behind a stack: ``robot_world`` hosts the true world (walls, the
unmapped boxes and posts, walking people) while the stack is given only the map, ``nd_driver``
drives it, ``sut_adapter`` judges it with the reference and the fault rule; every node a real
subprocess on real DDS. Scenarios: ``test/data/robot_hazards_nd.json`` (random hazards scenarios
whose in-process ND verdicts cover a pass, a collision with a person, a loiter at an unmapped post
and two stalls, one after a person walked into the robot).

* in process, from the scenario file: each case gets its recorded verdict, certified;
* behind the stack: every verdict, time, path and count of not-at-fault contacts equals the
  in-process full model's fed the wire's number formats;
* the world shows what the stack was not told: markers of the people moving, and a map without them.
"""
from __future__ import annotations

import json
import os
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]

import numpy as np  # noqa: E402
import pytest  # noqa: E402

from ambiegen_ros.ros import topics  # noqa: E402
from ambiegen_ros.ros.qos import DEFAULT, LATCHED  # noqa: E402
from ambiegen_ros.run_config import make_run  # noqa: E402
from ambiegen_ros.sims.full_model import full_model_executor  # noqa: E402
from helpers.sut_graph import Driver  # noqa: E402
from helpers.wire import wire_emulation  # noqa: E402

pytestmark = pytest.mark.skipif(os.environ.get("AMBIEGEN_TRANSPORT", "auto") == "rclpy",
                                reason="these tests drive the DDS backend")
CASES = json.loads((REPO / "test" / "data" / "robot_hazards_nd.json").read_text())
LOCKSTEP = {"lockstep": True, "time_scale": 0.0, "scan_rate": 10.0, "sim.dt": 0.1, "cmd_vel_stamped": True,
            "paired_start": True}


@pytest.fixture(scope="module")
def problem():
    return make_run("robot", str(REPO / CASES["config"]), seed=0)[0]


def scenarios(problem):
    return [problem.parse(case["scenario"]) for case in CASES["cases"]]


def test_hazards_scenarios_from_a_file_get_their_certified_verdicts_in_process(problem):
    full = full_model_executor(problem)
    for case, sc in zip(CASES["cases"], scenarios(problem)):
        out = full.execute(sc, seed=CASES["seed"])
        assert out.verdict == case["in_process"], (case["why"], out.detail)
        if out.failed:  # certified: the reference drove the true world (with people: the patient robot)
            assert out.reference["passed"], out.reference
        if case["why"].startswith("collision"):
            assert "drove into person" in out.detail
        if "walking into" in case["why"]:
            assert out.metrics["contacts_not_at_fault"] >= 1


def test_the_stack_sees_only_the_map_and_the_world_gives_the_in_process_verdicts(graph, problem):
    scs = scenarios(problem)
    full = full_model_executor(problem)
    with wire_emulation():
        wires = [full.execute(sc, seed=0) for sc in scs]
    procs, node = graph()
    config = str(REPO / CASES["config"])
    procs.start("world", "sim_nodes.robot_world", **LOCKSTEP)
    procs.start("nd", "sim_nodes.nd_driver", cmd_vel_stamped=True, paired_start=True)
    procs.start("adapter", "sim_nodes.sut_adapter", problem="robot", worker_id="sut", config_file=config,
                stall_topic="/nd_driver/stall", plan_topic="/plan", collision_topic="/collision", settle_time=0.1)
    maps, markers = [], []
    node.create_subscription("nav_msgs/msg/OccupancyGrid", "/map", maps.append, LATCHED)
    node.create_subscription("visualization_msgs/msg/MarkerArray", topics.WORLD_MARKERS, markers.append, DEFAULT)
    driver = Driver(node, problem)
    driver.wait_matched()
    driver.send("hz", scs)
    got = driver.wait("hz", len(scs), 1200, procs)  # a safety net: the wait ends with the last result, or a crash
    assert all(got), f"exited: {procs.exited()}\n{procs.logs()}"
    for i, (res, wire) in enumerate(zip(got, wires)):
        assert res.failure_kind == wire.failure_kind, (i, res.detail, wire.detail)
        assert np.array_equal(np.asarray(res.trajectory), wire.trajectory), i
        assert float(res.metrics["time"]) == pytest.approx(wire.metrics["time"], abs=1e-6), i
        assert int(res.metrics["contacts_not_at_fault"]) == wire.metrics["contacts_not_at_fault"], i
        if wire.failed:
            assert res.reference["passed"], res.reference
    # the map the stack was given holds the walls only; the world's markers show the rest, moving
    env = problem.environment(scs[1])
    assert any(np.array_equal(np.asarray(m.data).reshape(env.grid.shape) > 0, env.grid) for m in maps)
    people = [[(mk.pose.position.x, mk.pose.position.y) for mk in m.markers if mk.ns == "people"] for m in markers]
    people = [p for p in people if p]
    assert len(people) > 10 and len({tuple(np.round(p[0], 3)) for p in people}) > 5
