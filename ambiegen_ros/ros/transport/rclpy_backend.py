"""rclpy (ROS 2 Jazzy) backend: a thin adapter from the seam's ``Node`` to ``rclpy.node.Node``.

Import-safe without ROS: rclpy and friends are imported inside functions, so this module (its QoS
table, availability probe, the check of ``ambiegen_msgs``) loads and is unit-tested on machines
without rclpy. A node on this backend needs the Python classes that colcon generates for
``ambiegen_msgs``; a plain ``colcon build`` does not build that package (it sits inside the
``ambiegen_ros`` package's folder, where colcon never looks), so every node checks for them before
it creates its node (``missing_messages``, called by ``nodes.run_node``) and stops with one line
naming the command to run. Jazzy idioms:
``rclpy.init()`` returns None; spin inside ``try/except (KeyboardInterrupt,
ExternalShutdownException)``; ``node.destroy_node()`` then ``rclpy.try_shutdown()``.
"""
from __future__ import annotations

import importlib
import importlib.util
import shlex
import time
from pathlib import Path
from typing import Any, Callable, Sequence, cast

from ambiegen_ros.ros.qos import Qos

from . import signals
from .base import (ActionClient, BackendUnavailable, EndpointInfo, Node, Publisher, ServiceClient, Subscription,
                   Timer)
from .discovery import options_from_env


def to_rclpy_value(value: Any, ros_type: str) -> Any:
    """Adapt a field value built for the DDS backend to rclpy's generated setters.

    rclpy accepts numpy arrays only for fixed-size arrays (unbounded sequences want a list or an
    ``array.array``), and ``byte`` (IDL ``octet``) fields want ``bytes`` of length 1.
    """
    if hasattr(value, "tolist") and hasattr(value, "dtype") and getattr(value, "ndim", 0) >= 1:
        return value.tolist()
    if ros_type == "octet" and isinstance(value, int) and not isinstance(value, bool):
        return bytes([value])
    return value

BACKEND_NAME = "rclpy"
_import_error: str | None = None


def is_available() -> bool:
    """True when ``import rclpy`` works (checked once, without initialising ROS)."""
    global _import_error
    if _import_error is None:
        try:
            if importlib.util.find_spec("rclpy") is None:
                _import_error = "ModuleNotFoundError: No module named 'rclpy'"
            else:
                import rclpy  # noqa: F401
                _import_error = ""
        except Exception as exc:  # a broken ROS install raises other errors
            _import_error = f"{type(exc).__name__}: {exc}"
    return _import_error == ""


def unavailable_reason() -> str:
    is_available()
    return _import_error or ""


# ---------------------------------------------------------------------------------------------
# ambiegen_msgs: rclpy needs its generated Python classes (the DDS backend reads the .msg files)

MSGS_PACKAGE = "ambiegen_msgs"


def message_classes() -> tuple[str, ...]:
    """The ambiegen_msgs classes our topics use (``topics``), e.g. ``ScenarioResult``."""
    from ambiegen_ros.ros import topics

    names = [topics.RUN_CONFIG_TYPE, topics.STATUS_TYPE, topics.RESULT_TYPE, *topics.SCENARIO_TYPES.values()]
    return tuple(sorted({n.rsplit("/", 1)[1] for n in names if n.startswith(MSGS_PACKAGE + "/")}))


def messages_problem() -> str:
    """'' when ``ambiegen_msgs.msg`` imports with every class our topics use, else what is wrong.

    Imports no rclpy. The module may be missing (the package was not built, or its workspace not
    sourced) or a namespace package without the classes (a source folder ``ambiegen_msgs/`` on
    ``sys.path``, which holds only .msg files): get_message would fail later with "module
    'ambiegen_msgs.msg' has no attribute 'ScenarioResult'".
    """
    try:
        module = importlib.import_module(MSGS_PACKAGE + ".msg")
    except ImportError as exc:
        return f"{type(exc).__name__}: {exc}"
    except Exception as exc:  # a broken build raises other errors while importing
        return f"{MSGS_PACKAGE}.msg does not import ({type(exc).__name__}: {exc})"
    missing = [name for name in message_classes() if not hasattr(module, name)]
    if missing:
        where = getattr(module, "__file__", None) or ", ".join(
            dict.fromkeys(str(Path(p).resolve()) for p in getattr(module, "__path__", []))) or "?"
        return f"{MSGS_PACKAGE}.msg ({where}) has no {', '.join(missing)}"
    return ""


