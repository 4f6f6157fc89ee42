"""Services and actions on the DDS backend (``transport/dds_services.py``), with no ROS installed.

The clients, and ``sim_nodes.nav2_client.Nav2Client`` on them, against a server written here on
the same Cyclone DDS from PyPI that behaves as rmw_cyclonedds_cpp's service side does
(``rmw_node.cpp``): its request reader and reply writer carry ``serviceid=`` in USER_DATA, it echoes
the request header (``guid``, ``seq``) before the reply, and it replies only once its reply writer
has matched a reader with the ``clientid=`` of the request's writer. The NavigateToPose server
follows rcl_action's topics and QoS. test/real_ros/test_dds_nav2_client.py drives a real rclpy
server on rmw_cyclonedds_cpp with the same clients.
"""
from __future__ import annotations

import itertools
import json
import os
import re
import time
import uuid
from pathlib import Path
from typing import Any, Callable

import numpy as np
import pytest

from ambiegen_ros.ros import interfaces
from ambiegen_ros.ros import transport
from ambiegen_ros.ros.transport import dds_backend
from ambiegen_ros.ros.transport.dds_services import (FEEDBACK_QOS, SERVICES_QOS, STATUS_QOS, client_id,
                                                     unwrap_request, wrap_request)
from ambiegen_ros.ros.transport.dds_wire import dds_qos, service_topics, unpad_cdr, user_data_value

pytestmark = pytest.mark.skipif(not dds_backend.is_available(), reason="cyclonedds is not installed")

ACTION = "nav2_msgs/action/NavigateToPose"
CANCEL = "action_msgs/srv/CancelGoal"
GET_STATE = "lifecycle_msgs/srv/GetState"
CLEAR = "nav2_msgs/srv/ClearEntireCostmap"
TRIGGER = "std_srvs/srv/Trigger"
MANAGE = "nav2_msgs/srv/ManageLifecycleNodes"
ACCEPTED, EXECUTING, SUCCEEDED, CANCELED, ABORTED = 1, 2, 4, 5, 6
_ids = itertools.count(1)


# --- a server as rmw_cyclonedds_cpp's ------------------------------------------------------------
class FakeService:
    """One service. ``handler(request, token)`` returns the response, or None to answer later with
    ``respond(token, response)``; replies wait for the client's reply reader (its clientid)."""

    def __init__(self, node, srv_type: str, service: str, handler: Callable[[Any, Any], Any]):
        from cyclonedds.sub import DataReader

        reg = node._registry
        self.reg, self.handler = reg, handler
        self.request_type, self.response_type = srv_type + "_Request", srv_type + "_Response"
        request_topic, reply_topic = service_topics(service)
        ident = f"serviceid={client_id(node._dp.get_guid().bytes, 1000 + next(_ids))};"
        topic = node._topic(self.request_type, request_topic, request_topic, request_header=True)
        self.reader = DataReader(node._dp, topic, qos=dds_qos(SERVICES_QOS, reg.type_hash(self.request_type), ident))
        self.writer = node._wire_writer(reply_topic, self.response_type, SERVICES_QOS, ident)
        self.outbox: list[tuple[str, int, int, Any]] = []
        self.later: dict[Any, tuple[str, int, int]] = {}
        self.clientids: list[str] = []

    def poll(self) -> None:
        from cyclonedds._clayer import ddspy_take
        from cyclonedds.core import InstanceState, SampleState, ViewState

        got = ddspy_take(self.reader._ref, SampleState.Any | ViewState.Any | InstanceState.Any, 64)
        for data, info in got if not isinstance(got, int) else []:
            if not info.valid_data:
                continue
            guid, seq, cdr = unwrap_request(unpad_cdr(data) if data[3] & 3 else data)
            writer = self.reader.get_matched_publication_data(info.publication_handle)
            cid = user_data_value(getattr(writer, "qos", None), "clientid") or ""
            self.clientids.append(cid)
            token = object()
            response = self.handler(self.reg.deserialize(cdr, self.request_type), token)
            if response is None:
                self.later[token] = (cid, guid, seq)
            else:
                self.outbox.append((cid, guid, seq, response))
        for item in list(self.outbox):
            if self._reader_matched(item[0]):  # check_for_response_reader: YES
                cid, guid, seq, response = item
                self.writer.publish_raw(wrap_request(self.reg.serialize(response, self.response_type), guid, seq))
                self.outbox.remove(item)

    def respond(self, token, response) -> None:
        self.outbox.append((*self.later.pop(token), response))

    def _reader_matched(self, cid: str) -> bool:
        w = self.writer._writer
        return any(user_data_value(getattr(w.get_matched_subscription_data(h), "qos", None), "clientid") == cid
                   for h in w.get_matched_subscriptions())


