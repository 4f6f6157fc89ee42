"""bench/nav2_screen.py (issue 49): the screen's AUC is measured on Nav2's recorded hazards runs,
with failures recorded before today's known-failure entries judged by them."""
from __future__ import annotations

import importlib.util
import json
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
RUNS = REPO / "docs" / "results" / "nav2" / "runs.jsonl"


def screen():
    spec = importlib.util.spec_from_file_location("nav2_screen", REPO / "bench" / "nav2_screen.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_screen_scores_every_executed_hazards_run_and_knows_the_box_stop():
    ns = screen()
    rows = ns.scored(ns.from_runs(RUNS))
    recorded = [json.loads(line) for line in RUNS.read_text().splitlines()]
    executed = [r for r in recorded if (r.get("problem_config") or {}).get("scenario") == "hazards"
                and r["failure_kind"] not in ns.NOT_RUN]
    assert len(rows) == len(executed) and all(r["features"] for r in rows)
    stops = [r for r in rows if r["kind"] == "nav2_aborted"]
    (box_stop,) = [r for r in stops if r["known"]]  # error 105 at a box: #6091, known today
    assert box_stop["scenario"] and len(stops) > 1  # the others gave up at a blocked passage (208): new
    assert all(not r["known"] for r in rows if r["kind"] == "collision")
    auc = ns.aucs(rows)
    assert auc["new_certified_failure"]["positives"] == sum(r["failed"] for r in executed) - 1
    assert all(0.0 <= v <= 1.0 for row in auc.values() for k, v in row.items() if k != "positives")
    # a batch where nothing failed has nothing to rank
    assert ns.aucs([r for r in rows if not r["failed"]])["certified_failure"]["positives"] == 0


def test_a_campaign_whose_bag_is_gone_is_screened_from_its_seed_with_its_recorded_verdicts(tmp_path):
    """Issue 59: the hardened hours' bags were lost, their verdicts kept (nav2_near_misses rows). The
    scenarios come back from the seed (a real campaign here, sim-model surrogate), each checked by the
    goal Nav2 was sent; hand readings drop what was not the stack's (ours, setting) and mark the known."""
    import subprocess
    import sys

    import numpy as np
    import pytest

    from ambiegen_ros.core.config import load_config_file
    from ambiegen_ros.nodes.replay import recorded_scenarios
    from ambiegen_ros.problems import get_problem

    ns = screen()
    out = tmp_path / "regen"
    subprocess.run([sys.executable, "-m", "ambiegen_ros", "campaign", "--problem", "robot", "--algorithm", "random",
                    "--mode", "in_the_loop", "--sim-model", "surrogate", "--config", "config/robot_hazards.yaml",
                    "--profile", "refined", "--seed", "3", "--evaluations", "6", "--out", str(out)],
                   cwd=REPO, check=True, capture_output=True, timeout=300)
    (bag,) = out.glob("*.mcap")
    problem = get_problem("robot", load_config_file(REPO / "config" / "robot_hazards.yaml")["problem_config"])
    rec = recorded_scenarios(bag)
    maps = []
    for sid, sc in sorted(rec.scenarios.items()):
        env = problem.environment(problem.parse({"problem": sc.problem, "elements": sc.elements}))
        goal = ((np.asarray(env.goal, float) + 0.5) * env.resolution).tolist()  # as Nav2's goal, in the map frame
        maps.append({"scenario": sid, "goal": goal, "verdict": "PASS", "failed": False, "nav2_recoveries": "2"})
    maps[0].update(verdict="FAIL(collision)", failed=True)
    maps[1].update(verdict="FAIL(nav2_aborted)", failed=True)
    maps[2].update(verdict="FAIL(nav2_aborted)", failed=True)
    verdicts = [{"bag": "nav2.mcap", "maps": maps}]
    readings = {"nav2.mcap": {str(maps[1]["scenario"]): "known", str(maps[2]["scenario"]): "ours"}}
    rows = ns.from_regenerated(f"{bag},nav2.mcap,config/robot_hazards.yaml", verdicts, readings)
    assert [r["kind"] for r in rows] == ["collision", "nav2_aborted"] + ["none"] * (len(maps) - 3)
    assert [r["known"] for r in rows[:2]] == [False, True] and rows[0]["scenario"]["elements"]
    auc = ns.aucs(ns.scored(rows))
    assert auc["new_certified_failure"]["positives"] == 1 and auc["certified_failure"]["positives"] == 2
    maps[4]["goal"] = [maps[4]["goal"][0] + 1.0, maps[4]["goal"][1]]  # not the scenario Nav2 ran
    with pytest.raises(SystemExit, match="is not the one"):
        ns.from_regenerated(f"{bag},nav2.mcap,config/robot_hazards.yaml", verdicts, readings)
