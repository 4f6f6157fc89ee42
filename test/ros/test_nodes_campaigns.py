"""The ROS 2 layer end to end through the CLI: campaigns (surrogate, full models, in the loop, a
spent execution budget, the README's first command in small, random search) whose node processes
talk over real DDS (Cyclone from PyPI), each on its own ROS_DOMAIN_ID (``module_domains``,
test/conftest.py). The module's fixture runs them all at once; the tests read each run back from
its MCAP log with independent readers (rosbags' AnyReader decodes with the schema text stored in
the file; the ``mcap`` library reads channel metadata and metadata records). Budgets are small;
every wait ends on an event and its bound is a safety net, never the thing tested.
"""
from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[2]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

import pytest  # noqa: E402
from mcap.reader import make_reader  # noqa: E402
from rosbags.interfaces import QosDurability, QosReliability  # noqa: E402

from ambiegen_ros.problems import get_problem  # noqa: E402
from ambiegen_ros.ros import topics  # noqa: E402
from ambiegen_ros.ros.qos import STREAM  # noqa: E402
from ambiegen_ros.ros.runlog import iter_messages  # noqa: E402
from ambiegen_ros.ros.types import get_registry  # noqa: E402
from ambiegen_ros.sims.outcome import FAILURE_KINDS  # noqa: E402
from helpers.node_runs import _done_line, _env, _read_run  # noqa: E402

pytestmark = pytest.mark.skipif(
    os.environ.get("AMBIEGEN_TRANSPORT", "auto") == "rclpy", reason="these tests drive the DDS backend"
)


INVALID = FAILURE_KINDS["invalid_scenario"]