class FakeNav2:
    """bt_navigator's navigate_to_pose (rcl_action's services and topics), lifecycle GetState and
    a costmap clearing service. A goal's ``pose.position.x`` says what happens: < 0 rejected; 1
    succeeds after feedback with 2 recoveries; 2 aborts (102) after feedback with 1; 3 runs, with
    feedback on every poll, until cancelled."""

    def __init__(self, node, states: dict[str, str] | None = None):
        reg = self.reg = node._registry
        interfaces.ensure(reg, ACTION)
        interfaces.ensure(reg, CANCEL)
        interfaces.ensure(reg, GET_STATE)
        interfaces.ensure(reg, CLEAR)
        base = "/navigate_to_pose/_action/"
        self.services = [FakeService(node, ACTION + "_SendGoal", base + "send_goal", self.on_goal),
                         FakeService(node, ACTION + "_GetResult", base + "get_result", self.on_result),
                         FakeService(node, CANCEL, base + "cancel_goal", self.on_cancel)]
        self.feedback = node.create_publisher(ACTION + "_FeedbackMessage", base + "feedback", FEEDBACK_QOS)
        self.status = node.create_publisher("action_msgs/msg/GoalStatusArray", base + "status", STATUS_QOS)
        self.goals: dict[bytes, dict] = {}
        self.cleared = 0
        self.states = dict(states or {})  # node: label, asked at each call (a manager may change them)
        for name in self.states:
            self.services.append(FakeService(node, GET_STATE, f"/{name}/get_state", self._state(name)))
        self.services.append(FakeService(node, CLEAR, "/global_costmap/clear_entirely_global_costmap", self.on_clear))

    def _state(self, name: str):
        return lambda _req, _token: self.reg.new(GET_STATE + "_Response", current_state=self.reg.new(
            "lifecycle_msgs/msg/State", id=3, label=self.states[name]))

    def on_clear(self, _request, _token):
        self.cleared += 1
        return self.reg.new(CLEAR + "_Response")

    def on_goal(self, request, _token):
        key, x = bytes(bytearray(request.goal_id.uuid)), request.goal.pose.pose.position.x
        if x >= 0:
            self.goals[key] = {"x": x, "id": request.goal_id, "status": EXECUTING, "result_token": None, "fed": 0,
                               "frame": request.goal.pose.header.frame_id}
            self._publish_status()
        return self.reg.new(ACTION + "_SendGoal_Response", accepted=x >= 0,
                            stamp=self.reg.new("builtin_interfaces/msg/Time", sec=7))

    def on_result(self, request, token):
        goal = self.goals[bytes(bytearray(request.goal_id.uuid))]
        goal["result_token"] = token
        return None  # answered once the goal ends (poll)

    def on_cancel(self, request, _token):
        key = bytes(bytearray(request.goal_info.goal_id.uuid))
        goal = self.goals.get(key)
        ok = goal is not None and goal["status"] == EXECUTING
        if ok:
            goal["status"] = CANCELED
        return self.reg.new(CANCEL + "_Response", return_code=0 if ok else 2,
                            goals_canceling=[request.goal_info] if ok else [])

    def _publish_status(self) -> None:
        reg = self.reg
        self.status.publish(reg.new("action_msgs/msg/GoalStatusArray", status_list=[
            reg.new("action_msgs/msg/GoalStatus", goal_info=reg.new("action_msgs/msg/GoalInfo", goal_id=g["id"]),
                    status=g["status"]) for g in self.goals.values()]))

    def poll(self) -> None:
        for service in self.services:
            service.poll()
        reg = self.reg
        for goal in self.goals.values():
            if goal["status"] == EXECUTING and (goal["x"] == 3 or not goal["fed"]):
                recoveries = {1: 2, 2: 1}.get(goal["x"], 0)
                self.feedback.publish(reg.new(ACTION + "_FeedbackMessage", goal_id=goal["id"], feedback=reg.new(
                    ACTION + "_Feedback", number_of_recoveries=recoveries)))
                goal["fed"] += 1
            elif goal["status"] == EXECUTING and goal["result_token"] is not None and goal["x"] in (1, 2):
                goal["status"] = SUCCEEDED if goal["x"] == 1 else ABORTED
                self._publish_status()
            if goal["status"] in (SUCCEEDED, ABORTED, CANCELED) and goal["result_token"] is not None:
                result = reg.new(ACTION + "_Result", error_code=102 if goal["status"] == ABORTED else 0,
                                 error_msg="fake: no progress" if goal["status"] == ABORTED else "")
                self.services[1].respond(goal["result_token"], reg.new(
                    ACTION + "_GetResult_Response", status=goal["status"], result=result))
                goal["result_token"] = None
                if goal["status"] == CANCELED:
                    self._publish_status()


