"""A session survives its stack and its own parts (issue 57), on our ND stack, faults fired on events.

``ambiegen rerun --inject`` signals a process when a run's robot has started moving (never at a
wall-clock time). One invocation takes every class of fault in turn: the stack killed (SIGKILL of
``nd_driver``) and hung (SIGSTOP), and each part of ours killed (the world, the adapter, the
recorder). What must hold: a fault of the stack is FAIL(sut_crashed) naming the process and the
signal, certified like any failure, and the same scenario runs once more on a fresh stack; a fault
of ours is an error record naming the part, and the run is made again once the part is back; every
scenario gets the verdict the in-process full model gives it; every scenario sent is in a bag with
a result; the bag of the killed recorder is rebuilt readable. Also: the recorder stops with one line
when its file can take no more (a file size limit stands in for a full disk: the same OSError path);
and a stack that never comes back stops the command with one line, its last run filed.
"""
from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
from collections import Counter
from pathlib import Path

import pytest
from mcap.reader import make_reader

REPO = Path(__file__).resolve().parents[2]
for extra in (REPO, REPO / "test", REPO / "test" / "ros"):
    if str(extra) not in sys.path:
        sys.path.insert(0, str(extra))

from ambiegen_ros.ros import topics  # noqa: E402
from ambiegen_ros.trials.rows import TrialLog  # noqa: E402
from ambiegen_ros.trials.suite import load_suite  # noqa: E402
from test_trials_nd import CONFIG, PICKED, CASES, ambiegen, expected_verdicts, rerun_acting  # noqa: E402

pytestmark = pytest.mark.skipif(os.environ.get("AMBIEGEN_TRANSPORT", "auto") == "rclpy",
                                reason="these tests drive the DDS backend")
# Runs: 1 case0 (the stack killed), 2 case0 again, 3-4 case1 (world, adapter killed), 5 case1 (the stack
# hung), 6 case1 again, 7 case3 (the recorder killed), 8 case3. A fault of the stack rides on a long run
# (case0 and case1 last seconds of wall time): on case3, whose stall comes within a second, the stack
# may answer before the stop lands, and then the answer is what the run said.
FAULTS = ("nd_driver:SIGKILL@1", "robot_world:SIGKILL@3", "sut_adapter:SIGKILL@4", "nd_driver:SIGSTOP@5",
          "recorder:SIGKILL@7")


def ids(path: Path, topic: str) -> set[tuple[str, int]]:
    """(run id, scenario id) of every scenario or result message in a bag (decoded with rosbags)."""
    from rosbags.highlevel import AnyReader

    out = set()
    with AnyReader([path]) as reader:
        for conn, _, raw in reader.messages([c for c in reader.connections if c.topic == topic]):
            msg = reader.deserialize(raw, conn.msgtype)
            meta = getattr(msg, "meta", msg)
            out.add((meta.run_id, int(meta.scenario_id)))
    return out


