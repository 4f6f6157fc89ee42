"""The planner judge (``goal_mode:=plan``, issue 68) without a node or a middleware.

Its decisions: a path through a wall is FAIL(collision); a clear one PASS; a refusal where the
reference planner has a path is a failure carrying the certificate; a refusal the reference
proves right is INVALID_TEST; planning over the plugin's own time limit is a note, never a
failure; a smoothed path that hits a wall its input missed is FAIL(collision). And its way
there on a stand-in node: the map goes out, a costmap still showing another map never lets the
question go, the matching one does, and the planner's answer (or its silence) ends the run.
"""
from __future__ import annotations

import math
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
for extra in (REPO, REPO / "test", REPO / "test" / "sims"):
    if str(extra) not in sys.path:
        sys.path.insert(0, str(extra))

from ambiegen_ros.core.config import ConfigError  # noqa: E402
from ambiegen_ros.ros import conversions  # noqa: E402
from ambiegen_ros.sims.plans import rules  # noqa: E402
from ambiegen_ros.sims.plans.costmap import costmap_from_occupancy  # noqa: E402
from sim_nodes.adapter.judge import DECIDED, HOLD, RunView  # noqa: E402
from sim_nodes.adapter.registry import judge_for  # noqa: E402
from sim_nodes.adapter.robot_planner import (PlanAnswer, PlannerRobot, costmap_shows, parse_rules,  # noqa: E402
                                             plan_outcome, planner_rules)
from test_adapter_judges import REG, StandInNode, make_judge, robot, robot_job  # noqa: E402,F401

RES = 0.05


def room(wall: str = "none") -> np.ndarray:
    """A 60 x 40 cell room (3 x 2 m): a wall across x = 1.5 m with a gap (``gap``), without (``full``), or none."""
    occ = np.zeros((40, 60), dtype=np.int8)
    if wall != "none":
        occ[:, 29:31] = 100
        if wall == "gap":
            occ[2:20, 29:31] = 0  # 0.9 m: wide enough for the inflated robot
    return occ


def line(a, b, n=60):
    t = np.linspace(0.0, 1.0, n)[:, None]
    xy = (1 - t) * np.asarray(a) + t * np.asarray(b)
    return np.column_stack([xy, np.zeros(n)])


START, GOAL = (0.5, 1.5, 0.0), (2.5, 1.5, 0.0)


def test_a_straight_line_through_a_wall_fails_by_collision_and_a_clear_one_passes():
    blocked = costmap_from_occupancy(room("gap"), RES)
    out = plan_outcome(blocked, rules.navfn(), START, GOAL, PlanAnswer(status=4, path=line(START[:2], GOAL[:2])))
    assert out.verdict == "FAIL(collision)" and out.metrics["plan_oracle"] == "collision"
    assert out.failure_point is not None and 1.45 - 0.22 <= out.failure_point[0] <= 1.55  # the body meets the wall
    clear = costmap_from_occupancy(room("none"), RES)
    ok = plan_outcome(clear, rules.navfn(), START, GOAL, PlanAnswer(status=4, path=line(START[:2], GOAL[:2])))
    assert ok.verdict == "PASS" and ok.trajectory.shape == (60, 2)
    assert ok.metrics["plan_clearance_m"] is None  # no lethal cell anywhere
    assert ok.objectives["plan_closeness"] < out.objectives["plan_closeness"]  # the wall is closer to failing


def test_a_refusal_where_a_path_exists_fails_with_the_certificate_and_a_proved_one_is_invalid():
    gap = costmap_from_occupancy(room("gap"), RES)
    refused = PlanAnswer(status=6, error_code=208, error_msg="no valid path")
    out = plan_outcome(gap, rules.navfn(), START, GOAL, refused)
    assert out.verdict == "FAIL(requirement)" and out.detail.startswith("missed_path: ")
    cert = out.metrics["certificate"]
    assert cert["status"] == "path" and len(cert["poses"]) > 2
    assert all(p[1] < 1.0 for p in cert["poses"] if 1.4 < p[0] < 1.6)  # through the gap, low on the wall
    full = costmap_from_occupancy(room("full"), RES)
    proved = plan_outcome(full, rules.navfn(), START, GOAL, refused)
    assert proved.verdict.startswith("INVALID_TEST(") and not proved.failed
    assert proved.metrics["plan_oracle"] == "correct_refusal" and proved.metrics["reference"]["status"] == "absent"


