"""AmbieGen-ROS on a real ROS 2 Jazzy: colcon, ros2 run / launch / bag, rclpy nodes, mixed graphs.

Runs only where a Jazzy install is found (see conftest.py: ``AMBIEGEN_ROS_SETUP`` or
``/opt/ros/jazzy/setup.bash``, and ``import rclpy`` must work under it); otherwise every test is
skipped with the reason. ROS commands run as ``bash -c 'source ... && exec ...'`` subprocesses;
the ROS python sees the venv's packages (pymoo, numpy, mcap, shapely, rosbags, scipy) because the
venv's site-packages directory is appended to PYTHONPATH after sourcing (conftest.ros_command).

Each test its own ROS_DOMAIN_ID (``ros_domain``, test/conftest.py), ``ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET``. Tests with
an ``rmw`` parameter run on rmw_cyclonedds_cpp and on rmw_fastrtps_cpp (skipped, with the reason,
when the install has no Fast DDS). Logs are read back with the repo's own reader
(``runlog.summarize``) and independently with rosbags.
"""
from __future__ import annotations

import json
import os
import re
import shlex
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest
from mcap.reader import make_reader
from rosbags.highlevel import AnyReader

from jazzy_env import EXECUTABLES, REPO, RMWS, colcon_build, require, ros_args, ros_env, ros_run, venv_env

for extra in (REPO, REPO / "test" / "ros", REPO / "test" / "sims"):
    if str(extra) not in sys.path:
        sys.path.insert(0, str(extra))

from ambiegen_ros.nodes.replay import recorded_scenarios  # noqa: E402
from ambiegen_ros.problems import get_problem  # noqa: E402
from ambiegen_ros.ros import conversions, topics  # noqa: E402
from ambiegen_ros.ros.conversions import ScenarioMeta  # noqa: E402
from ambiegen_ros.ros.runlog import iter_messages, summarize  # noqa: E402
from ambiegen_ros.sims.full_model import full_model_executor  # noqa: E402

HERE = Path(__file__).resolve().parent
# evaluations of each mixed-graph run (AMBIEGEN_MIXED_EVALUATIONS=2000 runs the size)
MIXED_EVALUATIONS = int(os.environ.get("AMBIEGEN_MIXED_EVALUATIONS", "30"))
MIXED_TIMEOUT = 150 + 0.25 * MIXED_EVALUATIONS  # seconds a mixed-graph run may take


def answered(mcap: Path, run_id: str | None = None) -> dict[str, Any]:
    """The run's summary from the log, asserted complete: every scenario has exactly one result."""
    summary = summarize(mcap, run_id)
    brief = json.dumps({k: v for k, v in summary.items() if k != "outcomes"})
    assert summary["scenarios_published"] > 0, brief
    assert summary["unresolved"] == [], brief
    assert summary["results_received"] == summary["scenarios_published"], brief
    assert summary["timeouts"] == 0 and summary["errors"] == 0 and summary["duplicate_results"] == 0, brief
    return summary


def result_workers(mcap: Path, run_id: str) -> dict[int, str]:
    return {int(m.scenario_id): m.worker for t, _, _, m in iter_messages(mcap, {topics.RESULTS}) if m.run_id == run_id}


def rosbags_counts(mcap: Path) -> dict[str, int]:
    """Messages per topic, every one decoded by rosbags from the schema text stored in the file."""
    counts: dict[str, int] = {}
    with AnyReader([mcap]) as reader:
        for conn, _, raw in reader.messages():
            reader.deserialize(raw, conn.msgtype)
            counts[conn.topic] = counts.get(conn.topic, 0) + 1
    return counts


