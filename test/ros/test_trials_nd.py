"""``ambiegen rerun`` and ``ambiegen compare`` for real, on our ND stack (no ROS needed).

Each command is a real subprocess that starts ``robot_world``, ``nd_driver``, ``sut_adapter`` and a
recorder over Cyclone DDS, sends the suite's scenarios one at a time and appends a row per run. The
ND stack in lockstep is deterministic, so every run of a scenario must get the in-process full
model's verdict (fed the wire's number formats), N of N; the bag, read back with the mcap library
alone, holds every scenario sent and every result; a second invocation resumes instead of
repeating; a comparison writes its tables and a picture per scenario whose verdict changed.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
from collections import Counter
from pathlib import Path
from typing import Any, Callable

import pytest
from mcap.reader import make_reader

REPO = Path(__file__).resolve().parents[2]

from ambiegen_ros.nodes.replay import recorded_scenarios  # noqa: E402
from ambiegen_ros.problems import get_problem  # noqa: E402
from ambiegen_ros.ros import topics  # noqa: E402
from ambiegen_ros.sims.full_model import full_model_executor  # noqa: E402
from ambiegen_ros.trials import report  # noqa: E402
from ambiegen_ros.trials.rows import TrialLog  # noqa: E402
from ambiegen_ros.trials.suite import load_suite  # noqa: E402
from helpers.wire import wire_emulation  # noqa: E402

pytestmark = pytest.mark.skipif(os.environ.get("AMBIEGEN_TRANSPORT", "auto") == "rclpy",
                                reason="these tests drive the DDS backend")
CASES = json.loads((REPO / "test" / "data" / "robot_hazards_nd.json").read_text())
CONFIG = str(REPO / CASES["config"])
PICKED = (0, 1, 3)  # a pass, a collision with a person, a stall


def ambiegen(*args: str, timeout: float = 600) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k != "AMBIEGEN_TRANSPORT"}
    return subprocess.run([sys.executable, "-m", "ambiegen_ros", *args], capture_output=True, text=True, cwd=REPO,
                          env=env, timeout=timeout)


def rerun_acting(args: list[str], env: dict, when: Callable[[str], bool], act: Callable[[Any], None],
                 timeout: float = 600) -> tuple[int, list[str]]:
    """``ambiegen rerun ARGS`` with its output read as it comes: ``act(process)`` once, on the first
    line ``when`` accepts (an event, not a time). Returns its exit status and every line it said."""
    run = subprocess.Popen([sys.executable, "-m", "ambiegen_ros", "rerun", *args], cwd=REPO, env=env,
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    said: list[str] = []
    try:
        for line in run.stdout:
            said.append(line)
            if when(line):
                act(run)
                break
        said += run.stdout.readlines()
        return run.wait(timeout=timeout), said
    finally:
        if run.poll() is None:
            run.kill()


@pytest.fixture
def suite_file(tmp_path) -> Path:
    path = tmp_path / "hazards_suite.json"
    path.write_text(json.dumps({"suite": [{"scenario": CASES["cases"][i]["scenario"], "name": f"case{i}"}
                                          for i in PICKED]}))
    return path


def expected_verdicts(suite) -> dict[str, str]:
    problem = get_problem(suite.problem, suite.problem_config)
    full = full_model_executor(problem)
    with wire_emulation():
        return {e.key: full.execute(problem.parse(e.scenario), seed=0).verdict for e in suite.entries}


def test_rerun_gives_every_run_its_verdict_logs_every_scenario_and_resumes(tmp_path, suite_file, ros_domain):
    results = tmp_path / "trials.jsonl"
    args = [str(suite_file), "--stack", "nd", "--config", CONFIG, "--results", str(results),
            "--domain-id", str(ros_domain)]
    run = ambiegen("rerun", *args, "--repeat", "2")
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    suite = load_suite([str(suite_file)], CONFIG)
    expected = expected_verdicts(suite)
    assert sorted(expected.values()) == ["FAIL(collision)", "FAIL(stall)", "PASS"]
    rows = TrialLog(results).rows()
    assert Counter((r["key"], r["repeat"]) for r in rows) == {(k, n): 1 for k in expected for n in (1, 2)}
    for r in rows:
        assert r["verdict"] == expected[r["key"]], r["detail"]
        assert r["label"] == "nd" and r["stack"] == "nd" and r["seed"] == 0 and r["versions"]["ambiegen_ros"]
    hit = next(r for r in rows if r["failure_kind"] == "collision")
    assert hit["contact"]["robot_mps"] > 0.01 and "person_along_mps" in hit["contact"]  # both speeds, in the row
    assert "| case1 | 2 | 0 | 2 of 2: collision 2 |" in run.stdout  # the table: k of N by kind
    # the bag, read by the mcap library alone: every scenario sent and every result, and what ran
    bags = {r["bag"] for r in rows}
    assert len(bags) == 1
    bag = bags.pop()
    with open(bag, "rb") as fh:
        counts = Counter(channel.topic for _, channel, _ in make_reader(fh).iter_messages())
    # a scenario may go out twice: the generator re-sends one whose worker's heartbeat came late on a
    # loaded machine (core/dispatch.py), and the adapter answers the repeat from its record (its result again)
    assert counts[topics.scenarios("robot")] >= 6 and counts[topics.RESULTS] >= 6 and counts[topics.RUN_CONFIG] == 1
    recorded = recorded_scenarios(bag)
    assert len(recorded.scenarios) == 6 and set(recorded.scenarios) == set(recorded.outcomes)
    assert counts["/odom"] > 100
    # the same command again: nothing to make; one more repeat: only that
    again = ambiegen("rerun", *args, "--repeat", "2")
    assert again.returncode == 0 and "0 runs to make (6 already in" in again.stdout, again.stdout[-2000:]
    assert len(TrialLog(results).rows()) == 6
    more = ambiegen("rerun", *args, "--repeat", "3")
    assert more.returncode == 0, more.stderr[-2000:]
    assert sorted(r["repeat"] for r in TrialLog(results).rows()) == [1] * 3 + [2] * 3 + [3] * 3


def test_compare_runs_each_configuration_and_draws_what_changed(tmp_path, suite_file, ros_domain):
    """Our ND robot with a laser all round and a wider berth (a world option and a driver option, one
    file, as a Nav2 fix is): both configurations run, the tables and one picture per changed scenario."""
    wide = tmp_path / "wide.yaml"
    wide.write_text("nd_driver:\n  ros__parameters:\n    sim:\n      avoid_dist: 0.8\n"
                    "robot_world:\n  ros__parameters:\n    sim:\n      fov_deg: 360.0\n      beams: 361\n")
    results, out = tmp_path / "trials.jsonl", tmp_path / "reports"
    run = ambiegen("compare", str(suite_file), "--stack", "nd", "--config", CONFIG, "--results", str(results),
                   "--params", "nd=", "--params", f"wide={wide}", "--repeat", "1", "--out", str(out),
                   "--domain-id", str(ros_domain))
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    rows = TrialLog(results).rows()
    assert Counter(r["label"] for r in rows) == {"nd": 3, "wide": 3}
    # what each run cost: the cores of our nodes and of the stack while it was on (from /proc)
    assert all(r["cpu"]["ours_cores"] > 0 and r["cpu"]["stack_cores"] > 0 for r in rows), [r["cpu"] for r in rows]
    assert all(r["world"] == {"fov_deg": 360.0, "beams": 361} for r in rows if r["label"] == "wide")
    assert all(r["world"] == {} for r in rows if r["label"] == "nd")
    suite = load_suite([str(suite_file)], CONFIG)
    assert [r["verdict"] for r in rows if r["label"] == "nd"] == [expected_verdicts(suite)[e.key]
                                                                  for e in suite.entries]
    changed = report.changed(suite, results, ["nd", "wide"])
    pictures = sorted(out.glob("pictures_*/*.png"))
    assert len(pictures) == len(changed)
    text = next(out.glob("compare_*.md")).read_text()
    assert "What each configuration does against `nd`" in text and "| `wide` |" in text


def test_a_node_that_refuses_its_params_stops_the_configuration_with_its_own_words(tmp_path, suite_file, ros_domain):
    """A node of the session that exits while the stack comes up (here the adapter, given a goal
    mode it does not know) stops the command at once with the node's last line, instead of waiting
    out the start-up bound; nothing is recorded as run."""
    bad = tmp_path / "bad.yaml"
    bad.write_text("sut_adapter:\n  ros__parameters:\n    goal_mode: carrier_pigeon\n")
    results = tmp_path / "trials.jsonl"
    run = ambiegen("rerun", str(suite_file), "--stack", "nd", "--config", CONFIG, "--results", str(results),
                   "--params", f"bad={bad}", "--repeat", "1", "--domain-id", str(ros_domain), timeout=250)
    assert run.returncode == 1, run.stdout[-3000:] + run.stderr[-3000:]
    said = run.stdout + run.stderr
    assert "sut_adapter exited with code 2 while the stack came up" in said, said[-3000:]
    assert "goal_mode: unknown 'carrier_pigeon'" in said
    assert not results.exists() or TrialLog(results).rows() == []


def test_another_sessions_reader_is_waited_out_before_the_stack_starts(tmp_path, suite_file, ros_domain, monkeypatch):
    """An adapter of another session (or what remains of a killed one, until its lease ends) that
    takes scenarios on the domain: the command says so and waits for it to leave before its own
    nodes start, so the scenarios reach our adapter and recorder, not the other one. Every run is
    answered, with the full model's verdict."""
    from ambiegen_ros.ros import topics
    from ambiegen_ros.ros.qos import STREAM
    from ambiegen_ros.ros.transport import create_node

    env = {k: v for k, v in os.environ.items() if k != "AMBIEGEN_TRANSPORT"}
    env.update(ROS_DOMAIN_ID=str(ros_domain), PYTHONUNBUFFERED="1")
    other = subprocess.Popen([sys.executable, "-m", "sim_nodes.sut_adapter", "--ros-args", "-p", "problem:=robot",
                              "-p", "worker_id:=other_session"], env=env, cwd=REPO, stdout=subprocess.DEVNULL,
                             stderr=subprocess.DEVNULL)
    monkeypatch.setenv("ROS_DOMAIN_ID", str(ros_domain))  # restored after the test: the next test of this worker has its own
    node = create_node("probe", argv=[])
    try:
        pub = node.create_publisher(topics.SCENARIO_TYPES["robot"], topics.scenarios("robot"), STREAM)
        assert node.spin_until(lambda: pub.subscription_count() >= 1, 120), "the other adapter never showed up"
    finally:
        node.shutdown()
    results = tmp_path / "trials.jsonl"
    try:
        code, said = rerun_acting([str(suite_file), "--stack", "nd", "--config", CONFIG, "--results", str(results),
                                   "--repeat", "1", "--domain-id", str(ros_domain)], env,
                                  lambda line: "reader(s) of scenarios on ROS domain" in line,
                                  lambda _run: other.kill())  # its reader stays until its lease ends: waited out too
        assert code == 0, "".join(said)[-4000:]
    finally:
        if other.poll() is None:
            other.kill()
    assert any("waiting for 1 reader(s)" in line for line in said), "".join(said)[-3000:]
    rows = TrialLog(results).rows()
    expected = expected_verdicts(load_suite([str(suite_file)], CONFIG))
    assert [r["verdict"] for r in rows] == [expected[e] for e in expected], [r["detail"][:100] for r in rows]


