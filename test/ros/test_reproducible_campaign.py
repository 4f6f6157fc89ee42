"""Same seed, same campaign (issue 7, section 3): 1 and 3 sim workers give the same run.

Real processes over real DDS: ``ambiegen campaign`` in the loop (every F1 comes from the sim
workers), run twice with the same seed, once with 1 worker taking up to 64 scenarios at a time
(whole generations evaluated as one batch) and once with 3 workers taking at most 2 (every
scenario alone or in pairs, on whichever worker is free). Both must publish the same scenarios,
get the same F1 bits for each and end with a byte-identical ``suite.json``. With the surrogate
workers this catches F1 that depends on batching; with the full models, noise that depends on
the worker instead of the run's seed and the scenario id.

Each campaign has its own ROS_DOMAIN_ID (``module_domains``, test/conftest.py). Budgets are
small; every wait ends on the campaign's exit, bounded only as a safety net.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from ambiegen_ros.ros import topics  # noqa: E402
from ambiegen_ros.ros.runlog import iter_messages  # noqa: E402
from ambiegen_ros.sims.full_model import scenario_seed  # noqa: E402

pytestmark = pytest.mark.skipif(
    os.environ.get("AMBIEGEN_TRANSPORT", "auto") == "rclpy", reason="these tests drive the DDS backend"
)

# sim model: (search options, {workers: max in flight})
CASES = {
    "surrogate": (["--population", "20", "--offspring", "20", "--evaluations", "300"], {1: 64, 3: 2}),
    "full": (["--population", "10", "--offspring", "10", "--evaluations", "60"], {1: 64, 3: 2}),
}


def start_campaign(out: Path, sim_model: str, options: list[str], workers: int, domain: int, in_flight: int):
    args = [
        sys.executable, "-m", "ambiegen_ros", "campaign", "--problem", "thermostat", "--algorithm", "ga",
        "--mode", "in_the_loop", "--seed", "3", "--sim-model", sim_model, *options, "--workers", str(workers),
        "--max-in-flight", str(in_flight), "--domain-id", str(domain), "--result-timeout", "60", "--timeout", "600",  # safety nets
        "--out", str(out),
    ]
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain), PYTHONUNBUFFERED="1")
    env.pop("AMBIEGEN_TRANSPORT", None)
    return subprocess.Popen(args, cwd=REPO, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def read_run(out: Path) -> dict:
    """The run as its log and files tell it: scenarios and results by id, summary, suite bytes."""
    summary = json.loads((out / "summary.json").read_text())
    scenarios, results = {}, {}
    for topic, _, _, msg in iter_messages(summary["mcap"], {topics.scenarios("thermostat"), topics.RESULTS}):
        if topic == topics.RESULTS:
            results.setdefault(int(msg.scenario_id), msg)
        else:
            scenarios.setdefault(int(msg.meta.scenario_id), msg.meta.scenario_json)
    return {"summary": summary, "scenarios": scenarios, "results": results, "suite": (out / "suite.json").read_bytes()}


@pytest.fixture(scope="module")
def campaigns(tmp_path_factory, module_domains):
    """All four campaigns at once (each on its own domain): {(sim model, workers): run}."""
    root = tmp_path_factory.mktemp("same_seed")
    procs = {}
    for sim_model, (options, runs) in CASES.items():
        for w, in_flight in runs.items():
            procs[sim_model, w] = start_campaign(root / f"{sim_model}_w{w}", sim_model, options, w, module_domains(),
                                                 in_flight)
    try:
        for key, proc in procs.items():
            _, err = proc.communicate(timeout=700)
            assert proc.returncode == 0, f"{key}: exit {proc.returncode}\n{err[-3000:]}"
    finally:
        for proc in procs.values():
            if proc.poll() is None:
                proc.kill()
                proc.wait()
    return {key: read_run(root / f"{key[0]}_w{key[1]}") for key in procs}


@pytest.mark.parametrize("sim_model", list(CASES))
def test_one_and_three_workers_give_the_same_campaign(campaigns, sim_model):
    options, runs = CASES[sim_model]
    one, three = (campaigns[sim_model, w] for w in runs)

    for run, w in ((one, 1), (three, 3)):
        s = run["summary"]
        assert s["evaluations"] == int(options[-1]) and not s["unresolved"] and s["errors"] == s["timeouts"] == 0, s
        workers = {msg.worker for msg in run["results"].values()}
        assert len(workers) == w, f"expected {w} workers to share the scenarios, got {sorted(workers)}"
    executed = [msg for msg in one["results"].values() if msg.failure_kind != 6]  # 6 = INVALID_SCENARIO
    assert len({tuple(msg.objectives) for msg in executed}) > 1, "a run of identical F1 values proves nothing"
    if sim_model == "full":  # the noise of scenario k follows the run's seed and k
        for msg in executed:
            seed = {kv.key: kv.value for kv in msg.metrics}["seed"]
            assert seed == str(scenario_seed(3, msg.scenario_id)), (msg.scenario_id, seed)

    assert one["scenarios"] == three["scenarios"], "the search published different scenarios"
    assert one["results"].keys() == three["results"].keys()
    for sid, a in one["results"].items():
        b = three["results"][sid]
        got = (list(b.objective_names), [float(v).hex() for v in b.objectives], b.failed, b.failure_kind)
        want = (list(a.objective_names), [float(v).hex() for v in a.objectives], a.failed, a.failure_kind)
        assert got == want, f"scenario {sid}: 3 workers gave {got}, 1 worker {want}"
    for key in ("failures", "invalid", "best_f1"):
        assert one["summary"][key] == three["summary"][key], key
    assert one["suite"] == three["suite"], "suite.json differs"
    suite = json.loads(one["suite"])
    assert suite["seed"] == 3 and suite["mode"] == "in_the_loop" and len(suite["suite"]) > 0
