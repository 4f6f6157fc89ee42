"""The backend-neutral node interface every AmbieGen node is written against.

Nodes only see ``Node``, ``Publisher``, ``Subscription`` and ``Timer``; the rclpy and the Cyclone
DDS backends implement them. The parts that do not touch a middleware (ROS name resolution,
parameters, logging format, waiting for subscribers) live here so both backends behave alike.
"""
from __future__ import annotations

import abc
import re
import sys
import time
from dataclasses import dataclass
from typing import Any, Callable, ClassVar, Sequence

from ambiegen_ros.ros.limits import DEFAULT_MAX_MESSAGE_BYTES, MAX_MESSAGE_BYTES_PARAM, InputGuard
from ambiegen_ros.ros.qos import Qos

from . import params as _params
from .params import ParameterError

__all__ = [
    "TransportError", "BackendUnavailable", "ParameterError", "EndpointInfo", "Logger",
    "Publisher", "Subscription", "Timer", "ServiceClient", "ActionClient", "Node",
    "validate_node_name", "normalize_namespace", "resolve_topic_name",
]


class TransportError(RuntimeError):
    """A middleware operation failed (entity creation, write, bad payload)."""


class BackendUnavailable(TransportError):
    """The requested backend cannot be imported on this machine."""


@dataclass(frozen=True)
class EndpointInfo:
    """One publisher or subscription seen in the graph (what ``ros2 topic info -v`` shows)."""

    topic: str
    typename: str
    qos: Qos
    keep_all: bool = False
    type_hash: str = ""
    node_name: str = ""
    node_namespace: str = ""
    gid: bytes = b""
    """The endpoint's global id: tells a restarted process's endpoint from its dead predecessor's."""


_LEVELS = {"debug": 10, "info": 20, "warn": 30, "warning": 30, "error": 40, "fatal": 50}


class Logger:
    """ROS-formatted console logger (``[INFO] [sec.nsec] [name]: msg`` on stderr, like rcutils)."""

    def __init__(self, name: str, level: str = "info", stream=None):
        self.name = name
        self._stream = stream
        self.set_level(level)

    def set_level(self, level: str) -> None:
        key = str(level).lower()
        if key not in _LEVELS:
            raise ValueError(f"unknown log level {level!r}; use one of {sorted(_LEVELS)}")
        self._threshold = _LEVELS[key]

    def _log(self, severity: str, level: int, msg: Any) -> None:
        if level < self._threshold:
            return
        ns = time.time_ns()
        stream = self._stream or sys.stderr
        stream.write(f"[{severity}] [{ns // 1_000_000_000}.{ns % 1_000_000_000:09d}] [{self.name}]: {msg}\n")
        stream.flush()

    def debug(self, msg: Any) -> None:
        self._log("DEBUG", 10, msg)

    def info(self, msg: Any) -> None:
        self._log("INFO", 20, msg)

    def warning(self, msg: Any) -> None:
        self._log("WARN", 30, msg)

    warn = warning

    def error(self, msg: Any) -> None:
        self._log("ERROR", 40, msg)

    def fatal(self, msg: Any) -> None:
        self._log("FATAL", 50, msg)


# ---------------------------------------------------------------------------------------------
# ROS 2 name rules (REP / design article "Topic and Service name mapping to DDS")

_NODE_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
_TOKEN = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")


def validate_node_name(name: str) -> str:
    if not _NODE_NAME.match(name or ""):
        raise ValueError(f"invalid node name {name!r}: letters, digits and '_', not starting with a digit")
    return name


def normalize_namespace(namespace: str | None) -> str:
    """'' -> '/', 'a/b' -> '/a/b', '/a/' -> '/a'; each token must be a valid ROS name token."""
    ns = (namespace or "").strip()
    if not ns or ns == "/":
        return "/"
    tokens = [t for t in ns.strip("/").split("/")]
    for tok in tokens:
        if not _TOKEN.match(tok):
            raise ValueError(f"invalid namespace {namespace!r} (token {tok!r})")
    return "/" + "/".join(tokens)


def resolve_topic_name(topic: str, node_name: str, namespace: str,
                       remaps: Sequence[tuple[str, str]] = ()) -> str:
    """Fully qualified ROS name: relative names join the namespace, '~' is the node's private ns.

    Remap rules compare fully qualified names (both sides resolved against this node), first
    matching rule wins, as in rcl.
    """
    fqn = _expand(topic, node_name, namespace)
    for src, dst in remaps:
        try:
            if _expand(src, node_name, namespace) == fqn:
                return _expand(dst, node_name, namespace)
        except ValueError:
            continue
    return fqn