class FakeLifecycleManager:
    """Jazzy's lifecycle_manager as far as a bringup goes (``lifecycle_manager.cpp``), over the
    nodes of a ``FakeNav2``: STARTUP configures every node, then activates them in order and stops
    at the first that fails (``fail_activations`` of them fail, as a costmap that got no TF in
    time); CLEANUP takes inactive nodes back to unconfigured and fails on any other; ``is_active``
    says whether the last bringup succeeded. Commands are recorded in ``commands``."""

    def __init__(self, node, nav2: FakeNav2, name: str = "lifecycle_manager_navigation"):
        self.reg, self.nav2 = node._registry, nav2
        interfaces.ensure(self.reg, TRIGGER)
        interfaces.ensure(self.reg, MANAGE)
        self.services = [FakeService(node, TRIGGER, f"/{name}/is_active", self.on_is_active),
                         FakeService(node, MANAGE, f"/{name}/manage_nodes", self.on_manage)]
        self.active, self.fail_activations, self.asked = False, 0, 0
        self.commands: list[int] = []

    def on_is_active(self, _request, _token):
        self.asked += 1
        return self.reg.new(TRIGGER + "_Response", success=self.active, message="")

    def _startup(self) -> bool:
        states = self.nav2.states
        if any(label != "unconfigured" for label in states.values()):
            return False  # configuring a configured node fails: the bringup stops there
        states.update({name: "inactive" for name in states})
        for name in states:
            if self.fail_activations:
                self.fail_activations -= 1
                return False
            states[name] = "active"
        return True

    def on_manage(self, request, _token):
        command = int(request.command)
        self.commands.append(command)
        states, ok = self.nav2.states, False
        if command == 6:  # CLEANUP
            ok = all(label == "inactive" for label in states.values())
            if ok:
                states.update({name: "unconfigured" for name in states})
        elif command == 0:  # STARTUP
            ok = self._startup()
        self.active = command == 0 and ok
        return self.reg.new(MANAGE + "_Response", success=ok)

    def poll(self) -> None:
        for service in self.services:
            service.poll()


# --- fixtures ------------------------------------------------------------------------------------
@pytest.fixture
def pair(monkeypatch, ros_domain):
    """(client node, server node) in this process on the test's domain."""
    monkeypatch.setenv("ROS_DOMAIN_ID", str(ros_domain))
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    client = transport.create_node("dds_services_client", argv=[], backend="dds")
    server = transport.create_node("dds_services_server", argv=[], backend="dds")
    yield client, server
    client.shutdown()
    server.shutdown()


