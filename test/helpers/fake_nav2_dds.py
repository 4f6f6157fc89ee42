"""A FAKE of Nav2 (not Nav2): the five nodes of a Nav2 stack, each played on Cyclone DDS from PyPI.

``test/helpers/fake_nav2/ros2`` (a fake ``ros2``) runs this file for ``ros2 launch ...`` (``--launch``:
the five as its children, as ``--stack bringup``'s ``navigation_launch.py`` starts them) and for ``ros2
run PKG EXE --ros-args -r __node:=NAME ...`` (``--stack ours``: one node); NAME says which node it
plays. Every one answers ``/<NAME>/get_state`` with ``active``; the services speak rmw_cyclonedds_cpp's
format (``FakeService``, from the client tests), so the adapter drives it as it drives Nav2. What the test needs of a stack that holds its robot:

* ``bt_navigator``: ``navigate_to_pose``; a goal it accepts gets feedback at 10 Hz while it runs (as
  Nav2's navigator does whatever the robot does) and is aborted with 105 (FollowPath's
  FAILED_TO_MAKE_PROGRESS) once ``/cmd_vel`` has been silent for ``FAKE_NAV2_PATIENCE_S`` s (0: never,
  the goal runs until cancelled), as Nav2's progress checker ends a robot that does not move;
* ``controller_server``: ``/cmd_vel`` (Twist) at 10 Hz, zero while no goal runs; once a goal's feedback
  comes, ``FAKE_NAV2_DRIVE`` commands of 0.1 m/s ahead, then, with ``FAKE_NAV2_CONTROLLER``: ``hold``
  nothing more for that goal (a collision monitor holding the robot: it stops publishing), still
  running; ``freeze``: the process stops being scheduled: it becomes, under the same pid and node
  name, a process that sleeps for ever (state S, no CPU: as a frozen cgroup or an uninterruptible
  wait leaves a process, which no signal state shows);
* ``controller_server``, with ``FAKE_NAV2_STARVED=1``: a starved controller, as navigation2 jazzy's says
  it on /rosout (``rcl_interfaces/msg/Log``, rcl's QoS): "Control loop missed its desired rate of
  10.0000 Hz. ..." each cycle while a goal runs (its 10 Hz: every cycle missed);
* ``planner_server`` and ``controller_server`` serve their costmap's clearing; the lifecycle manager says
  it is active; ``behavior_server`` only answers its state.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
for extra in (REPO, REPO / "test" / "ros"):
    if str(extra) not in sys.path:
        sys.path.insert(0, str(extra))

from ambiegen_ros.ros import interfaces, transport  # noqa: E402
from ambiegen_ros.ros.qos import Qos  # noqa: E402
from ambiegen_ros.ros.transport.dds_services import FEEDBACK_QOS, STATUS_QOS  # noqa: E402
from test_dds_services import FakeService  # noqa: E402  (rmw_cyclonedds_cpp's service side)

ACTION = "nav2_msgs/action/NavigateToPose"
FEEDBACK = "/navigate_to_pose/_action/feedback"
GET_STATE, CLEAR, TRIGGER = "lifecycle_msgs/srv/GetState", "nav2_msgs/srv/ClearEntireCostmap", "std_srvs/srv/Trigger"
MANAGE, CANCEL = "nav2_msgs/srv/ManageLifecycleNodes", "action_msgs/srv/CancelGoal"
EXECUTING, SUCCEEDED, CANCELED, ABORTED = 2, 4, 5, 6
COMMANDS = Qos(reliable=True, transient_local=False, depth=10)
ANY = Qos(reliable=False, transient_local=False, depth=10)  # best effort: matches any writer
PERIOD_S = 0.1


def answer(node, srv_type: str, **fields):
    return lambda _request, _token: node._registry.new(srv_type + "_Response", **fields)


class Navigator:
    """bt_navigator's action: feedback while a goal runs, an abort once the commands stop for patience s."""

    def __init__(self, node):
        self.node, self.reg = node, node._registry
        base = "/navigate_to_pose/_action/"
        self.services = [FakeService(node, ACTION + "_SendGoal", base + "send_goal", self.on_goal),
                         FakeService(node, ACTION + "_GetResult", base + "get_result", self.on_result),
                         FakeService(node, CANCEL, base + "cancel_goal", self.on_cancel)]
        self.feedback = node.create_publisher(ACTION + "_FeedbackMessage", FEEDBACK, FEEDBACK_QOS)
        self.status = node.create_publisher("action_msgs/msg/GoalStatusArray", base + "status", STATUS_QOS)
        node.create_subscription("geometry_msgs/msg/Twist", "/cmd_vel", self.on_cmd_vel, ANY, raw=True)
        self.patience = float(os.environ.get("FAKE_NAV2_PATIENCE_S", "0"))
        self.goals: dict[bytes, dict] = {}
        self.commanded = 0.0
        self.next_feedback = 0.0

    def on_cmd_vel(self, _data, _receive_ns=0) -> None:
        self.commanded = time.monotonic()

    def on_goal(self, request, _token):
        key = bytes(bytearray(request.goal_id.uuid))
        self.goals[key] = {"id": request.goal_id, "status": EXECUTING, "token": None, "since": time.monotonic()}
        print(f"goal {request.goal.pose.pose.position.x:.3f} {request.goal.pose.pose.position.y:.3f}", flush=True)
        self._publish_status()
        return self.reg.new(ACTION + "_SendGoal_Response", accepted=True,
                            stamp=self.reg.new("builtin_interfaces/msg/Time", sec=1))

    def on_result(self, request, token):
        self.goals[bytes(bytearray(request.goal_id.uuid))]["token"] = token
        return None  # answered when the goal ends

    def on_cancel(self, request, _token):
        goal = self.goals.get(bytes(bytearray(request.goal_info.goal_id.uuid)))
        ok = goal is not None and goal["status"] == EXECUTING
        if ok:
            goal["status"] = CANCELED
            self._publish_status()
        return self.reg.new(CANCEL + "_Response", return_code=0 if ok else 2,
                            goals_canceling=[request.goal_info] if ok else [])

    def _publish_status(self) -> None:
        reg = self.reg
        self.status.publish(reg.new("action_msgs/msg/GoalStatusArray", status_list=[
            reg.new("action_msgs/msg/GoalStatus", goal_info=reg.new("action_msgs/msg/GoalInfo", goal_id=g["id"]),
                    status=g["status"]) for g in self.goals.values()]))

    def poll(self, now: float) -> None:
        feed = now >= self.next_feedback
        if feed:
            self.next_feedback = now + PERIOD_S
        for goal in self.goals.values():
            if goal["status"] == EXECUTING:
                held = now - max(goal["since"], self.commanded)
                if self.patience > 0 and held > self.patience:
                    print(f"aborted: no command for {held:.1f} s", flush=True)
                    goal["status"] = ABORTED
                    self._publish_status()
                elif feed:
                    self.feedback.publish(self.reg.new(ACTION + "_FeedbackMessage", goal_id=goal["id"],
                                                       feedback=self.reg.new(ACTION + "_Feedback")))
            if goal["status"] != EXECUTING and goal["token"] is not None:
                aborted = goal["status"] == ABORTED
                result = self.reg.new(ACTION + "_Result", error_code=105 if aborted else 0,
                                      error_msg="fake: held still, no progress" if aborted else "")
                self.services[1].respond(goal["token"], self.reg.new(ACTION + "_GetResult_Response",
                                                                     status=goal["status"], result=result))
                goal["token"] = None