def _expand(topic: str, node_name: str, namespace: str) -> str:
    if not topic:
        raise ValueError("empty topic name")
    ns = normalize_namespace(namespace)
    name = topic.replace("{node}", node_name).replace("{ns}", ns.rstrip("/") or "")
    if name.startswith("~"):
        base = (ns.rstrip("/") + "/" + node_name)
        rest = name[1:]
        if rest and not rest.startswith("/"):
            raise ValueError(f"invalid topic name {topic!r}: '~' must be followed by '/'")
        name = base + rest
    elif not name.startswith("/"):
        name = ns.rstrip("/") + "/" + name
    if name.endswith("/") or "//" in name:
        raise ValueError(f"invalid topic name {topic!r}")
    for tok in name[1:].split("/"):
        if not _TOKEN.match(tok):
            raise ValueError(f"invalid topic name {topic!r} (token {tok!r})")
    return name


# ---------------------------------------------------------------------------------------------


class Publisher(abc.ABC):
    """Sends messages of one type on one topic."""

    topic: str
    typename: str
    qos: Qos

    @abc.abstractmethod
    def publish(self, msg: Any) -> None:
        """Serialise and send a backend-native message (see ``Node.new_message``)."""

    @abc.abstractmethod
    def publish_raw(self, data: bytes) -> None:
        """Send already-serialised CDR (with its 4-byte encapsulation header) unchanged."""

    @abc.abstractmethod
    def subscription_count(self) -> int:
        """Matched subscriptions right now (local and remote)."""

    def destroy(self) -> None:  # pragma: no cover - optional in backends
        pass


class Subscription(abc.ABC):
    topic: str
    typename: str
    qos: Qos
    raw: bool

    def destroy(self) -> None:  # pragma: no cover - optional in backends
        pass


class Timer(abc.ABC):
    period_s: float

    @abc.abstractmethod
    def cancel(self) -> None:
        """Stop calling the callback; idempotent."""

    @abc.abstractmethod
    def is_canceled(self) -> bool:
        ...


class ServiceClient(abc.ABC):
    """Calls one ROS 2 service without blocking, as rclpy's ``Client`` does (its method names too).

    ``call_async`` returns a future (``done()``, ``result()``, ``add_done_callback(fn(future))``);
    it completes inside ``spin``/``spin_once``, never on another thread. A request sent while no
    server is matched is lost, as on rclpy: ask ``service_is_ready()`` first.
    """

    service: str
    srv_type: str

    @abc.abstractmethod
    def service_is_ready(self) -> bool:
        """A server's request reader and its response writer are both matched."""

    @abc.abstractmethod
    def new_request(self, **fields: Any) -> Any:
        """A backend-native request of this service, fields set from keyword arguments."""

    @abc.abstractmethod
    def call_async(self, request: Any) -> Any:
        """Send ``request``; the future's result is the response."""


class ActionClient(abc.ABC):
    """A ROS 2 action client with the part of rclpy's ``ActionClient`` API AmbieGen uses.

    ``send_goal_async(goal, feedback_callback)`` returns a future of a goal handle (``accepted``,
    ``status``, ``get_result_async()`` -> future of the ``GetResult`` response with ``status`` and
    ``result``, ``cancel_goal_async()``); ``feedback_callback`` receives the ``FeedbackMessage``
    (its ``feedback`` field holds the action's feedback) of that goal only.
    """

    action_name: str
    action_type: str

    @abc.abstractmethod
    def server_is_ready(self) -> bool:
        """Its three services have a server, and its feedback and status topics a publisher."""

    @abc.abstractmethod
    def new_goal(self, **fields: Any) -> Any:
        """A backend-native goal of this action, fields set from keyword arguments."""

    @abc.abstractmethod
    def send_goal_async(self, goal: Any, feedback_callback: Callable[[Any], None] | None = None) -> Any:
        ...