def run_until(client, servers, predicate: Callable[[], bool], timeout: float = 10.0) -> bool:
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            return False
        client.spin_once(0.005)
        for server in servers:
            server.poll()
    return True


def pose(node, x: float, frame: str = "map"):
    make = node.new_message
    return make("geometry_msgs/msg/PoseStamped", header=make("std_msgs/msg/Header", frame_id=frame),
                pose=make("geometry_msgs/msg/Pose", position=make("geometry_msgs/msg/Point", x=float(x))))


# --- the wire, without a peer --------------------------------------------------------------------
def test_names_header_and_client_ids_are_rmw_cyclonedds_cpps():
    assert service_topics("/controller_server/get_state") == ("rq/controller_server/get_stateRequest",
                                                              "rr/controller_server/get_stateReply")
    from ambiegen_ros.ros.types import dds_type_name, get_registry

    reg = get_registry()
    interfaces.ensure(reg, ACTION)
    interfaces.ensure(reg, GET_STATE)
    assert dds_type_name(ACTION + "_SendGoal_Request") == "nav2_msgs::action::dds_::NavigateToPose_SendGoal_Request_"
    assert dds_type_name(GET_STATE + "_Response") == "lifecycle_msgs::srv::dds_::GetState_Response_"
    cdr = reg.serialize(reg.new(GET_STATE + "_Request"), GET_STATE + "_Request")
    assert cdr == b"\x00\x01\x00\x00\x00"  # rosidl's one-byte member of an empty message
    wrapped = wrap_request(cdr, 2**64 - 5, 9)
    assert wrapped[4:20] == (2**64 - 5).to_bytes(8, "little") + (9).to_bytes(8, "little")
    assert unwrap_request(wrapped) == (2**64 - 5, 9, cdr)
    big = b"\x00\x00\x00\x00" + (5).to_bytes(8, "big") + (3).to_bytes(8, "big") + b"\x01"
    assert unwrap_request(big) == (5, 3, b"\x00\x00\x00\x00\x01")
    # csid_to_string: hex, the first byte std::setw(2) (space-filled), the rest unpadded, dot-separated
    assert client_id(bytes([1, 0x1f] + [0] * 10 + [9, 9, 9, 9]), 258) == " 1.1f.0.0.0.0.0.0.0.0.0.0.0.0.1.2"
    with pytest.raises(ValueError):
        unwrap_request(b"\x00\x01\x00\x00" + bytes(8))


def _jazzy_share() -> Path | None:
    setup = os.environ.get("AMBIEGEN_ROS_SETUP") or "/opt/ros/jazzy/setup.bash"
    share = Path(setup).parent / "share"
    return share if (share / "nav2_msgs" / "action" / "NavigateToPose.action").is_file() else None


@pytest.mark.skipif(_jazzy_share() is None, reason="no Jazzy build with nav2_msgs: $AMBIEGEN_ROS_SETUP (default "
                                                   "/opt/ros/jazzy/setup.bash) has no share/nav2_msgs")
def test_the_definitions_are_jazzys_field_for_field_and_hash_for_hash():
    """interfaces.py against the Jazzy build's .srv/.action files and the RIHS01 hashes of its .json."""
    from rosbags.typesys import get_types_from_msg

    from ambiegen_ros.ros.types import TypeRegistry

    reg, share = TypeRegistry(), _jazzy_share()
    for typename in [*interfaces.SERVICES, *interfaces.ACTIONS]:
        pkg, kind, name = typename.split("/")
        text = re.sub(r"#[^\n]*", "", (share / pkg / kind / f"{name}.{kind}").read_text())
        interfaces.ensure(reg, typename)
        theirs = interfaces.derived_types(typename, text)
        assert theirs.keys() == interfaces.derived_types(typename, {**interfaces.SERVICES,
                                                                    **interfaces.ACTIONS}[typename]).keys()
        for derived, msg in theirs.items():
            (_, (consts, fields)), = get_types_from_msg(msg, f"{pkg}/msg/{derived.split('/')[2]}").items()
            assert reg.store.fielddefs[derived] == (consts, fields), derived
        hashes = {h["type_name"]: h["hash_string"]
                  for h in json.loads((share / pkg / kind / f"{name}.json").read_text())["type_hashes"]}
        for derived in theirs:
            assert reg.type_hash(derived) == hashes[derived], derived