# --- colcon and the executables ------------------------------------------------------------------
def test_a_clean_clone_builds_with_colcon(jazzy, tmp_path):
    """Committed state only: a fresh `git clone` builds, installs every executable and the launch file."""
    clone = tmp_path / "clone"
    subprocess.run(["git", "clone", "--quiet", str(REPO), str(clone)], check=True, timeout=120)
    install, run, took = colcon_build(clone, tmp_path)
    assert run.returncode == 0, f"{run.stdout[-3000:]}\n{run.stderr[-3000:]}"
    lib = install / "lib" / "ambiegen_ros"
    assert sorted(p.name for p in lib.iterdir()) == sorted(EXECUTABLES)
    assert (install / "share" / "ambiegen_ros" / "launch" / "campaign.launch.py").is_file()
    listed = ros_run("ros2 pkg executables ambiegen_ros", install, venv=False)
    assert listed.returncode == 0, listed.stderr
    assert sorted(line.split()[1] for line in listed.stdout.split("\n") if line.strip()) == sorted(EXECUTABLES)
    shown = ros_run(f"{jazzy['executable']} -c 'from ambiegen_msgs.msg import ScenarioResult, RobotScenario; "
                    "print(ScenarioResult.__slots__)'", install, venv=False)
    assert shown.returncode == 0 and "_scenario_id" in shown.stdout, shown.stderr
    print(f"colcon build of a clean clone: {took:.0f} s")


def test_every_executable_answers_help_under_ros2_run(workspace):
    loop = "; ".join(f"echo '=== {e}'; ros2 run ambiegen_ros {e} --help; echo \"=== rc $?\"" for e in EXECUTABLES)
    run = ros_run(f"bash -c {shlex.quote(loop)}", workspace, timeout=240)
    sections = re.split(r"^=== (\w+)\n", run.stdout, flags=re.M)[1:]
    outputs = dict(zip(sections[::2], sections[1::2]))
    assert sorted(outputs) == sorted(EXECUTABLES), run.stdout[-3000:] + run.stderr[-3000:]
    for exe, out in outputs.items():
        assert out.rstrip().endswith("=== rc 0"), f"{exe}:\n{out}\n{run.stderr[-2000:]}"
        assert "usage:" in out and "Traceback" not in out, f"{exe}:\n{out}"


# --- ros2 launch ---------------------------------------------------------------------------------
LAUNCH_EVALUATIONS = 40


@pytest.fixture(scope="session")
def launched(workspace, tmp_path_factory, session_domains) -> dict[str, Any]:
    """`ros2 launch ambiegen_ros campaign.launch.py` (all rclpy, Cyclone, a domain of its own) run to its end."""
    out = tmp_path_factory.mktemp("launch")
    args = dict(problem="thermostat", algorithm="ga", evaluations=LAUNCH_EVALUATIONS, workers=2, seed=3,
                mode="in_the_loop", output_dir=str(out))
    cmd = "ros2 launch ambiegen_ros campaign.launch.py " + " ".join(shlex.quote(f"{k}:={v}") for k, v in args.items())
    t0 = time.monotonic()
    run = ros_run(cmd, workspace, env=ros_env(session_domains()), timeout=240, cwd=out)
    return {"out": out, "run": run, "elapsed": time.monotonic() - t0, "mcaps": sorted(out.glob("*.mcap"))}


def test_ros2_launch_campaign_ends_by_itself_with_every_scenario_answered(launched):
    run = launched["run"]
    assert run.returncode == 0, f"{run.stdout[-4000:]}\n{run.stderr[-3000:]}"
    assert len(launched["mcaps"]) == 1, launched["mcaps"]
    mcap = launched["mcaps"][0]
    assert re.fullmatch(r"thermostat-ga-s3-[0-9a-f]{6}_\d{8}T\d{6}Z\.mcap", mcap.name), mcap.name
    with open(mcap, "rb") as fh:
        assert make_reader(fh).get_summary() is not None, "the MCAP has no summary section: not finalised"
    summary = answered(mcap)
    assert summary["scenarios_published"] + summary["not_sent"] >= LAUNCH_EVALUATIONS and summary["final_state"] == "done"
    workers = set(result_workers(mcap, summary["run_id"]).values())
    assert len(workers) == 2 and all(w.startswith("thermostat_sim_") for w in workers), workers
    assert summary["run_id"] in run.stdout + run.stderr  # the launch's own summary names the run
    with open(mcap, "rb") as fh:
        meta = {m.name: m.metadata for m in make_reader(fh).iter_metadata()}
    assert meta["ambiegen_recorder"]["middleware"] == "rclpy over rmw_cyclonedds_cpp", meta
    # the rclpy recorder's file read back by rosbags, every message decoded
    counts = rosbags_counts(mcap)
    assert counts[topics.RESULTS] == summary["results_received"] + summary["duplicate_results"]
    assert counts[topics.scenarios("thermostat")] == sum(1 for _ in iter_messages(mcap, {topics.scenarios("thermostat")}))
    print(f"ros2 launch: {summary['scenarios_published']} scenarios in {launched['elapsed']:.0f} s (incl. launch start-up)")


