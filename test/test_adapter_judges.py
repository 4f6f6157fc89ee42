"""The adapter's judges without a node or a middleware (issue 67): each fed samples, statuses and
the stack's result directly, on a stand-in node that records what it would publish.

Each way of running a scenario (``sim_nodes/adapter/``: a robot on topics, a robot through Nav2's
action, a vehicle, a thermostat) must put the scenario on its topics and reach the verdict its
rules say; the rules that read Nav2's answer (``nav2_rules``) must turn an abort of ours into an
error record, blame a give-up at the stack's own time per goal only when the reference makes it
in that time, and mark a PASS after recoveries as a near miss; the parameter tables must refuse a
bad value with one line naming the parameter; and a scenario the adapter fails to set up must
still end in an error record, with the traceback logged when the fault is the adapter's. The
robot judged is ``robot_profile``'s (issue 69): its radius and a car's turning radius decide what
is an invalid test, '' is the Pioneer, and a bad profile stops the node (a real process) in one line.
"""
from __future__ import annotations

import math
import sys
from collections import deque
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
for extra in (REPO, REPO / "test", REPO / "test" / "sims"):
    if str(extra) not in sys.path:
        sys.path.insert(0, str(extra))

from ambiegen_ros.core.config import ConfigError  # noqa: E402
from ambiegen_ros.problems import get_problem  # noqa: E402
from ambiegen_ros.ros import conversions  # noqa: E402
from ambiegen_ros.ros.types import TypeRegistry  # noqa: E402
from ambiegen_ros.sims import Outcome, reference  # noqa: E402
from ambiegen_ros.sims.full_model import sim_config  # noqa: E402
from ambiegen_ros.sims.stamp_order import StampOrder  # noqa: E402
from sim_nodes.adapter import nav2_rules, params  # noqa: E402
from sim_nodes.adapter.job import Job  # noqa: E402
from sim_nodes.adapter.judge import DECIDED, HOLD, RunView  # noqa: E402
from sim_nodes.adapter.node import COMMON, SutAdapter, help_doc  # noqa: E402
from sim_nodes.adapter.registry import JUDGES, judge_for  # noqa: E402
from sim_nodes.adapter.robot_nav2 import Nav2Robot  # noqa: E402
from sim_nodes.adapter.robot_topic import TopicRobot  # noqa: E402
from sim_nodes.adapter.samples import timed  # noqa: E402
from sim_nodes.adapter.thermostat import ThermostatRun  # noqa: E402
from sim_nodes.adapter.vehicle import VehicleRun  # noqa: E402
from test_full_models import GENTLE, easy_robot_elements  # noqa: E402

REG = TypeRegistry()
S = 1_000_000_000  # ns per s


class Pub:
    def __init__(self, topic: str):
        self.topic, self.sent = topic, []

    def publish(self, msg) -> None:
        self.sent.append(msg)

    def subscription_count(self) -> int:
        return 1


class StandInNode:
    """What a judge asks of its node: publishers (recording), subscriptions, messages and a clock."""

    def __init__(self):
        self.pubs: dict[str, Pub] = {}
        self.subs: dict[str, object] = {}
        self.ns = 0
        self.said: list[str] = []
        self.logger = SimpleNamespace(warning=self.said.append, info=self.said.append, error=self.said.append)

    def create_publisher(self, typename, topic, qos):
        self.pubs[topic] = Pub(topic)
        return self.pubs[topic]

    def create_subscription(self, typename, topic, callback, qos):
        self.subs[topic] = callback

    def new_message(self, typename, **fields):
        return REG.new(typename, **fields)

    def now_ns(self) -> int:
        return self.ns


class StandInNav2:
    """Nav2's action client as the adapter reads it: the last result, the recoveries, the goals sent."""

    def __init__(self):
        self.result, self.recoveries, self.handle, self.goals, self.cleared = None, 0, None, [], 0

    def send(self, goal) -> None:
        self.goals.append(goal)
        self.result, self.recoveries = None, 0

    def clear_costmaps(self) -> None:
        self.cleared += 1

    def cancel(self) -> None:
        pass