def test_a_path_leaving_a_blocked_start_is_as_close_as_its_judged_poses_came():
    """The poses leaving a colliding start are not judged (start_blocked), so they are no closest call:
    a path that starts 0.125 m from a wall's last cell centre came as close as its first judged pose,
    the first one clear of the inscribed radius, not 0.125 m."""
    occ = room("none")
    occ[:, 0:2] = 100  # a wall along x = 0 .. 0.1 m
    walled = costmap_from_occupancy(occ, RES)
    start = (0.2, 1.0, 0.0)  # 0.125 m from the wall's last cell centre: inside the inscribed radius
    path = np.vstack([line(start[:2], (0.7, 1.0), 11), line((0.7, 1.0), (2.5, 1.0), 40)[1:]])
    out = plan_outcome(walled, rules.smac_2d(), start, (2.5, 1.0, 0.0), PlanAnswer(status=4, path=path))
    assert out.verdict == "PASS", out.detail
    assert "start_blocked" in out.detail or out.metrics["plan_oracle"] == "start_blocked"
    assert 0.2158 < out.metrics["plan_clearance_m"] < 0.3  # the judged poses only (the start's: 0.125 m)


def test_planning_over_the_plugins_own_limit_is_a_note_never_a_failure():
    clear = costmap_from_occupancy(room("none"), RES)
    slow = PlanAnswer(status=4, path=line(START[:2], GOAL[:2]), planning_time=3.5)
    out = plan_outcome(clear, rules.smac_2d(), START, GOAL, slow)
    assert out.verdict == "PASS" and "over its max_planning_time 2.0" in out.metrics["plan_performance"]
    assert "plan_performance" not in plan_outcome(clear, rules.navfn(), START, GOAL, slow).metrics  # NavFn: none


def test_a_smoothed_path_into_a_wall_its_input_missed_fails_by_collision():
    gap = costmap_from_occupancy(room("gap"), RES)
    around = np.vstack([line(START[:2], (1.5, 0.55), 30), line((1.5, 0.55), GOAL[:2], 30)[1:]])
    fine = plan_outcome(gap, rules.navfn(), START, GOAL, PlanAnswer(status=4, path=around))
    assert fine.verdict == "PASS", fine.detail
    cut = plan_outcome(gap, rules.navfn(), START, GOAL,
                       PlanAnswer(status=4, path=around, smoothed=line(START[:2], GOAL[:2])))
    assert cut.verdict == "FAIL(collision)" and cut.metrics["plan_oracle"] == "smoother_collision"
    assert cut.metrics["smoothed_poses"] == len(line(START[:2], GOAL[:2])) and "smoothed_poses" not in fine.metrics
    assert cut.metrics["smoothed_clearance_m"] < cut.metrics["plan_clearance_m"]  # the shortcut runs closer


def test_the_rules_come_from_the_plugin_with_the_users_overrides_and_a_bad_one_is_one_line():
    assert parse_rules("tolerance=0.25, allow_unknown=false") == {"tolerance": 0.25, "allow_unknown": False}
    r = planner_rules("navfn", parse_rules("tolerance=0.25"))
    assert r.name == "navfn" and r.tolerance == 0.25
    assert planner_rules("smac_hybrid", {"motion_model": "REEDS_SHEPP"}).reversing
    with pytest.raises(ConfigError, match="planner_rules"):
        planner_rules("navfn", {"turning": 1.0})
    with pytest.raises(ConfigError, match="planner_rules"):
        make_judge(PlannerRobot, SimpleNamespace(name="robot"), planner_rules="tolerance")
    assert judge_for("robot", "plan") is PlannerRobot


