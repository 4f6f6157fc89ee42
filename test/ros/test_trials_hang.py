"""A stack that holds its robot is not hung; a frozen one is (issue 70).

Nav2's collision monitor stops publishing ``/cmd_vel`` once it holds the robot still, while the rest
of Nav2 goes on: ``ambiegen compare`` called that a crash, 2 of 2. A session now calls a hang only
when every sign of life the stack shows on the graph (``/cmd_vel``, the navigator's action feedback)
has been silent for ``hang_after`` s, or when a node of the stack stops being scheduled (its threads
run no more: ``supervise.Scheduling``), whatever the topics say.

The runs here are real: ``run_trials`` starts our world, adapter and recorder and a FAKE Nav2
(test/helpers/fake_nav2_dds.py, started as ``--stack bringup`` starts Nav2, through a fake ``ros2``
on PATH) whose navigator sends feedback while its controller holds the robot (no ``/cmd_vel``) or freezes.
``hang_after`` is 4 s; faults fire on events (the robot moving, the controller's own count of commands).
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]

from ambiegen_ros.nav2_params import OVERLAY_FILE, package_file  # noqa: E402
from ambiegen_ros.ros.transport import dds_backend  # noqa: E402
from ambiegen_ros.trials.configs import StackConfig, prepare  # noqa: E402
from ambiegen_ros.trials.faults import parse_fault  # noqa: E402
from ambiegen_ros.trials.rows import TrialLog  # noqa: E402
from ambiegen_ros.trials.runner import TrialSettings, run_trials  # noqa: E402
from ambiegen_ros.trials.suite import load_suite  # noqa: E402
from ambiegen_ros.trials.reruns import starved  # noqa: E402
from ambiegen_ros.trials.supervise import SCHEDULED_FLOOR_S, Scheduling, Watch  # noqa: E402

pytestmark = pytest.mark.skipif(os.environ.get("AMBIEGEN_TRANSPORT", "auto") == "rclpy"
                                or not dds_backend.is_available(), reason="these tests drive the DDS backend")
CASES = json.loads((REPO / "test" / "data" / "robot_hazards_nd.json").read_text())
CONFIG = str(REPO / CASES["config"])
PARAMS = REPO / "config" / "nav2" / "pioneer_navfn_dwb.yaml"
FAKE_ROS2 = REPO / "test" / "helpers" / "fake_nav2"
HANG_AFTER = 4.0  # beyond the adapter's crash_grace (2 s), in which a run that Nav2 ended still waits


def run_on_fake_nav2(tmp_path: Path, ros_domain: int, controller: str, patience_s: float,
                     inject: tuple[str, ...] = ()) -> tuple[list[dict], Path, list[dict]]:
    """One scenario (a pass on our robot) on the fake Nav2, run as ``ambiegen rerun --stack ours``
    runs it on Jazzy's bringup: (rows, the session's folder, its events)."""
    suite_file = tmp_path / "suite.json"
    suite_file.write_text(json.dumps({"suite": [{"scenario": CASES["cases"][0]["scenario"], "name": "case0"}]}))
    results, bags = tmp_path / "trials.jsonl", tmp_path / "bags"
    bags.mkdir()
    env = {"PATH": f"{FAKE_ROS2}{os.pathsep}{os.environ['PATH']}", "FAKE_ROS2_PYTHON": sys.executable,
           "FAKE_NAV2_CONTROLLER": controller, "FAKE_NAV2_PATIENCE_S": str(patience_s), "AMBIEGEN_TRANSPORT": "dds"}
    settings = TrialSettings(stack="bringup", results=results, bags=bags, repeat=1, domain_id=ros_domain,
                             hang_after=HANG_AFTER, start_timeout=120.0, ready_timeout=120.0,
                             faults=[parse_fault(f) for f in inject], extra_env=env)
    # The world's silence rule (starved_world_gap_s) is off here, explicitly; it stays on in the product
    # and in test_timing_starved.py. These tests are about the hang watch, and on a loaded machine (the
    # suite's two workers) our world can stall longer than 0.35 s while Nav2 drives (4 of 6 runs of two
    # stacks beside two busy loops, docs/results/nav2/load.md): such runs are starved and run again, and
    # max_errors of them in a row stop the configuration (StackStopped), which is no hang
    quiet_world = tmp_path / "no_world_rule.yaml"
    quiet_world.write_text("sut_adapter:\n  ros__parameters:\n    starved_world_gap_s: 0.0\n")
    prepared = prepare(StackConfig("fake", (str(PARAMS), str(quiet_world))), "bringup",
                       str(package_file(*OVERLAY_FILE)), 1.0, bags)
    said: list[str] = []
    run_trials(load_suite([str(suite_file)], CONFIG), [prepared], settings, say=said.append)
    everything = TrialLog(results).rows()
    assert everything, "\n".join(said)
    folder = Path(everything[0]["bag"]).parent
    # a run the machine starved (a goal acknowledged after 1 s, say: seen with the suite's two workers)
    # is an error record of its own, run again at once, never a run of the stack: not these tests' subject
    rows = [r for r in everything if not starved(r)]
    events = [json.loads(line) for line in (folder / "events.jsonl").read_text().splitlines()] \
        if (folder / "events.jsonl").exists() else []
    return rows, folder, events


def held_for(log: Path) -> list[float]:
    """Seconds without a command before the fake navigator gave up, per goal (its log's own words)."""
    return [float(line.split("for ")[1].split(" s")[0]) for line in log.read_text().splitlines()
            if line.startswith("aborted: no command for")]


def test_a_held_robot_with_live_feedback_is_no_crash(tmp_path, ros_domain, session_env):
    """The controller stops commanding once the robot moved a little (held), the navigator's
    feedback goes on, and the navigator ends the goal itself (105) after 2 x hang_after without a
    command: the run is the stack's result, no death, no restart."""
    rows, folder, events = run_on_fake_nav2(tmp_path, ros_domain, "hold", 2 * HANG_AFTER)
    assert len(rows) == 1, [r["detail"] for r in rows]
    row = rows[0]
    assert row["failure_kind"] != "sut_crashed" and "stopped" not in row["detail"], row["detail"]
    assert row["nav2_error_code"] == 105, (row["nav2_status"], row["detail"])  # the stack's own end
    assert not [e for e in events if e["event"] in ("death", "restart")], events
    # what the watch faced: commands during the run, then none for longer than hang_after
    held = held_for(folder / "logs" / "nav2.log")
    assert held and held[-1] > HANG_AFTER, held  # one hold per goal (a starved run's goal held too)
    from mcap.reader import make_reader

    with open(row["bag"], "rb") as fh:
        commands = sum(1 for _, channel, _ in make_reader(fh).iter_messages() if channel.topic == "/cmd_vel")
    assert commands > 0


def test_a_stopped_controller_is_a_crash_while_the_navigator_still_talks(tmp_path, ros_domain, session_env):
    """SIGSTOP of the controller once the robot moves: FAIL(sut_crashed) naming it, one death (the
    scheduling rule leaves a stopped process to the watch that names it so); the rerun on a fresh
    stack is held, not hung, and ends by the navigator's own result."""
    rows, _, events = run_on_fake_nav2(tmp_path, ros_domain, "hold", 2 * HANG_AFTER,
                                       inject=("controller_server:SIGSTOP@1",))
    assert [r["failure_kind"] for r in rows][:1] == ["sut_crashed"], [r["detail"] for r in rows]
    assert "controller_server stopped (hung: SIGSTOP)" in rows[0]["detail"], rows[0]["detail"]
    assert len(rows) == 2 and rows[1]["failure_kind"] != "sut_crashed" and rows[1]["nav2_error_code"] == 105, \
        [r["detail"] for r in rows]
    deaths = [(e["process"], e["what"]) for e in events if e["event"] == "death"]
    assert deaths == [("controller_server", "stopped (hung: SIGSTOP)")], deaths


def test_a_controller_that_stops_being_scheduled_is_a_crash_whatever_the_topics_say(tmp_path, ros_domain,
                                                                                     session_env):
    """The controller's process freezes (not a signal's stop: state S, no CPU), the navigator's
    feedback goes on and it never gives up: only the scheduling rule can end the run, as the
    stack's crash, and on the fresh stack the same crash comes back."""
    rows, _, events = run_on_fake_nav2(tmp_path, ros_domain, "freeze", 0.0)
    assert [r["failure_kind"] for r in rows] == ["sut_crashed", "sut_crashed"], [r["detail"] for r in rows]
    assert all("controller_server stopped being scheduled (hung: no CPU time for" in r["detail"] for r in rows), \
        [r["detail"] for r in rows]
    deaths = [e["process"] for e in events if e["event"] == "death"]
    assert deaths == ["controller_server", "controller_server"], events


class Group:
    """What ``Watch`` and ``Scheduling`` read of a ``campaign.ProcessGroup``: named processes, a log folder."""

    def __init__(self, log_dir: Path):
        self.procs: dict[str, subprocess.Popen] = {}
        self.log_dir = log_dir

    def start(self, name: str, argv: list[str], env: dict) -> subprocess.Popen:
        self.procs[name] = subprocess.Popen(argv, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                            start_new_session=True)
        return self.procs[name]


def test_an_idle_node_is_scheduled_and_a_process_that_runs_no_more_is_not(tmp_path, ros_domain):
    """Real processes: an idle DDS node of ours (behind a wrapper that only waits for it, as ``ros2
    run`` does), one that sleeps for ever, and one stopped by SIGSTOP. Only the sleeper is called
    unscheduled, once; the wrapper's waiting is no hang; the stopped one is the watch's to name."""
    env = dict(os.environ, ROS_DOMAIN_ID=str(ros_domain), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    env.pop("AMBIEGEN_TRANSPORT", None)
    idle = "from ambiegen_ros.ros.transport import create_node\ncreate_node('idle_probe', argv=[]).spin()"
    group = Group(tmp_path)
    wrapped = ["/bin/sh", "-c", f'"{sys.executable}" -c "$0"; :', idle]  # sh waits on its child, as ros2 run
    group.start("behavior_server", wrapped, dict(env, PYTHONPATH=str(REPO)))
    group.start("planner_server", [sys.executable, "-c", "import time\nwhile True: time.sleep(3600)"], env)
    stopped = group.start("controller_server", [sys.executable, "-c", idle], dict(env, PYTHONPATH=str(REPO)))
    watch, scheduling = Watch(group), Scheduling()
    try:
        stopped.send_signal(signal.SIGSTOP)
        found: list = []
        deadline = time.monotonic() + 60
        while not any(d.process == "planner_server" for d in found) and time.monotonic() < deadline:
            found += scheduling.poll(group, "run 1", SCHEDULED_FLOOR_S)
            time.sleep(0.2)
        for _ in range(5):  # a few more looks: each process once
            found += scheduling.poll(group, "run 1", SCHEDULED_FLOOR_S)
            time.sleep(0.2)
        assert [(d.process, d.part, d.group) for d in found] == [("planner_server", "stack", "planner_server")], found
        assert found[0].what.startswith("stopped being scheduled (hung: no CPU time for")
        assert [d.process for d in watch.poll()] == ["controller_server"]  # the stop: the watch's, named so
        # a new run starts every clock afresh: the sleeper is not called again at once
        assert scheduling.poll(group, "run 2", SCHEDULED_FLOOR_S) == []
    finally:
        for proc in group.procs.values():
            for sig in (signal.SIGCONT, signal.SIGKILL):  # the wrapper's child too
                os.killpg(proc.pid, sig)
            proc.wait()
