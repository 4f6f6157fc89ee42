"""``ambiegen rerun --stack planner`` on the real Jazzy planner_server (issue 68).

Skipped, with the reason, unless a Jazzy install is found (jazzy_env.py: ``$AMBIEGEN_ROS_SETUP``,
e.g. a private build's ``/root/jazzy-verify/install/setup.bash``, or ``/opt/ros/jazzy``). Jazzy's
own nav2_params.yaml (NavFn, its inflation and robot radius, its smoother_server) runs two
scenarios: a clear diagonal and a wall across it. The planner_server must come up on our map and
TF, answer both, and our oracles must judge each answer on the costmap read back: no error record,
no lost run, a path of poses for each, and for the wall a path that leaves the straight line
(NavFn goes round it). A verdict other than PASS would be a finding, named in the assertion.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
for extra in (REPO, REPO / "test" / "ros", REPO / "test" / "sims", REPO / "test" / "helpers"):
    if str(extra) not in sys.path:
        sys.path.insert(0, str(extra))

from jazzy_env import require, ros_env, ros_run  # noqa: E402
from test_nav2 import jazzy_params  # noqa: E402
from test_trials_planner import scenarios  # noqa: E402

PLANNER = ("nav2_msgs", "nav2_planner", "nav2_navfn_planner", "nav2_smoother", "nav2_lifecycle_manager",
           "nav2_bringup", "rmw_cyclonedds_cpp")


def test_jazzy_navfn_answers_two_maps_and_our_oracles_judge_both(jazzy, workspace, tmp_path, ros_domain):
    from ambiegen_ros.trials.rows import TrialLog

    require(jazzy, *PLANNER)
    cases = scenarios()
    suite = tmp_path / "two.json"
    suite.write_text(json.dumps({"suite": [{"scenario": cases[n], "name": n} for n in ("clear", "wall")]}))
    results, bags = tmp_path / "rows.jsonl", tmp_path / "bags"
    run = ros_run(f"ros2 run ambiegen_ros ambiegen rerun {suite} --stack planner --params jazzy={jazzy_params(jazzy)} "
                  f"--config {REPO / 'config' / 'robot.yaml'} --our-transport dds --repeat 1 --domain-id {ros_domain} "
                  f"--results {results} --bags {bags}", workspace, ros_env(ros_domain), timeout=900)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    rows = {r["scenario_name"]: r for r in TrialLog(results).rows()}
    assert set(rows) == {"clear", "wall"}, rows
    for name, row in rows.items():
        assert row["failure_kind"] not in ("error", "sim_timeout", "invalid_test"), (name, row["detail"])
        assert row["metrics"]["planner"] == "navfn" and int(row["metrics"]["plan_poses"]) > 1, (name, row["metrics"])
        assert row["failure_kind"] == "none", f"a finding on {name}? {row['verdict']}: {row['detail']}"
    assert rows["wall"]["metrics"]["plan_clearance_m"] not in (None, "None")  # a wall near the path, measured
    (logs,) = bags.glob("jazzy_*/logs")
    assert "planner_server" in (logs / "planner_server.log").read_text()


def test_jazzy_navfn_plans_through_a_via_and_our_oracles_judge_the_joined_legs(jazzy, workspace, tmp_path, ros_domain):
    """config/robot_planner_vias.yaml's room with one via (test/helpers/hazards_cases.py): the
    adapter asks compute_path_through_poses on config/nav2/planners/navfn.yaml (Jazzy's NavFn, a
    0.5 m square tolerance), and the path Jazzy joins from its two legs must pass every oracle, the
    via's included. Anything else is named in the assertion."""
    from hazards_cases import via_scenario

    from ambiegen_ros.trials.rows import TrialLog

    require(jazzy, *PLANNER)
    suite = tmp_path / "via.json"
    suite.write_text(json.dumps({"suite": [{"scenario": via_scenario(), "name": "via"}]}))
    results, bags = tmp_path / "rows.jsonl", tmp_path / "bags"
    params = REPO / "config" / "nav2" / "planners" / "navfn.yaml"
    run = ros_run(f"ros2 run ambiegen_ros ambiegen rerun {suite} --stack planner --params navfn={params} "
                  f"--config {REPO / 'config' / 'robot_planner_vias.yaml'} --our-transport dds --repeat 1 "
                  f"--domain-id {ros_domain} --results {results} --bags {bags}", workspace, ros_env(ros_domain),
                  timeout=900)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    (row,) = TrialLog(results).rows()
    m = row["metrics"]
    assert row["failure_kind"] == "none", f"a finding? {row['verdict']}: {row['detail']}"
    assert m["planner"] == "navfn" and m["plan_oracle"] == "pass" and int(m["plan_poses"]) > 100, m
    assert json.loads(m["plan_vias"]) == [[10.125, 1.625, 1.5708]]  # asked through the via, judged through it
