"""A robot bag holds every run from its first message (issue 70, part 5).

The recorder is told the stack's topics (``extra_topics``); the stack may come up after it. It
says on ``/ambiegen/recorder_status`` when it reads all of them, and the generator sends no
scenario before that (``min_recorders``). Checked on a real ``ambiegen campaign --stack nd`` of 2
scenarios, read back with the ``mcap`` package's reader: each run's result carries the
trajectory the adapter judged, and every state of it must be in the bag with its scan, its
transform and the command that answered it (in lockstep the world steps only on an answer).
Before the fix the recorder looked for the stack's topics once a second while the first scenario
was already on its way: a short campaign's bag could miss the first run's first steps, or hold no
``/scan`` at all (on an idle machine the old bags were whole: a lockstep world re-sends its first
state until it is answered, so the check is also run on the issue's bags cut out of this one).
Node tests pin the race itself: a generator in the loop stays waiting while its recorder waits
for a publisher (the old one sent at once), a topic that appears late is read from the first
message sent after the recorder says ready, and one that never appears ends the wait with one
warning line naming it.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from helpers.sut_graph import Procs

REPO = Path(__file__).resolve().parents[2]
ROBOT_TOPICS = ("/odom", "/scan", "/tf", "/cmd_vel")

pytestmark = pytest.mark.skipif(os.environ.get("AMBIEGEN_TRANSPORT", "auto") == "rclpy",
                                reason="the test's own node runs on the DDS backend")


@pytest.fixture(scope="module")
def campaign(tmp_path_factory, module_domains) -> Path:
    """The issue's command (2 scenarios), as a subprocess on a domain of its own; its directory."""
    out = tmp_path_factory.mktemp("two_scenarios")
    env = dict(os.environ, ROS_DOMAIN_ID=str(module_domains()))
    env.pop("AMBIEGEN_TRANSPORT", None)
    run = subprocess.run([sys.executable, "-m", "ambiegen_ros.cli", "campaign", "--problem", "robot", "--stack", "nd",
                          "--evaluations", "20", "--seed", "1", "--out", str(out), "--overwrite"],
                         cwd=REPO, env=env, capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    return out


def read_bag(path: Path) -> list[tuple[str, int, object]]:
    """(topic, log time, decoded message) of the topics this test reads, in log-time order."""
    from mcap.reader import make_reader

    from ambiegen_ros.ros import topics
    from ambiegen_ros.ros.types import get_registry

    registry = get_registry()
    wanted = [*ROBOT_TOPICS, "/initialpose", topics.RESULTS, topics.scenarios("robot")]
    with open(path, "rb") as fh:
        return [(channel.topic, message.log_time, registry.deserialize(message.data, schema.name))
                for schema, channel, message in make_reader(fh).iter_messages(topics=wanted, log_time_order=True)]


def stamp(topic: str, msg) -> int:
    from ambiegen_ros.ros.conversions import stamp_ns

    return stamp_ns(msg.transforms[0].header if topic == "/tf" else msg.header)


def scenario_windows(rows) -> dict[int, tuple[int, int, object]]:
    """Scenario id -> (log time of its scenario message, log time of its result, the result)."""
    from ambiegen_ros.ros import topics

    sent = {int(m.meta.scenario_id): t for topic, t, m in rows if topic == topics.scenarios("robot")}
    return {int(m.scenario_id): (sent[int(m.scenario_id)], t, m) for topic, t, m in rows if topic == topics.RESULTS}


def judged_states(odom: list[tuple[int, tuple[float, float]]], trajectory: list[tuple[float, float]],
                  after: int) -> list[int] | None:
    """The stamps of the run's states in the bag: the first run of consecutive /odom samples
    (distinct stamps, in stamp order) after stamp ``after`` whose positions are the judged
    trajectory's, pose for pose; None if the bag has no such run (a state missing, or the run's
    start not recorded)."""
    n = len(trajectory)
    for i in range(len(odom) - n + 1):
        if odom[i][0] > after and all(abs(odom[i + k][1][0] - x) < 1e-9 and abs(odom[i + k][1][1] - y) < 1e-9
                                      for k, (x, y) in enumerate(trajectory)):
            return [s for s, _ in odom[i:i + n]]
    return None


def run_problems(rows) -> list[str]:
    """What the bag misses of each run, in the order the scenarios ran: a state the adapter judged
    (its trajectory, pose for pose, from the first), a robot topic with nothing in the run, its scan
    or transform, or the command that answered a step. Empty: every run is whole.

    A run is found by the world's own stamps, not by when the recorder took its messages: a
    recorder that lags on a loaded machine takes a run's last states after its result (a few
    hundred ms later on two busy cores), though the bag holds them all."""
    problems = []
    stamps = {topic: {stamp(topic, msg) for t, _, msg in rows if t == topic} for topic in ROBOT_TOPICS}
    odom = sorted({stamp("/odom", m): (m.pose.pose.position.x, m.pose.pose.position.y)
                   for topic, _, m in rows if topic == "/odom"}.items())
    after = -1
    for sid, (_, _, result) in sorted(scenario_windows(rows).items()):
        trajectory = [(p.pose.position.x, p.pose.position.y) for p in result.trajectory.poses]
        states = judged_states(odom, trajectory, after)
        if states is None:
            problems.append(f"scenario {sid}: /odom misses states of the {len(trajectory)} the adapter judged")
            continue
        after = states[-1]
        for topic in ("/scan", "/tf", "/cmd_vel"):
            wanted = set(states[:-1] if topic == "/cmd_vel" else states)  # the last state is answered by no command
            missing = wanted - stamps[topic]
            if missing == wanted:
                problems.append(f"scenario {sid}: no {topic} in its run")
            elif missing:
                problems.append(f"scenario {sid}: {topic} misses states of the run")
    return problems


def test_each_run_of_a_two_scenario_campaign_is_in_the_bag_from_its_first_state(campaign):
    (bag,) = campaign.glob("*.mcap")
    rows = read_bag(bag)
    windows = scenario_windows(rows)
    assert sorted(windows) == [0, 1], windows
    assert all(len(result.trajectory.poses) > 10 for _, _, result in windows.values())
    assert run_problems(rows) == []
    starts = [windows[sid][2].trajectory.poses[0].pose.position for sid in (0, 1)]
    setups = [m.pose.pose.position for topic, _, m in rows if topic == "/initialpose"]
    assert [(p.x, p.y) for p in starts] == [(p.x, p.y) for p in setups]  # each run starts at its own set-up


def test_the_check_sees_a_bag_that_starts_late_or_has_no_scan(campaign):
    """The issue's bags, cut out of this one: the robot's topics read from a few steps into the
    first run (as a recorder that found them a second late), and no /scan at all."""
    (bag,) = campaign.glob("*.mcap")
    rows = read_bag(bag)
    first = sorted({stamp(topic, m) for topic, _, m in rows if topic == "/odom"})[:3]
    late = [r for r in rows if r[0] not in ROBOT_TOPICS or stamp(r[0], r[2]) not in first]
    assert {p.split(":")[0] for p in run_problems(late)} == {"scenario 0"}
    no_scan = [r for r in rows if r[0] != "/scan"]
    problems = run_problems(no_scan)
    assert all("/scan" in p for p in problems), problems
    assert {f"scenario {sid}: no /scan in its run" for sid in (0, 1)} == set(problems)


def test_campaign_logs_say_the_recorder_was_ready_before_the_first_scenario(campaign):
    recorder = (campaign / "logs" / "recorder.log").read_text()
    generator = (campaign / "logs" / "generator.log").read_text()
    from ambiegen_ros.campaign import STACK_TOPICS

    assert f"reading all {len(STACK_TOPICS)} extra topics" in recorder and "WARN" not in recorder, recorder
    assert "1 recorders ready" in generator, generator


# --- the recorder's side, one node at a time ------------------------------------------------------
def recorder_status(node, statuses: list) -> None:
    from ambiegen_ros.nodes.generator import RECORDER_STATUS_QOS
    from ambiegen_ros.ros import topics

    def on_status(msg) -> None:
        statuses.append(({kv.key: kv.value for kv in msg.values}, int(msg.level[0] if isinstance(msg.level, bytes)
                                                                         else msg.level)))

    node.create_subscription(topics.RECORDER_STATUS_TYPE, topics.RECORDER_STATUS, on_status, RECORDER_STATUS_QOS)


def stop(procs: Procs, name: str) -> int:
    """SIGINT to one node (a recorder closes its MCAP), its exit status."""
    proc = procs.procs[name]
    proc.send_signal(signal.SIGINT)
    return proc.wait(60)


@pytest.fixture()
def driver(tmp_path, monkeypatch, ros_domain):
    """(node subprocesses, a node in this process) on this test's own domain."""
    from ambiegen_ros.ros.transport import create_node

    monkeypatch.setenv("ROS_DOMAIN_ID", str(ros_domain))
    monkeypatch.delenv("AMBIEGEN_TRANSPORT", raising=False)
    procs = Procs(ros_domain, tmp_path / "logs")
    node = create_node("recorder_ready_test", argv=[])
    try:
        yield procs, node
    finally:
        node.shutdown()
        procs.stop_all()


def test_a_topic_that_appears_late_is_read_from_its_first_message_once_the_recorder_says_ready(driver, tmp_path):
    from mcap.reader import make_reader

    from ambiegen_ros.ros.qos import DEFAULT

    procs, node = driver
    mcap = tmp_path / "late.mcap"
    procs.start("recorder", "ambiegen_ros.nodes.recorder", output=str(mcap), extra_topics="/late_chatter",
                topic_wait=600.0)
    statuses: list = []
    recorder_status(node, statuses)
    assert node.spin_until(lambda: statuses, 120), procs.logs()
    assert statuses[-1][0] == {"state": "waiting", "missing": "/late_chatter"}  # no publisher yet: it waits
    pub = node.create_publisher("std_msgs/msg/String", "/late_chatter", DEFAULT)
    assert node.spin_until(lambda: statuses[-1][0]["state"] == "ready", 120), procs.logs()
    assert statuses[-1] == ({"state": "ready", "missing": ""}, 0)
    pub.publish(node.new_message("std_msgs/msg/String", data="first"))  # right away: nothing else waited for
    node.finish_io(ack_s=60.0)
    assert stop(procs, "recorder") == 0, procs.logs()
    with open(mcap, "rb") as fh:
        got = [bytes(message.data) for _, channel, message in make_reader(fh).iter_messages()
               if channel.topic == "/late_chatter"]
    assert len(got) == 1 and b"first" in got[0]


def test_a_topic_that_never_appears_ends_the_wait_with_one_warning_naming_it(driver, tmp_path):
    procs, node = driver
    procs.start("recorder", "ambiegen_ros.nodes.recorder", output=str(tmp_path / "never.mcap"),
                extra_topics="/never_published,/ambiegen/results", topic_wait=1.0)
    statuses: list = []
    recorder_status(node, statuses)
    assert node.spin_until(lambda: statuses and statuses[-1][0]["state"] == "ready", 120), procs.logs()
    assert statuses[-1] == ({"state": "ready", "missing": "/never_published"}, 1)  # WARN: a run topic is no wait
    assert stop(procs, "recorder") == 0, procs.logs()
    warnings = [line for line in procs.log("recorder").splitlines() if "WARN" in line]
    assert len(warnings) == 1 and "/never_published" in warnings[0] and "/ambiegen/results" not in warnings[0], warnings


def test_the_generator_sends_no_scenario_before_its_recorder_reads_every_topic(driver, tmp_path):
    """The generator (in the loop: it would send at once) stays waiting while its recorder waits
    for a topic's publisher, through many status messages, and starts once the publisher is there."""
    from ambiegen_ros.ros import topics
    from ambiegen_ros.ros.qos import DEFAULT, STREAM

    procs, node = driver
    procs.start("recorder", "ambiegen_ros.nodes.recorder", output=str(tmp_path / "gate.mcap"),
                extra_topics="/late_chatter", topic_wait=600.0)
    procs.start("generator", "ambiegen_ros.nodes.generator", problem="thermostat", mode="in_the_loop", evaluations=4,
                population=2, offspring=2, seed=1, min_subscribers=1, min_recorders=1, subscriber_wait=600.0,
                status_period=0.1, exit_when_done=False)
    states: list[str] = []
    sent: list[int] = []
    node.create_subscription(topics.STATUS_TYPE, topics.STATUS, lambda m: states.append(m.state), DEFAULT)
    node.create_subscription(topics.SCENARIO_TYPES["thermostat"], topics.scenarios("thermostat"),
                             lambda m: sent.append(int(m.meta.scenario_id)), STREAM)
    assert node.spin_until(lambda: len(states) >= 20, 120), procs.logs()  # the generator is up, and says why
    assert set(states) == {"waiting"} and sent == [], (states, sent)
    node.create_publisher("std_msgs/msg/String", "/late_chatter", DEFAULT)
    assert node.spin_until(lambda: sent, 120), procs.logs()
    assert "1 recorders ready" in procs.log("generator"), procs.log("generator")


def lagged_copy(bag: Path, out: Path, keep_publish_time: bool) -> Path:
    """The bag as a recorder that fell behind would have written it: the run's /odom messages
    sent before scenario 0's result and logged in the last 0.1 s before it are logged 0.2 s after it (their publish times
    kept, or, as an older recorder wrote, equal to the new log times)."""
    from mcap.reader import make_reader
    from mcap.writer import Writer

    from ambiegen_ros.ros.robot_bag import read_index

    entry = read_index(bag).entries[0]
    with open(bag, "rb") as fh:
        reader = make_reader(fh)
        summary = reader.get_summary()
        messages = [(channel, message) for _, channel, message in reader.iter_messages(log_time_order=True)]
    with open(out, "wb") as fh:
        writer = Writer(fh)
        writer.start(profile="ros2")
        schemas = {sid: writer.register_schema(s.name, s.encoding, s.data) for sid, s in summary.schemas.items()}
        channels = {cid: writer.register_channel(c.topic, c.message_encoding, schemas.get(c.schema_id, 0), c.metadata)
                    for cid, c in summary.channels.items()}
        late = {k for k, (c, m) in enumerate(messages)
                if c.topic == "/odom" and entry.end_ns - 100_000_000 <= m.log_time <= entry.end_ns
                and m.publish_time <= entry.end_pub_ns}  # sent before the result
        assert late
        for k, (channel, message) in enumerate(messages):
            log_time = message.log_time + (300_000_000 if k in late else 0)
            writer.add_message(channels[channel.id], log_time, message.data,
                               message.publish_time if keep_publish_time else log_time)
        writer.finish()
    return out


def test_show_keeps_the_states_a_lagging_recorder_logged_after_the_result(campaign, tmp_path):
    """`ambiegen show` cuts a run at its result: a state logged after it but sent before it is the
    run's (publish time), and an older bag that kept no send time loses it, as before."""
    from ambiegen_ros.ros.robot_bag import read_index, read_run

    (bag,) = campaign.glob("*.mcap")
    whole = read_run(read_index(bag), 0).poses
    kept = read_run(read_index(lagged_copy(bag, tmp_path / "kept.mcap", True)), 0).poses
    lost = read_run(read_index(lagged_copy(bag, tmp_path / "lost.mcap", False)), 0).poses
    assert kept.shape == whole.shape and (kept == whole).all()
    assert len(lost) < len(whole) and set(map(tuple, lost)) <= set(map(tuple, whole))