def _workspace_of(path: Path) -> Path | None:
    """The colcon workspace ``path`` lies in: the parent of its ``install`` or ``build`` folder,
    when that parent has a ``src`` folder."""
    for parent in path.parents:
        if parent.name in ("install", "build") and (parent.parent / "src").is_dir():
            return parent.parent
    return None


def msgs_build_command(module_file: str | Path | None = None) -> str:
    """The shell command that builds ambiegen_msgs beside this package and sources the result.

    From the workspace this code runs in (found from ``module_file``, default this file, without
    resolving symlinks: a ``--symlink-install`` build links back into ``src``): ``cd WS && colcon
    build --base-paths src src/<repo>/ambiegen_msgs && source install/setup.bash``, with the
    repository's folder as found under ``src``. Run from a checkout outside any workspace, the
    checkout itself is the workspace (``--paths . ambiegen_msgs``).
    """
    here = Path(module_file or __file__).absolute()
    workspace = _workspace_of(here)
    checkout = here.parents[3] if len(here.parents) > 3 else None  # <repo>/ambiegen_ros/ros/transport/x.py
    if checkout is not None and not (checkout / MSGS_PACKAGE / "package.xml").is_file():
        checkout = None
    if workspace is None and checkout is not None:
        if checkout.parent.name != "src":
            return (f"cd {shlex.quote(str(checkout))} && colcon build --paths . {MSGS_PACKAGE} "
                    "&& source install/setup.bash")
        workspace = checkout.parent.parent
    msgs = f"src/<repository folder>/{MSGS_PACKAGE}"
    if workspace is not None:
        found = sorted({str(p.parent.relative_to(workspace)) for pattern in ("src/*", "src/*/*")
                        for p in workspace.glob(f"{pattern}/{MSGS_PACKAGE}/package.xml")})
        if len(found) == 1:
            msgs = shlex.quote(found[0])
    build = f"colcon build --base-paths src {msgs} && source install/setup.bash"
    return f"cd {shlex.quote(str(workspace))} && {build}" if workspace is not None else f"in your workspace: {build}"


def missing_messages(module_file: str | Path | None = None) -> str:
    """'' when ambiegen_msgs is usable, else the one line a node prints before it stops."""
    problem = messages_problem()
    if not problem:
        return ""
    return (f"{MSGS_PACKAGE} is not built or not sourced ({problem}); a plain `colcon build` skips it because it "
            f"sits inside the ambiegen_ros package's folder; run: {msgs_build_command(module_file)}")


# ---------------------------------------------------------------------------------------------
# QoS mapping (pure data, testable without rclpy)


def no_event_handlers(publisher: bool):
    """No QoS event handlers on our endpoints. rclpy's defaults (incompatible QoS and type, each
    a waitable on the executor) are rebuilt into the wait set on every wakeup: with ~20 endpoints a
    node's wait set triples, and at Nav2's rates that was most of our nodes' CPU (issue 58,
    py-spy). Incompatible QoS shows in ``ros2 topic info -v`` and in the adapter's own checks
    ("nobody publishes ...")."""
    from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks

    return (PublisherEventCallbacks if publisher else SubscriptionEventCallbacks)(use_default_callbacks=False)


def qos_profile_kwargs(qos: Qos) -> dict[str, Any]:
    """Policy names/values for ``rclpy.qos.QoSProfile``, as strings (no rclpy needed)."""
    return {
        "history": "keep_all" if qos.keep_all else "keep_last",
        "depth": max(1, int(qos.depth)),
        "reliability": "reliable" if qos.reliable else "best_effort",
        "durability": "transient_local" if qos.transient_local else "volatile",
    }


def to_rclpy_qos(qos: Qos):
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
    kw = qos_profile_kwargs(qos)
    return QoSProfile(
        history=HistoryPolicy.KEEP_ALL if qos.keep_all else HistoryPolicy.KEEP_LAST,
        depth=kw["depth"],
        reliability=ReliabilityPolicy.RELIABLE if qos.reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=(DurabilityPolicy.TRANSIENT_LOCAL if qos.transient_local
                    else DurabilityPolicy.VOLATILE),
    )