def settings(judge, **values):
    """The judge's settings read from its tables, ``values`` standing in for ``-p NAME:=VALUE``."""
    return params.declare(lambda name, default, help: values.get(name, default), COMMON + judge.PARAMS)


def make_judge(judge, problem, oracle=None, **values):
    node = StandInNode()
    values = {"problem": problem.name, "goal_mode": judge.goal_mode or "topic", **values}
    s = settings(judge, **values)
    made = judge(node, s, oracle or sim_config(problem.name), problem)
    host = SimpleNamespace(job=None, on_sample=lambda msg: None, sample_qos=None, on_nav2_left_active=None)
    if judge is Nav2Robot:  # the topics, and a stand-in for Nav2's client
        TopicRobot.wire(made, host)
        made.nav2 = StandInNav2()
    else:
        made.wire(host)
    return made, node, host


@pytest.fixture(scope="module")
def robot():
    p = get_problem("robot", {"profile": "refined"})
    return p, p.parse({"problem": "robot", "elements": easy_robot_elements()})


def robot_job(judge, node, scenario):
    msg = conversions.scenario_message(node.new_message, 0, judge.problem, scenario, conversions.ScenarioMeta("r", 1))
    job = Job("r", 1, scenario, msg)
    judge.setup(job, 0.0)
    return job


def along_the_diagonal(seconds: float, speed: float = 0.3, dt: float = 0.1):
    """Times and (x, y, yaw, v) rows of a robot leaving (1.5, 1.5) towards the goal (48.5, 48.5)."""
    t = np.arange(0.0, seconds + 1e-9, dt)
    d = speed * t / math.sqrt(2)
    return t, np.column_stack([1.5 + d, 1.5 + d, np.full(len(t), math.pi / 4), np.full(len(t), speed)])


# --- a robot on its topics ------------------------------------------------------------------------
def test_the_robot_on_topics_publishes_map_and_start_then_the_goal_and_knows_the_start(robot):
    judge, node, _ = make_judge(TopicRobot, robot[0])
    job = robot_job(judge, node, robot[1])
    assert job.phase == "settle" and job.settle_until == pytest.approx(0.3)
    assert [len(node.pubs[t].sent) for t in ("/map", "/initialpose", "/goal_pose")] == [1, 1, 0]
    assert job.start_pose[2] == pytest.approx(math.pi / 4)  # facing the route's first leg (start_heading route)
    judge.send_goal(job)
    (goal,) = node.pubs["/goal_pose"].sent
    assert (goal.pose.position.x, goal.pose.position.y) == (48.5, 48.5)
    row = lambda x, y, yaw: (0, 0, x, y, yaw, 0.0)  # noqa: E731
    assert judge.at_start(row(1.6, 1.5, math.pi / 4), job)
    assert not judge.at_start(row(30.0, 30.0, math.pi / 4), job)  # a world still showing the last run
    assert not judge.at_start(row(1.5, 1.5, 0.0), job)  # turned by more than start_yaw_tolerance
    scenario_heading, _, _ = make_judge(TopicRobot, robot[0], start_heading="scenario")
    assert robot_job(scenario_heading, StandInNode(), robot[1]).start_pose[2] == 0.0