class Controller:
    """Commands at 10 Hz: zero without a goal; with one, a few ahead, then held (or frozen)."""

    def __init__(self, node):
        self.node = node
        self.services = [FakeService(node, CLEAR, "/local_costmap/clear_entirely_local_costmap",
                                     answer(node, CLEAR))]
        self.pub = node.create_publisher("geometry_msgs/msg/Twist", "/cmd_vel", COMMANDS)
        interfaces.ensure(node._registry, ACTION)
        node.create_subscription(ACTION + "_FeedbackMessage", FEEDBACK, self.on_feedback, ANY, raw=True)
        self.mode = os.environ.get("FAKE_NAV2_CONTROLLER", "hold")
        self.rosout = None
        if os.environ.get("FAKE_NAV2_STARVED") == "1":  # rcl's /rosout publisher: reliable, transient local
            self.rosout = node.create_publisher("rcl_interfaces/msg/Log", "/rosout",
                                                Qos(reliable=True, transient_local=True, depth=1000))
        self.drive = int(os.environ.get("FAKE_NAV2_DRIVE", "20"))
        self.goal: bytes | None = None
        self.sent = 0  # commands ahead for this goal
        self.next = 0.0

    def on_feedback(self, data, _receive_ns=0) -> None:
        goal = bytes(data[4:20])  # after the CDR header: the goal id
        if goal != self.goal:
            self.goal, self.sent = goal, 0

    def poll(self, now: float) -> None:
        if now < self.next:
            return
        self.next = now + PERIOD_S
        if self.rosout is not None and self.goal is not None:
            self.rosout.publish(self.node.new_message(
                "rcl_interfaces/msg/Log", level=30, name=self.node.name, msg="Control loop missed its desired rate of "
                "10.0000 Hz. Current loop rate is 4.1000 Hz."))
        if self.goal is not None and self.sent >= self.drive:
            if self.mode == "freeze":
                print("frozen", flush=True)
                os.execv(sys.executable, [sys.executable, "-c", "import time\nwhile True: time.sleep(3600)",
                                          "--ros-args", "-r", f"__node:={self.node.name}"])
            return  # held: nothing on /cmd_vel
        ahead = 0.1 if self.goal is not None else 0.0
        self.sent += self.goal is not None
        make = self.node.new_message
        self.pub.publish(make("geometry_msgs/msg/Twist", linear=make("geometry_msgs/msg/Vector3", x=ahead)))