# --- on a stand-in node ---------------------------------------------------------------------------
class Future:
    def __init__(self, value=None):
        self.value, self.callbacks = value, []

    def result(self):
        return self.value

    def add_done_callback(self, cb):
        self.callbacks.append(cb)
        if self.value is not None:  # done already: at once, as a finished future does
            cb(self)

    def resolve(self, value):
        self.value = value
        for cb in self.callbacks:
            cb(self)


class StandInAction:
    def __init__(self):
        self.goals, self.futures = [], []

    def server_is_ready(self):
        return True

    def new_goal(self, **fields):
        return SimpleNamespace(**fields)

    def send_goal_async(self, request):
        self.goals.append(request)
        self.futures.append(Future())
        return self.futures[-1]


class PlannerNode(StandInNode):
    def __init__(self):
        super().__init__()
        self.actions = {}

    def create_action_client(self, typename, name):
        self.actions[name] = StandInAction()
        return self.actions[name]

    def create_client(self, typename, service):
        return SimpleNamespace(service_is_ready=lambda: True, new_request=lambda: None,
                               call_async=lambda _r: Future(SimpleNamespace(current_state=SimpleNamespace(
                                   label="active"))))


@pytest.fixture()
def planner(robot, monkeypatch):
    monkeypatch.setattr("test_adapter_judges.StandInNode", PlannerNode)
    judge, node, host = make_judge(PlannerRobot, robot[0], map_upsample=2, answer_timeout=5.0)
    node.ns = 10  # the map's stamp
    job = robot_job(judge, node, robot[1])
    host.job = job
    return judge, node, job


def costmap_message(published, stamp_ns, occupied=None):
    """The OccupancyGrid a Nav2 costmap would publish for ``published`` (lethal = 100), stamped."""
    info = published.info
    data = np.asarray(published.data, dtype=np.int8) if occupied is None else occupied
    return REG.new("nav_msgs/msg/OccupancyGrid", header=conversions.header(REG.new, stamp_ns), info=info,
                   data=np.where(np.asarray(data).reshape(-1) >= 100, 100, 0).astype(np.int8))


def answer_with(action, path_xy, status=4, code=0):
    result = SimpleNamespace(error_code=code, error_msg="", planning_time=SimpleNamespace(sec=0, nanosec=1000),
                             path=conversions.path(REG.new, 0, path_xy))
    handle = SimpleNamespace(accepted=True, get_result_async=lambda: Future(SimpleNamespace(status=status,
                                                                                            result=result)))
    action.futures[-1].resolve(handle)


def test_the_question_waits_for_a_costmap_that_shows_this_map_then_the_answer_decides(planner):
    judge, node, job = planner
    (grid,) = node.pubs["/map"].sent
    assert grid.info.width == 2 * job.msg.map.info.width  # map_upsample
    assert node.pubs["/tf_static"].sent[0].transforms[1].child_frame_id == "base_link"
    judge.send_goal(job)
    view = RunView(0.0, None, False, lambda: False)
    plan = node.actions["compute_path_to_pose"]
    stale = np.zeros(len(grid.data), dtype=np.int8)  # the last scenario's walls gone, this one's not yet in
    judge.on_costmap(costmap_message(grid, 20, stale))
    assert judge.step(job, view) == HOLD and not plan.goals and "lethal" in judge.why_not
    judge.on_costmap(costmap_message(grid, 0))  # right cells, stamped before the map
    assert judge.step(job, view) == HOLD and not plan.goals
    judge.on_costmap(costmap_message(grid, 20))
    assert judge.step(job, view) == HOLD
    (goal,) = plan.goals
    assert goal.use_start and (goal.start.pose.position.x, goal.goal.pose.position.x) == (1.5, 48.5)
    # the robot problem's wall stack at column 48 lies across no diagonal: a straight line is clear
    answer_with(plan, np.array([[1.5, 1.5], [25.0, 25.0], [48.5, 48.5]]))
    assert judge.step(job, view) == DECIDED  # judged on the turn after the answer
    out = job.judge.outcome()
    assert out.verdict == "PASS" and out.metrics["planner"] == "navfn", out.detail