def launch_on_fast_dds(workspace: Path, out: Path, domain: int, timeout: float, **args) -> Path:
    """``ros2 launch ambiegen_ros campaign.launch.py`` with ``args`` on rmw_fastrtps_cpp; its log."""
    cmd = "ros2 launch ambiegen_ros campaign.launch.py " + " ".join(
        shlex.quote(f"{k}:={v}") for k, v in {**args, "output_dir": str(out)}.items())
    run = ros_run(cmd, workspace, env=ros_env(domain, "rmw_fastrtps_cpp"), timeout=timeout, cwd=out)
    assert run.returncode == 0, f"{run.stdout[-4000:]}\n{run.stderr[-3000:]}"
    (mcap,) = out.glob("*.mcap")
    return mcap


def test_ros2_launch_robot_campaign_on_fast_dds(jazzy, workspace, tmp_path, ros_domain):
    """What most Jazzy users run: the launch with RMW_IMPLEMENTATION=rmw_fastrtps_cpp (Jazzy's
    default RMW), on the robot problem, so OccupancyGrid maps and pose timelines cross Fast DDS and
    the suite runs on the full model."""
    require(jazzy, "rmw_fastrtps_cpp")
    mcap = launch_on_fast_dds(workspace, tmp_path, ros_domain, 300, problem="robot", algorithm="random",
                              evaluations=30, workers=2, seed=4, mode="surrogate")
    summary = answered(mcap)
    assert summary["final_state"] == "done"
    assert len(set(result_workers(mcap, summary["run_id"]).values())) == 2
    counts = rosbags_counts(mcap)
    assert counts.get(topics.timeline("robot"), 0) > 0, counts  # the full model's poses came through
    with open(mcap, "rb") as fh:
        meta = {m.name: m.metadata for m in make_reader(fh).iter_metadata()}
    assert meta["ambiegen_recorder"]["middleware"] == "rclpy over rmw_fastrtps_cpp", meta


def test_a_fast_dds_launch_of_2000_evaluations_loses_nothing(jazzy, workspace, tmp_path, ros_domain):
    """Issue 19, part 0: on Fast DDS the launch's log once lost results at the end of a 2,000
    evaluation in-the-loop thermostat campaign (1958 of 2000): nodes ended with samples still in
    flight. Every scenario and result must now be in the finalised log, counted by rosbags."""
    require(jazzy, "rmw_fastrtps_cpp")
    mcap = launch_on_fast_dds(workspace, tmp_path, ros_domain, 900, problem="thermostat", algorithm="ga",
                              evaluations=2000, workers=2, seed=11, mode="in_the_loop")
    summary = answered(mcap)
    counts = rosbags_counts(mcap)
    assert counts[topics.scenarios("thermostat")] == counts[topics.RESULTS] == summary["scenarios_published"], counts
    assert counts.get(topics.not_sent("thermostat"), 0) == summary["not_sent"], counts
    assert summary["scenarios_published"] + summary["not_sent"] == 2000, counts