def test_a_goal_nothing_answered_goes_again_and_one_the_stack_answered_does_not(robot):
    """A goal lost on the wire (a stack part's discovery not complete): with a status topic, no
    status since the goal after GOAL_RESEND_S goes again, at most GOAL_RESENDS times; a status
    heard, or no topic that could tell, and it goes once."""
    from sim_nodes.adapter.robot_topic import GOAL_RESEND_S, GOAL_RESENDS

    def turn(judge, job, now):
        return judge.step(job, RunView(now, judge_order, False, lambda: False))

    judge_order = StampOrder([("stall", "decision")])
    judge, node, _ = make_judge(TopicRobot, robot[0], stall_topic="/nd_driver/stall")
    job = robot_job(judge, node, robot[1])
    judge.send_goal(job)
    sent = job.goal_sent
    turn(judge, job, sent + GOAL_RESEND_S / 2)
    assert len(node.pubs["/goal_pose"].sent) == 1  # not yet: a stack may take a moment
    for k in range(GOAL_RESENDS + 2):
        turn(judge, job, job.goal_sent + GOAL_RESEND_S + 0.1)
    assert len(node.pubs["/goal_pose"].sent) == 1 + GOAL_RESENDS and job.goal_sends == 1 + GOAL_RESENDS
    assert any("it goes again" in line for line in node.said)

    answered, node2, _ = make_judge(TopicRobot, robot[0], stall_topic="/nd_driver/stall")
    job2 = robot_job(answered, node2, robot[1])
    answered.send_goal(job2)
    job2.heard["stall"] = 1  # the stack's first status since the goal (the node counts them)
    turn(answered, job2, job2.goal_sent + 10 * GOAL_RESEND_S)
    assert len(node2.pubs["/goal_pose"].sent) == 1

    blind, node3, _ = make_judge(TopicRobot, robot[0])  # no status, no plan topic: nothing tells a lost goal
    job3 = robot_job(blind, node3, robot[1])
    blind.send_goal(job3)
    turn(blind, job3, job3.goal_sent + 10 * GOAL_RESEND_S)
    assert len(node3.pubs["/goal_pose"].sent) == 1


def run_by_stamps(judge, job, deliveries):
    """The node's way from messages to the oracle: samples and collision statuses into the stamp
    order in the given delivery order, released, timed and fed to the judge."""
    order = StampOrder(list(judge.STREAMS[:1]))
    for kind, stamp, payload in deliveries:
        if kind == "sample":
            order.sample(stamp, (stamp, 0, *payload))
        else:
            order.message("collision", stamp, payload)
    released = order.release()
    batch, job.t_prev = timed(released, (released[0][0], 0), "sim", 1.0, job.t_prev)
    judge.feed(job, *batch)
    return job.judge


def test_the_robot_on_topics_decides_a_collision_at_its_stamp_whatever_the_order_of_arrival(robot):
    t, rows = along_the_diagonal(3.0)
    samples = [("sample", int(round(ti * S)), tuple(r)) for ti, r in zip(t, rows)]
    bump = ("status", int(1.5 * S), "bumped")
    heartbeat = ("status", int(3.0 * S), None)
    outcomes = []
    for deliveries in (samples + [bump, heartbeat], [bump] + samples + [heartbeat]):
        judge, node, _ = make_judge(TopicRobot, robot[0], collision_topic="/bumper")
        outcomes.append(run_by_stamps(judge, robot_job(judge, node, robot[1]), deliveries).outcome())
    for out in outcomes:
        assert out.failure_kind == "collision" and "reported on /bumper: bumped" in out.detail
        assert float(out.metrics["time"]) == pytest.approx(1.5)  # the status's stamp, not its arrival
    quiet, node, _ = make_judge(TopicRobot, robot[0], collision_topic="/bumper")
    job = robot_job(quiet, node, robot[1])
    assert not run_by_stamps(quiet, job, samples + [heartbeat]).decided  # no bump: 3 s of driving decide nothing


def test_odometry_from_the_start_pose_is_judged_in_the_map_frame(robot):
    judge, node, _ = make_judge(TopicRobot, robot[0], odom_frame="start", start_heading="scenario")
    job = robot_job(judge, node, robot[1])
    t = np.array([0.0, 1.0])
    judge.feed(job, t, np.array([[0.0, 0.0, 0.0, 0.0], [0.5, 0.0, 0.0, 0.5]]), [{}, {}])
    out = job.judge.outcome()
    assert np.allclose(out.trajectory, [[1.5, 1.5], [2.0, 1.5]])  # the start pose (1.5, 1.5, 0) + 0.5 m along x


# --- a robot through Nav2's action ------------------------------------------------------------------
def nav2_run(robot, seconds: float = 2.0, **values):
    judge, node, _ = make_judge(Nav2Robot, robot[0], **values)
    job = robot_job(judge, node, robot[1])
    judge.send_goal(job)
    if seconds:
        t, rows = along_the_diagonal(seconds)
        judge.feed(job, t, rows, [{}] * len(t))
    return judge, node, job