def _campaign(domain: int, out: Path, problem: str, algorithm: str, evaluations: int, **extra: Any) -> subprocess.Popen:
    args = [sys.executable, "-m", "ambiegen_ros", "campaign", "--problem", problem, "--algorithm", algorithm,
            "--evaluations", str(evaluations), "--seed", "1", "--domain-id", str(domain), "--out", str(out),
            "--timeout", "400"]  # a safety net: four campaigns share a (busy) machine
    for key, value in extra.items():
        args += [f"--{key.replace('_', '-')}", str(value)]
    return subprocess.Popen(args, cwd=REPO, env=_env(domain), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _assert_summary_consistent(summary: dict[str, Any], out: Path) -> None:
    brief = json.dumps({k: v for k, v in summary.items() if k != "outcomes"})
    assert "log_error" not in summary, brief
    assert all(code == 0 for code in summary["exit_codes"].values()), brief
    assert summary["unresolved"] == [], brief
    assert summary["scenarios_published"] > 0, brief
    assert summary["results_received"] == summary["scenarios_published"] == summary["scenario_messages"], brief
    assert sum(summary["outcomes"].values()) == summary["results_received"], brief
    assert summary["timeouts"] == 0 and summary["errors"] == 0 and summary["duplicate_results"] == 0, brief
    assert summary["final_state"] == "done", brief
    assert "ambiegen_run" in summary["metadata"], brief
    done = _done_line((out / "logs" / "generator.log").read_text())
    assert done["run_id"] == summary["run_id"]
    assert (done["scenarios"], done["settled"]) == (summary["scenarios_published"], summary["results_received"]), brief
    assert done["not_sent"] == summary["not_sent"] == sum(summary["not_sent_rules"].values()), brief
    assert "invalid_scenario" not in summary["outcomes"], brief  # what the problem calls invalid is never sent
    assert (done["failures"], done["invalid_tests"], done["timeouts"], done["errors"], done["invalid"]) == (
        summary["failures"], summary["invalid_tests"], summary["timeouts"], summary["errors"], summary["invalid"]
    ), brief


# --- 1-3: campaigns through the CLI ------------------------------------------------------------------
CAMPAIGNS = {
    # name: (unused, problem, algorithm, evaluations, extra CLI options); domains from ``module_domains``
    "thermostat": (None, "thermostat", "ga", 300, {"population": 20, "offspring": 20}),
    "robot": (None, "robot", "nsga2", 200, {"population": 20, "offspring": 20}),
    "vehicle": (None, "vehicle", "nsga2", 200, {"population": 20, "offspring": 20}),
    "in_the_loop": (None, "thermostat", "ga", 240, {"population": 30, "offspring": 30, "mode": "in_the_loop", "workers": 2}),
    # spent before the first generation is through: what was sent finishes, the rest is never sent
    "budget": (None, "thermostat", "ga", 240, {"population": 30, "offspring": 30, "mode": "in_the_loop",
                                               "execution_budget": 0.001}),
    # the README's first command, smaller: refined roads searched in the loop find certified failures
    "demo": (None, "vehicle", "nsga2", 300, {"population": 50, "offspring": 50, "mode": "in_the_loop", "workers": 2,
                                             "profile": "refined"}),
    # random maps in the loop: drawn from every sample, 17 of these 40 would have had no route
    "random": (None, "robot", "random", 40, {"population": 20, "mode": "in_the_loop", "profile": "refined",
                                             "sim_model": "surrogate"}),
}


@pytest.fixture(scope="module")
def campaigns(tmp_path_factory, module_domains):
    """All campaigns at once (each on its own domain): exit code, summary and output folder."""
    root = tmp_path_factory.mktemp("campaigns")
    procs = {}
    for name, (_, problem, algorithm, evaluations, extra) in CAMPAIGNS.items():
        procs[name] = _campaign(module_domains(), root / name, problem, algorithm, evaluations, **extra)
    out = {}
    try:
        for name, proc in procs.items():
            stdout, stderr = proc.communicate(timeout=480)  # a safety net beyond the campaigns' own
            summary_path = root / name / "summary.json"
            summary = json.loads(summary_path.read_text()) if summary_path.exists() else {}
            out[name] = (proc.returncode, summary, root / name, stdout + stderr)
    finally:
        for proc in procs.values():
            if proc.poll() is None:
                proc.kill()
                proc.wait()
    return out


@pytest.mark.parametrize("name", ["thermostat", "robot", "vehicle"])
def test_surrogate_campaign_end_to_end(campaigns, name):
    code, summary, out, output = campaigns[name]
    assert code == 0, output[-3000:]
    _assert_summary_consistent(summary, out)
    evaluations = CAMPAIGNS[name][3]
    assert summary["evaluations"] == evaluations and summary["mode"] == "surrogate"
    suite = re.search(r"executing (\d+) suite scenarios", (out / "logs" / "generator.log").read_text())
    assert suite and int(suite.group(1)) == summary["scenarios_published"]
    assert re.search(rf"^\s+MCAP\s+{re.escape(summary['mcap'])}$", output, re.M) and Path(summary["mcap"]).parent == out


FULL_MODEL_OBJECTIVES = {"thermostat": "thermostat_rmse", "robot": "robot_time", "vehicle": "vehicle_max_oob"}


@pytest.mark.parametrize("name", ["thermostat", "robot", "vehicle"])
def test_campaign_suites_run_on_the_full_models_and_stream_timelines(campaigns, name):
    """The suite is executed by the full-model simulators (their objective, their failure kinds),
    and each execution is streamed as standard messages (Odometry / Temperature) into the log."""
    _, summary, _, _ = campaigns[name]
    problem = CAMPAIGNS[name][1]
    results, samples = [], 0
    for topic, typename, _, msg in iter_messages(summary["mcap"], {topics.RESULTS, topics.timeline(problem)}):
        if topic == topics.RESULTS:
            results.append(msg)
        else:
            samples += 1
            assert typename == topics.TIMELINE_TYPES[problem]
    assert results and samples >= len(results)
    # a scenario that breaks a static reference check is answered INVALID_TEST without being run
    not_run = (FAILURE_KINDS["invalid_scenario"], FAILURE_KINDS["invalid_test"])
    executed = [r for r in results if r.failure_kind not in not_run or len(r.objective_names)]
    assert executed and all(list(r.objective_names) == [FULL_MODEL_OBJECTIVES[problem]] for r in executed)
    allowed = {"thermostat": {"none", "requirement"}, "robot": {"none", "collision", "stall", "loiter", "timeout"},
               "vehicle": {"none", "out_of_lane", "stall", "timeout"}}[problem]
    assert {k for k in summary["outcomes"] if k not in ("invalid_scenario", "invalid_test")} <= allowed
    assert summary["failures"] == sum(r.failed for r in results)


def test_in_the_loop_campaign_end_to_end(campaigns):
    code, summary, out, output = campaigns["in_the_loop"]
    assert code == 0, output[-3000:]
    _assert_summary_consistent(summary, out)
    evaluations = CAMPAIGNS["in_the_loop"][3]
    # in the loop every evaluation is a scenario executed by a sim node, or one the problem calls invalid
    assert summary["scenarios_published"] + summary["not_sent"] == evaluations == summary["evaluations"]
    assert summary["mode"] == "in_the_loop"


def test_a_spent_execution_budget_stops_sending_at_once_and_the_sent_scenarios_finish(campaigns):
    """Not at the end of a generation: a real-time stack given an hour gets an hour plus one run."""
    code, summary, out, output = campaigns["budget"]
    assert code == 0, output[-3000:]
    _assert_summary_consistent(summary, out)  # every scenario published has its result in the log
    log = (out / "logs" / "generator.log").read_text()
    withdrawn = re.search(r"budget spent: (\d+) scenarios not sent", log)
    assert withdrawn, log[-2000:]
    assert 1 <= summary["scenarios_published"] < 30  # one generation is 30 scenarios
    assert summary["scenarios_published"] + summary["not_sent"] + int(withdrawn.group(1)) == 30
    assert f"{withdrawn.group(1)} not sent (budget spent)" in log


def test_a_campaign_draws_each_distinct_certified_failure(campaigns, tmp_path):
    """The README's first command in small: failures found, certified, grouped by what failed and
    where, one picture each, the paths printed; drawing again never draws over a picture."""
    from ambiegen_ros.nodes.gallery import draw_failures

    code, summary, out, output = campaigns["demo"]
    assert code == 0, output[-3000:]
    assert summary["failures"] > 0 and summary["outcomes"].get("out_of_lane", 0) > 0, summary
    pictures = summary["failure_pictures"]
    assert 1 <= summary["distinct_failures"] <= summary["certified_failures"] == summary["failures"]
    assert len(pictures) == min(summary["distinct_failures"], 12)
    assert len({p["signature"] for p in pictures}) == len(pictures)  # distinct failures, described apart
    for picture in pictures:
        path = Path(picture["path"])
        assert path.parent == out / "failures" and path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert pictures[0]["path"] in output  # printed where a newcomer looks
    pair = summary["same_failure_pair"]  # two failures counted as one, side by side, for a reader to judge
    if summary["distinct_failures"] < summary["certified_failures"]:
        assert Path(pair["path"]).read_bytes()[:4] == b"\x89PNG" and pair["path"] in output
        assert pair["scenario_ids"][0] in [p["scenario_id"] for p in pictures]
    else:
        assert pair is None
    before = {p: p.stat().st_mtime_ns for p in (out / "failures").iterdir()}
    again = draw_failures(summary["mcap"], out / "failures")
    assert again["distinct_failures"] == summary["distinct_failures"] and again["failure_pictures"] == []
    assert again["same_failure_pair"] is None  # already drawn: not drawn over
    assert {p: p.stat().st_mtime_ns for p in (out / "failures").iterdir()} == before
    elsewhere = draw_failures(summary["mcap"], tmp_path / "pictures")
    assert [Path(p["path"]).name for p in elsewhere["failure_pictures"]] == [Path(p["path"]).name for p in pictures]


def _scenario_validity(summary: dict[str, Any], scenario_jsons: list[str]) -> list[tuple[bool, str | None]]:
    """What the run's own problem (rebuilt from the run config in the log) says of each scenario."""
    from ambiegen_ros.ros.runlog import read_metadata

    config = json.loads(read_metadata(summary["mcap"])["ambiegen_run"]["config_json"])
    problem = get_problem(config["problem"], config["problem_config"])
    ev = problem.evaluate_scenarios([problem.parse(json.loads(text)) for text in scenario_jsons])
    return list(zip(ev.valid.tolist(), ev.reasons))


def test_a_campaign_never_sends_a_scenario_the_problem_calls_invalid(campaigns):
    """Issue 47: the search's invalid roads (its constraint violations) are logged with their reason
    and told to the search, never sent to a simulator; the summary counts them apart."""
    code, summary, out, output = campaigns["demo"]
    assert code == 0, output[-3000:]
    _assert_summary_consistent(summary, out)
    assert summary["not_sent"] > 0 and summary["invalid"] == 0, summary  # the search makes invalid roads
    assert summary["scenarios_published"] + summary["not_sent"] == summary["evaluations"] == 300
    run = _read_run(Path(summary["mcap"]))
    sent = {s[0] for s in run["scenarios"]}
    unsent = {s[0]: s for s in run["not_sent"]}
    assert len(unsent) == len(run["not_sent"]) == summary["not_sent"]
    assert sorted(sent | set(unsent)) == list(range(300)) and not sent & set(unsent)
    # no simulator got one: every result is a sent scenario's, from a sim worker
    assert {r[0] for r in run["results"]} == sent and len(run["results"]) == len(sent)
    assert all(r[1].startswith("vehicle_sim_") and r[2] != INVALID for r in run["results"])
    # each one in the log with the rule the problem itself names; every sent one is valid by it
    judged = _scenario_validity(summary, [s[1] for s in unsent.values()])
    for (sid, _, valid, reason, attempt, _), (really_valid, rule) in zip(unsent.values(), judged):
        assert not valid and not really_valid and reason == rule and reason and attempt == 0, (sid, reason, rule)
    assert sum(summary["not_sent_rules"].values()) == summary["not_sent"]
    assert re.search(rf"^\s+not sent\s+{summary['not_sent']}\s", output, re.M), output[-3000:]


def test_random_search_in_a_campaign_sends_only_valid_maps(campaigns):
    """Random search draws valid scenarios (as an RQ3 executor's random fill does): its whole budget
    is executed, none is a map without a route."""
    code, summary, out, output = campaigns["random"]
    assert code == 0, output[-3000:]
    _assert_summary_consistent(summary, out)
    assert summary["not_sent"] == 0 and summary["scenarios_published"] == summary["evaluations"] == 40, summary
    run = _read_run(Path(summary["mcap"]))
    scenarios = {}
    for topic, _, _, msg in iter_messages(summary["mcap"], {topics.scenarios("robot")}):
        scenarios[int(msg.meta.scenario_id)] = msg.meta.scenario_json
    assert sorted(scenarios) == list(range(40)) and not run["not_sent"]
    assert all(valid for valid, _ in _scenario_validity(summary, list(scenarios.values())))
    assert json.loads(run["config"][0].config_json)["random_samples"] == "valid"


def test_mcap_read_back_by_rosbags_holds_the_whole_run(campaigns):
    code, summary, out, _ = campaigns["in_the_loop"]
    assert code == 0
    mcap = Path(summary["mcap"])
    run = _read_run(mcap)
    done = _done_line((out / "logs" / "generator.log").read_text())
    run_id = done["run_id"]
    sids = [s[0] for s in run["scenarios"] if s[3] == run_id]
    unsent = [s[0] for s in run["not_sent"] if s[5] == run_id]
    rids = [r[0] for r in run["results"] if r[3] == run_id]
    assert len(sids) == len(set(sids)) == done["scenarios"] == summary["scenario_messages"]
    assert len(unsent) == done["not_sent"]
    assert sorted(sids + unsent) == list(range(done["scenarios"] + done["not_sent"]))  # ids 0..N-1, each once
    assert sorted(rids) == sorted(sids) and len(rids) == done["settled"]
    assert len(run["config"]) == 1 and run["config"][0].run_id == run_id
    assert run["status"] and run["status"][-1].state == "done"
    assert run["status"][-1].results_received == done["settled"]

    reg = get_registry()
    conns = run["connections"]
    scen_topic = topics.scenarios("thermostat")
    for topic in (scen_topic, topics.RESULTS, topics.RUN_CONFIG, topics.STATUS):
        conn = conns[topic]
        assert conn.msgdef.data == reg.msgdef(conn.msgtype)  # the full ros2msg schema text
        (qos,) = conn.ext.offered_qos_profiles
        assert qos.reliability == QosReliability.RELIABLE
    assert "ScenarioHeader meta" in conns[scen_topic].msgdef.data
    assert conns[topics.RUN_CONFIG].ext.offered_qos_profiles[0].durability == QosDurability.TRANSIENT_LOCAL
    assert conns[scen_topic].ext.offered_qos_profiles[0].depth == STREAM.depth

    with open(mcap, "rb") as fh:
        reader = make_reader(fh)
        assert reader.get_header().profile == "ros2"
        summ = reader.get_summary()
        assert summ is not None and summ.statistics.message_count == sum(c.msgcount for c in conns.values())
        for channel in summ.channels.values():
            typename = summ.schemas[channel.schema_id].name
            assert channel.metadata["topic_type_hash"] == reg.type_hash(typename)
            assert channel.metadata["offered_qos_profiles"].startswith("- history: keep_last")
        meta = {m.name: m.metadata for m in reader.iter_metadata()}
    assert meta["ambiegen_run"]["run_id"] == run_id and meta["ambiegen_run"]["seed"] == "1"
    config = json.loads(meta["ambiegen_run"]["config_json"])
    assert config["seed"] == 1 and config["problem"] == "thermostat"
    assert "version" in meta["ambiegen_recorder"]
    assert meta["ambiegen_recorder"]["middleware"].startswith("dds backend over Cyclone DDS 11.")


def test_two_workers_share_without_executing_twice(campaigns):
    code, summary, out, _ = campaigns["in_the_loop"]
    assert code == 0
    run = _read_run(Path(summary["mcap"]))
    workers = {r[1] for r in run["results"]}
    suffix = summary["run_id"][-6:]  # worker ids are unique per run
    assert workers == {f"thermostat_sim_0_{suffix}", f"thermostat_sim_1_{suffix}"}  # both used, nobody else answered
    sids = [r[0] for r in run["results"]]
    assert len(sids) == len(set(sids)) == summary["scenarios_published"]  # each executed once
    assigned = {s[0]: s[1] for s in run["scenarios"]}
    assert all(assigned[sid] == worker for sid, worker, *_ in run["results"])  # by the worker it was sent to
    assert summary["scenario_messages"] == summary["scenarios_published"]  # nothing re-sent