def qos_from_profile_fields(reliability: str, durability: str, history: str, depth: int) -> tuple[Qos, bool]:
    """(Qos, keep_all) from lower-case policy names (e.g. ``ReliabilityPolicy.RELIABLE.name.lower()``)."""
    keep_all = history.lower() == "keep_all"
    return (Qos(reliable=reliability.lower() == "reliable",
                transient_local=durability.lower() == "transient_local",
                depth=0 if keep_all else int(depth)), keep_all)


# ---------------------------------------------------------------------------------------------


class _RclpyPublisher(Publisher):
    def __init__(self, pub, typename: str, topic: str, qos: Qos):
        self._pub = pub
        self.typename = typename
        self.topic = topic
        self.qos = qos

    def publish(self, msg: Any) -> None:
        self._pub.publish(msg)

    def publish_raw(self, data: bytes) -> None:
        # rclpy.Publisher.publish sends ``bytes`` through rcl_publish_serialized_message.
        self._pub.publish(bytes(data))

    def subscription_count(self) -> int:
        return int(self._pub.get_subscription_count())


class _RclpySubscription(Subscription):
    def __init__(self, sub, typename: str, topic: str, qos: Qos, raw: bool):
        self._sub = sub
        self.typename = typename
        self.topic = topic
        self.qos = qos
        self.raw = raw


class _RclpyServiceClient(ServiceClient):
    """rclpy's own client; the seam adds only how a request is made."""

    def __init__(self, client, srv_class, srv_type: str):
        self._client, self._class = client, srv_class
        self.service, self.srv_type = client.srv_name, srv_type

    def service_is_ready(self) -> bool:
        return self._client.service_is_ready()

    def new_request(self, **fields: Any) -> Any:
        return self._class.Request(**fields)

    def call_async(self, request: Any) -> Any:
        return self._client.call_async(request)


class _RclpyActionClient(ActionClient):
    """rclpy's own ``ActionClient`` (its futures and goal handles); the seam adds how a goal is made."""

    def __init__(self, node, action_class, action_type: str, action: str):
        from rclpy.action import ActionClient as RclpyActionClient

        self._client, self._class = RclpyActionClient(node, action_class, action), action_class
        self.action_name, self.action_type = action, action_type

    def server_is_ready(self) -> bool:
        return self._client.server_is_ready()

    def new_goal(self, **fields: Any) -> Any:
        return self._class.Goal(**fields)

    def send_goal_async(self, goal: Any, feedback_callback: Callable[[Any], None] | None = None) -> Any:
        return self._client.send_goal_async(goal, feedback_callback=feedback_callback)


class _RclpyTimer(Timer):
    def __init__(self, timer, period_s: float):
        self._timer = timer
        self.period_s = period_s

    def cancel(self) -> None:
        self._timer.cancel()

    def is_canceled(self) -> bool:
        return bool(self._timer.is_canceled())


_live = 0  # nodes alive on the default context; the last one shuts rclpy down


class _ContextAwareLogger:
    """The node's rclpy logger (console and /rosout) while the rclpy context lives; the seam's
    console logger after rclpy's SIGINT handler has shut it down, when every line a node logs while
    finalising would also make rcl print "Failed to publish log message to rosout"."""

    def __init__(self, ros_logger: Any, console: Any):
        self._ros, self._console = ros_logger, console

    def _target(self) -> Any:
        import rclpy
        return self._ros if rclpy.ok() else self._console

    def __getattr__(self, name: str) -> Any:  # debug, info, warning, warn, error, fatal
        return getattr(self._target(), name)


