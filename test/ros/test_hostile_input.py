"""Hostile samples over real DDS between processes: the nodes drop them, count them and keep serving.

A thermostat worker, a robot ``external_sim`` (it subscribes ``/map``) and a recorder run as
subprocesses on the test's own ROS_DOMAIN_ID (``ros_domain``). This test process sends them, on their own topics:

* bytes that break the CDR layout (truncated, huge sequence lengths, wrong header), from a writer
  whose DDS type is a plain byte sequence under the same names -- the receiving Cyclone drops
  them before decoding ("deserialization ... failed" in the node's log);
* a well-formed layout with a string that is not UTF-8 -- the node's guard counts it as malformed;
* well-formed scenarios with a wrong problem, NaN genome, 100 000-deep JSON, a path-traversing run
  id -- each answered with INVALID_SCENARIO naming the field;
* a 100 MB OccupancyGrid -- dropped by the receiver's size limit (``max_message_bytes``, 4 MB)
  without being buffered;

then a valid scenario, which must still be answered. Every process must be alive, its resident
memory bounded (``/proc/<pid>/status`` VmRSS), and the counters (heartbeat values, shutdown log
line) must show the drops.
"""
from __future__ import annotations

import os
import re
import struct
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

import numpy as np  # noqa: E402
import pytest  # noqa: E402

from ambiegen_ros.problems import get_problem  # noqa: E402
from ambiegen_ros.ros import conversions, topics  # noqa: E402
from ambiegen_ros.ros.conversions import ScenarioMeta  # noqa: E402
from ambiegen_ros.ros.qos import DEFAULT, LATCHED, STREAM  # noqa: E402
from ambiegen_ros.ros.types import get_registry  # noqa: E402
from ambiegen_ros.sims.outcome import FAILURE_KINDS  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_nodes import Nodes  # noqa: E402  (the node-subprocess helper of the ROS tests)

pytestmark = pytest.mark.skipif(
    os.environ.get("AMBIEGEN_TRANSPORT", "auto") == "rclpy", reason="these tests drive the DDS backend"
)

REG = get_registry()
INVALID = FAILURE_KINDS["invalid_scenario"]
SCENARIO_TYPE = topics.SCENARIO_TYPES["thermostat"]
RSS_GROWTH_LIMIT = 60 * 1024 * 1024
INPUT_LINE = re.compile(r"input: (\d+) samples taken, (\d+) dropped \(oversize (\d+), malformed (\d+), handler errors (\d+)\)")


def vm_rss(pid: int) -> int:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) * 1024
    raise AssertionError(f"no VmRSS for {pid}")


class ByteWriter:
    """A DDS writer whose type is ``sequence<octet>`` under a ROS type's DDS name: it can put any
    bytes on the wire (our own writers refuse payloads that do not fit the real layout)."""

    def __init__(self, topic: str, typename: str, domain_participant):
        import cyclonedds.idl.types as T
        from cyclonedds.idl import make_idl_struct
        from cyclonedds.pub import DataWriter
        from cyclonedds.topic import Topic
        from ambiegen_ros.ros.transport import dds_backend as D

        cls = make_idl_struct(typename.rsplit("/", 1)[-1] + "_", REG.dds_type_name(typename), {"data": T.sequence[T.uint8]})
        t = Topic(domain_participant, "rt" + topic, cls, qos=D._DdsQos(D.Policy.DataRepresentation(use_cdrv0_representation=True)))
        self.writer = DataWriter(domain_participant, t, qos=D.dds_qos(STREAM))
        self._write, self._pad = D.ddspy_write, D.pad_cdr

    def send(self, payload: bytes) -> None:
        """The wire carries header + uint32 length + payload: whatever the receiver's type makes of it."""
        assert self._write(self.writer._ref, self._pad(b"\x00\x01\x00\x00" + struct.pack("<I", len(payload)) + payload)) == 0