def test_ctrl_c_stops_the_command_and_records_no_lost_run(tmp_path, suite_file, ros_domain):
    """SIGINT while a run is on (sent once the first run is in the results): the command stops with
    status 130 and says how to resume; the results hold the finished runs only, none filed as lost."""
    import signal as signals

    results = tmp_path / "trials.jsonl"
    env = {k: v for k, v in os.environ.items() if k != "AMBIEGEN_TRANSPORT"}
    env["PYTHONUNBUFFERED"] = "1"
    code, said = rerun_acting([str(suite_file), "--stack", "nd", "--config", CONFIG, "--results", str(results),
                               "--repeat", "3", "--domain-id", str(ros_domain)], env,
                              lambda line: line.startswith("[1/9]"),
                              lambda run: run.send_signal(signals.SIGINT), timeout=300)  # the 2nd run has gone out
    assert code == 130, "".join(said)[-3000:]
    assert any("interrupted; the runs made are in" in line for line in said), "".join(said)[-2000:]
    rows = TrialLog(results).rows()
    assert 1 <= len(rows) <= 2 and all(r["failure_kind"] not in ("sim_timeout", "error") for r in rows), \
        [(r["scenario_name"], r["verdict"]) for r in rows]


def test_a_search_on_the_supervised_stack_goes_on_after_a_crash(tmp_path, ros_domain):
    """``ambiegen stack-search`` (issue 57): the search asks, the supervised stack runs each scenario.
    Its driver killed in the 2nd run is that scenario's FAIL(sut_crashed), run once more on a fresh
    stack; the search is told every batch and asks the next, to the end of its budget."""
    import yaml

    config = yaml.safe_load(Path(CONFIG).read_text())
    config.update(population=4, offspring=4)
    small = tmp_path / "search.yaml"
    small.write_text(yaml.safe_dump(config))
    results = tmp_path / "search.jsonl"
    run = ambiegen("stack-search", "--stack", "nd", "--config", str(small), "--algorithm", "ga", "--seed", "3",
                   "--hours", "10", "--evaluations", "12", "--results", str(results),
                   "--domain-id", str(ros_domain), "--inject", "nd_driver:SIGKILL@2")
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    rows = TrialLog(results).rows()
    generations = {r["scenario_name"].split("-")[0] for r in rows}
    assert generations == {"g1", "g2", "g3"}, (  # 12 evaluations: 3 batches of 4
        [(r["scenario_name"], r["verdict"], str(r.get("detail"))[:100]) for r in rows], run.stdout[-3000:])
    assert "generation 1 told" in run.stdout and "generation 2 told" in run.stdout
    crash = next(r for r in rows if r["failure_kind"] == "sut_crashed")
    assert "nd_driver killed by SIGKILL" in crash["detail"] and crash["scenario_name"] == rows[1]["scenario_name"]
    again = [r for r in rows if r.get("crash_rerun_of")]
    assert len(again) == 1 and again[0]["key"] == crash["key"] and again[0]["failure_kind"] != "sut_crashed"
    for name in {r["scenario_name"] for r in rows}:  # each scenario run has a verdict of the stack
        assert any(r["scenario_name"] == name and r["failure_kind"] not in ("error", "sim_timeout") for r in rows)
    assert results.with_name("search_reports").is_dir()
    again_cmd = ambiegen("stack-search", "--stack", "nd", "--config", str(small), "--hours", "1",
                         "--results", str(results))
    assert again_cmd.returncode == 2 and "exists" in again_cmd.stderr  # a search never appends to another's file