def view(newest=None, watermark=math.inf, unjudged=False, grace=False):
    return RunView(0.0, SimpleNamespace(newest=newest, watermark=watermark), unjudged, lambda: grace)


def test_a_nav2_abort_with_one_of_ours_error_codes_becomes_an_error_record(robot):
    for code, ours in ((107, True), (105, False)):
        judge, _, job = nav2_run(robot, ours_error_codes="102,107,202")
        assert judge.settings.ours_error_codes == {102, 107, 202} and judge.nav2.cleared == 1
        judge.nav2.result = {"status": "aborted", "error_code": code, "error_msg": "no data"}
        assert judge.step(job, view(grace=True)) == HOLD  # a crash report may still explain it
        assert judge.step(job, view()) == DECIDED
        out = nav2_rules.with_stack_word(job.judge.outcome(), judge.nav2, job)
        out = nav2_rules.ours_or_the_stacks(out, judge.settings.ours_error_codes)
        assert out.metrics["nav2_error_code"] == code and "no data" in out.detail
        if ours:
            assert out.failure_kind == "error" and not out.failed and "error 107 is ours" in out.detail
            assert out.metrics["sut_failure_kind"] == "nav2_aborted"
        else:
            assert out.failure_kind == "nav2_aborted" and out.failed


def test_nav2s_result_waits_until_the_samples_before_it_are_judged(robot):
    judge, _, job = nav2_run(robot)
    judge.nav2.result = {"status": "succeeded", "error_code": 0, "error_msg": ""}
    assert judge.step(job, view(newest=7 * S, watermark=6 * S)) is None  # a status stream still behind
    assert judge.step(job, view(newest=9 * S, watermark=7 * S, unjudged=True)) is None  # samples in hand
    assert not job.judge.decided
    assert judge.step(job, view(newest=9 * S, watermark=7 * S)) == DECIDED  # its stamp: the newest then, 7 s


def test_a_pass_after_recoveries_is_a_near_miss(robot):
    for recoveries, said in ((0, None), (1, "(a near miss: after 1 recovery)"), (5, "(a near miss: after 5 recoveries)")):
        judge, _, job = nav2_run(robot)
        judge.nav2.result, judge.nav2.recoveries = {"status": "succeeded", "error_code": 0, "error_msg": ""}, recoveries
        assert judge.step(job, view()) == DECIDED
        out = job.judge.outcome()
        assert out.failure_kind == "none" and out.detail.startswith("Nav2 reached the goal after 2.0 s")
        assert out.detail.endswith(said) if said else "near miss" not in out.detail
    early, _, job = nav2_run(robot, early_verdicts=True)  # the monitors decide: Nav2's success is not the verdict
    early.nav2.result = {"status": "succeeded", "error_code": 0, "error_msg": ""}
    assert early.step(job, view()) is None and not job.judge.decided


def test_a_goal_refused_at_once_goes_again_when_the_worlds_clock_has_run_on(robot):
    judge, node, job = nav2_run(robot, seconds=0.0)
    judge.nav2.result = {"status": "aborted", "error_code": 103, "error_msg": "Resulting plan has 0 poses"}
    node.ns = 5 * S
    assert judge.step(job, view()) == HOLD and not job.judge.decided
    assert "aborted its goal after 0.0 s (error 103: Resulting plan has 0 poses)" == job.nav2_first_abort
    judge.nav2.result = None
    node.ns = int(5.5 * S)
    assert judge.step(job, view()) is None and len(judge.nav2.goals) == 1  # half a second: not yet
    node.ns = 6 * S
    assert judge.step(job, view()) is None and len(judge.nav2.goals) == 2
    assert job.nav2_resend_wait_s == pytest.approx(1.0)
    judge.nav2.result = {"status": "aborted", "error_code": 103, "error_msg": "again"}
    assert judge.step(job, view()) == DECIDED  # a real failure repeats: the second answer is the verdict
    assert job.judge.outcome().failure_kind == "nav2_aborted"