def test_a_planner_that_never_answers_is_hung_and_a_costmap_that_never_comes_is_ours(planner):
    judge, node, job = planner
    judge.send_goal(job)
    (grid,) = node.pubs["/map"].sent
    judge.on_costmap(costmap_message(grid, 20))
    judge.step(job, RunView(judge.since, None, False, lambda: False))
    assert judge.step(job, RunView(judge.since + 6.0, None, False, lambda: False)) == DECIDED
    assert job.judge.outcome().verdict == "FAIL(sut_crashed)" and "hung" in job.judge.outcome().detail
    other, node2, job2 = judge, node, job
    other.begin(job2)
    node2.ns = 30  # a new map, after the last costmap's stamp 20
    other.setup(job2, 0.0)
    other.send_goal(job2)
    assert other.step(job2, RunView(other.since + 25.0, None, False, lambda: False)) == DECIDED
    assert job2.judge.outcome().failure_kind == "error" and "did not show" in job2.judge.outcome().detail


# --- the planner stack's node set (--stack planner) -------------------------------------------------
def test_the_planner_stack_runs_the_params_plugin_under_its_rules_and_refuses_one_we_cannot_judge(tmp_path):
    from ambiegen_ros.campaign import node_argv
    from ambiegen_ros.launch_logic import planner_stack, planner_under_test
    from ambiegen_ros.trials.configs import Prepared, StackConfig
    from ambiegen_ros.trials.runner import TrialSettings
    from ambiegen_ros.trials.session import stack_nodes

    hybrid = {"planner_server": {"ros__parameters": {"planner_plugins": ["Hy"], "Hy": {
        "plugin": "nav2_smac_planner::SmacPlannerHybrid", "motion_model_for_search": "REEDS_SHEPP",
        "minimum_turning_radius": 0.3, "tolerance": 0.2}}},
        "global_costmap": {"global_costmap": {"ros__parameters": {"robot_radius": 0.3}}}, "smoother_server": {}}
    planner_id, key, text = planner_under_test(hybrid)
    r = planner_rules(key, parse_rules(text))
    assert (planner_id, r.name, r.reversing, r.min_turning_radius, r.robot_radius) == ("Hy", "smac_hybrid", True,
                                                                                      0.3, 0.3)
    nodes = {n.name: n for n in planner_stack(hybrid, tmp_path / "p.yaml", "t1", 5, 30.0, "prob.yaml", "")}
    assert set(nodes) == {"planner_server", "smoother_server", "lifecycle_manager_planner", "sut_adapter"}
    assert nodes["lifecycle_manager_planner"].parameters["node_names"] == ["planner_server", "smoother_server"]
    assert node_argv(nodes["planner_server"])[:4] == ["ros2", "run", "nav2_planner", "planner_server"]
    assert all(n.parameters["use_sim_time"] is False for n in nodes.values() if n.package != "ambiegen_ros")
    adapter = nodes["sut_adapter"].parameters
    assert (adapter["goal_mode"], adapter["planner_id"], adapter["smooth"]) == ("plan", "Hy", True)
    with pytest.raises(ValueError, match="planner_server.GridBased.plugin"):
        planner_under_test({"planner_server": {"ros__parameters": {"GridBased": {"plugin": "my/Planner"}}}})
    settings = TrialSettings(stack="planner", results=tmp_path / "r.jsonl", bags=tmp_path)
    prepared = Prepared(StackConfig("j", ()), hybrid, tmp_path / "p.yaml", "d", {}, None, None)
    made = stack_nodes(settings, prepared, tmp_path / "problem.yaml", tmp_path / "b.mcap", "t1")
    assert [n.name for n in made][0] == "recorder" and "robot_world" not in [n.name for n in made]
    assert "/global_costmap/costmap" in made[0].parameters["extra_topics"]


