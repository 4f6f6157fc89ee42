"""ROS 2 services and actions on the DDS backend, as rmw_cyclonedds_cpp (Jazzy) puts them on the wire.

So that ``sut_adapter`` can talk to Nav2 without rclpy, whose executor costs 0.3-0.5 ms of CPU per
received message (Nav2's action feedback comes at 100 Hz). What rmw_cyclonedds_cpp does
(``src/rmw_node.cpp``: ``rmw_init_cs``, ``rmw_send_request``, ``rmw_take_response_request``,
``check_for_response_reader``, ``rmw_service_server_is_available``; ``src/Serialization.cpp``;
``src/ServiceTypeSupport_impl.hpp``), and so this module:

* a client writes ``rq<service>Request`` (type ``pkg::srv::dds_::Name_Request_``) and reads
  ``rr<service>Reply`` (``..._Response_``), both with the services' QoS (reliable, volatile, keep
  last 10); an action's services are ``<action>/_action/{send_goal,cancel_goal,get_result}``;
* every sample is the CDR encapsulation header, ``cdds_request_header_t {uint64 guid; int64 seq}``
  (the sender's byte order) and then the message, aligned as if the header were not there (16
  bytes keep every alignment). ``guid`` is the client's request writer's instance handle, echoed
  by the server: a client takes only the replies with its own. ``seq`` counts per process;
* the client's writer and reader carry ``clientid=<id>;`` in USER_DATA (the participant's GUID
  prefix and a counter, printed like ``csid_to_string``). A Cyclone service replies to a request
  whose writer has a client id only once its reply writer has matched a reader with the same id,
  waiting 100 ms at most, then it drops the reply (``rmw_send_response`` returns TIMEOUT): without
  the id it would reply at once, lost while our reader is not matched yet;
* a server is ready when a matched request reader and a matched reply writer carry the same
  ``serviceid=``; with no service id anywhere, when both are matched at all.

Replies, feedback and status are taken inside the node's ``spin`` and complete the futures there,
on the spinning thread, as rclpy's executor does. Feedback of goals that are not ours is skipped by
its goal id (the first 16 bytes) before it is decoded.
"""
from __future__ import annotations

import itertools
import struct
import uuid
from typing import Any, Callable

import numpy as np

from ambiegen_ros.ros import interfaces
from ambiegen_ros.ros.qos import Qos

from .base import ActionClient, ServiceClient, TransportError
from .dds_wire import service_topics, user_data_value

SERVICES_QOS = Qos(reliable=True, transient_local=False, depth=10)  # rmw_qos_profile_services_default
FEEDBACK_QOS = Qos(reliable=True, transient_local=False, depth=10)  # rmw_qos_profile_default
STATUS_QOS = Qos(reliable=True, transient_local=True, depth=1)  # rcl_action_qos_profile_status_default
HEADER = {True: struct.Struct("<Qq"), False: struct.Struct(">Qq")}  # by the encapsulation's little-endian flag
HEADER_BYTES = 16
UUID_TYPE = "unique_identifier_msgs/msg/UUID"
GOAL_STATUS_ARRAY = "action_msgs/msg/GoalStatusArray"
CANCEL_GOAL = "action_msgs/srv/CancelGoal"
STATUS_UNKNOWN, STATUS_ACCEPTED = 0, 1  # action_msgs/GoalStatus

_sequence = itertools.count(1)  # rmw_send_request's process-wide request number
_client_ids = itertools.count(1)  # get_unique_csid's counter


class Future:
    """The part of rclpy's Future the clients need; completed on the spinning thread."""

    def __init__(self) -> None:
        self._done = False
        self._result: Any = None
        self._callbacks: list[Callable[["Future"], None]] = []

    def done(self) -> bool:
        return self._done

    def result(self) -> Any:
        """The result, None while not done (as rclpy)."""
        return self._result

    def set_result(self, result: Any) -> None:
        self._result, self._done = result, True
        callbacks, self._callbacks = self._callbacks, []
        for fn in callbacks:
            fn(self)

    def add_done_callback(self, fn: Callable[["Future"], None]) -> None:
        """``fn(self)`` when the result comes, or now when it is here already."""
        if self._done:
            fn(self)
        else:
            self._callbacks.append(fn)