# --- services ------------------------------------------------------------------------------------
def test_a_service_call_is_answered_to_its_own_client_only(pair):
    client, server = pair
    reg = client._registry
    first = client.create_client(GET_STATE, "/controller_server/get_state")
    second = client.create_client(GET_STATE, "controller_server/get_state")  # relative: the same service
    assert first.service == "/controller_server/get_state" and not first.service_is_ready()
    served = FakeService(server, GET_STATE, "/controller_server/get_state", lambda _r, _t: reg.new(
        GET_STATE + "_Response", current_state=reg.new("lifecycle_msgs/msg/State", id=3, label="active")))
    assert run_until(client, [served], lambda: first.service_is_ready() and second.service_is_ready())
    futures = [first.call_async(first.new_request()), second.call_async(second.new_request()),
               first.call_async(first.new_request())]
    seen = []
    futures[0].add_done_callback(lambda f: seen.append(f.result().current_state.label))
    assert not futures[0].done() and futures[0].result() is None
    assert run_until(client, [served], lambda: all(f.done() for f in futures))
    assert [f.result().current_state.label for f in futures] == ["active"] * 3 and seen == ["active"]
    # each request named its client: the writer's clientid, which its reply reader carries too
    assert len(served.clientids) == 3 and served.clientids[0] == served.clientids[2] != served.clientids[1]
    assert all(re.fullmatch(r"[ 0-9a-f]{2}(\.[0-9a-f]{1,2}){15}", c) for c in served.clientids)
    stats = client.input_stats()
    assert stats["taken"] >= 3 and stats["dropped"] == 0  # each client skipped the other's reply, uncounted


def test_no_server_no_answer_and_a_request_reader_alone_is_no_server(pair):
    from cyclonedds.sub import DataReader

    client, server = pair
    c = client.create_client(CLEAR, "/global_costmap/clear_entirely_global_costmap")
    lost = c.call_async(c.new_request())  # nobody reads it: as on rclpy, it never completes
    interfaces.ensure(server._registry, CLEAR)
    request_topic, _ = service_topics("/global_costmap/clear_entirely_global_costmap")
    topic = server._topic(CLEAR + "_Request", request_topic, request_topic, request_header=True)
    reader = DataReader(server._dp, topic, qos=dds_qos(SERVICES_QOS, "", "serviceid=x;"))
    assert run_until(client, [], lambda: bool(c._writer._writer.get_matched_subscriptions()))
    assert not c.service_is_ready() and not lost.done() and reader is not None
    with pytest.raises(transport.TransportError, match="service type"):
        client.create_client("nav2_msgs/srv/NoSuchService", "/x")


