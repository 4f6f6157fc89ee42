"""McapLog (the recorder's writer), recover() and the rosbag2 QoS text.

Files are read back with independent readers: rosbags' AnyReader (what rosbag2 users rely on),
the mcap reader for the raw records, and mcap-ros2-support's decoder (Foxglove's).
"""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rosbags.highlevel import AnyReader
from rosbags.interfaces import QosDurability, QosHistory, QosReliability
from rosbags.rosbag2.metadata import parse_qos

from ambiegen_ros.ros import qos
from ambiegen_ros.ros.mcap_log import McapLog, recover
from ambiegen_ros.ros.types import get_registry

ROOT = Path(__file__).resolve().parents[2]
ROBOT = "ambiegen_msgs/msg/RobotScenario"
RESULT = "ambiegen_msgs/msg/ScenarioResult"
STATUS = "ambiegen_msgs/msg/RunStatus"


@pytest.fixture(scope="module")
def reg():
    return get_registry()


def _robot(reg, i: int) -> bytes:
    msg = reg.new(ROBOT)
    msg.meta.scenario_id = i
    msg.meta.run_id = "run-1"
    msg.map.info.width = msg.map.info.height = 20
    msg.map.data = np.where(np.arange(400) % 7 == i % 7, 100, 0).astype(np.int8)
    return reg.serialize(msg, ROBOT)


def _result(reg, i: int) -> bytes:
    msg = reg.new(RESULT, scenario_id=i, objectives=[float(i), 0.5], failed=bool(i % 2),
                  failure_kind=1 if i % 2 else 0, detail=f"result {i}")
    return reg.serialize(msg, RESULT)


# --- QoS text ------------------------------------------------------------------------------------
def test_offered_qos_yaml_is_jazzy_rosbag2_form():
    text = qos.to_offered_qos_yaml(qos.LATCHED)
    assert not text.endswith("\n")  # yaml-cpp's Dump of a sequence, as rosbag2 stores it
    (profile,) = yaml.safe_load(text)
    assert profile == {
        "history": "keep_last",
        "depth": 1,
        "reliability": "reliable",
        "durability": "transient_local",
        "deadline": {"sec": 9223372036, "nsec": 854775807},
        "lifespan": {"sec": 9223372036, "nsec": 854775807},
        "liveliness": "automatic",
        "liveliness_lease_duration": {"sec": 9223372036, "nsec": 854775807},
        "avoid_ros_namespace_conventions": False,
    }
    for q in (qos.DEFAULT, qos.LATCHED, qos.STREAM, qos.Qos(reliable=False, depth=5)):
        (parsed,) = parse_qos(yaml.safe_load(qos.to_offered_qos_yaml(q)))  # rosbags' rosbag2 parser
        assert parsed.history == QosHistory.KEEP_LAST and parsed.depth == q.depth
        assert parsed.reliability == (QosReliability.RELIABLE if q.reliable else QosReliability.BEST_EFFORT)
        assert parsed.durability == (QosDurability.TRANSIENT_LOCAL if q.transient_local else QosDurability.VOLATILE)


# --- writing and reading back ------------------------------------------------------------------------
def _write_sample(reg, path: Path, n: int = 40, compression: str = "zstd", chunk_size: int = 1 << 20):
    with McapLog(path, compression=compression, chunk_size=chunk_size) as log:
        robots = log.add_channel("/ambiegen/robot/scenarios", ROBOT, qos.LATCHED)
        results = log.add_channel("/ambiegen/results", RESULT, qos.DEFAULT)
        log.add_channel("/ambiegen/status", STATUS, qos.DEFAULT)  # declared, never written
        assert log.add_channel("/ambiegen/results", RESULT, qos.DEFAULT) == results
        with pytest.raises(ValueError):
            log.add_channel("/ambiegen/results", ROBOT, qos.DEFAULT)
        log.add_metadata("ambiegen_run", {"run_id": "run-1", "config_json": '{"problem": "robot"}'})
        for i in range(n):
            log.write(robots, _robot(reg, i), 1_000 + 10 * i)
            log.write(results, memoryview(_result(reg, i)), 1_005 + 10 * i, publish_time_ns=1_001 + 10 * i)
        assert log.counts() == {"/ambiegen/robot/scenarios": n, "/ambiegen/results": n, "/ambiegen/status": 0}
    return log