COUNTER = """
import json, sys, time
import rclpy
from rclpy.qos import QoSProfile, ReliabilityPolicy, DurabilityPolicy
from ambiegen_msgs.msg import ScenarioResult, ThermostatScenario
rclpy.init()
node = rclpy.create_node("bag_play_counter")
counts = {"results": 0, "scenarios": 0}
qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE)
def count(key):
    def on(msg):
        counts[key] += 1
    return on
node.create_subscription(ScenarioResult, "/ambiegen/results", count("results"), qos)
node.create_subscription(ThermostatScenario, "/ambiegen/thermostat/scenarios", count("scenarios"), qos)
print("ready", flush=True)
deadline, expected = time.monotonic() + float(sys.argv[1]), json.loads(sys.argv[2])
while time.monotonic() < deadline and counts != expected:
    rclpy.spin_once(node, timeout_sec=0.1)
print(json.dumps(counts), flush=True)
"""


def test_ros2_bag_info_and_play_of_our_log(jazzy, launched, workspace, graph, tmp_path, ros_domain):
    require(jazzy, "ros2bag", "rosbag2_storage_mcap")
    if not launched["mcaps"]:
        pytest.fail(f"the launch wrote no MCAP:\n{launched['run'].stdout[-3000:]}")
    mcap = launched["mcaps"][0]
    ours = {topics.RESULTS: 0, topics.scenarios("thermostat"): 0}
    for topic, *_ in iter_messages(mcap, set(ours)):
        ours[topic] += 1
    info = ros_run(f"ros2 bag info {shlex.quote(str(mcap))}", workspace, env=ros_env(ros_domain))
    assert info.returncode == 0, info.stderr
    listed = dict(re.findall(r"Topic: (\S+) \| Type: \S+ \| Count: (\d+)", info.stdout))
    for topic, n in ours.items():
        assert int(listed.get(topic, -1)) == n, info.stdout
    assert re.search(r"Storage id:\s+mcap", info.stdout), info.stdout

    expected = {"results": ours[topics.RESULTS], "scenarios": ours[topics.scenarios("thermostat")]}
    script = tmp_path / "counter.py"
    script.write_text(COUNTER)
    g = graph()
    env = ros_env(ros_domain)
    g.ros("counter", f"{jazzy['executable']} {script} 90 {shlex.quote(json.dumps(expected))}", workspace, env)
    g.wait_for("counter", "ready", 60)
    g.ros("play", f"ros2 bag play {shlex.quote(str(mcap))} --delay 3 --disable-keyboard-controls", workspace, env)
    assert g.wait("play", 120) == 0, g.logs()
    assert g.wait("counter", 60) == 0, g.logs()
    got = json.loads(g.log("counter").strip().splitlines()[-1])
    assert got == expected, g.logs()


def test_replay_executes_the_launched_log_on_rclpy_workers(launched, workspace, graph, tmp_path, ros_domain):
    if not launched["mcaps"]:
        pytest.fail("the launch wrote no MCAP")
    mcap, report = launched["mcaps"][0], tmp_path / "replay.json"
    g, env = graph(), ros_env(ros_domain)
    g.ros("worker", f"ros2 run ambiegen_ros thermostat_sim {ros_args(worker_id='replay_worker')}", workspace, env)
    g.ros("replay", f"ros2 run ambiegen_ros replay {ros_args(log=mcap, mode='execute', report=report, subscriber_wait=60.0)}",
          workspace, env)
    assert g.wait("replay", 180) == 0, g.logs()
    assert g.stop("worker") == 0, g.logs()
    data = json.loads(report.read_text())
    assert data["settled"] == data["scenarios"] > 0, data
    assert set(data["changes"]) == {"none"}, data["changes"]  # the same simulator gives the same verdicts