def test_every_shipped_planner_config_makes_a_stack_and_a_smoother_config_smooths(tmp_path):
    """config/nav2/planners/: each file names a plugin we judge, with Jazzy's round robot; the three
    smoother files add smoother_server with one smoother plugin each, and the adapter smooths."""
    import yaml

    from ambiegen_ros.launch_logic import planner_stack

    found = {}
    for path in sorted((REPO / "config" / "nav2" / "planners").glob("*.yaml")):
        params = yaml.safe_load(path.read_text())
        nodes = {n.name: n for n in planner_stack(params, path, "t", 5, 30.0, "prob.yaml", "")}
        adapter = nodes["sut_adapter"].parameters
        assert "robot_radius=0.22" in adapter["planner_rules"], path.name
        found[path.stem] = adapter["smooth"]
        if adapter["smooth"]:
            plugins = params["smoother_server"]["ros__parameters"]["smoother_plugins"]
            assert len(plugins) == 1 and "plugin" in params["smoother_server"]["ros__parameters"][plugins[0]]
    assert {k for k, v in found.items() if v} == {"navfn_simple_smoother", "navfn_savitzky_golay",
                                                  "navfn_constrained_smoother"}
    assert {"navfn", "navfn_astar", "smac_2d", "smac_hybrid", "smac_hybrid_rs", "smac_lattice", "theta_star"} <= set(found)


def test_a_lattice_is_judged_by_its_primitives_file_and_a_file_that_cannot_tell_is_one_line(tmp_path):
    """A 1 m Ackermann set raises the turning limit; a diff set (rotations in place) turns the kinematic
    oracles off, so an in-place turn is no tight_turn; an unreadable file names the param."""
    import json

    from ambiegen_ros.launch_logic import planner_under_test
    from ambiegen_ros.sims.plans.oracles import check_turning

    def lattice(path):
        return {"planner_server": {"ros__parameters": {"planner_plugins": ["La"], "La": {
            "plugin": "nav2_smac_planner/SmacPlannerLattice", "lattice_filepath": str(path)}}}}

    judged = {}
    for model in ("ackermann", "diff"):
        f = tmp_path / model / "output.json"
        f.parent.mkdir()
        f.write_text(json.dumps({"lattice_metadata": {"motion_model": model, "turning_radius": 1.0,
                                                      "grid_resolution": 0.05}, "primitives": []}))
        _, key, text = planner_under_test(lattice(f))
        judged[model] = planner_rules(key, parse_rules(text))
    assert judged["ackermann"].min_turning_radius == 1.0 and not judged["ackermann"].reversing
    assert judged["diff"].min_turning_radius is None
    # straight, a turn in place through 90 degrees, straight: a corner of radius ~0.07 m
    corner = np.array([[0.0, 0, 0], [0.1, 0, 0], [0.2, 0, 0], [0.2, 0, 1.57], [0.2, 0.1, 1.57], [0.2, 0.2, 1.57]])
    assert check_turning(corner, judged["ackermann"]) is not None
    assert check_turning(corner, judged["diff"]) is None
    assert planner_rules("smac_lattice", {}).min_turning_radius == 0.5  # no file: Jazzy's default set
    with pytest.raises(ValueError, match="planner_server.La.lattice_filepath"):
        planner_under_test(lattice(tmp_path / "missing.json"))


def test_a_search_in_the_loop_climbs_towards_findings_and_paths_close_to_walls():
    """``loop_f1`` of a planner's answer (no time, no route driven): a finding above any path that
    held, a path closer to a lethal cell above a farther one, no path or an unusable answer 0."""
    from ambiegen_ros.nodes.generator import loop_evaluation
    from ambiegen_ros.problems import get_problem
    from ambiegen_ros.sims import Outcome

    problem = get_problem("robot", {"profile": "refined", "loop_objective": "pace"})

    def answer(kind: str, clearance):
        return Outcome({"plan_closeness": 0.0}, kind not in ("none", "invalid_test"), kind, kind,
                       metrics={"plan_oracle": "x", "plan_clearance_m": clearance})

    found, close, far, none, proved = (answer("collision", 0.0), answer("none", 0.05), answer("none", 1.5),
                                       answer("none", None), answer("invalid_test", None))
    f1 = loop_evaluation([found, close, far, none, proved], problem.loop_f1).f1
    assert f1[0] == 2.0 and 1.0 > f1[1] > f1[2] > 0.0 and f1[3] == 0.0 and f1[4] == 0.0, f1