@pytest.mark.parametrize("compression", ["zstd", "lz4", "none"])
def test_rosbags_reads_back_topics_types_and_messages(reg, tmp_path, compression):
    path = tmp_path / "run.mcap"
    log = _write_sample(reg, path, compression=compression)
    log.close()  # idempotent
    with pytest.raises(ValueError):
        log.write(1, b"\x00\x01\x00\x00", 0)
    with AnyReader([path]) as reader:
        topics = {c.topic: (c.msgtype, c.msgcount) for c in reader.connections}
        assert topics == {
            "/ambiegen/robot/scenarios": (ROBOT, 40),
            "/ambiegen/results": (RESULT, 40),
            "/ambiegen/status": (STATUS, 0),
        }
        latched = next(c for c in reader.connections if c.topic == "/ambiegen/robot/scenarios")
        assert latched.ext.offered_qos_profiles[0].durability == QosDurability.TRANSIENT_LOCAL
        seen = []
        for conn, stamp, raw in reader.messages():
            msg = reader.deserialize(raw, conn.msgtype)  # uses the schema text stored in the file
            if conn.msgtype == ROBOT:
                seen.append(("robot", msg.meta.scenario_id, stamp))
                assert raw == _robot(reg, msg.meta.scenario_id)
            else:
                seen.append(("result", msg.scenario_id, stamp))
                assert msg.detail == f"result {msg.scenario_id}"
        assert sorted(seen, key=lambda s: s[2]) == [
            item for i in range(40) for item in (("robot", i, 1_000 + 10 * i), ("result", i, 1_005 + 10 * i))
        ]


def test_records_carry_ros2_profile_schemas_qos_hash_and_metadata(reg, tmp_path):
    path = tmp_path / "run.mcap"
    _write_sample(reg, path, n=5)
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        assert reader.get_header().profile == "ros2"
        assert reader.get_header().library.startswith("ambiegen-ros ")
        summary = reader.get_summary()
        assert summary.statistics.message_count == 10 and summary.statistics.channel_count == 3
        schemas = {s.name: s for s in summary.schemas.values()}
        assert set(schemas) == {ROBOT, RESULT, STATUS}  # one schema per type
        assert all(s.encoding == "ros2msg" for s in schemas.values())
        assert schemas[ROBOT].data.decode() == reg.msgdef(ROBOT)
        for channel in summary.channels.values():
            assert channel.message_encoding == "cdr"
            typename = summary.schemas[channel.schema_id].name
            assert channel.metadata["topic_type_hash"] == reg.type_hash(typename)
            expected = qos.LATCHED if channel.topic.endswith("scenarios") else qos.DEFAULT
            assert channel.metadata["offered_qos_profiles"] == qos.to_offered_qos_yaml(expected)
        (meta,) = list(reader.iter_metadata())
        assert meta.name == "ambiegen_run" and meta.metadata["run_id"] == "run-1"
        # Foxglove's ROS 2 decoder reads the same file from the schema text alone
        decoded = [(ch.topic, m.log_time, d) for _, ch, m, d in reader.iter_decoded_messages()]
        assert len(decoded) == 10
        results = [d for topic, _, d in decoded if topic == "/ambiegen/results"]
        assert [r.scenario_id for r in results] == list(range(5))
        assert results[3].failed is True and list(results[3].objectives) == [3.0, 0.5]


def test_metadata_values_must_be_strings(tmp_path):
    with McapLog(tmp_path / "x.mcap") as log:
        with pytest.raises(TypeError):
            log.add_metadata("bad", {"seed": 3})
        with pytest.raises(KeyError):
            log.write(7, b"\x00\x01\x00\x00", 0)


# --- crash recovery ------------------------------------------------------------------------------------
def _recovered_ids(path: Path) -> list[tuple[str, int]]:
    reg = get_registry()
    out = []
    with AnyReader([path]) as reader:
        for conn, _, raw in reader.messages():
            msg = reg.deserialize(raw, conn.msgtype)
            out.append((conn.topic, msg.meta.scenario_id if conn.msgtype == ROBOT else msg.scenario_id))
    return out