# --- short real runs of every executable, all on rclpy -------------------------------------------
def campaign_on_rclpy(workspace: Path, out: Path, domain: int, timeout: float, flags: str) -> dict[str, Any]:
    """``ros2 run ambiegen_ros ambiegen campaign FLAGS`` (every node on rclpy): its summary, every
    node's exit code asserted 0 (the node logs shown otherwise)."""
    cmd = (f"ros2 run ambiegen_ros ambiegen campaign {flags} --domain-id {domain} --discovery-range SUBNET "
           f"--out {out} --json --timeout {timeout:g}")
    run = ros_run(cmd, workspace, env=ros_env(domain), timeout=timeout + 100)
    logs = "\n".join(f"--- {p.name}\n{p.read_text(errors='replace')[-1500:]}" for p in (out / "logs").glob("*.log"))
    assert run.returncode == 0, f"{run.stdout[-2000:]}\n{run.stderr[-2000:]}\n{logs}"
    summary = json.loads(run.stdout[run.stdout.index("{"):])
    assert all(code == 0 for code in summary["exit_codes"].values()), summary["exit_codes"]
    return summary


@pytest.mark.parametrize("problem", ["vehicle", "robot"])
def test_ambiegen_campaign_under_ros2_run_on_rclpy(problem, workspace, tmp_path, ros_domain):
    """`ros2 run ambiegen_ros ambiegen campaign`: its recorder, generator and sim worker run on the
    ROS python, hence on rclpy (AMBIEGEN_TRANSPORT=rclpy: no fall-back)."""
    out = tmp_path / "camp"
    summary = campaign_on_rclpy(workspace, out, ros_domain, 150,
                                f"--problem {problem} --algorithm random --evaluations 6 --population 3 --workers 1 "
                                "--sim-model surrogate --seed 2")
    assert set(summary["exit_codes"]) == {"recorder", "generator", f"{problem}_sim_0"}
    answered(next(out.glob("*.mcap")), summary["run_id"])


def test_nd_stack_campaign_under_ros2_run_on_rclpy(workspace, tmp_path, ros_domain):
    """Issue 19's done-when on rclpy: `ambiegen campaign --problem robot --stack nd --evaluations 20
    --seed 1`, every node (robot_world, nd_driver, sut_adapter, generator, recorder) on rclpy; every
    scenario answered, the world's topics in the log (counted by rosbags)."""
    out = tmp_path / "nd"
    summary = campaign_on_rclpy(workspace, out, ros_domain, 600, "--problem robot --stack nd --evaluations 20 --seed 1")
    mcap = next(out.glob("*.mcap"))
    answered(mcap, summary["run_id"])
    counts = rosbags_counts(mcap)
    for topic in ("/scan", "/odom", "/tf", "/tf_static", "/cmd_vel", "/plan", "/map"):
        assert counts.get(topic, 0) > 0, (topic, counts)
    with open(mcap, "rb") as fh:
        meta = {m.name: m.metadata for m in make_reader(fh).iter_metadata()}
    assert meta["ambiegen_recorder"]["middleware"].startswith("rclpy"), meta


# --- mixed graphs -------------------------------------------------------------------------------
@pytest.mark.parametrize("rmw", RMWS)
def test_rclpy_generator_and_recorder_with_dds_backend_workers(rmw, jazzy, workspace, graph, tmp_path, ros_domain):
    require(jazzy, rmw)
    domain = ros_domain
    g, env, mcap, run_id = graph(), ros_env(domain, rmw), tmp_path / "mixed.mcap", f"mixed-{rmw}"
    g.ros("recorder", f"ros2 run ambiegen_ros recorder {ros_args(output=mcap)}", workspace, env)
    for k in range(2):
        g.venv(f"dds_worker_{k}", "sim_nodes.thermostat_sim", {"worker_id": f"dds_worker_{k}", "min_result_subscribers": 2},
               venv_env(domain))
    g.ros("generator", "ros2 run ambiegen_ros generator " + ros_args(
        problem="thermostat", algorithm="ga", evaluations=MIXED_EVALUATIONS, population=10, offspring=10, seed=5, run_id=run_id,
        mode="in_the_loop", min_subscribers=3, min_workers=2, subscriber_wait=60.0, result_timeout=60.0), workspace, env)
    t0 = time.monotonic()
    assert g.wait("generator", MIXED_TIMEOUT + 30) == 0, g.logs()
    took = time.monotonic() - t0
    for name in ("dds_worker_0", "dds_worker_1", "recorder"):
        assert g.stop(name) == 0, g.logs()
    answered(mcap, run_id)
    assert set(result_workers(mcap, run_id).values()) == {"dds_worker_0", "dds_worker_1"}
    print(f"{rmw}: rclpy generator + 2 DDS-backend workers: {took:.0f} s")