def test_the_planner_stack_sends_maps_at_the_costmaps_own_resolution():
    from ambiegen_ros.trials.session import planner_upsample

    settings = SimpleNamespace(map_upsample=5)
    costmap = lambda res: {"global_costmap": {"global_costmap": {"ros__parameters": {"resolution": res}}}}  # noqa: E731
    assert planner_upsample(costmap(0.05), settings) == 20  # Jazzy's: 1 m scenario cells as 0.05 m map cells
    assert planner_upsample(costmap(0.1), settings) == 10
    assert planner_upsample(costmap(0.05), settings, cell_m=0.25) == 5  # config/robot_planner.yaml's 0.25 m cells
    assert planner_upsample({}, settings) == 5 and planner_upsample(costmap("x"), settings) == 5


def test_a_finding_is_written_as_nav2s_maintainers_ask_for_one(tmp_path):
    """``ambiegen planner-report``'s files: the map map_server loads (the scenario's walls at the
    costmap's resolution, rows flipped as map_server flips them), the params, a script for a stock
    Jazzy with the start and goal the adapter sent, a runnable suite, and a page with the label and
    k of N; an unknown label or scenario is one clear error."""
    import json as _json

    from ambiegen_ros.run_config import make_run
    from ambiegen_ros.trials.planner_findings import map_of, read_pgm, write_finding

    problem = make_run("robot", str(REPO / "config" / "robot_planner.yaml"), seed=0)[0]
    G, lengths = problem.sample(1, np.random.default_rng(5))
    scenario = problem.codec.from_rows(problem.codec.join(G, lengths))[0]
    row = {"scenario_name": "case", "scenario": scenario.to_dict(), "failed": True, "failure_kind": "collision",
           "detail": "collision: pose 3 ...", "versions": {"ambiegen_ros": "x"}, "when": "now"}
    rows = [row] * 9 + [{**row, "failed": False, "failure_kind": "none"}]
    params = REPO / "config" / "nav2" / "planners" / "theta_star.yaml"
    page = write_finding(rows, "case", problem, params, 5, tmp_path, "fixed_on_main", "#5863, fixed by #5908", "why")
    text = page.read_text()
    assert "fixed on main, still in Jazzy" in text and "#5908" in text and "9 of 10 reruns" in text
    occupied, res, start, goal = map_of(problem, scenario, 5)
    assert res == pytest.approx(0.05) and occupied.shape == (250, 250)
    assert np.array_equal(read_pgm(tmp_path / "case.pgm"), occupied)
    assert occupied[::5, ::5].sum() == problem.environment(scenario).grid.sum()  # the same walls, finer
    meta = (tmp_path / "case.yaml").read_text()
    assert "resolution: 0.05" in meta and "image: case.pgm" in meta and "mode: trinary" in meta
    script = (tmp_path / "case_reproduce.py").read_text()
    compile(script, "case_reproduce.py", "exec")  # valid Python for the user's Jazzy
    assert f"START, GOAL = {tuple(round(v, 4) for v in start)}" in script and "getPath" in script
    assert (tmp_path / "case_params.yaml").read_text() == params.read_text()
    assert _json.loads((tmp_path / "case_suite.json").read_text())["suite"][0]["scenario"] == row["scenario"]
    assert "MIN_RADIUS = None" in script  # Theta*: no turning limit to report
    assert "SMOOTH = False" in script and "smoother_server" not in script.split('"""')[1]
    smoothed = write_finding(rows, "case", problem, REPO / "config" / "nav2" / "planners" /
                             "navfn_constrained_smoother.yaml", 5, tmp_path / "smooth", "new", "", "why")
    script = (smoothed.parent / "case_reproduce.py").read_text()
    compile(script, "case_reproduce.py", "exec")
    assert "SMOOTH = True" in script and "ros2 run nav2_smoother smoother_server" in script
    assert "node_names:=\"['planner_server', 'smoother_server']\"" in script
    hybrid = write_finding(rows, "case", problem, REPO / "config" / "nav2" / "planners" / "smac_hybrid.yaml", 5,
                           tmp_path / "hybrid", "known", "#4271", "why", min_turning_radius=0.4)
    script = (hybrid.parent / "case_reproduce.py").read_text()
    assert "MIN_RADIUS = 0.4" in script and "minimum turning radius, 0.4 m" in hybrid.read_text()
    # the script's own tightest-turn check, run here without ROS: a 0.3 m arc between two straights
    import ast
    import math
    tree = ast.parse(script)
    helper = ast.Module([n for n in tree.body if isinstance(n, ast.FunctionDef) and n.name == "tightest_turn"], [])
    space = {"math": math, "RESOLUTION": 0.05}
    exec(compile(helper, "case_reproduce.py", "exec"), space)
    arc = [(0.3 * math.sin(t), 0.3 - 0.3 * math.cos(t)) for t in np.linspace(0, math.pi / 2, 12)]
    line = [(-0.05 * k, 0.0) for k in range(6, 0, -1)] + arc + [(0.3, 0.3 + 0.05 * k) for k in range(1, 6)]
    radius, i = space["tightest_turn"](line)
    assert radius == pytest.approx(0.3, rel=0.02) and 6 <= i < 18
    assert space["tightest_turn"]([(0.05 * k, 0.0) for k in range(10)]) == (math.inf, -1)
    with pytest.raises(ValueError, match="label"):
        write_finding(rows, "case", problem, params, 5, tmp_path, "maybe", "", "")
    with pytest.raises(ValueError, match="no row"):
        write_finding(rows, "other", problem, params, 5, tmp_path, "new", "", "")
    with pytest.raises(ValueError, match="exists"):  # a report is never replaced
        write_finding(rows, "case", problem, params, 5, tmp_path, "known", "", "other words")
    assert "#5908" in page.read_text()
    # a shrunk scenario's map (``ambiegen shrink``): its cleared cells are free in what map_server loads
    from ambiegen_ros.problems.robot.problem import CLEARED

    ys, xs = np.nonzero(problem.environment(scenario).grid)
    shrunk = {**scenario.to_dict(), "metadata": {CLEARED: [[int(xs[0]), int(ys[0])]]}}
    small = write_finding([{**row, "scenario": shrunk}], "case", problem, params, 5, tmp_path / "small", "new", "", "")
    grid = read_pgm(small.parent / "case.pgm")
    assert grid.sum() == occupied.sum() - 25 and not grid[5 * ys[0]:5 * ys[0] + 5, 5 * xs[0]:5 * xs[0] + 5].any()


