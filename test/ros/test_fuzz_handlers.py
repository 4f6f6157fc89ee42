"""Hypothesis against every subscription handler of every node, through the transport's guard.

The nodes are the real ones (worker, SUT adapter, external simulator, robot world, ND driver,
generator, recorder) on the
DDS backend in this process (a ROS_DOMAIN_ID of its own from ``module_domains``); each generated sample is handed
to the subscription exactly as the backend hands it a received sample (``DdsSubscription._deliver``:
size limit, decoding, handler). Nothing may escape into ``spin``, every sample is counted, memory
stays flat, and a scenario that decodes is answered with a result naming the bad field.
"""
from __future__ import annotations

import json
import math
import os
import struct
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

import numpy as np  # noqa: E402
import pytest  # noqa: E402
from hypothesis import HealthCheck, given, settings, strategies as st  # noqa: E402

from ambiegen_ros.problems import get_problem  # noqa: E402
from ambiegen_ros.ros import conversions, limits, topics  # noqa: E402
from ambiegen_ros.ros.conversions import ScenarioMeta  # noqa: E402
from ambiegen_ros.ros.types import get_registry  # noqa: E402
from ambiegen_ros.sims.outcome import FAILURE_KINDS  # noqa: E402

pytestmark = pytest.mark.skipif(
    os.environ.get("AMBIEGEN_TRANSPORT", "auto") == "rclpy", reason="feeds the DDS backend's subscriptions"
)

FUZZ = settings(max_examples=200, deadline=None, suppress_health_check=list(HealthCheck), database=None)
REG = get_registry()
ANSWERS = {FAILURE_KINDS["invalid_scenario"], FAILURE_KINDS["error"]}


def rss_bytes() -> int:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) * 1024
    return 0


@pytest.fixture(scope="module")
def graph(tmp_path_factory, module_domains):
    """One of each node, all subscriptions reachable; shut down at the end."""
    old = os.environ.get("ROS_DOMAIN_ID")
    os.environ["ROS_DOMAIN_ID"] = str(module_domains())
    from ambiegen_ros.nodes.generator import Generator
    from ambiegen_ros.nodes.recorder import Recorder
    from ambiegen_ros.ros.transport import create_node
    from sim_nodes.external_sim import ExternalSim
    from sim_nodes.nd_driver import NDDriverNode
    from sim_nodes.robot_world import RobotWorldNode
    from sim_nodes.sut_adapter import SutAdapter
    from sim_nodes.worker import SimWorker

    out = tmp_path_factory.mktemp("fuzz")
    argv = ["x", "--ros-args", "-p", "model:=surrogate", "-p", "worker_id:=fuzz_w", "-p", "heartbeat_period:=60.0"]
    made = {
        "worker": SimWorker("thermostat", argv=argv, node=create_node("fuzz_worker", argv=argv, backend="dds")),
        "robot_worker": SimWorker("robot", argv=argv, node=create_node("fuzz_robot", argv=argv, backend="dds")),
        "adapter": SutAdapter(node=create_node("fuzz_adapter", argv=["x", "--ros-args", "-p", "problem:=robot",
                                                                    "-p", "collision_topic:=/fuzz/bumper"], backend="dds")),
        "external_robot": ExternalSim(node=create_node("fuzz_ext_robot", argv=["x"], backend="dds")),
        "external_car": ExternalSim(node=create_node("fuzz_ext_car", argv=["x", "--ros-args", "-p", "problem:=vehicle"],
                                                     backend="dds")),
        "external_room": ExternalSim(node=create_node("fuzz_ext_room", argv=["x", "--ros-args", "-p", "problem:=thermostat"],
                                                      backend="dds")),
        "robot_world": RobotWorldNode(node=create_node("fuzz_world", argv=["x", "--ros-args", "-p", "map_topic:=/fuzz/map"],
                                                       backend="dds")),
        "nd_driver": NDDriverNode(node=create_node("fuzz_nd", argv=["x", "--ros-args", "-p", "map_topic:=/fuzz/map"],
                                                   backend="dds")),
        "generator": Generator(node=create_node("fuzz_generator", argv=[
            "x", "--ros-args", "-p", "problem:=thermostat", "-p", "run_id:=fuzz-run", "-p", "mode:=in_the_loop",
            "-p", "min_subscribers:=0"], backend="dds")),
        "recorder": Recorder(node=create_node("fuzz_recorder", argv=[
            "x", "--ros-args", "-p", f"output:={out / 'fuzz.mcap'}", "-p", "discover:=false"], backend="dds")),
    }
    yield made
    for name, obj in made.items():
        print(f"{name}: {obj.node.input_stats()}")  # inputs tried and dropped (pytest -s shows them)
        endpoint = getattr(obj, "endpoint", None)
        if endpoint is not None:
            endpoint.stop()  # heartbeat thread first, then the node's entities
        if name == "recorder":
            obj.close()
        obj.node.shutdown()
    if old is None:
        os.environ.pop("ROS_DOMAIN_ID", None)
    else:
        os.environ["ROS_DOMAIN_ID"] = old


