"""``--stack planner`` end to end on real DDS, against a FAKE planner_server (issue 68).

``run_trials`` starts what ``ambiegen rerun --stack planner`` starts: the recorder, our adapter in
``goal_mode:=plan`` and, through a fake ``ros2`` on PATH, the planner stack's nodes; the fake
planner (test/helpers/fake_planner_dds.py, not Nav2) builds its costmap from our /map and answers
a straight line from start to goal (``straight``) or NO_VALID_PATH to every goal (``refuse``). Our
oracle must then call a line through a wall FAIL(collision), a line over a clear floor PASS, and a
refusal of a reachable goal a missed path with the reference planner's certificate. A planner that
dies by SIGSEGV on a map (``crash_blocked``) is FAIL(sut_crashed), the planner stack is restarted as
one unit and shows up again (its compute_path_to_pose server, not a navigator's topics), the map
crashes it once more, and the next map passes on the fresh stack.

Through poses (config/robot_planner_vias.yaml: a scenario with a via asks
compute_path_through_poses, and the fake joins its legs as Jazzy's planner_server does): legs that
end short of the via inside NavFn's tolerance, the next leg starting there, PASS; a path that
ignores the via is a missed via; a refusal where the reference passes every leg is a missed path
whose certificate holds both legs.
"""
from __future__ import annotations

import copy
import json
import os
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
for extra in (REPO / "test" / "sims",):
    if str(extra) not in sys.path:
        sys.path.insert(0, str(extra))

from ambiegen_ros.ros.transport import dds_backend  # noqa: E402
from ambiegen_ros.trials.configs import StackConfig, prepare  # noqa: E402
from ambiegen_ros.trials.rows import TrialLog  # noqa: E402
from ambiegen_ros.trials.runner import TrialSettings, run_trials  # noqa: E402
from ambiegen_ros.trials.suite import load_suite  # noqa: E402
from hazards_cases import via_scenario  # noqa: E402
from test_full_models import easy_robot_elements  # noqa: E402

pytestmark = pytest.mark.skipif(os.environ.get("AMBIEGEN_TRANSPORT", "auto") == "rclpy"
                                or not dds_backend.is_available(), reason="these tests drive the DDS backend")
CONFIG = str(REPO / "config" / "robot.yaml")
PARAMS = REPO / "config" / "nav2" / "pioneer_navfn_dwb.yaml"  # NavFn (GridBased); no smoother_server
VIAS_CONFIG = str(REPO / "config" / "robot_planner_vias.yaml")
NAVFN = REPO / "config" / "nav2" / "planners" / "navfn.yaml"  # Jazzy's NavFn: a 0.5 m square tolerance
FAKE_ROS2 = REPO / "test" / "helpers" / "fake_nav2"


def scenarios() -> dict[str, dict]:
    """Start (1.5, 1.5), goal (48.5, 48.5): ``clear`` leaves the diagonal free; ``wall`` puts a
    horizontal wall of 5 m across it in row 25 (a path around it exists)."""
    clear = {"problem": "robot", "elements": easy_robot_elements()}
    wall = copy.deepcopy(clear)
    wall["elements"][24] = {"type": "horizontal", "size": 5, "position": 25}
    return {"clear": clear, "wall": wall}


def run_planner_stack(tmp_path: Path, ros_domain: int, mode: str, names: tuple[str, ...], config: str = CONFIG,
                      params: Path = PARAMS) -> list[dict]:
    cases = {**scenarios(), "via": via_scenario()}
    suite_file = tmp_path / "suite.json"
    suite_file.write_text(json.dumps({"suite": [{"scenario": cases[n], "name": n} for n in names]}))
    results, bags = tmp_path / "trials.jsonl", tmp_path / "bags"
    bags.mkdir()
    env = {"PATH": f"{FAKE_ROS2}{os.pathsep}{os.environ['PATH']}", "FAKE_ROS2_PYTHON": sys.executable,
           "FAKE_NAV2_PLANNER": mode, "AMBIEGEN_TRANSPORT": "dds"}
    settings = TrialSettings(stack="planner", results=results, bags=bags, repeat=1, domain_id=ros_domain,
                             start_timeout=120.0, ready_timeout=120.0, extra_env=env)
    prepared = prepare(StackConfig("fake", (str(params),)), "planner", None, 1.0, bags)
    said: list[str] = []
    run_trials(load_suite([str(suite_file)], config), [prepared], settings, say=said.append)
    rows = TrialLog(results).rows()
    assert len(rows) >= len(names), "\n".join(said)  # a crash is run once more
    return rows