def test_a_give_up_at_the_stacks_time_per_goal_counts_only_if_the_reference_makes_it_in_that_time():
    """The hazards scenario's reference needs 62.3 s (test_hazards_world): a 50 s tree cannot be blamed."""
    from helpers.hazards_cases import hazards_case

    problem, scenario = hazards_case("collision with a person")

    def certified(elapsed: float, budget: float) -> Outcome:
        out = Outcome(objectives={"robot_time": elapsed}, failed=True, failure_kind="nav2_aborted",
                      detail=f"Nav2 aborted its goal after {elapsed:.1f} s (error 0)")
        given = nav2_rules.budget_spent(out.failure_kind, elapsed, budget)
        return reference.certify(out, reference.after(problem, scenario, sim_config("robot"), out, budget=given))

    assert nav2_rules.budget_spent("nav2_aborted", 46.0, 50.0) == 50.0  # within 10 % of the budget
    assert nav2_rules.budget_spent("nav2_aborted", 20.0, 50.0) is None  # long before it: not the budget's
    assert nav2_rules.budget_spent("collision", 50.0, 50.0) is None
    short = certified(49.0, 50.0)
    assert short.failure_kind == "invalid_test" and "the stack's own 50 s per goal" in short.detail
    assert certified(119.0, 120.0).failed  # 120 s was time enough for the reference


# --- a vehicle ---------------------------------------------------------------------------------------
def test_the_vehicle_publishes_the_road_and_judges_the_cars_odometry():
    p = get_problem("vehicle", {"profile": "refined"})
    sc = p.parse({"problem": "vehicle", "elements": [{"type": t, "length": ln, "angle": a} for t, ln, a in GENTLE]})
    judge, node, _ = make_judge(VehicleRun, p)
    msg = conversions.scenario_message(node.new_message, 0, p, sc, conversions.ScenarioMeta("r", 1))
    job = Job("r", 1, sc, msg)
    judge.setup(job, 3.0)
    (road,) = node.pubs["/road"].sent
    assert len(road.poses) == len(msg.road.poses) > 2 and job.phase == "waiting" and job.go == 3.0
    assert job.limit_sim == pytest.approx(job.judge.time_limit) and math.isfinite(job.limit_sim)
    pts = conversions.path_points(msg.road)
    heading = math.atan2(pts[1, 1] - pts[0, 1], pts[1, 0] - pts[0, 0])
    off = pts[0] + 20.0 * np.array([math.sin(heading), -math.cos(heading)])  # 20 m right of the road
    judge.feed(job, np.array([0.0, 0.1]), np.array([[*off, heading, 1.0], [*off, heading, 1.0]]), [{}, {}])
    out = job.judge.outcome()
    assert out.failure_kind == "out_of_lane" and out.failed


# --- a thermostat ------------------------------------------------------------------------------------
def test_the_thermostat_publishes_its_set_points_on_their_schedule():
    p = get_problem("thermostat", {"profile": "replication"})
    elements = [{"temperature": 16 + 2 * i, "duration": 60, "model": 7 - i} for i in range(3)]
    sc = p.parse({"problem": "thermostat", "elements": elements})
    judge, node, _ = make_judge(ThermostatRun, p, time_scale=3600.0)
    msg = conversions.scenario_message(node.new_message, 0, p, sc, conversions.ScenarioMeta("r", 1))
    job = Job("r", 1, sc, msg)
    judge.setup(job, 0.0)
    sent = lambda: [m.data for m in node.pubs["/thermostat/setpoint"].sent]  # noqa: E731
    assert sent() == [16.0] and [m.data for m in node.pubs["/thermostat/room_model"].sent] == [7]
    assert len(node.pubs["/thermostat/initial_temperature"].sent) == 1
    assert judge.step(job, RunView(100.0, None, False, lambda: False)) is None and sent() == [16.0]  # no reading yet
    job.anchor = 100.0  # the first reading arrived: the room's clock starts; 60 min = 1 wall s at 3600x
    judge.step(job, RunView(100.9, None, False, lambda: False))
    assert sent() == [16.0]
    judge.step(job, RunView(101.0, None, False, lambda: False))
    assert sent() == [16.0, 18.0]
    judge.step(job, RunView(105.0, None, False, lambda: False))  # a late turn catches up, in order, once
    judge.step(job, RunView(106.0, None, False, lambda: False))
    assert sent() == [16.0, 18.0, 20.0] and [m.data for m in node.pubs["/thermostat/room_model"].sent] == [7, 6, 5]
    reading = REG.new("sensor_msgs/msg/Temperature", temperature=21.5)
    assert judge.sample_of(reading)[2] == 21.5
    with pytest.raises(ValueError):
        judge.sample_of(REG.new("sensor_msgs/msg/Temperature", temperature=float("nan")))