class Manager:
    def __init__(self, node):
        self.services = [FakeService(node, TRIGGER, f"/{node.name}/is_active", answer(node, TRIGGER, success=True)),
                         FakeService(node, MANAGE, f"/{node.name}/manage_nodes", answer(node, MANAGE, success=True))]

    def poll(self, now: float) -> None:
        pass


class Planner:
    def __init__(self, node):
        self.services = [FakeService(node, CLEAR, "/global_costmap/clear_entirely_global_costmap",
                                     answer(node, CLEAR))]

    def poll(self, now: float) -> None:
        pass


class Idle(Planner):
    def __init__(self, node):
        self.services = []


ROLES = {"bt_navigator": Navigator, "controller_server": Controller, "planner_server": Planner,
         "lifecycle_manager_navigation": Manager}


NODES = ("controller_server", "planner_server", "behavior_server", "bt_navigator", "lifecycle_manager_navigation")


def launch() -> int:
    """``ros2 launch nav2_bringup navigation_launch.py ...``: the five nodes as children, each death
    said as ``ros2 launch`` says it (the session's watch reads those lines); SIGINT goes on to them."""
    kids = {subprocess.Popen([sys.executable, __file__, "--ros-args", "-r", f"__node:={name}"]): (name, k)
            for k, name in enumerate(NODES, 1)}
    stop: list[int] = []
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda number, _frame: stop.append(number))
    while kids and not stop:
        for proc in [p for p in kids if p.poll() is not None]:
            name, k = kids.pop(proc)
            print(f"[ERROR] [{name}-{k}]: process has died [pid {proc.pid}, exit code {proc.returncode}, "
                  f"cmd '{sys.executable} {__file__}'].", flush=True)
        time.sleep(0.1)
    for proc in kids:
        proc.send_signal(signal.SIGINT)
    for proc in kids:
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
    return 0


def main() -> int:
    if sys.argv[1:2] == ["--launch"]:
        return launch()
    name = next((a[8:] for a in sys.argv if a.startswith("__node:=")), "fake_nav2")
    node = transport.create_node(name, argv=[], backend="dds")
    for srv in (GET_STATE, CLEAR, TRIGGER, MANAGE, CANCEL):
        interfaces.ensure(node._registry, srv)
    interfaces.ensure(node._registry, ACTION)
    state = node._registry.new("lifecycle_msgs/msg/State", id=3, label="active")
    if name == "planner_server" and os.environ.get("FAKE_NAV2_PLANNER"):  # --stack planner: fake_planner_dds.py
        from fake_planner_dds import PathPlanner

        role = PathPlanner(node, os.environ["FAKE_NAV2_PLANNER"])
    else:
        role = ROLES.get(name, Idle)(node)
    services = role.services + [FakeService(node, GET_STATE, f"/{name}/get_state",
                                            answer(node, GET_STATE, current_state=state))]
    stop: list[int] = []
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda number, _frame: stop.append(number))
    print(f"{name} ready (a fake)", flush=True)
    while not stop:
        node.spin_once(0.02)
        for service in services:
            service.poll()
        role.poll(time.monotonic())
    node.shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