class Node(abc.ABC):
    """A ROS 2 node: parameters, pub/sub, timers, a single-threaded spin loop.

    Callbacks run only inside ``spin``/``spin_once`` on the calling thread, so node code needs no
    locks. SIGINT/SIGTERM make ``spin`` return (``ok()`` turns False) so nodes can finalise files.
    """

    backend_name: ClassVar[str] = "?"

    def __init__(self, name: str, namespace: str = "", argv: Sequence[str] | None = None,
                 parameter_overrides: dict[str, Any] | None = None):
        self._argv = list(sys.argv if argv is None else argv)
        self._ros_args = _params.parse_ros_args(self._argv)
        requested = validate_node_name(name)
        self._name = validate_node_name(self._ros_args.node_name_override(requested) or requested)
        ns_override = self._ros_args.namespace_override(requested)
        self._namespace = normalize_namespace(ns_override if ns_override is not None else namespace)
        self._overrides = dict(parameter_overrides or {})
        self._parameters: dict[str, Any] = {}
        self._descriptions: dict[str, str] = {}
        self._logger = self._make_logger()
        self._guard_obj: InputGuard | None = None

    # -- identity -----------------------------------------------------------------------------
    @property
    def name(self) -> str:
        return self._name

    @property
    def rmw(self) -> str | None:
        """The ROS middleware implementation under this node (None: not an RMW, e.g. the DDS backend)."""
        return None

    @property
    def middleware(self) -> str:
        """What carries this node's samples (recorded in logs: a result says which stack made it)."""
        return self.backend_name

    @property
    def namespace(self) -> str:
        return self._namespace

    @property
    def fully_qualified_name(self) -> str:
        return self._namespace.rstrip("/") + "/" + self._name

    @property
    def logger(self):
        return self._logger

    @property
    def argv(self) -> list[str]:
        """The process arguments without ROS sections (for nodes with their own CLI)."""
        return _params.strip_ros_args(self._argv)

    def _make_logger(self):
        lg = Logger(self.fully_qualified_name.lstrip("/").replace("/", "."))
        if self._ros_args.log_level:
            lg.set_level(self._ros_args.log_level)
        return lg

    def resolve_topic_name(self, topic: str) -> str:
        return resolve_topic_name(topic, self._name, self._namespace,
                                  self._ros_args.topic_remaps(self._name))

    # -- parameters -----------------------------------------------------------------------------
    def declare_parameter(self, name: str, default: Any = None, description: str = "") -> Any:
        """Declare once; returns the override from argv/params file/overrides, else ``default``.

        The value must have the default's type (an integer is accepted for a float default);
        a mismatch raises ParameterError naming the parameter.
        """
        if name in self._parameters:
            raise ParameterError(f"parameter {name!r} already declared")
        found, value = self._parameter_source(name, default, description)
        value = _params.coerce_parameter(name, value, default) if found else default
        self._parameters[name] = value
        self._descriptions[name] = description
        return value

    def get_parameter(self, name: str) -> Any:
        try:
            return self._parameters[name]
        except KeyError:
            raise ParameterError(f"parameter {name!r} has not been declared") from None

    def has_parameter(self, name: str) -> bool:
        return name in self._parameters

    @property
    def parameters(self) -> dict[str, Any]:
        return dict(self._parameters)

    @abc.abstractmethod
    def _parameter_source(self, name: str, default: Any, description: str) -> tuple[bool, Any]:
        """(True, value) if something overrides ``name``, else (False, None)."""

    # -- received samples -----------------------------------------------------------------------
    def input_guard(self) -> InputGuard:
        """The node's guard for received samples (declares ``max_message_bytes`` on first use)."""
        if self._guard_obj is None:
            limit = self.declare_parameter(
                MAX_MESSAGE_BYTES_PARAM, DEFAULT_MAX_MESSAGE_BYTES,
                "largest serialised sample accepted on any subscription; larger ones are dropped and counted")
            try:
                self._guard_obj = InputGuard(self.logger, limit)
            except ValueError as exc:
                raise ParameterError(str(exc)) from None
        return self._guard_obj

    def input_stats(self) -> dict[str, int]:
        """Samples taken by this node's subscriptions and those dropped, by reason."""
        return self.input_guard().stats.as_dict() if self._guard_obj is not None else {
            "taken": 0, "dropped": 0, "oversize": 0, "malformed": 0, "handler_errors": 0}

    def finish_io(self, drain: bool = False, quiet_s: float = 0.5, drain_s: float = 3.0, ack_s: float = 5.0) -> None:
        """Let this node's messages arrive before it goes (``run_node`` calls it after a stop).

        With ``drain`` (a recorder), subscription callbacks keep running on whatever is still on
        its way, until nothing came for ``quiet_s`` (``drain_s`` at most: a run that goes on is
        not waited for). Then every reliable publisher waits, ``ack_s`` at most, until the
        readers matched to it acknowledged its samples: a node that ends before that takes its
        last messages with it (a deleted writer's unacknowledged samples are never resent; on
        Fast DDS a campaign's last results were lost so). A second Ctrl-C cuts it short.
        """
        if drain:
            self._take_pending(quiet_s, time.monotonic() + drain_s)
        self._wait_acknowledged(time.monotonic() + ack_s)

    def _take_pending(self, quiet_s: float, deadline: float) -> None:
        """Run subscription callbacks until none ran for ``quiet_s`` (or ``deadline``, monotonic s)."""

    def _wait_acknowledged(self, deadline: float) -> None:
        """Block until every reliable publisher's samples are acknowledged (or ``deadline``)."""

    def _log_input_stats(self) -> None:
        """One line at shutdown: how many samples arrived and how many were refused."""
        if self._guard_obj is not None:
            self.logger.info(self._guard_obj.stats.summary())

    # -- communication --------------------------------------------------------------------------
    @abc.abstractmethod
    def create_publisher(self, typename: str, topic: str, qos: Qos) -> Publisher:
        ...

    @abc.abstractmethod
    def create_subscription(self, typename: str, topic: str, callback: Callable[..., None],
                            qos: Qos, raw: bool = False) -> Subscription:
        """raw=False: ``callback(msg)``; raw=True: ``callback(cdr_bytes, receive_time_ns)``, or
        ``callback(cdr_bytes, receive_time_ns, source_time_ns)`` for a callback of three arguments
        (the writer's clock when it sent the sample: MCAP's publish time).

        Every sample passes ``input_guard()``: oversize or undecodable samples and handler
        exceptions are dropped and counted (``input_stats()``), never raised into ``spin``.
        """

    @abc.abstractmethod
    def create_timer(self, period_s: float, callback: Callable[[], None]) -> Timer:
        ...

    @abc.abstractmethod
    def create_client(self, srv_type: str, service: str) -> ServiceClient:
        """A client of service ``service`` of type ``pkg/srv/Name`` (on the DDS backend: one of
        ``ambiegen_ros.ros.interfaces.SERVICES``)."""

    @abc.abstractmethod
    def create_action_client(self, action_type: str, action: str) -> ActionClient:
        """A client of action ``action`` of type ``pkg/action/Name`` (on the DDS backend: one of
        ``ambiegen_ros.ros.interfaces.ACTIONS``)."""

    @abc.abstractmethod
    def now_ns(self) -> int:
        """Current ROS time in nanoseconds since the epoch."""

    @abc.abstractmethod
    def new_message(self, typename: str, **fields: Any) -> Any:
        """A backend-native message with defaults, fields set from keyword arguments."""

    @abc.abstractmethod
    def topic_names_and_types(self) -> list[tuple[str, list[str]]]:
        """Every topic with a publisher or subscription in the graph, sorted by name."""

    @abc.abstractmethod
    def publishers_info(self, topic: str) -> list[EndpointInfo]:
        """Publishers on ``topic`` with their offered QoS (the recorder stores them)."""

    # -- execution ------------------------------------------------------------------------------
    @abc.abstractmethod
    def spin(self) -> None:
        """Run callbacks until shutdown or SIGINT/SIGTERM; returns normally in both cases."""

    @abc.abstractmethod
    def spin_once(self, timeout_s: float | None = None) -> None:
        """Wait up to ``timeout_s`` for work and run what is ready."""

    @abc.abstractmethod
    def ok(self) -> bool:
        ...

    @abc.abstractmethod
    def request_shutdown(self) -> None:
        """Make ``spin`` return soon and ``ok()`` False; safe from callbacks and signal handlers."""

    @abc.abstractmethod
    def shutdown(self) -> None:
        """Release the middleware entities; idempotent."""

    def wait_for_subscribers(self, publisher: Publisher, count: int = 1, timeout_s: float = 5.0) -> bool:
        """Block (without running callbacks) until ``publisher`` has ``count`` matches."""
        deadline = time.monotonic() + max(0.0, timeout_s)
        while True:
            if publisher.subscription_count() >= count:
                return True
            if time.monotonic() >= deadline or not self.ok():
                return publisher.subscription_count() >= count
            time.sleep(0.005)

    def spin_until(self, predicate: Callable[[], bool], timeout_s: float | None = None) -> bool:
        """Spin until ``predicate()`` is true, the timeout passes or the node stops."""
        deadline = None if timeout_s is None else time.monotonic() + timeout_s
        while self.ok() and not predicate():
            left = None if deadline is None else deadline - time.monotonic()
            if left is not None and left <= 0:
                break
            self.spin_once(0.05 if left is None else min(0.05, left))
        return bool(predicate())

    def __enter__(self) -> "Node":
        return self

    def __exit__(self, *exc) -> None:
        self.shutdown()

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.fully_qualified_name} backend={self.backend_name}>"