# --- the tables -------------------------------------------------------------------------------------
@pytest.mark.parametrize("name, value, says", [
    ("stamp_clock", "sundial", "stamp_clock: unknown 'sundial' (allowed: sim|wall|receive)"),
    ("goal_mode", "carrier_pigeon", "goal_mode: unknown 'carrier_pigeon' (allowed: topic|action|plan)"),
    ("problem", "submarine", "problem: unknown 'submarine' (allowed: robot|vehicle|thermostat)"),
    ("time_scale", 0.0, "time_scale: must be > 0"),
    ("time_scale", float("nan"), "time_scale: must be > 0"),
    ("map_upsample", 0, "map_upsample: must be >= 1"),
    ("start_heading", "backwards", "start_heading: unknown 'backwards' (allowed: route|scenario)"),
    ("ours_error_codes", "107,abc", "ours_error_codes: comma separated integers, not '107,abc'"),
])
def test_a_bad_value_is_one_config_error_line_naming_the_parameter(name, value, says):
    with pytest.raises(ConfigError) as error:
        settings(Nav2Robot, **{name: value})
    assert str(error.value) == says and "\n" not in str(error.value)


def test_the_tables_keep_the_defaults_and_choose_the_judge():
    robot_topic = settings(TopicRobot)
    assert robot_topic.early_verdicts is True and robot_topic.settle_time == 0.3 and robot_topic.map_upsample == 1
    nav2 = settings(Nav2Robot, goal_mode="action")
    assert nav2.early_verdicts is False and nav2.ours_error_codes == set() and nav2.nav2_restarts == 3
    assert settings(Nav2Robot, goal_mode="action", early_verdicts=True).early_verdicts is True
    assert [judge_for("robot", "topic"), judge_for("robot", "action"), judge_for("vehicle", "action"),
            judge_for("thermostat", "topic")] == [TopicRobot, Nav2Robot, VehicleRun, ThermostatRun]
    names = [p.name for p in COMMON] + [p.name for judge in JUDGES for p in judge.PARAMS]
    text = help_doc()
    assert all(f"  {name} (" in text for name in names)  # every parameter in --help, with its help
    assert "ours_error_codes (str, default '')" in text and "comma separated" in text


# --- the robot judged: the one robot_profile names (issue 69) -----------------------------------------
def adapter_oracle(judge=TopicRobot, **values):
    """The oracle config ``SutAdapter`` builds from its parameters, ``values`` standing in for ``-p``."""
    s = settings(judge, goal_mode=judge.goal_mode, **values)
    stand_in = SimpleNamespace(problem_name="robot", run_invalid=False, reference=True, settings=s,
                               node=SimpleNamespace(declare_parameter=lambda name, default, help: default))
    return SutAdapter._oracle(stand_in, judge.ORACLE_FIELDS)


def accepted(oracle, grid: np.ndarray, start: tuple, goal: tuple, start_yaw: float):
    """``SutAdapter.accept`` of a scenario on ``grid`` (0.1 m cells): what it answered at once
    (INVALID_TEST, never sent) and what it queued to run."""
    env = SimpleNamespace(grid=grid, resolution=0.1, start=start, goal=goal, start_yaw=start_yaw, goal_yaw=None,
                          unmapped=None)
    problem = SimpleNamespace(name="robot", environment=lambda scenario: env, hazards=False)
    answered, queue = [], deque()
    stand_in = SimpleNamespace(job=None, queue=queue, answered={}, mode=TopicRobot, validity=lambda scenario: (True, ""),
                               run_invalid=False, reference=True, problem=problem, oracle=oracle, idle=lambda: None,
                               publish=lambda run_id, sid, outcome: answered.append(outcome),
                               node=SimpleNamespace(logger=SimpleNamespace(info=lambda text: None)))
    SutAdapter.accept(stand_in, "r", 1, None, None)
    return answered, list(queue)