# --- through poses (ComputePathThroughPoses) ----------------------------------------------------------
def test_a_finding_through_vias_is_written_with_its_vias(tmp_path):
    """A finding of config/robot_planner_vias.yaml: its script asks ComputePathThroughPoses through the
    scenario's vias, in order, then the goal (as the adapter did), and its page reruns it on that config."""
    from ambiegen_ros.run_config import make_run
    from ambiegen_ros.trials.planner_findings import write_finding

    config = "config/robot_planner_vias.yaml"
    problem = make_run("robot", str(REPO / config), seed=0)[0]
    G, lengths = problem.sample(1, np.random.default_rng(3))
    scenario = problem.codec.from_rows(problem.codec.join(G, lengths))[0]
    vias = [tuple(round(v, 4) for v in via) for via in problem.via_poses(scenario)]
    assert vias  # the config gives every scenario one via or more
    row = {"scenario_name": "case", "scenario": scenario.to_dict(), "failed": True, "failure_kind": "requirement",
           "detail": "missed_via: ...", "versions": {"ambiegen_ros": "x"}, "when": "now"}
    page = write_finding([row], "case", problem, REPO / "config" / "nav2" / "planners" / "navfn.yaml", 5, tmp_path,
                         "new", "", "why", config=config)
    script = (tmp_path / "case_reproduce.py").read_text()
    compile(script, "case_reproduce.py", "exec")
    assert f"VIAS = {vias}" in script and "getPathThroughPoses" in script and "asks\nComputePathThroughPoses" in script
    text = page.read_text()
    assert f"--config {config}" in text and "ComputePathThroughPoses with `use_start: true`" in text
    assert str(vias[0]) in text