@pytest.mark.parametrize("rmw", RMWS)
def test_ambiegen_campaign_with_rclpy_workers(rmw, jazzy, workspace, graph, tmp_path, ros_domain):
    require(jazzy, rmw)
    domain = ros_domain
    g, env, out = graph(), ros_env(domain, rmw), tmp_path / "camp"
    for k in range(2):
        name = f"rclpy_worker_{k}"
        g.ros(name, f"ros2 run ambiegen_ros thermostat_sim {ros_args(name, worker_id=name, min_result_subscribers=2)}",
              workspace, env)
    cmd = [sys.executable, "-m", "ambiegen_ros", "campaign", "--problem", "thermostat", "--algorithm", "ga",
           "--evaluations", str(MIXED_EVALUATIONS), "--population", "10", "--offspring", "10", "--mode", "in_the_loop",
           "--workers", "0", "--remote-workers", "2", "--seed", "6", "--domain-id", str(domain),
           "--discovery-range", "SUBNET", "--out", str(out), "--json", "--timeout", str(MIXED_TIMEOUT)]
    t0 = time.monotonic()
    run = subprocess.run(cmd, cwd=REPO, env=venv_env(domain), capture_output=True, text=True, timeout=MIXED_TIMEOUT + 90)
    took = time.monotonic() - t0
    assert run.returncode == 0, f"{run.stdout[-2000:]}\n{run.stderr[-2000:]}\n{g.logs()}"
    summary = json.loads(run.stdout[run.stdout.index("{"):])
    mcap = next(out.glob("*.mcap"))
    answered(mcap, summary["run_id"])
    assert set(result_workers(mcap, summary["run_id"]).values()) == {"rclpy_worker_0", "rclpy_worker_1"}
    for k in range(2):
        assert g.stop(f"rclpy_worker_{k}") == 0, g.logs()
    print(f"{rmw}: ambiegen campaign (DDS backend) + 2 rclpy workers: {took:.0f} s")


# --- the adapter ---------------------------------------------------------------------------------
def test_sut_adapter_against_external_sim_on_rclpy(workspace, graph, tmp_path, ros_domain):
    """external_sim + sut_adapter + generator + recorder, all rclpy; verdicts = the full model's."""
    g, env, mcap = graph(), ros_env(ros_domain), tmp_path / "adapter.mcap"
    common = dict(problem="vehicle", profile="refined", time_scale=40.0)
    g.ros("recorder", f"ros2 run ambiegen_ros recorder {ros_args(output=mcap)}", workspace, env)
    g.ros("external", f"ros2 run ambiegen_ros external_sim {ros_args(**common)}", workspace, env)
    g.ros("adapter", f"ros2 run ambiegen_ros sut_adapter {ros_args(worker_id='sut', min_result_subscribers=2, **common)}",
          workspace, env)
    g.ros("generator", "ros2 run ambiegen_ros generator " + ros_args(
        problem="vehicle", profile="refined", evaluations=60, population=12, seed=4, run_id="adapter",
        min_subscribers=2, min_workers=1, max_in_flight=2, subscriber_wait=60.0, result_timeout=60.0), workspace, env)
    assert g.wait("generator", 180) == 0, g.logs()
    for name in ("adapter", "external", "recorder"):
        assert g.stop(name) == 0, g.logs()
    answered(mcap, "adapter")
    problem_name, run_id, scenarios, outcomes, _seed = recorded_scenarios(mcap)
    assert (problem_name, run_id) == ("vehicle", "adapter") and set(outcomes) == set(scenarios)
    assert set(result_workers(mcap, run_id).values()) == {"sut"}
    problem = get_problem("vehicle", {"profile": "refined"})
    full = full_model_executor(problem)
    for sid, scenario in scenarios.items():
        ref = full.execute(problem.parse(scenario.to_dict()), seed=0)
        assert outcomes[sid].failure_kind == ref.failure_kind, (sid, outcomes[sid].detail, ref.detail)


