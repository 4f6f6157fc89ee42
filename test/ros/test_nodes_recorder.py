"""The recorder node interrupted, as a real process over real DDS (Cyclone from PyPI): SIGINT mid
run leaves a valid MCAP, a stopped recorder still takes what was on its way, and after SIGKILL
``ambiegen recover`` keeps everything that was flushed. Each test runs its nodes on its own
ROS_DOMAIN_ID (``ros_domain``); every wait ends on an event and its bound is a safety net.
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

import numpy as np  # noqa: E402
import pytest  # noqa: E402
from mcap.exceptions import McapError  # noqa: E402
from mcap.reader import make_reader  # noqa: E402

from ambiegen_ros.problems import get_problem  # noqa: E402
from ambiegen_ros.ros import conversions, topics  # noqa: E402
from ambiegen_ros.ros.conversions import ScenarioMeta  # noqa: E402
from ambiegen_ros.ros.mcap_log import recover  # noqa: E402
from ambiegen_ros.ros.qos import LATCHED, STREAM  # noqa: E402
from ambiegen_ros.ros.types import get_registry  # noqa: E402
from helpers.node_runs import _env, _read_run  # noqa: E402

pytestmark = pytest.mark.skipif(
    os.environ.get("AMBIEGEN_TRANSPORT", "auto") == "rclpy", reason="these tests drive the DDS backend"
)


# --- 7: the recorder interrupted ----------------------------------------------------------------------
def test_sigint_to_recorder_mid_run_leaves_a_valid_mcap(nodes_factory, test_node, tmp_path, ros_domain):
    domain = ros_domain
    nodes = nodes_factory(domain)
    mcap = tmp_path / "sigint.mcap"
    watcher = test_node("sigint_watch", domain)
    seen = {"results": 0}
    watcher.create_subscription(topics.RESULT_TYPE, topics.RESULTS, lambda m: seen.__setitem__("results", seen["results"] + 1), STREAM)
    recorder = nodes.start("recorder", "ambiegen_ros.nodes.recorder", output=str(mcap), flush_period=5.0)
    nodes.start("w", "sim_nodes.thermostat_sim", worker_id="w", model="surrogate", min_result_subscribers=2)
    gen = nodes.start(
        "generator", "ambiegen_ros.nodes.generator", problem="thermostat", algorithm="ga", mode="in_the_loop",
        evaluations=50000, population=50, offspring=50, seed=1, run_id="sigint-run", min_subscribers=2, min_workers=1,
    )
    assert watcher.spin_until(lambda: seen["results"] >= 40, 300), nodes.log("generator")[-2000:]
    recorder.send_signal(signal.SIGINT)
    assert nodes.wait("recorder", 60) == 0
    assert gen.poll() is None  # the run was still going
    nodes.stop("generator")
    nodes.stop("w")

    with open(mcap, "rb") as fh:
        reader = make_reader(fh)
        summ = reader.get_summary()
        assert summ is not None and summ.statistics.message_count > 0  # finalised: summary + footer
        meta = {m.name: m.metadata for m in reader.iter_metadata()}
    assert meta["ambiegen_run"]["run_id"] == "sigint-run"
    run = _read_run(mcap)  # rosbags reads every message
    assert len(run["config"]) == 1 and len(run["scenarios"]) >= 40
    assert len(run["results"]) >= 20  # the flush period was 5 s: all of this came from the final close
    assert sum(c.msgcount for c in run["connections"].values()) == summ.statistics.message_count


def test_a_stopped_recorder_takes_what_was_already_on_its_way(nodes_factory, test_node, tmp_path, ros_domain):
    """A burst of results, then SIGINT to the recorder the moment the last one is written: every
    result published before the stop is in the log (the recorder drains its readers before it
    closes, and the publisher waits for the recorder's acknowledgements before it goes)."""
    from ambiegen_ros.ros.qos import Qos

    nodes = nodes_factory(ros_domain)
    mcap = tmp_path / "burst.mcap"
    recorder = nodes.start("recorder", "ambiegen_ros.nodes.recorder", output=str(mcap), discover=False)
    node = test_node("burst", ros_domain)
    pub = node.create_publisher(topics.RESULT_TYPE, topics.RESULTS, Qos(reliable=True, depth=10, keep_all=True))
    assert node.spin_until(lambda: pub.subscription_count() >= 1, 120), nodes.log("recorder")  # a safety net
    make, burst = node.new_message, 3000
    before = time.time_ns()
    for i in range(burst):
        pub.publish(make(topics.RESULT_TYPE, run_id="burst", scenario_id=i, worker="w", detail="x" * 200))
    after = time.time_ns()
    recorder.send_signal(signal.SIGINT)
    node.finish_io(ack_s=60.0)  # this side: until the recorder acknowledged all (a safety net of a bound)
    assert nodes.wait("recorder", 120) == 0, nodes.log("recorder")
    with open(mcap, "rb") as fh:
        logged = [(get_registry().deserialize(m.data, topics.RESULT_TYPE).scenario_id, m.publish_time, m.log_time)
                  for _, ch, m in make_reader(fh).iter_messages() if ch.topic == topics.RESULTS]
    ids = [sid for sid, _, _ in logged]
    assert sorted(ids) == list(range(burst)), f"{burst - len(set(ids))} of {burst} results lost"
    # each message's publish time is when this side sent it (in the order sent); its log time when the recorder took it
    sent = [published for _, published, _ in sorted(logged)]
    assert before <= sent[0] and sent == sorted(sent) and sent[-1] <= after
    assert all(published <= log_time for _, published, log_time in logged)


def test_sigkill_to_recorder_then_recover_keeps_everything_flushed(nodes_factory, test_node, tmp_path, ros_domain):
    domain = ros_domain
    nodes = nodes_factory(domain)
    mcap = tmp_path / "killed.mcap"
    flush_period = 0.25
    recorder = nodes.start("recorder", "ambiegen_ros.nodes.recorder", output=str(mcap), flush_period=flush_period)
    node = test_node("sigkill_publisher", domain)
    problem = get_problem("thermostat")
    pub = node.create_publisher(topics.SCENARIO_TYPES["thermostat"], topics.scenarios("thermostat"), STREAM)
    cfg = node.create_publisher(topics.RUN_CONFIG_TYPE, topics.RUN_CONFIG, LATCHED)
    assert node.wait_for_subscribers(pub, 1, 120) and node.wait_for_subscribers(cfg, 1, 120)  # safety nets
    cfg.publish(conversions.run_config_message(node.new_message, node.now_ns(), "kill-rec", {"seed": 77, "problem": "thermostat"}, "test"))
    X = problem.codec.join(*problem.sample(50, np.random.default_rng(1)))
    scenarios = [problem.codec.from_row(r) for r in X]
    sent = 300
    for i in range(sent):
        pub.publish(conversions.scenario_message(node.new_message, node.now_ns(), problem, scenarios[i % 50], ScenarioMeta("kill-rec", i)))
        node.spin_once(0.0)
    # kill once the file on disk holds every message (seen by recovering a copy): an event, so a
    # busy machine only makes the wait longer; the 120 s bound is a safety net
    probe_dir = tmp_path / "probe"
    probe_dir.mkdir()
    deadline, flushed, k = time.monotonic() + 120, 0, 0
    while flushed < sent + 1 and time.monotonic() < deadline:  # + 1: the run config
        copy, k = probe_dir / f"copy{k}.mcap", k + 1
        copy.write_bytes(mcap.read_bytes())
        try:
            flushed = recover(copy, probe_dir / f"fixed{k}.mcap")["messages"]
        except McapError:  # not even the header on disk yet
            flushed = 0
        node.spin_once(flush_period / 2)
    assert flushed == sent + 1, f"{flushed} of {sent + 1} messages flushed to {mcap}"
    os.kill(recorder.pid, signal.SIGKILL)
    assert recorder.wait(5) == -signal.SIGKILL

    fixed = tmp_path / "fixed.mcap"
    cli = subprocess.run([sys.executable, "-m", "ambiegen_ros", "recover", str(mcap), "-o", str(fixed)],
                         cwd=REPO, env=_env(domain), capture_output=True, text=True, timeout=60)
    assert cli.returncode == 0, cli.stderr
    report = json.loads(cli.stdout)
    assert report["complete"] is False and report["metadata"] >= 2
    run = _read_run(fixed)
    ids = [s[0] for s in run["scenarios"]]
    assert ids == list(range(len(ids)))  # a prefix, in order, nothing invented
    assert len(ids) == sent  # everything flushed before the kill survived it
    assert report["messages"] == len(ids) + len(run["config"]) and len(run["config"]) == 1
    with open(fixed, "rb") as fh:
        reader = make_reader(fh)
        summ = reader.get_summary()
        meta = {m.name: m.metadata for m in reader.iter_metadata()}
        hashes = {c.topic: c.metadata.get("topic_type_hash") for c in summ.channels.values()}
    assert meta["ambiegen_run"]["seed"] == "77"
    assert hashes[topics.scenarios("thermostat")] == get_registry().type_hash(topics.SCENARIO_TYPES["thermostat"])