def test_a_surrogate_search_runs_its_suite_on_the_stack_best_first(tmp_path, ros_domain):
    """``stack-search --mode surrogate``: the search on the surrogate first, then its suite on the
    supervised stack, best first; the seed gives the suite an in-process search of the same run
    config gives."""
    import yaml

    from ambiegen_ros.core.search import Search
    from ambiegen_ros.run_config import make_run

    config = yaml.safe_load(Path(CONFIG).read_text())
    config.update(population=10, offspring=10, evaluations=60, suite_size=3, restarts=1)
    small = tmp_path / "surrogate.yaml"
    small.write_text(yaml.safe_dump(config))
    results = tmp_path / "search.jsonl"
    run = ambiegen("stack-search", "--stack", "nd", "--config", str(small), "--mode", "surrogate", "--seed", "5",
                   "--hours", "10", "--results", str(results), "--domain-id", str(ros_domain))
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    problem, settings = make_run("robot", small, algorithm="ga", seed=5)
    suite = [item["scenario"] for item in Search(problem, settings, valid_samples=True).run().suite if item["valid"]]
    rows = TrialLog(results).rows()
    assert [r["scenario_name"] for r in rows] == [f"s-{i}" for i in range(len(suite))]
    assert [r["scenario"] for r in rows] == suite and all(r["verdict"] for r in rows)
    record = json.loads(results.with_name("search.search.json").read_text())  # what a rerun of the search needs
    assert record["seed"] == 5 and record["mode"] == "surrogate" and record["search"]["population"] == 10