def fake_nav2_graph(jazzy, workspace, graph, monkeypatch, ros_domain, *fake_args: str, **adapter: Any):
    """A fake navigate_to_pose server (``fake_nav2.py``) driving external_sim, the adapter in
    action mode against it, and this process on the DDS backend in the same domain."""
    if "nav2_msgs" not in jazzy["packages"]:
        pytest.skip("nav2_msgs is not in the install: the adapter imports nav2_msgs.action.NavigateToPose "
                    "(sim_nodes/sut_adapter.py), so no typed navigate_to_pose server can stand in for Nav2")
    from test_adapter import PROFILE  # the DDS-backend driver of test/ros

    g, env = graph(), ros_env(ros_domain)
    common = dict(problem="robot", profile=PROFILE["robot"], time_scale=150.0)
    g.ros("fake_nav2", " ".join([jazzy["executable"], str(HERE / "fake_nav2.py"), "/fake_nav2/goal_pose", *fake_args]),
          workspace, env)
    g.ros("external", f"ros2 run ambiegen_ros external_sim {ros_args(goal_topic='/fake_nav2/goal_pose', **common)}",
          workspace, env)
    # the fake is no lifecycle node and has no costmaps: no readiness check of those, nothing to clear
    g.ros("adapter", "ros2 run ambiegen_ros sut_adapter " + ros_args(
        worker_id="sut", goal_mode="action", nav2_lifecycle_nodes="''", nav2_clear_costmaps="''", **adapter, **common),
        workspace, env)
    g.wait_for("fake_nav2", "navigate_to_pose ready", 60)
    for key, value in venv_env(ros_domain).items():
        monkeypatch.setenv(key, value)
    return g


def test_sut_adapter_nav2_action_mode_against_a_fake_navigate_to_pose(jazzy, workspace, graph, monkeypatch, ros_domain):
    """goal_mode:=action: the goal goes out as a nav2_msgs NavigateToPose goal to a typed rclpy
    action server standing in for Nav2, which hands it to external_sim; with early_verdicts
    odometry gives the verdict."""
    g = fake_nav2_graph(jazzy, workspace, graph, monkeypatch, ros_domain, early_verdicts=True)
    from test_adapter import PROFILE, Driver, easy_robot_elements, scenario

    from ambiegen_ros.ros.transport import create_node

    node = create_node("nav2_test_driver", argv=[])
    try:
        problem = get_problem("robot", {"profile": PROFILE["robot"]})
        driver = Driver(node, problem)
        driver.wait_matched(timeout=60)
        sc = scenario(problem, easy_robot_elements())
        goal = conversions.scenario_message(node.new_message, node.now_ns(), problem, sc,
                                            ScenarioMeta("nav2", 0)).goal.pose.position
        driver.send("nav2", [sc])
        (res,) = driver.wait("nav2", 1, 90)
    finally:
        node.shutdown()
    assert res is not None, g.logs()
    ref = full_model_executor(problem).execute(sc, seed=0)
    assert (res.failure_kind, res.failed) == (ref.failure_kind, ref.failed), (res.detail, ref.detail)
    goals = re.findall(r"^goal (\S+) (\S+) (\S+)$", g.log("fake_nav2"), flags=re.M)
    assert len(goals) == 1, g.logs()
    # the goal the server received is the scenario's goal, in the map frame
    assert (float(goals[0][0]), float(goals[0][1]), goals[0][2]) == (pytest.approx(goal.x, abs=1e-6),
                                                                      pytest.approx(goal.y, abs=1e-6), "map")
    g.wait_for("adapter", "navigate_to_pose finished: succeeded", 30)
    assert res.metrics["nav2_status"] in ("succeeded", "running (cancelled: the oracle decided first)")