# --- the action, through Nav2Client --------------------------------------------------------------
def test_nav2_client_on_dds_readiness_goals_feedback_results_rejection_and_cancel(pair):
    from sim_nodes.nav2_client import Nav2Client

    client, server = pair
    lines = []

    class Log:
        def info(self, m):
            lines.append(m)

        warning = info

    nav2 = Nav2Client(client, "navigate_to_pose", ["controller_server", "planner_server"],
                      ["/global_costmap/clear_entirely_global_costmap"], Log())
    assert nav2.missing() == ["Nav2's navigate_to_pose action server is not up",
                              "Nav2 node controller_server is not active", "Nav2 node planner_server is not active"]
    fake = FakeNav2(server, {"controller_server": "active", "planner_server": "inactive"})
    assert run_until(client, [fake], lambda: nav2.missing() == ["Nav2 node planner_server is not active"])
    assert nav2.active == {"controller_server"}
    nav2.clear_costmaps()
    assert run_until(client, [fake], lambda: fake.cleared == 1)

    nav2.send(pose(client, 1, "map"))  # succeeded, after feedback counting 2 recoveries
    assert run_until(client, [fake], lambda: nav2.result is not None)
    assert nav2.result == {"status": "succeeded", "error_code": 0, "error_msg": ""} and nav2.recoveries == 2
    assert nav2.handle.accepted and nav2.handle.status == SUCCEEDED and nav2.handle.stamp.sec == 7
    assert [g["frame"] for g in fake.goals.values()] == ["map"]

    nav2.send(pose(client, 2))  # aborted with Nav2's error code and message
    assert run_until(client, [fake], lambda: nav2.result is not None)
    assert nav2.result == {"status": "aborted", "error_code": 102, "error_msg": "fake: no progress"}
    assert nav2.recoveries == 1

    nav2.send(pose(client, -1))  # rejected
    assert run_until(client, [fake], lambda: nav2.result is not None)
    assert nav2.result["status"] == "rejected" and nav2.handle is None and nav2.recoveries == 0

    nav2.send(pose(client, 3))  # runs, feedback streaming, until we cancel it
    assert run_until(client, [fake], lambda: nav2.handle is not None and nav2.handle.status == EXECUTING)
    handle, goal = nav2.handle, list(fake.goals.values())[-1]
    assert run_until(client, [fake], lambda: goal["fed"] >= 20)
    assert nav2.result is None
    nav2.cancel()
    assert run_until(client, [fake], lambda: handle.status == CANCELED)
    assert goal["status"] == CANCELED and nav2.result is None  # late: logged, not recorded
    assert run_until(client, [fake], lambda: any("canceled" in m and "after its scenario" in m for m in lines))
    assert client._subs and client.input_stats()["dropped"] == 0
    action = nav2.action
    assert not action._feedback_callbacks and not action._handles  # finished goals leave nothing behind


def test_goal_handles_refuse_results_of_rejected_goals_and_feedback_of_other_goals_is_skipped(pair):
    client, server = pair
    action = client.create_action_client(ACTION, "/navigate_to_pose")
    fake = FakeNav2(server)
    assert run_until(client, [fake], action.server_is_ready)
    got: list = []
    rejected = action.send_goal_async(action.new_goal(pose=pose(client, -5)), feedback_callback=got.append)
    assert run_until(client, [fake], rejected.done)
    assert not rejected.result().accepted
    with pytest.raises(TypeError):
        rejected.result().get_result_async()
    # feedback of a goal this client never sent reaches no callback, and is not decoded
    stranger = client._registry.new("unique_identifier_msgs/msg/UUID", uuid=np.frombuffer(uuid.uuid4().bytes, np.uint8))
    running = action.send_goal_async(action.new_goal(pose=pose(client, 3)), feedback_callback=got.append)
    assert run_until(client, [fake], running.done) and running.result().accepted
    for _ in range(5):
        fake.feedback.publish(client._registry.new(ACTION + "_FeedbackMessage", goal_id=stranger))
    assert run_until(client, [fake], lambda: len(got) >= 10)
    mine = bytes(bytearray(running.result().goal_id.uuid))
    assert {bytes(bytearray(m.goal_id.uuid)) for m in got} == {mine}
    cancel = running.result().cancel_goal_async()
    assert run_until(client, [fake], cancel.done)
    assert cancel.result().return_code == 0 and len(cancel.result().goals_canceling) == 1


# --- a bringup that gave up ----------------------------------------------------------------------
def _quiet_log(lines: list):
    class Log:
        def info(self, m):
            lines.append(m)

        warning = info
    return Log()