def subscriptions(graph):
    """(node label, subscription) for every subscription of every node."""
    return [(label, sub) for label, obj in graph.items() for sub in obj.node._subs]


# --- hostile bytes ---------------------------------------------------------------------------------
def valid_sample(typename: str) -> bytes:
    return REG.serialize(REG.new(typename), typename)


@st.composite
def hostile_bytes(draw, typename: str):
    """Random bytes, or a valid sample truncated / with a wrong header / a huge length inside."""
    base = bytearray(valid_sample(typename))
    kind = draw(st.sampled_from(["random", "truncate", "header", "length", "flip"]))
    if kind == "random":
        return draw(st.binary(max_size=512))
    if kind == "truncate":
        return bytes(base[: draw(st.integers(0, max(0, len(base) - 1)))])
    if kind == "header":
        return draw(st.binary(min_size=4, max_size=4)) + bytes(base[4:])
    if kind == "length":  # a sequence / string length far larger than the payload
        at = 4 + 4 * draw(st.integers(0, max(0, (len(base) - 8) // 4)))
        base[at:at + 4] = struct.pack("<I", draw(st.sampled_from([0x7FFFFFFF, 0xFFFFFFFF, 10**8, 1 << 24])))
        return bytes(base)
    i = draw(st.integers(0, len(base) - 1))
    base[i] ^= draw(st.integers(1, 255))
    return bytes(base)


def feed(sub, data: bytes) -> None:
    sub._deliver(data, time.time_ns())  # exactly what DdsSubscription._drain does per received sample


@FUZZ
@given(data=st.data())
def test_every_subscription_survives_hostile_bytes(graph, data):
    label, sub = data.draw(st.sampled_from(subscriptions(graph)), label="subscription")
    payload = data.draw(hostile_bytes(sub.typename), label="payload")
    node = graph[label].node
    before = node.input_stats()
    feed(sub, payload)  # must not raise
    after = node.input_stats()
    assert node.ok()
    assert after["taken"] == before["taken"] + 1


def test_every_node_subscription_was_fuzzed(graph):
    """The map of subscriptions the fuzzing covers (a node gaining one is covered automatically)."""
    topics_by_node = {label: sorted(sub.topic for sub in obj.node._subs) for label, obj in graph.items()}
    assert topics.RESULTS in topics_by_node["generator"] and topics.WORKERS in topics_by_node["generator"]
    assert topics.scenarios("thermostat") in topics_by_node["worker"]
    assert topics.RUN_CONFIG in topics_by_node["worker"]
    assert "/map" in topics_by_node["external_robot"] and "/goal_pose" in topics_by_node["external_robot"]
    assert "/odom" in topics_by_node["adapter"] and "/fuzz/bumper" in topics_by_node["adapter"]
    assert len(topics_by_node["recorder"]) >= 6


# --- hostile but well-formed scenarios: answered, naming the field ----------------------------------
FLOATS = st.one_of(st.sampled_from([math.nan, math.inf, -math.inf, 1e308, -0.0]), st.floats(allow_nan=True))
NAMES = st.one_of(st.text(max_size=40), st.sampled_from(["../../etc/passwd", "a/b", "run\x00id", "run\nid", "..", "."]))


def deep_json(depth: int) -> str:
    return '{"problem":"thermostat","elements":' + "[" * depth + "]" * depth + "}"


@st.composite
def hostile_scenario(draw):
    problem = get_problem("thermostat")
    scenario = problem.codec.from_row(problem.sample_rows(1, np.random.default_rng(draw(st.integers(0, 2**16))))[0])
    msg = conversions.scenario_message(REG.new, 0, problem, scenario, ScenarioMeta("fuzz-run", 7))
    attack = draw(st.sampled_from(["problem", "run_id", "genome", "json_deep", "json_garbage", "json_big", "floats"]))
    if attack == "problem":
        msg.meta.problem = draw(st.text(min_size=1, max_size=200).filter(lambda s: s != "thermostat"))
    elif attack == "run_id":
        msg.meta.run_id = draw(NAMES.filter(lambda s: not limits._NAME.match(s) or ".." in s))
    elif attack == "genome":
        genome = np.array(msg.meta.genome, dtype=float)
        if len(genome):
            genome[draw(st.integers(0, len(genome) - 1))] = draw(st.sampled_from([math.nan, math.inf, -math.inf]))
        msg.meta.genome = genome
    elif attack == "json_deep":
        msg.meta.scenario_json = deep_json(draw(st.integers(limits.MAX_JSON_DEPTH + 1, 100_000)))
    elif attack == "json_garbage":
        msg.meta.scenario_json = draw(st.text(max_size=300))
    elif attack == "json_big":
        msg.meta.scenario_json = json.dumps({"problem": "thermostat", "elements": [{"temperature": 20}] * 50_000})
    else:  # NaN / inf in every float field the worker reads
        msg.meta.f1 = draw(FLOATS)
        msg.meta.f2 = draw(FLOATS)
        msg.setpoints = np.full(len(msg.setpoints), draw(FLOATS))
        msg.initial_temperature = draw(FLOATS)
        genome = np.array(msg.meta.genome, dtype=float)
        genome[:] = draw(st.sampled_from([math.nan, math.inf]))
        msg.meta.genome = genome
    return attack, REG.serialize(msg, topics.SCENARIO_TYPES["thermostat"])


@FUZZ
@given(case=hostile_scenario())
def test_hostile_scenario_is_answered_naming_the_field(graph, case):
    attack, payload = case
    worker = graph["worker"]
    sub = next(s for s in worker.node._subs if s.topic == topics.scenarios("thermostat"))
    sent = []
    publish = worker.endpoint.results.publish
    worker.endpoint.results.publish = sent.append  # capture the answer (the real message object)
    try:
        feed(sub, payload)
    finally:
        worker.endpoint.results.publish = publish
    worker.pending.clear()
    assert len(sent) == 1, f"{attack}: expected exactly one result, got {len(sent)}"
    result = sent[0]
    assert result.failure_kind in ANSWERS, (attack, result.detail)
    field = {"problem": "meta.problem", "run_id": "meta.run_id", "genome": "meta.genome",
             "json_deep": "meta.scenario_json", "json_garbage": "meta.scenario_json",
             "json_big": "meta.scenario_json", "floats": "meta.genome"}[attack]
    assert result.detail.startswith(field), (attack, result.detail[:200])
    assert len(result.detail) <= 2000
    assert limits.check_name(result.run_id, "echoed run id", allow_empty=True) == result.run_id  # never unsafe


@FUZZ
@given(objectives=st.lists(FLOATS, min_size=1, max_size=3), run_id=st.sampled_from(["fuzz-run", "other-run", "x"]),
       scenario_id=st.integers(0, 2**32 - 1))
def test_generator_survives_hostile_results(graph, objectives, run_id, scenario_id):
    """Results for unknown runs / scenarios and with NaN objectives: dropped or settled as errors."""
    gen = graph["generator"]
    sub = next(s for s in gen.node._subs if s.topic == topics.RESULTS)
    msg = REG.new(topics.RESULT_TYPE, run_id=run_id, scenario_id=scenario_id, problem="thermostat", worker="w",
                  objective_names=[f"o{i}" for i in range(len(objectives))], objectives=np.array(objectives))
    before = gen.node.input_stats()
    feed(sub, REG.serialize(msg, topics.RESULT_TYPE))
    assert gen.node.input_stats()["handler_errors"] == before["handler_errors"]
    for outcome in gen.remote.outcomes.values():
        assert all(math.isfinite(v) for v in outcome.objectives.values())


def test_oversize_sample_is_dropped_before_decoding(graph):
    ext = graph["external_robot"]
    sub = next(s for s in ext.node._subs if s.topic == "/map")
    limit = ext.node.input_guard().max_bytes
    assert limit == limits.DEFAULT_MAX_MESSAGE_BYTES
    grid = REG.new("nav_msgs/msg/OccupancyGrid", data=np.zeros(limit + 1, dtype=np.int8))
    grid.info.width, grid.info.height, grid.info.resolution = limit + 1, 1, 0.1
    before = ext.node.input_stats()
    feed(sub, REG.serialize(grid, "nav_msgs/msg/OccupancyGrid"))
    after = ext.node.input_stats()
    assert after["oversize"] == before["oversize"] + 1
    assert ext.map is None or ext.map[0].size <= limit  # never decoded


def test_memory_stays_flat_under_a_flood(graph):
    """20 000 hostile samples across all subscriptions: RSS grows by less than 40 MB."""
    subs = subscriptions(graph)
    rng = np.random.default_rng(3)
    samples = [valid_sample(sub.typename) for _, sub in subs]
    for i in range(2000):  # warm-up: caches, first-use allocations
        feed(subs[i % len(subs)][1], samples[i % len(subs)][: i % 64])
    start = rss_bytes()
    for i in range(20_000):
        k = int(rng.integers(len(subs)))
        base = bytearray(samples[k])
        if rng.random() < 0.5:
            base = base[: int(rng.integers(len(base)))]
        else:
            base[int(rng.integers(len(base)))] ^= 0xFF
        feed(subs[k][1], bytes(base))
    grown = rss_bytes() - start
    graph["worker"].pending.clear()
    graph["robot_worker"].pending.clear()
    assert grown < 40 * 1024 * 1024, f"RSS grew by {grown / 1e6:.1f} MB"
    for label, obj in graph.items():
        assert obj.node.ok(), label