def client_id(participant_guid: bytes, number: int) -> str:
    """rmw_cyclonedds_cpp's client/service id: the participant's 12-byte GUID prefix and a 4-byte
    big-endian counter, printed in hex as ``csid_to_string`` does (first byte ``setw(2)``, space-filled)."""
    data = bytes(participant_guid[:12]) + number.to_bytes(4, "big")
    return f"{data[0]:2x}" + "".join(f".{b:x}" for b in data[1:])


def wrap_request(cdr: bytes, guid: int, seq: int) -> bytes:
    """A message's CDR (little-endian, as the registry writes it) with the request header inserted."""
    return cdr[:4] + HEADER[True].pack(guid, seq) + cdr[4:]


def unwrap_request(data: bytes) -> tuple[int, int, bytes]:
    """(guid, seq, message CDR with its encapsulation header) of a request or reply sample."""
    if len(data) < 4 + HEADER_BYTES:
        raise ValueError(f"{len(data)} bytes: shorter than a request header")
    guid, seq = HEADER[bool(data[1] & 1)].unpack_from(data, 4)
    return guid, seq, bytes(data[:4]) + bytes(data[4 + HEADER_BYTES:])


def _known(registry: Any, srv_type: str) -> None:
    if not (registry.has(srv_type + "_Request") and registry.has(srv_type + "_Response")):
        try:
            interfaces.ensure(registry, srv_type)
        except (KeyError, ValueError) as exc:
            raise TransportError(f"service type {srv_type!r}: {exc}") from None


class DdsServiceClient(ServiceClient):
    """A service client as rmw_cyclonedds_cpp's (see the module docstring)."""

    def __init__(self, node: Any, srv_type: str, service: str):
        registry = node._registry
        _known(registry, srv_type)
        self._node, self._registry = node, registry
        self.srv_type, self.service = srv_type, node.resolve_topic_name(service)
        self._request_type, self._response_type = srv_type + "_Request", srv_type + "_Response"
        request_topic, reply_topic = service_topics(self.service)
        ident = f"clientid={client_id(node._dp.get_guid().bytes, next(_client_ids))};"
        self._pending: dict[int, Future] = {}
        self._writer = node._wire_writer(request_topic, self._request_type, SERVICES_QOS, ident)
        # rmw_send_request: pub->pubiid (the binding may return it as a signed 64-bit number)
        self._guid = int(self._writer._writer.get_instance_handle()) & 0xFFFF_FFFF_FFFF_FFFF
        self._reader = node._wire_reader(reply_topic, self._response_type, SERVICES_QOS, ident,
                                         self._on_reply, self._decode)

    def service_is_ready(self) -> bool:
        """``check_for_service_reader_writer``: a request reader and a reply writer of one service."""
        writer, reader = self._writer._writer, self._reader._reader
        if writer is None or reader is None:
            return False
        readers = writer.get_matched_subscriptions()
        writers = reader.get_matched_publications()
        if not readers or not writers:
            return False
        ids = {user_data_value(getattr(writer.get_matched_subscription_data(h), "qos", None), "serviceid")
               for h in readers}
        ids.discard(None)
        if not ids:  # servers without an id (older RMWs): matched both ways is all we can know
            return True
        return any(user_data_value(getattr(reader.get_matched_publication_data(h), "qos", None), "serviceid") in ids
                   for h in writers)

    def new_request(self, **fields: Any) -> Any:
        return self._registry.new(self._request_type, **fields)

    def call_async(self, request: Any) -> Future:
        seq = next(_sequence)
        future = self._pending[seq] = Future()
        try:
            self._writer.publish_raw(wrap_request(self._registry.serialize(request, self._request_type),
                                                  self._guid, seq))
        except Exception:
            del self._pending[seq]
            raise
        return future

    def _decode(self, data: bytes) -> tuple[int, Any] | None:
        guid, seq, cdr = unwrap_request(data)
        if guid != self._guid or seq not in self._pending:  # another client's reply, or a stale one
            return None
        return seq, self._registry.deserialize(cdr, self._response_type)

    def _on_reply(self, taken: tuple[int, Any] | None) -> None:
        if taken is not None:
            seq, response = taken
            future = self._pending.pop(seq, None)
            if future is not None:
                future.set_result(response)