def gap_of(cells: int) -> np.ndarray:
    """4 x 4 m of 0.1 m cells, a wall across the middle with a gap ``cells`` wide."""
    g = np.zeros((40, 40), dtype=bool)
    g[19:21, :] = True
    g[19:21, 17:17 + cells] = False
    return g


def test_with_the_turtlebot4_profile_the_adapter_judges_its_body_and_sends_what_only_it_passes(robot):
    from ambiegen_ros.sims.reference.robot import body_radius
    from ambiegen_ros.sims.robot_profile import load_profile

    tb4 = adapter_oracle(Nav2Robot, robot_profile="turtlebot4")
    assert body_radius(tb4) == 0.22 and tb4.robot_profile.name == "turtlebot4"
    judge, node, _ = make_judge(TopicRobot, robot[0], oracle=tb4)  # the judge of a run measures the TB4's body
    assert robot_job(judge, node, robot[1]).judge.walls.footprint == pytest.approx(load_profile("turtlebot4").footprint())
    # a 0.7 m gap: the TB4 keeps 0.22 + 0.1 m from each side, the Pioneer would need 0.26 + 0.1 m
    answered, queued = accepted(tb4, gap_of(7), (20, 5), (20, 35), math.pi / 2)
    assert answered == [] and len(queued) == 1 and queued[0].before.passed
    (pioneer,), queued = accepted(adapter_oracle(), gap_of(7), (20, 5), (20, 35), math.pi / 2)
    assert pioneer.failure_kind == "invalid_test" and "0.36" in pioneer.detail and not queued


def test_with_the_ackermann_car_a_turn_tighter_than_its_radius_is_an_invalid_test_with_the_reason():
    hairpin = np.ones((60, 19), dtype=bool)  # a 1.5 m corridor, the goal behind the start: a U-turn 1.56 m across
    hairpin[2:58, 2:17] = False
    (car,), queued = accepted(adapter_oracle(Nav2Robot, robot_profile="ackermann_car"), hairpin, (9, 40), (9, 10),
                              math.pi / 2)
    assert car.failure_kind == "invalid_test" and not car.failed and not queued
    assert car.detail.startswith("no car-like robot drives it") and "turn" in car.detail, car.detail
    assert car.metrics["reference_min_turning_radius_m"] == pytest.approx(0.779, abs=1e-3)
    answered, queued = accepted(adapter_oracle(robot_profile="turtlebot4"), hairpin, (9, 40), (9, 10), math.pi / 2)
    assert answered == [] and len(queued) == 1  # a robot that turns in place drives it: the car's radius refused it


def test_no_profile_keeps_the_pioneer_and_a_bad_one_is_one_line_naming_the_field(tmp_path):
    from ambiegen_ros.sims.reference.robot import body_radius, footprint_radius

    plain = adapter_oracle()
    assert plain == sim_config("robot", {"run_invalid": False, "reference": True})  # today's config, unchanged
    assert getattr(plain, "robot_profile", None) is None and body_radius(plain) == footprint_radius()
    assert settings(Nav2Robot, goal_mode="action").robot_profile == ""
    bad = tmp_path / "slow.yaml"
    bad.write_text((REPO / "config" / "robots" / "turtlebot4.yaml").read_text().replace("x: 0.5", "x: 0.0", 1))
    with pytest.raises(ConfigError) as error:
        adapter_oracle(robot_profile=str(bad))
    assert str(error.value) == f"robot_profile {bad}: limits.max_speed.x: must be > 0, got 0.0"
    with pytest.raises(ConfigError, match="^robot_profile roomba: robot_profile: no shipped profile 'roomba'"):
        adapter_oracle(robot_profile="roomba")