def scenario(prob, seed: int, **meta_fields):
    row = prob.sample_rows(1, np.random.default_rng(seed))[0]
    msg = conversions.scenario_message(REG.new, time.time_ns(), prob, prob.codec.from_row(row),
                                       ScenarioMeta("hostile-run", seed))
    for key, value in meta_fields.items():
        setattr(msg.meta, key, value)
    return msg


def test_hostile_samples_over_dds_are_dropped_counted_and_the_nodes_keep_serving(tmp_path, monkeypatch, ros_domain):
    nodes = Nodes(ros_domain, tmp_path / "logs")
    monkeypatch.setenv("ROS_DOMAIN_ID", str(ros_domain))
    from ambiegen_ros.ros.transport import create_node

    try:
        worker = nodes.start("hostile_worker", "sim_nodes.thermostat_sim", worker_id="hw", model="surrogate",
                             min_result_subscribers=1, heartbeat_period=0.3)
        ext = nodes.start("hostile_ext", "sim_nodes.external_sim", problem="robot")
        rec = nodes.start("hostile_rec", "ambiegen_ros.nodes.recorder", output=str(tmp_path / "hostile.mcap"),
                          discover=False)
        # this process sends a 100 MB map, so its own limit is raised (the first node here sets the domain's)
        node = create_node("attacker", argv=["attacker"], backend="dds",
                           parameter_overrides={"max_message_bytes": 200_000_000})
        results, beats = [], []
        node.create_subscription(topics.RESULT_TYPE, topics.RESULTS, results.append, STREAM)
        node.create_subscription(topics.WORKERS_TYPE, topics.WORKERS, beats.append, DEFAULT)
        pub = node.create_publisher(SCENARIO_TYPE, topics.scenarios("thermostat"), STREAM)
        pub_map = node.create_publisher("nav_msgs/msg/OccupancyGrid", "/map", LATCHED)
        bytes_out = ByteWriter(topics.scenarios("thermostat"), SCENARIO_TYPE, node._dp)

        ready = node.spin_until(lambda: any(b.name == "hw" for b in beats) and pub.subscription_count() >= 2
                                and pub_map.subscription_count() >= 1
                                and bytes_out.writer.get_publication_matched_status().current_count >= 2, 120)
        assert ready, "nodes did not come up:\n" + "\n".join(nodes.log(n)[-1500:] for n in nodes.procs)
        problem = get_problem("thermostat")
        pub.publish(scenario(problem, 0))  # warm-up: first use of the model (imports, compiles)
        assert node.spin_until(lambda: any(int(r.scenario_id) == 0 for r in results), 120), nodes.log("hostile_worker")
        node.spin_until(lambda: False, 1.0)
        rss0 = {name: vm_rss(p.pid) for name, p in nodes.procs.items()}

        valid = REG.serialize(scenario(problem, 1), SCENARIO_TYPE)
        # 1. layout-breaking bytes: the receiving Cyclone refuses them before any decoding
        for cut in (0, 3, 7, 50, len(valid) // 2, len(valid) - 9):
            bytes_out.send(valid[:cut])
        for huge in (0x7FFFFFFF, 0xFFFFFFFF):
            bytes_out.send(struct.pack("<I", huge) * 16)
        bytes_out.send(b"\xff" * 64)
        # 2. a layout that fits, with a run id that is not UTF-8: the node's guard counts it
        good_layout = bytearray(valid)
        good_layout[16:19] = b"\xff\xfe\xfd"  # ScenarioHeader.header.frame_id ("map")
        for _ in range(5):
            pub.publish_raw(bytes(good_layout))
        # 3. well-formed but hostile: each must be answered, naming the field
        hostile = {
            101: ("meta.problem", scenario(problem, 101, problem="robot\x00; rm -rf /")),
            102: ("meta.genome", scenario(problem, 102)),
            103: ("meta.scenario_json", scenario(problem, 103, scenario_json="[" * 100_000 + "]" * 100_000)),
            104: ("meta.run_id", scenario(problem, 104, run_id="../../etc/passwd")),
            105: ("meta.scenario_json", scenario(problem, 105, scenario_json='{"problem": "thermostat", "elements": 5}')),
        }
        hostile[102][1].meta.genome = np.full(len(hostile[102][1].meta.genome), np.nan)
        for sid, (_, msg) in hostile.items():
            msg.meta.scenario_id = sid
            pub.publish(msg)
        # 4. a 100 MB map to external_sim (and the recorder, which records /map only if asked: not here)
        side = 10_000
        grid = REG.new("nav_msgs/msg/OccupancyGrid", data=np.zeros(side * side, dtype=np.int8))
        grid.info.width = grid.info.height = side
        grid.info.resolution = 0.05
        pub_map.publish(grid)
        del grid
        # 5. the valid scenario: still served
        pub.publish(scenario(problem, 8))  # seed 8: a scenario the surrogate scores (valid)

        def answered() -> bool:
            ids = {int(r.scenario_id) for r in results if r.run_id in ("hostile-run", "______etc_passwd")}
            return set(hostile) | {8} <= ids

        assert node.spin_until(answered, 120), (
            f"answers for {sorted(int(r.scenario_id) for r in results)}; worker log:\n{nodes.log('hostile_worker')[-3000:]}")
        by_id = {int(r.scenario_id): r for r in results}
        for sid, (field, _) in hostile.items():
            assert by_id[sid].failure_kind == INVALID, (sid, by_id[sid].detail)
            assert by_id[sid].detail.startswith(field), (sid, field, by_id[sid].detail[:200])
        assert by_id[104].run_id == "______etc_passwd"  # the traversing run id is never echoed as is
        assert by_id[8].failure_kind != INVALID and by_id[8].worker == "hw", by_id[8].detail

        # counters in the heartbeat, once they include everything sent
        def stats() -> dict[str, int]:
            last = [b for b in beats if b.name == "hw"][-1]
            return {kv.key: int(kv.value) for kv in last.values if kv.key.startswith("input_")}

        beats.clear()
        node.spin_until(lambda: any(b.name == "hw" for b in beats) and stats()["input_malformed"] >= 5, 120)
        counted = stats()
        assert counted["input_malformed"] >= 5 and counted["input_dropped"] >= 5, counted
        assert counted["input_taken"] >= 5 + len(hostile) + 1, counted
        print(f"worker heartbeat counters: {counted}")

        # the 100 MB sample has arrived and been refused (Cyclone logs "dropping oversize" at once)
        assert node.spin_until(lambda: "oversize" in nodes.log("hostile_ext"), 120), \
            nodes.log("hostile_ext")[-2000:]
        for name, proc in nodes.procs.items():
            assert proc.poll() is None, f"{name} died:\n{nodes.log(name)[-3000:]}"
            grown = vm_rss(proc.pid) - rss0[name]
            print(f"{name}: RSS {rss0[name] / 1e6:.1f} MB before the hostile samples, grew by {grown / 1e6:.1f} MB")
            assert grown < RSS_GROWTH_LIMIT, f"{name}: RSS grew by {grown / 1e6:.1f} MB"
        worker_log = nodes.log("hostile_worker")
        assert "deserialization" in worker_log and "failed" in worker_log  # Cyclone refused the broken layouts
        assert "oversize" in nodes.log("hostile_ext")  # the 100 MB map, refused by the size limit

        for name in ("hostile_worker", "hostile_ext", "hostile_rec"):
            assert nodes.stop(name, 30) == 0, nodes.log(name)[-3000:]
        taken, dropped, _, malformed, _ = map(int, INPUT_LINE.findall(nodes.log("hostile_worker"))[-1])
        assert malformed >= 5 and taken >= 5 + len(hostile) + 1
        assert INPUT_LINE.search(nodes.log("hostile_rec")), nodes.log("hostile_rec")[-2000:]
    finally:
        from ambiegen_ros.ros import transport
        transport.shutdown()
        nodes.cleanup()