def test_a_scenario_with_vias_asks_through_poses_and_the_path_is_judged_through_them(robot, monkeypatch):
    """config/robot_planner_vias.yaml: the message carries map, start and goal; the vias come from the
    scenario (its meta.scenario_json), at their cells' centres. The question goes to
    compute_path_through_poses with the vias, then the goal, as goals; a path that skips the via is
    a missed via, one through it holds."""
    from ambiegen_ros.run_config import make_run
    from hazards_cases import via_scenario

    monkeypatch.setattr("test_adapter_judges.StandInNode", PlannerNode)
    problem = make_run("robot", str(REPO / "config" / "robot_planner_vias.yaml"), seed=0)[0]
    scenario = problem.parse(via_scenario())
    judge, node, host = make_judge(PlannerRobot, problem, map_upsample=5, answer_timeout=5.0)
    node.ns = 10
    job = host.job = robot_job(judge, node, scenario)
    assert not any(m for m in judge.missing() if "action is not up" in m)
    judge.send_goal(job)
    (grid,) = node.pubs["/map"].sent
    judge.on_costmap(costmap_message(grid, 20))
    view = RunView(0.0, None, False, lambda: False)
    assert judge.step(job, view) == HOLD
    assert not node.actions["compute_path_to_pose"].goals
    (goal,) = node.actions["compute_path_through_poses"].goals
    assert [(g.pose.position.x, g.pose.position.y) for g in goal.goals] == [(10.125, 1.625), (0.625, 10.125)]
    assert goal.use_start and (goal.start.pose.position.x, goal.start.pose.position.y) == (0.625, 0.625)
    assert {g.header.frame_id for g in goal.goals} == {"map"}
    start, via, end = (0.625, 0.625), (10.125, 1.625), (0.625, 10.125)
    dense = lambda a, b: line(a, b, int(math.dist(a, b) / 0.05) + 1)[:, :2]  # noqa: E731  (a planner's 5 cm steps)
    answer_with(node.actions["compute_path_through_poses"], np.vstack([dense(start, via), dense(via, end)[1:]]))
    assert judge.step(job, view) == DECIDED
    out = job.judge.outcome()
    assert out.verdict == "PASS" and len(out.metrics["plan_vias"]) == 1, out.detail
    # the same question answered by a line that never goes near the via
    judge.begin(job)
    node.ns = 30
    job = host.job = robot_job(judge, node, scenario)
    judge.send_goal(job)
    judge.on_costmap(costmap_message(node.pubs["/map"].sent[-1], 40))
    judge.step(job, view)
    answer_with(node.actions["compute_path_through_poses"], dense(start, end))
    judge.step(job, view)
    out = job.judge.outcome()
    assert out.verdict == "FAIL(requirement)" and out.detail.startswith("missed_via: "), out.detail
    assert out.failure_point == pytest.approx(via, abs=0.05)  # where it should have gone


def test_a_refusal_through_poses_is_judged_leg_by_leg():
    gap = costmap_from_occupancy(room("gap"), RES)
    via = (1.0, 0.3, 0.0)  # low beside the wall, on the way to the gap
    refused = PlanAnswer(status=6, error_code=308, error_msg="no valid path")
    out = plan_outcome(gap, rules.navfn(), START, GOAL, refused, vias=(via,))
    assert out.verdict == "FAIL(requirement)" and out.detail.startswith("missed_path: "), out.detail
    assert len(out.metrics["certificate"]["legs"]) == 2 and out.metrics["plan_error_code"] == 308
    beyond = (2.5, 0.5, 0.0)  # behind the full wall: there and back again is impossible
    full = costmap_from_occupancy(room("full"), RES)
    proved = plan_outcome(full, rules.navfn(), START, START, refused, vias=(beyond,))
    assert proved.verdict.startswith("INVALID_TEST(") and proved.metrics["plan_oracle"] == "correct_refusal"
    assert "leg 1 (the start -> via 1)" in proved.detail and proved.metrics["reference"]["status"] == "absent"