def test_every_fault_is_filed_under_its_true_cause_and_the_runs_go_on(tmp_path, ros_domain):
    suite_file = tmp_path / "hazards_suite.json"
    suite_file.write_text(json.dumps({"suite": [{"scenario": CASES["cases"][i]["scenario"], "name": f"case{i}"}
                                                for i in PICKED]}))
    results = tmp_path / "trials.jsonl"
    args = [str(suite_file), "--stack", "nd", "--config", CONFIG, "--results", str(results), "--repeat", "1",
            "--domain-id", str(ros_domain)]
    for fault in FAULTS:
        args += ["--inject", fault]
    run = ambiegen("rerun", *args, timeout=900)
    assert run.returncode == 0, run.stdout[-4000:] + run.stderr[-3000:]
    rows = TrialLog(results).rows()
    expected = expected_verdicts(load_suite([str(suite_file)], CONFIG))
    kinds = [(r["scenario_name"], r["failure_kind"]) for r in rows]
    assert kinds[:2] == [("case0", "sut_crashed"), ("case0", expected_kind(expected, rows[1]))], kinds
    # 1: the stack killed: its failure, named, certified, and a fresh stack
    crash = rows[0]
    assert crash["failed"] and "nd_driver killed by SIGKILL" in crash["detail"], crash["detail"]
    assert crash["reference_check"], "a crash is certified like any failure"
    assert [r["process"] for r in crash["restarts"]] == ["nd_driver"] and crash["restarts"][0]["ok"]
    # 2: the same scenario once more on the fresh stack: the crash did not come back
    assert rows[1]["crash_rerun_of"]["scenario_id"] == crash["scenario_id"]
    # 3-5: the world and the adapter killed: errors of ours, and the run made again
    assert rows[2]["failure_kind"] == "error" and "robot_world killed by SIGKILL (ours" in rows[2]["detail"]
    assert {r["process"] for r in rows[2]["restarts"]} == {"robot_world", "nd_driver"}  # a new world's clock: a new stack
    assert rows[3]["failure_kind"] == "error" and "sut_adapter killed by SIGKILL (ours" in rows[3]["detail"]
    # 5-6: the stack hung (SIGSTOP): its failure too, a fresh stack, and the scenario once more on it
    hung = [r for r in rows if "stopped (hung: SIGSTOP)" in r["detail"]]
    assert len(hung) == 1 and hung[0] is rows[4] and hung[0]["failure_kind"] == "sut_crashed", kinds
    assert [r["process"] for r in hung[0]["restarts"]] == ["nd_driver"]
    assert rows[5]["crash_rerun_of"]["scenario_id"] == hung[0]["scenario_id"]
    # 7: the recorder killed: an error of ours, the run made again into the next bag
    killed = next(r for r in rows if "the recorder" in r["detail"] or "recorder killed" in r["detail"])
    assert killed is rows[6] and killed["failure_kind"] == "error" and killed["restarts"][0]["process"] == "recorder"
    # every scenario got its own verdict in the end, and only our errors were run again
    counted = [r for r in rows if r["failure_kind"] not in ("error", "sut_crashed")]
    assert Counter(r["key"] for r in counted) == {k: 1 for k in expected}
    assert all(r["verdict"] == expected[r["key"]] for r in counted), [(r["scenario_name"], r["verdict"]) for r in counted]
    # the bags: the killed recorder's rebuilt, the next one whole; every scenario sent has a result in them
    folder = Path(rows[0]["bag"]).parent
    readable = [folder / "trials.recovered.mcap", folder / "trials.1.mcap"]
    sent, answered = set(), set()
    for bag in readable:
        sent |= ids(bag, topics.scenarios("robot"))
        answered |= ids(bag, topics.RESULTS)
    assert sent == answered == {(r["run_id"], r["scenario_id"]) for r in rows}
    events = [json.loads(line) for line in (folder / "events.jsonl").read_text().splitlines()]
    assert [e["process"] for e in events if e["event"] == "death"] == ["nd_driver", "robot_world", "sut_adapter",
                                                                       "nd_driver", "recorder"]
    assert all(e["ok"] and e["took_s"] > 0 for e in events if e["event"] == "restart")
    # the crash is drawn with the failures, in the reports the command wrote beside its results
    drawn = {p.name for p in (results.parent / "trials_reports").glob("pictures_*/*.png")}
    assert "case0.png" in drawn and f"picture: {results.parent}" in run.stdout, drawn