class DdsGoalHandle:
    """rclpy's ClientGoalHandle, for what the clients read of it."""

    def __init__(self, client: "DdsActionClient", goal_id: Any, response: Any):
        self._client = client
        self.goal_id = goal_id
        self.accepted = bool(response.accepted)
        self.stamp = response.stamp
        self.status = STATUS_UNKNOWN  # from the status topic and the result, as rclpy's

    def get_result_async(self) -> Future:
        if not self.accepted:
            raise TypeError("Goal was not accepted")  # as rclpy
        return self._client._get_result_async(self)

    def cancel_goal_async(self) -> Future:
        if not self.accepted:
            raise TypeError("Goal was not accepted")
        return self._client._cancel_goal_async(self)


class DdsActionClient(ActionClient):
    """An action client as rcl_action builds one: three service clients and two subscriptions."""

    def __init__(self, node: Any, action_type: str, action: str):
        registry = node._registry
        try:
            interfaces.ensure(registry, action_type)
            interfaces.ensure(registry, CANCEL_GOAL)
        except (KeyError, ValueError) as exc:
            raise TransportError(f"action type {action_type!r}: {exc}") from None
        self._registry = registry
        self.action_type, self.action_name = action_type, node.resolve_topic_name(action)
        base = self.action_name + "/_action/"
        self._send = DdsServiceClient(node, action_type + "_SendGoal", base + "send_goal")
        self._cancel = DdsServiceClient(node, CANCEL_GOAL, base + "cancel_goal")
        self._result = DdsServiceClient(node, action_type + "_GetResult", base + "get_result")
        self._feedback_type = action_type + "_FeedbackMessage"
        self._feedback_callbacks: dict[bytes, Callable[[Any], None]] = {}
        self._handles: dict[bytes, DdsGoalHandle] = {}
        self._feedback = node.create_subscription(self._feedback_type, base + "feedback", self._on_feedback,
                                                  FEEDBACK_QOS, raw=True)
        self._status = node.create_subscription(GOAL_STATUS_ARRAY, base + "status", self._on_status, STATUS_QOS)

    def server_is_ready(self) -> bool:
        """``rcl_action_server_is_available``."""
        return (self._send.service_is_ready() and self._cancel.service_is_ready()
                and self._result.service_is_ready() and self._feedback.publisher_count() > 0
                and self._status.publisher_count() > 0)

    def new_goal(self, **fields: Any) -> Any:
        return self._registry.new(self.action_type + "_Goal", **fields)

    def send_goal_async(self, goal: Any, feedback_callback: Callable[[Any], None] | None = None) -> Future:
        key = uuid.uuid4().bytes
        goal_id = self._registry.new(UUID_TYPE, uuid=np.frombuffer(key, dtype=np.uint8))
        request = self._send.new_request(goal_id=goal_id, goal=goal)
        if feedback_callback is not None:
            self._feedback_callbacks[key] = feedback_callback
        outer = Future()

        def on_response(future: Future) -> None:
            handle = DdsGoalHandle(self, goal_id, future.result())
            if handle.accepted:
                self._handles[key] = handle
            else:
                self._feedback_callbacks.pop(key, None)
            outer.set_result(handle)

        try:
            self._send.call_async(request).add_done_callback(on_response)
        except Exception:
            self._feedback_callbacks.pop(key, None)
            raise
        return outer

    def _get_result_async(self, handle: DdsGoalHandle) -> Future:
        key = bytes(bytearray(handle.goal_id.uuid))
        future = self._result.call_async(self._result.new_request(goal_id=handle.goal_id))

        def done(f: Future) -> None:  # the goal is over: no more feedback or status for it
            handle.status = int(f.result().status)
            self._feedback_callbacks.pop(key, None)
            self._handles.pop(key, None)

        future.add_done_callback(done)
        return future

    def _cancel_goal_async(self, handle: DdsGoalHandle) -> Future:
        info = self._registry.new("action_msgs/msg/GoalInfo", goal_id=handle.goal_id)  # stamp 0: this goal only
        return self._cancel.call_async(self._cancel.new_request(goal_info=info))

    def _on_feedback(self, data: bytes, _receive_ns: int) -> None:
        callback = self._feedback_callbacks.get(bytes(data[4:20]))  # goal_id.uuid: the first field
        if callback is not None:
            callback(self._registry.deserialize(data, self._feedback_type))

    def _on_status(self, msg: Any) -> None:
        for status in msg.status_list:
            handle = self._handles.get(bytes(bytearray(status.goal_info.goal_id.uuid)))
            if handle is not None:
                handle.status = int(status.status)