def test_a_bringup_that_gave_up_is_cleaned_up_and_started_again_until_the_nodes_are_active(pair):
    """The race seen on a loaded machine: the controller's costmap waited for TF from sim time 0, the
    world's first /clock jumped past its timeout, the manager gave up with every node inactive."""
    from sim_nodes.nav2_client import Nav2Client

    client, server = pair
    lines: list = []
    fake = FakeNav2(server, {"controller_server": "inactive", "planner_server": "inactive"})
    manager = FakeLifecycleManager(server, fake)
    manager.fail_activations = 1  # the first restart fails too (its log says so); the second brings it up
    nav2 = Nav2Client(client, "navigate_to_pose", ["controller_server", "planner_server"], [], _quiet_log(lines),
                      manager="lifecycle_manager_navigation", restarts=3, restart_after=0.05)
    assert run_until(client, [fake, manager], lambda: nav2.missing() == [], timeout=30)
    assert manager.commands == [6, 0, 6, 0] and nav2.restarts == 2 and nav2.restarts_left == 1
    assert fake.states == {"controller_server": "active", "planner_server": "active"}
    assert sum("bringup gave up" in m for m in lines) == 2 and any("failed too" in m for m in lines)
    assert any("succeeded" in m for m in lines)


def test_a_manager_that_is_active_or_busy_is_left_alone_and_restarts_stop_at_their_limit(pair):
    from sim_nodes.nav2_client import Nav2Client

    client, server = pair
    fake = FakeNav2(server, {"controller_server": "inactive"})
    manager = FakeLifecycleManager(server, fake)
    manager.active = True  # its bringup succeeded; a node inactive now is another matter (a respawn)
    nav2 = Nav2Client(client, "navigate_to_pose", ["controller_server"], [], _quiet_log([]),
                      manager="lifecycle_manager_navigation", restarts=2, restart_after=0.05)
    assert run_until(client, [fake, manager], lambda: (nav2.missing(), manager.asked)[1] >= 3, timeout=30)
    assert manager.commands == []
    manager.active, manager.fail_activations = False, 99  # now every bringup fails: two tries, then none
    assert run_until(client, [fake, manager], lambda: (nav2.missing(), nav2.restarts_left)[1] == 0
                     and not nav2._restarting, timeout=30)
    asked = manager.asked
    assert not run_until(client, [fake, manager], lambda: (nav2.missing(), manager.asked)[1] > asked, timeout=1.0)
    assert manager.commands == [6, 0, 6, 0]
    unmanaged = Nav2Client(client, "navigate_to_pose", ["controller_server"], [], _quiet_log([]),
                           restarts=2, restart_after=0.0)  # no manager named: never asks
    assert unmanaged.restarts_left == 0


def test_a_lifecycle_node_leaving_active_is_forgotten_and_reported(pair):
    """Jazzy's lifecycle manager takes the whole stack down when a bond lapses (a node starved of CPU
    for bond_timeout); each node publishes its transitions on ``<node>/transition_event``."""
    from ambiegen_ros.ros.qos import DEFAULT
    from sim_nodes.nav2_client import TRANSITION_EVENT, Nav2Client

    client, server = pair
    fake = FakeNav2(server, {"controller_server": "active"})
    nav2 = Nav2Client(client, "navigate_to_pose", ["controller_server"], [], _quiet_log([]))
    left: list = []
    nav2.watch_transitions(DEFAULT, lambda name, what: left.append((name, what)))
    assert run_until(client, [fake], lambda: (nav2.missing(), nav2.active)[1] == {"controller_server"})
    events = server.create_publisher(TRANSITION_EVENT, "/controller_server/transition_event", DEFAULT)
    make = server.new_message

    def event(start: str, goal: str):
        return make(TRANSITION_EVENT, start_state=make("lifecycle_msgs/msg/State", label=start),
                    goal_state=make("lifecycle_msgs/msg/State", label=goal))

    def publish_until(predicate) -> bool:
        deadline = time.monotonic() + 10
        while not predicate() and time.monotonic() < deadline:
            events.publish(event("inactive", "activating"))  # not a departure: ignored
            events.publish(event("active", "deactivating"))
            run_until(client, [fake], predicate, timeout=0.2)
        return predicate()

    assert publish_until(lambda: bool(left))
    assert left[0] == ("controller_server", "active -> deactivating") and "controller_server" not in nav2.active
    assert all(what.startswith("active") for _, what in left)