def test_a_stack_that_never_comes_back_stops_with_one_line_and_its_last_run_filed(tmp_path, ros_domain):
    """The stack killed on run 2 after its params file went away (once run 1 is filed: an event): the
    relaunch exits at once, so the command stops saying so (no wait for the 300 s bound), with run 2
    filed as the stack's crash and in the bag with its result."""
    suite_file = tmp_path / "hazards_suite.json"
    suite_file.write_text(json.dumps({"suite": [{"scenario": CASES["cases"][i]["scenario"], "name": f"case{i}"}
                                                for i in (0, 1)]}))
    params = tmp_path / "settle.yaml"  # the nodes' params file, as a Nav2 stack has one
    params.write_text("sut_adapter:\n  ros__parameters:\n    settle_time: 0.1\n")
    results, bags = tmp_path / "trials.jsonl", tmp_path / "bags"
    args = [str(suite_file), "--stack", "nd", "--config", CONFIG, "--params", f"settle={params}", "--results",
            str(results), "--bags", str(bags), "--repeat", "1", "--domain-id", str(ros_domain),
            "--inject", "nd_driver:SIGKILL@2"]
    env = {k: v for k, v in os.environ.items() if k != "AMBIEGEN_TRANSPORT"}

    def params_away(_run) -> None:
        for params in bags.glob("*.params.yaml"):
            params.rename(params.with_suffix(".away"))

    code, said = rerun_acting(args, env, lambda line: line.startswith("[1/"), params_away)
    text = "".join(said)
    assert code == 1, text[-3000:]
    stops = [line for line in said if "stopped:" in line]
    assert len(stops) == 1 and "nd_driver did not come back: it exited with status" in stops[0], text[-3000:]
    rows = TrialLog(results).rows()
    assert [r["scenario_name"] for r in rows] == ["case0", "case1"]
    assert rows[1]["failure_kind"] == "sut_crashed" and "nd_driver killed by SIGKILL" in rows[1]["detail"]
    assert rows[1]["restarts"][-1]["ok"] is False and "did not come back" in rows[1]["restarts"][-1]["why"]
    bag = Path(rows[1]["bag"])
    sent, answered = ids(bag, topics.scenarios("robot")), ids(bag, topics.RESULTS)
    assert sent == answered == {(r["run_id"], r["scenario_id"]) for r in rows}


def expected_kind(expected: dict, row: dict) -> str:
    return {"PASS": "none"}.get(expected[row["key"]], expected[row["key"]][5:-1])


def test_the_recorder_stops_with_one_line_when_its_file_can_take_no_more(tmp_path, ros_domain, monkeypatch):
    """A file size limit (RLIMIT_FSIZE: writes beyond it fail with EFBIG, as a full disk fails with
    ENOSPC) on the recorder: it says so, exits with status 3, and its log is rebuilt readable."""
    from ambiegen_ros.ros.mcap_log import recover
    from ambiegen_ros.ros.transport import create_node
    from ambiegen_ros.ros.qos import STREAM

    bag = tmp_path / "full.mcap"
    env = dict(os.environ, ROS_DOMAIN_ID=str(ros_domain), PYTHONUNBUFFERED="1")
    env.pop("AMBIEGEN_TRANSPORT", None)
    limit = 400_000
    proc = subprocess.Popen([sys.executable, "-m", "ambiegen_ros.nodes.recorder", "--ros-args", "-p",
                             f"output:={bag}", "-p", "flush_period:=0.2", "-p", "compression:=none"],
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            preexec_fn=lambda: resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit)))
    monkeypatch.setenv("ROS_DOMAIN_ID", str(ros_domain))  # restored after the test: the next test of this worker has its own
    node = create_node("filler", argv=[])
    try:
        pub = node.create_publisher("std_msgs/msg/String", f"{topics.NAMESPACE}/filler", STREAM)
        node.spin_until(lambda: pub.subscription_count() >= 1, 60)
        for k in range(400):  # about 4 MB in all: ten times what the file may hold
            if proc.poll() is not None:
                break
            pub.publish(node.new_message("std_msgs/msg/String", data=f"{k:05d}" + "x" * 10_000))
            node.spin_until(lambda: False, 0.02)
        out, _ = proc.communicate(timeout=60)
    finally:
        node.shutdown()
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 3, out[-2000:]
    lines = [line for line in out.splitlines() if "cannot write" in line]
    assert len(lines) == 1 and "disk full?" in lines[0] and "ambiegen recover" in lines[0], out[-2000:]
    stats = recover(bag, tmp_path / "rebuilt.mcap")
    assert stats["messages"] > 0
    with open(tmp_path / "rebuilt.mcap", "rb") as fh:
        kept = sum(1 for _, channel, _ in make_reader(fh).iter_messages() if channel.topic.endswith("/filler"))
    assert 0 < kept < 400