class RclpyNode(Node):
    backend_name = BACKEND_NAME

    def __init__(self, name: str, namespace: str = "", argv: Sequence[str] | None = None,
                 parameter_overrides: dict[str, Any] | None = None):
        if not is_available():
            raise BackendUnavailable(f"rclpy backend unavailable: {unavailable_reason()}")
        super().__init__(name, namespace, argv, parameter_overrides)
        global _live
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.parameter import Parameter

        if not rclpy.ok():
            # the RMW applies ROS_AUTOMATIC_DISCOVERY_RANGE / ROS_STATIC_PEERS itself; rcl would
            # turn a misspelt range into LOCALHOST with a warning, we refuse it as the DDS backend does
            options_from_env()
            from rclpy.signals import SignalHandlerOptions

            # without rclpy's SIGINT/SIGTERM handlers (they would shut the context down with
            # samples still on their way): ours stop the spin and leave the node usable (signals.py)
            rclpy.init(args=self._argv, signal_handler_options=SignalHandlerOptions.NO)
            cli_args = None
        else:  # context exists (second node in the process): pass this node's own ROS args
            cli_args = self._argv[1:] if len(self._argv) > 1 else None
        overrides = [Parameter(k, value=v) for k, v in self._overrides.items()]
        # rclpy applies remaps (__node, __ns, topics) and argv parameters itself.
        self._node = rclpy.create_node(name, namespace=namespace or None, cli_args=cli_args,
                                       parameter_overrides=overrides)
        self._name = self._node.get_name()
        self._namespace = self._node.get_namespace()
        self._logger = _ContextAwareLogger(self._node.get_logger(), self._make_logger())
        self._executor = SingleThreadedExecutor()
        self._executor.add_node(self._node)
        self._stopped = False
        self._closed = False
        self._msg_classes: dict[str, Any] = {}
        self._publishers: list[Any] = []
        _live += 1
        signals.register(self, self.request_shutdown)

    # -- parameters ------------------------------------------------------------------------------
    def _parameter_source(self, name, default, description):
        from rcl_interfaces.msg import ParameterDescriptor
        # Dynamic typing lets the seam apply one type rule (params.coerce_parameter) on both
        # backends; an empty-list default is declared untyped (rclpy cannot infer its type).
        desc = ParameterDescriptor(description=description, dynamic_typing=True)
        seed = None if (default is None or default == []) else default
        param = self._node.declare_parameter(name, seed, desc)
        value = param.value
        if value is None:
            return False, None
        if isinstance(value, tuple) or type(value).__name__ == "array":
            value = list(value)
        return True, value

    # -- communication --------------------------------------------------------------------------
    def _msg_class(self, typename: str):
        cls = self._msg_classes.get(typename)
        if cls is None:
            from rosidl_runtime_py.utilities import get_message
            cls = self._msg_classes[typename] = get_message(typename)
        return cls

    def create_publisher(self, typename: str, topic: str, qos: Qos) -> Publisher:
        pub = self._node.create_publisher(self._msg_class(typename), topic, to_rclpy_qos(qos),
                                          event_callbacks=no_event_handlers(publisher=True))
        self._publishers.append((qos, pub))
        return _RclpyPublisher(pub, typename, pub.topic_name, qos)

    def create_subscription(self, typename: str, topic: str, callback: Callable[..., None],
                            qos: Qos, raw: bool = False) -> Subscription:
        # Always take serialised bytes, so the seam's guard sees every sample's size before
        # decoding it (rclpy's C deserialiser, as a plain subscription would) and counts drops.
        from rclpy.serialization import deserialize_message
        cls = self._msg_class(typename)
        deliver = self.input_guard().wrap(self.resolve_topic_name(topic), callback, raw,
                                          lambda data: deserialize_message(data, cls))

        def on_sample(data: Any, info: dict[str, int]) -> None:  # two arguments: rclpy adds the message info
            deliver(data, time.time_ns(), info.get("source_timestamp"))

        # Jazzy's rclpy types the callback as one argument and calls one of two with the info
        sub = self._node.create_subscription(cls, topic, cast(Any, on_sample), to_rclpy_qos(qos), raw=True,
                                             event_callbacks=no_event_handlers(publisher=False))
        return _RclpySubscription(sub, typename, sub.topic_name, qos, raw)

    def create_timer(self, period_s: float, callback: Callable[[], None]) -> Timer:
        return _RclpyTimer(self._node.create_timer(period_s, callback), period_s)

    def create_client(self, srv_type: str, service: str) -> ServiceClient:
        from rosidl_runtime_py.utilities import get_service

        cls = get_service(srv_type)
        return _RclpyServiceClient(self._node.create_client(cls, service), cls, srv_type)

    def create_action_client(self, action_type: str, action: str) -> ActionClient:
        from rosidl_runtime_py.utilities import get_action

        return _RclpyActionClient(self._node, get_action(action_type), action_type, action)

    def now_ns(self) -> int:
        return int(self._node.get_clock().now().nanoseconds)

    def new_message(self, typename: str, **fields: Any) -> Any:
        cls = self._msg_class(typename)
        types = cls.get_fields_and_field_types()
        return cls(**{name: to_rclpy_value(value, types.get(name, "")) for name, value in fields.items()})

    def topic_names_and_types(self) -> list[tuple[str, list[str]]]:
        return sorted((name, sorted(types)) for name, types in self._node.get_topic_names_and_types())

    def publishers_info(self, topic: str) -> list[EndpointInfo]:
        fqn = self.resolve_topic_name(topic)
        out = []
        for info in self._node.get_publishers_info_by_topic(fqn):
            p = info.qos_profile
            qos, keep_all = qos_from_profile_fields(p.reliability.name, p.durability.name,
                                                    p.history.name, p.depth)
            th = getattr(info, "topic_type_hash", "")
            out.append(EndpointInfo(topic=fqn, typename=info.topic_type, qos=qos, keep_all=keep_all,
                                    type_hash=str(th) if th else "", node_name=info.node_name,
                                    node_namespace=info.node_namespace,
                                    gid=bytes(bytearray(getattr(info, "endpoint_gid", b"") or b""))))
        return out

    @property
    def rmw(self) -> str:
        from rclpy.utilities import get_rmw_implementation_identifier
        return get_rmw_implementation_identifier()

    @property
    def middleware(self) -> str:
        return f"rclpy over {self.rmw}"

    def resolve_topic_name(self, topic: str) -> str:
        resolve = getattr(self._node, "resolve_topic_name", None)  # rcl's own rules when present
        return resolve(topic) if resolve is not None else super().resolve_topic_name(topic)

    # -- execution -------------------------------------------------------------------------------
    def _guarded(self, fn, *args) -> None:
        """Run the executor; a stop (SIGINT, external shutdown) ends it quietly, whatever rclpy raises.

        rclpy's signal handler may shut the context down between two ``spin_once`` calls, and the
        next one then raises ``RCLError: context is not valid``: that is a stop, not a crash.
        """
        import rclpy
        from rclpy.executors import ExternalShutdownException
        try:
            fn(*args)
        except (KeyboardInterrupt, ExternalShutdownException):
            self._stopped = True
        except Exception:
            if rclpy.ok():
                raise
            self._stopped = True

    def spin(self) -> None:
        # Our own loop over spin_once (not executor.spin) so request_shutdown() ends it too.
        def loop():
            while self.ok():
                self._executor.spin_once(timeout_sec=0.1)
        self._guarded(loop)

    def spin_once(self, timeout_s: float | None = None) -> None:
        self._guarded(self._executor.spin_once, timeout_s)

    def ok(self) -> bool:
        import rclpy
        return not self._stopped and not self._closed and rclpy.ok()

    def request_shutdown(self) -> None:
        self._stopped = True

    def _take_pending(self, quiet_s: float, deadline: float) -> None:
        import rclpy

        last, seen = time.monotonic(), self.input_stats()["taken"]
        while rclpy.ok() and not self._closed:
            self._executor.spin_once(timeout_sec=min(0.05, quiet_s))
            now, taken = time.monotonic(), self.input_stats()["taken"]
            if taken != seen:
                last, seen = now, taken
            if now - last >= quiet_s or now >= deadline:
                return

    def _wait_acknowledged(self, deadline: float) -> None:
        from rclpy.duration import Duration

        if self._closed:
            return
        for qos, pub in self._publishers:
            left = deadline - time.monotonic()
            if qos.reliable and left > 0:
                pub.wait_for_all_acked(Duration(nanoseconds=int(left * 1e9)))

    def shutdown(self) -> None:
        global _live
        if self._closed:
            return
        self._closed = True
        signals.unregister(self)
        self._log_input_stats()
        import rclpy
        try:
            self._executor.remove_node(self._node)
            self._executor.shutdown()
            self._node.destroy_node()
        finally:
            _live -= 1
            if _live <= 0:
                rclpy.try_shutdown()