def test_a_straight_line_through_a_wall_fails_by_collision_and_over_a_clear_floor_passes(tmp_path, ros_domain,
                                                                                          session_env):
    rows = run_planner_stack(tmp_path, ros_domain, "straight", ("clear", "wall"))
    by_name = {r["scenario_name"]: r for r in rows}
    assert by_name["clear"]["failure_kind"] == "none", by_name["clear"]["detail"]
    wall = by_name["wall"]
    assert wall["failure_kind"] == "collision" and wall["detail"].startswith("collision: pose "), wall["detail"]
    logs = Path(rows[0]["bag"]).parent / "logs"
    planner_log = (logs / "planner_server.log").read_text()
    assert planner_log.count("plan straight:") == 2 and "costmap 2:" in planner_log  # one map, one goal each


def test_a_refusal_where_a_path_exists_is_a_missed_path_with_the_certificate(tmp_path, ros_domain, session_env):
    (row,) = run_planner_stack(tmp_path, ros_domain, "refuse", ("wall",))
    assert row["failure_kind"] == "requirement" and row["detail"].startswith("missed_path: "), row["detail"]
    assert "error 208" in row["detail"] and "the reference planner found" in row["detail"]


def test_a_planner_that_segfaults_on_a_map_is_a_crash_that_comes_back_and_the_restarted_stack_goes_on(
        tmp_path, ros_domain, session_env):
    rows = run_planner_stack(tmp_path, ros_domain, "crash_blocked", ("wall", "clear"))
    kinds = [(r["scenario_name"], r["failure_kind"]) for r in rows]
    assert kinds == [("wall", "sut_crashed"), ("wall", "sut_crashed"), ("clear", "none")], kinds
    crash, again, clear = rows
    assert "planner_server" in crash["detail"] and "SIGSEGV" in crash["detail"], crash["detail"]
    assert again["crash_rerun_of"]["scenario_id"] == crash["scenario_id"]
    for row in (crash, again):
        restarted = {r["process"]: r for r in row["restarts"]}
        assert set(restarted) >= {"planner_server", "lifecycle_manager_planner"}, row["restarts"]
        assert all(r["ok"] for r in restarted.values())


@pytest.mark.parametrize("mode, kind, oracle", [("short", "none", "pass"), ("skip_vias", "requirement", "missed_via"),
                                                ("refuse", "requirement", "missed_path")])
def test_through_poses_legs_from_where_the_last_ended_pass_and_a_skipped_via_or_a_refusal_is_a_finding(
        tmp_path, ros_domain, session_env, mode, kind, oracle):
    (row,) = run_planner_stack(tmp_path, ros_domain, mode, ("via",), VIAS_CONFIG, NAVFN)
    m = {k: json.loads(v) if k in ("plan_vias", "certificate") else v for k, v in row["metrics"].items()}
    assert row["failure_kind"] == kind and m["plan_oracle"] == oracle, row["detail"]
    assert m["plan_vias"] == [[10.125, 1.625, 1.5708]]  # cell (40, 6)'s centre, 90 degrees (the result's JSON text)
    logs = (Path(row["bag"]).parent / "logs" / "planner_server.log").read_text()
    assert "plan through " in logs and "(10.12, 1.62) -> (0.62, 10.12)" in logs  # goals: the via, then the goal
    if mode == "skip_vias":
        assert "via 1 at (10.125, 1.625)" in row["detail"] and "error" not in row["detail"]
    if mode == "refuse":
        assert "error 308" in row["detail"] and "through 1 via" in row["detail"]
        assert len(m["certificate"]["legs"]) == 2