def drive_easy_map(g, run_id: str):
    """One easy robot map sent through the fake Nav2 graph by a DDS-backend driver; its result."""
    from test_adapter import PROFILE, Driver, easy_robot_elements, scenario

    from ambiegen_ros.ros.transport import create_node

    node = create_node(f"nav2_{run_id}_driver", argv=[])
    try:
        problem = get_problem("robot", {"profile": PROFILE["robot"]})
        driver = Driver(node, problem)
        driver.wait_matched(timeout=60)
        driver.send(run_id, [scenario(problem, easy_robot_elements())])
        (res,) = driver.wait(run_id, 1, 90)
    finally:
        node.shutdown()
    assert res is not None, g.logs()
    return res


def test_sut_adapter_takes_nav2s_own_abort_as_the_verdict(jazzy, workspace, graph, monkeypatch, ros_domain):
    """goal_mode:=action with its default ``early_verdicts:=false``: Nav2's own result decides. A
    navigate_to_pose server that aborts (error 102) gives FAIL(nav2_aborted) with the code and
    message (the easy map has a clearance route: a failure, not an invalid test), and the early
    verdict is recorded beside it."""
    g = fake_nav2_graph(jazzy, workspace, graph, monkeypatch, ros_domain, "abort")
    res = drive_easy_map(g, "abort")
    assert res.failure_kind == "nav2_aborted" and res.failed, res.detail
    assert "error 102" in res.detail and "failed to make progress" in res.detail
    # metrics travel as text (diagnostic_msgs/KeyValue)
    assert res.metrics["nav2_status"] == "aborted" and int(res.metrics["nav2_error_code"]) == 102
    assert res.metrics["decided_by"] == "stack" and res.metrics["early_verdicts"] == "False"
    assert int(res.metrics["nav2_recoveries"]) == 2  # from the action's feedback
    assert res.metrics["early_verdict"] in ("undecided", "none", "stall", "loiter")
    # refused before any odometry was judged: sent once more, refused again, and that is the verdict
    assert "error 102" in res.metrics["nav2_first_abort"] and g.log("fake_nav2").count("goal ") == 2, g.log("fake_nav2")


def test_a_pass_after_nav2s_recoveries_is_a_near_miss(jazzy, workspace, graph, monkeypatch, ros_domain):
    """Nav2 succeeding after a round of its recovery branch (its feedback's ``number_of_recoveries``)
    is a PASS, recorded as a near miss: the count in the metrics, the words in the detail."""
    g = fake_nav2_graph(jazzy, workspace, graph, monkeypatch, ros_domain, "recover")
    res = drive_easy_map(g, "recover")
    assert res.failure_kind == "none" and not res.failed, res.detail
    assert int(res.metrics["nav2_recoveries"]) == 1 and "a near miss: after 1 recovery" in res.detail, res.detail


def test_a_goal_nav2_refuses_at_once_goes_once_more(jazzy, workspace, graph, monkeypatch, ros_domain):
    """Nav2 refusing its goal before the robot could move (a startup race, not a verdict): the
    adapter sends it once more when the world's clock has run a simulated second (sent again at
    once, a real MPPI refused it again 0.1 s later), and the run is judged on the second; the first
    answer is kept."""
    g = fake_nav2_graph(jazzy, workspace, graph, monkeypatch, ros_domain, "refuse-first", early_verdicts=True)
    res = drive_easy_map(g, "refuse")
    assert not res.failed and res.failure_kind == "none", res.detail
    assert "error 103" in res.metrics["nav2_first_abort"] and "0 poses" in res.metrics["nav2_first_abort"]
    assert "goal refused" in g.log("fake_nav2") and g.log("fake_nav2").count("goal ") == 2, g.log("fake_nav2")
    # no odometry before the fake forwards a goal: the ROS clock (external_sim's /clock) decided
    assert float(res.metrics["nav2_resend_wait_s"]) >= 1.0, res.metrics