def test_recover_truncated_file_keeps_every_flushed_message(reg, tmp_path):
    path = tmp_path / "live.mcap"
    log = McapLog(path, chunk_size=4096)
    robots = log.add_channel("/ambiegen/robot/scenarios", ROBOT, qos.LATCHED)
    results = log.add_channel("/ambiegen/results", RESULT, qos.DEFAULT)
    log.add_metadata("ambiegen_run", {"run_id": "run-1"})
    expected = []
    for i in range(30):
        log.write(robots, _robot(reg, i), 10 * i)
        log.write(results, _result(reg, i), 10 * i + 5)
        expected += [("/ambiegen/robot/scenarios", i), ("/ambiegen/results", i)]
    log.flush()
    flushed_size, flushed = path.stat().st_size, len(expected)
    i = 30
    while path.stat().st_size < flushed_size + 12_000 and i < 3_000:
        # more chunks reach the disk (through an 8 KB buffer); the last one stays half-built
        log.write(robots, _robot(reg, i), 10 * i)
        log.write(results, _result(reg, i), 10 * i + 5)
        expected += [("/ambiegen/robot/scenarios", i), ("/ambiegen/results", i)]
        i += 1
    snapshot = path.read_bytes()  # what a SIGKILL would leave: no summary, no footer
    log.close()
    assert len(snapshot) >= flushed_size + 12_000

    counts = []
    for cut in sorted({flushed_size, flushed_size + 1, flushed_size + 777, len(snapshot) - 3, len(snapshot)}):
        broken = tmp_path / f"cut{cut}.mcap"
        broken.write_bytes(snapshot[:cut])
        with pytest.raises(Exception):
            with AnyReader([broken]) as reader:  # a truncated file is not readable as is
                list(reader.messages())
        fixed = tmp_path / f"fixed{cut}.mcap"
        report = recover(broken, fixed)
        ids = _recovered_ids(fixed)
        assert ids == expected[: len(ids)]  # a prefix, in order, nothing invented
        assert len(ids) >= flushed and report["messages"] == len(ids) and not report["complete"]
        assert report["metadata"] == 1
        counts.append(len(ids))
        with open(fixed, "rb") as f:
            channels = make_reader(f).get_summary().channels.values()
            assert {c.metadata["topic_type_hash"] for c in channels} == {reg.type_hash(ROBOT), reg.type_hash(RESULT)}
    assert counts == sorted(counts) and counts[-1] > flushed

    report = recover(path, tmp_path / "complete.mcap")  # an intact file loses nothing
    assert report["complete"] and _recovered_ids(tmp_path / "complete.mcap") == expected


def test_recover_skips_a_corrupt_chunk(reg, tmp_path):
    path = tmp_path / "run.mcap"
    _write_sample(reg, path, n=40, chunk_size=4096)
    with open(path, "rb") as f:
        chunks = sorted(make_reader(f).get_summary().chunk_indexes, key=lambda c: c.chunk_start_offset)
    assert len(chunks) > 3
    victim = chunks[1]
    data = bytearray(path.read_bytes())
    data[victim.chunk_start_offset + victim.chunk_length - 20] ^= 0xFF  # inside the compressed data
    path.write_bytes(bytes(data))
    report = recover(path, tmp_path / "fixed.mcap")
    assert report["bad_chunks"] == 1 and report["chunks"] == len(chunks) - 1
    ids = _recovered_ids(tmp_path / "fixed.mcap")
    assert 0 < len(ids) < 80 and len(ids) == report["messages"]


_CHILD = textwrap.dedent(
    """
    import sys
    from ambiegen_ros.ros import qos
    from ambiegen_ros.ros.mcap_log import McapLog
    from ambiegen_ros.ros.types import get_registry
    reg = get_registry()
    log = McapLog(sys.argv[1], chunk_size=2048)
    ch = log.add_channel("/ambiegen/results", "ambiegen_msgs/msg/ScenarioResult", qos.DEFAULT)
    def result(i):
        msg = reg.new("ambiegen_msgs/msg/ScenarioResult", scenario_id=i, detail="x" * 200)
        return reg.serialize(msg, "ambiegen_msgs/msg/ScenarioResult")
    for i in range(100):
        log.write(ch, result(i), i)
    log.flush()
    print("flushed 100", flush=True)
    i = 100
    while True:  # keep writing until killed, never flushing or closing
        log.write(ch, result(i), i)
        i += 1
    """
)


def test_recover_after_sigkill_of_a_writer_process(tmp_path):
    path = tmp_path / "killed.mcap"
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    child = subprocess.Popen([sys.executable, "-c", _CHILD, str(path)], stdout=subprocess.PIPE, text=True, env=env)
    try:
        assert child.stdout.readline().strip() == "flushed 100"
        flushed_size = path.stat().st_size
        deadline = time.monotonic() + 20
        while path.stat().st_size < flushed_size + 20_000 and time.monotonic() < deadline:
            time.sleep(0.01)
    finally:
        child.kill()  # SIGKILL: no finally blocks, no summary
        child.wait(timeout=10)
    fixed = tmp_path / "fixed.mcap"
    report = recover(path, fixed)
    ids = [i for _, i in _recovered_ids(fixed)]
    assert len(ids) >= 100 and ids == list(range(len(ids)))
    assert not report["complete"] and report["messages"] == len(ids)
    shutil.rmtree(tmp_path, ignore_errors=True)