def test_the_adapter_node_refuses_a_bad_profile_in_one_line_and_exits(tmp_path, ros_domain):
    import os
    import subprocess

    bad = tmp_path / "bad.yaml"
    bad.write_text("name: bad\nfootprint: {radius: 0.2, polygon: [[0, 0], [1, 0], [0, 1]]}\n")
    run = subprocess.run([sys.executable, "-m", "sim_nodes.sut_adapter", "--ros-args", "-p", "problem:=robot",
                          "-p", f"robot_profile:={bad}"], cwd=REPO, capture_output=True, text=True, timeout=120,
                         env={**os.environ, "ROS_DOMAIN_ID": str(ros_domain)})
    lines = (run.stdout + run.stderr).strip().splitlines()
    assert run.returncode == 2 and len(lines) == 1, lines
    assert lines[0].endswith(f"robot_profile {bad}: footprint: give either radius or polygon")


# --- setup that fails -------------------------------------------------------------------------------
def setup_on_a_stand_in(error: Exception):
    """``SutAdapter.setup`` on a STAND-IN whose judge raises ``error``: what it finished with, what it logged."""
    finished, logged = [], []

    def raise_it(job, now):
        raise error

    stand_in = SimpleNamespace(mode=SimpleNamespace(setup=raise_it), finish=finished.append,
                               node=SimpleNamespace(logger=SimpleNamespace(error=logged.append)))
    SutAdapter.setup(stand_in, Job("r", 4, None, None), 0.0)
    (outcome,) = finished
    return outcome, logged


def test_a_bad_scenario_message_is_an_error_record_without_a_traceback():
    from ambiegen_ros.core.attributes import ScenarioError

    outcome, logged = setup_on_a_stand_in(ScenarioError("map.info", "10 x 10 cells but 3 data values", "w x h"))
    assert outcome.failure_kind == "error" and not outcome.failed and "ScenarioError" in outcome.detail
    assert "10 x 10 cells" in outcome.detail and not logged


def test_a_fault_of_the_adapter_logs_its_traceback_and_still_ends_in_an_error_record():
    outcome, logged = setup_on_a_stand_in(AttributeError("'NoneType' object has no attribute 'info'"))
    assert outcome.failure_kind == "error" and not outcome.failed
    assert "AttributeError in the adapter" in outcome.detail and "a fault of ours" in outcome.detail
    (log,) = logged
    assert "scenario 4" in log and "Traceback (most recent call last)" in log and "raise_it" in log


def test_a_run_being_judged_is_still_held_until_its_result_is_out():
    """Heartbeats count a run the adapter judges after Nav2 answered (reference, timing, hazards: a
    moment) until its result is out: on the K=1 Nav2 measurement the runner heard "idle" in that
    moment and sent the scenario again. ``SutAdapter.finish`` on a STAND-IN adapter."""
    held = []

    def stand_in_for(job, with_timing):
        stand_in = SimpleNamespace(
            queue=deque(), job=job, finishing=None, _fast=None, topics={}, order=SimpleNamespace(streams={}),
            reference=False, problem_name="robot", problem=SimpleNamespace(hazards=False), known_failures=[],
            ours_error_codes=set(), time_scale=1.0, stamp_clock="sim", idle=lambda: None,
            nav2=SimpleNamespace(result=None, handle=None, recoveries=0, cancel=lambda: None),
            mode=SimpleNamespace(with_timing=with_timing, certifies_itself=False),
            node=SimpleNamespace(logger=SimpleNamespace(info=lambda text: None)))
        stand_in.publish = lambda run_id, sid, out: held.append((sid, SutAdapter.in_flight(stand_in)))
        return stand_in

    stand_in = stand_in_for(Job("r", 4, None, None, started=0.0), lambda out: out)
    SutAdapter.finish(stand_in, Outcome.rejected("judged"))
    assert held == [(4, 1)] and SutAdapter.in_flight(stand_in) == 0  # held while its result went out, then not

    def judging_fails(out):
        raise RuntimeError("a fault while judging")

    stand_in = stand_in_for(Job("r", 5, None, None, started=0.0), judging_fails)
    with pytest.raises(RuntimeError):
        SutAdapter.finish(stand_in, Outcome.rejected("judged"))
    assert SutAdapter.in_flight(stand_in) == 0  # never held for ever
