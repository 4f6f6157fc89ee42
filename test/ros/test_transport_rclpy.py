"""The transport seam's rclpy backend, on a machine without rclpy: its QoS table, the backend
choice, the adapter against a fake of the Jazzy API surface it uses, its value adaptation, and a
static type check of the seam.
"""
from __future__ import annotations

import inspect
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

import pytest  # noqa: E402

from ambiegen_ros.ros import transport  # noqa: E402
from ambiegen_ros.ros.qos import DEFAULT, LATCHED, Qos  # noqa: E402
from ambiegen_ros.ros.transport import rclpy_backend  # noqa: E402

STRING = "std_msgs/msg/String"
SOURCE_NS = 1_700_000_000_000_000_007  # the fake middleware's source timestamp of every sample


# ---------------------------------------------------------------------------------------------
# rclpy backend parts that need no rclpy, backend selection


def test_rclpy_qos_table():
    assert rclpy_backend.qos_profile_kwargs(DEFAULT) == {
        "history": "keep_last", "depth": 10, "reliability": "reliable", "durability": "volatile"}
    assert rclpy_backend.qos_profile_kwargs(LATCHED)["durability"] == "transient_local"
    assert rclpy_backend.qos_profile_kwargs(LATCHED)["depth"] == 1
    assert rclpy_backend.qos_profile_kwargs(Qos(reliable=False, depth=0)) == {
        "history": "keep_last", "depth": 1, "reliability": "best_effort", "durability": "volatile"}
    assert rclpy_backend.qos_from_profile_fields("RELIABLE", "TRANSIENT_LOCAL", "KEEP_LAST", 1) == (LATCHED, False)
    assert rclpy_backend.qos_from_profile_fields("BEST_EFFORT", "VOLATILE", "KEEP_ALL", 5)[1] is True
    assert rclpy_backend.qos_profile_kwargs(Qos(keep_all=True))["history"] == "keep_all"


@pytest.mark.skipif(rclpy_backend.is_available(), reason="rclpy is installed here")
def test_backend_selection_without_rclpy(monkeypatch):
    assert transport.available_backends() == ["dds"]
    monkeypatch.setenv("AMBIEGEN_TRANSPORT", "rclpy")
    with pytest.raises(transport.BackendUnavailable, match="rclpy.*AMBIEGEN_TRANSPORT=dds"):
        transport.create_node("x")
    with pytest.raises(transport.BackendUnavailable):
        rclpy_backend.RclpyNode("x")
    monkeypatch.setenv("AMBIEGEN_TRANSPORT", "auto")
    assert transport.select_backend() == "dds"
    monkeypatch.delenv("AMBIEGEN_TRANSPORT")
    assert transport.select_backend() == "dds"
    monkeypatch.setenv("AMBIEGEN_TRANSPORT", "zenoh")
    with pytest.raises(ValueError, match="rclpy, dds, auto"):
        transport.select_backend()


def _fake_rclpy(monkeypatch):
    """A minimal in-memory stand-in for the Jazzy rclpy API surface the adapter uses.

    It checks call shapes (keyword names as in Jazzy) and wires publishers to subscriptions, so
    the adapter's own logic (raw wrapper, QoS objects, parameter flow, spin/shutdown handling)
    runs here; it proves nothing about real rclpy, which this machine lacks.
    """
    import enum
    import types as pytypes

    class ExternalShutdownException(Exception):
        pass

    state = {"ok": False, "init_args": None, "shutdowns": 0, "topics": {}, "acked_waits": 0, "signal_options": None,
             "event_callbacks": []}

    class QoSProfile:
        def __init__(self, *, history, depth, reliability, durability):
            self.history, self.depth, self.reliability, self.durability = history, depth, reliability, durability

    Rel = enum.Enum("ReliabilityPolicy", "RELIABLE BEST_EFFORT")
    Dur = enum.Enum("DurabilityPolicy", "TRANSIENT_LOCAL VOLATILE")
    Hist = enum.Enum("HistoryPolicy", "KEEP_LAST KEEP_ALL")

    class Parameter:
        def __init__(self, name, type_=None, value=None):
            self.name, self.value = name, value

    class ParameterDescriptor:
        def __init__(self, *, description="", dynamic_typing=False):
            self.description, self.dynamic_typing = description, dynamic_typing

    class FakeMsg:
        def __init__(self, data=""):
            self.data = data

        @classmethod
        def get_fields_and_field_types(cls):  # every rosidl-generated class has it
            return {"data": "string"}

    class Pub:
        def __init__(self, topic):
            self.topic_name = topic

        def publish(self, msg):  # rclpy accepts the message class or exactly ``bytes``
            if not (type(msg) is bytes or isinstance(msg, FakeMsg)):
                raise TypeError(type(msg))
            for cb, raw in state["topics"].get(self.topic_name, []):
                if type(msg) is bytes:
                    cb(msg if raw else FakeMsg(msg.decode("latin-1")))
                else:
                    cb(("CDR:" + msg.data).encode() if raw else msg)

        def get_subscription_count(self):
            return len(state["topics"].get(self.topic_name, []))

        def wait_for_all_acked(self, timeout):  # Jazzy: rclpy.duration.Duration -> bool
            state["acked_waits"] += 1
            return True

    class FakeNode:
        def __init__(self, name, namespace, overrides):
            self.name, self.ns = name, namespace or "/"
            self.params = {p.name: p.value for p in overrides}
            self.pending = []
            self.destroyed = False

        def get_name(self):
            return self.name

        def get_namespace(self):
            return self.ns

        def get_logger(self):
            return pytypes.SimpleNamespace(info=print, warning=print, debug=print, error=print)

        def resolve_topic_name(self, topic):
            return topic if topic.startswith("/") else self.ns.rstrip("/") + "/" + topic

        def declare_parameter(self, name, value=None, descriptor=None, ignore_override=False):
            assert descriptor.dynamic_typing is True
            return Parameter(name, value=self.params.get(name, value))

        def create_publisher(self, msg_type, topic, qos_profile, *, callback_group=None, event_callbacks=None,
                             qos_overriding_options=None):
            assert isinstance(qos_profile, QoSProfile)
            state["event_callbacks"].append(event_callbacks)
            return Pub(self.resolve_topic_name(topic))

        def create_subscription(self, msg_type, topic, callback, qos_profile, *, callback_group=None,
                                event_callbacks=None, qos_overriding_options=None, raw=False):
            fqn = self.resolve_topic_name(topic)
            state["event_callbacks"].append(event_callbacks)
            state["topics"].setdefault(fqn, []).append((lambda m: self.pending.append((callback, m)), raw))
            return pytypes.SimpleNamespace(topic_name=fqn)

        def create_timer(self, period, callback):
            return pytypes.SimpleNamespace(cancel=lambda: None, is_canceled=lambda: False)

        def get_clock(self):
            return pytypes.SimpleNamespace(now=lambda: pytypes.SimpleNamespace(nanoseconds=123))

        def get_topic_names_and_types(self):
            return [("/b", ["x/msg/B"]), ("/a", ["x/msg/A"])]

        def get_publishers_info_by_topic(self, topic):
            q = QoSProfile(history=Hist.KEEP_LAST, depth=1, reliability=Rel.RELIABLE, durability=Dur.TRANSIENT_LOCAL)
            return [pytypes.SimpleNamespace(node_name="n", node_namespace="/", topic_type="x/msg/A",
                                            qos_profile=q, topic_type_hash="RIHS01_x")]

        def destroy_node(self):
            self.destroyed = True

    class SingleThreadedExecutor:
        def __init__(self, *, context=None):
            self.nodes = []

        def add_node(self, node):
            self.nodes.append(node)

        def remove_node(self, node):
            self.nodes.remove(node)

        def shutdown(self, timeout_sec=None):
            return True

        def spin_once(self, timeout_sec=None):
            if not state["ok"]:
                raise ExternalShutdownException()
            for node in self.nodes:
                while node.pending:  # rclpy's rule: a callback of two arguments gets the message info
                    cb, m = node.pending.pop(0)
                    try:
                        inspect.signature(cb).bind(m)
                        cb(m)
                    except TypeError:
                        cb(m, {"source_timestamp": SOURCE_NS, "received_timestamp": SOURCE_NS + 1})

    def init(*, args=None, context=None, domain_id=None, signal_handler_options=None):
        state["ok"], state["init_args"], state["signal_options"] = True, args, signal_handler_options

    def create_node(node_name, *, context=None, cli_args=None, namespace=None, use_global_arguments=True,
                    enable_rosout=True, start_parameter_services=True, parameter_overrides=None,
                    allow_undeclared_parameters=False, automatically_declare_parameters_from_overrides=False,
                    enable_logger_service=False):
        return FakeNode(node_name, namespace, parameter_overrides or [])

    def try_shutdown(*, context=None):
        state["ok"] = False
        state["shutdowns"] += 1

    mods = {
        "rclpy": pytypes.ModuleType("rclpy"), "rclpy.executors": pytypes.ModuleType("rclpy.executors"),
        "rclpy.parameter": pytypes.ModuleType("rclpy.parameter"), "rclpy.qos": pytypes.ModuleType("rclpy.qos"),
        "rcl_interfaces": pytypes.ModuleType("rcl_interfaces"),
        "rcl_interfaces.msg": pytypes.ModuleType("rcl_interfaces.msg"),
        "rosidl_runtime_py": pytypes.ModuleType("rosidl_runtime_py"),
        "rosidl_runtime_py.utilities": pytypes.ModuleType("rosidl_runtime_py.utilities"),
        "rclpy.serialization": pytypes.ModuleType("rclpy.serialization"),
        "rclpy.signals": pytypes.ModuleType("rclpy.signals"), "rclpy.duration": pytypes.ModuleType("rclpy.duration"),
        "rclpy.event_handler": pytypes.ModuleType("rclpy.event_handler"),
    }
    for kind in ("PublisherEventCallbacks", "SubscriptionEventCallbacks"):  # Jazzy's signature
        setattr(mods["rclpy.event_handler"], kind, type(kind, (), {"__init__": lambda self, *, use_default_callbacks=True,
                                                                     **callbacks: setattr(
            self, "use_default_callbacks", use_default_callbacks)}))
    mods["rclpy.signals"].SignalHandlerOptions = enum.Enum("SignalHandlerOptions", "NO SIGINT SIGTERM ALL")
    mods["rclpy.duration"].Duration = lambda *, seconds=0, nanoseconds=0: pytypes.SimpleNamespace(
        nanoseconds=int(seconds * 1e9) + nanoseconds)
    # the adapter subscribes raw and decodes itself (so its input guard sees sizes): the fake's "CDR"
    mods["rclpy.serialization"].deserialize_message = lambda data, cls: cls(
        data[4:].decode() if data.startswith(b"CDR:") else data.decode("latin-1"))
    mods["rclpy"].__dict__.update(init=init, ok=lambda context=None: state["ok"], create_node=create_node,
                                  try_shutdown=try_shutdown)
    mods["rclpy.executors"].__dict__.update(SingleThreadedExecutor=SingleThreadedExecutor,
                                            ExternalShutdownException=ExternalShutdownException)
    mods["rclpy.parameter"].Parameter = Parameter
    mods["rclpy.qos"].__dict__.update(QoSProfile=QoSProfile, ReliabilityPolicy=Rel, DurabilityPolicy=Dur,
                                      HistoryPolicy=Hist)
    mods["rcl_interfaces.msg"].ParameterDescriptor = ParameterDescriptor
    mods["rosidl_runtime_py.utilities"].get_message = lambda name: FakeMsg
    for name, mod in mods.items():
        monkeypatch.setitem(sys.modules, name, mod)
    monkeypatch.setattr(rclpy_backend, "_import_error", "")
    return state


def test_rclpy_adapter_against_a_fake_jazzy_api(monkeypatch):
    state = _fake_rclpy(monkeypatch)
    node = transport.create_node("gen", argv=["prog", "--ros-args", "-p", "rate:=2"], backend="rclpy",
                                 parameter_overrides={"rate": 3})
    assert node.backend_name == "rclpy" and state["init_args"][0] == "prog"
    assert node.declare_parameter("rate", 1.0) == 3.0 and isinstance(node.get_parameter("rate"), float)
    assert node.declare_parameter("absent", []) == []
    got = []
    pub = node.create_publisher(STRING, "chat", LATCHED)
    node.create_subscription(STRING, "/chat", lambda m: got.append(m.data), DEFAULT)
    node.create_subscription(STRING, "chat", lambda d, t: got.append((d, t > 0)), DEFAULT, raw=True)
    sent = []
    node.create_subscription(STRING, "chat", lambda d, t, source: sent.append(source), DEFAULT, raw=True)
    assert pub.subscription_count() == 3 and pub.topic == "/chat"
    # no QoS event handlers: rclpy's default ones are waitables rebuilt into every wait (issue 58)
    assert [type(e).__name__ for e in state["event_callbacks"]] == [
        "PublisherEventCallbacks", "SubscriptionEventCallbacks", "SubscriptionEventCallbacks",
        "SubscriptionEventCallbacks"]
    assert not any(e.use_default_callbacks for e in state["event_callbacks"])
    pub.publish(node.new_message(STRING, data="hi"))
    pub.publish_raw(bytearray(b"\x00\x01\x00\x00"))
    node.spin_once(0.0)
    assert got == ["hi", (b"CDR:hi", True), "\x00\x01\x00\x00", (b"\x00\x01\x00\x00", True)]
    assert sent == [SOURCE_NS, SOURCE_NS]  # a raw callback of three arguments gets the writer's send time
    assert node.now_ns() == 123 and node.topic_names_and_types()[0][0] == "/a"
    (ep,) = node.publishers_info("chat")
    assert (ep.qos, ep.keep_all, ep.type_hash, ep.topic) == (LATCHED, False, "RIHS01_x", "/chat")
    ticks = []
    node.create_timer(0.1, lambda: ticks.append(1))
    node.request_shutdown()
    node.spin()  # returns at once: stop requested
    assert not node.ok()
    # rclpy's own SIGINT handler would shut the context down with samples on their way: ours is used
    assert state["signal_options"].name == "NO"
    pub.publish(node.new_message(STRING, data="late"))
    node.finish_io(drain=True, quiet_s=0.01, drain_s=1.0, ack_s=1.0)  # after a stop: still taken, and acked
    assert got[-2:] == ["late", (b"CDR:late", True)] and state["acked_waits"] == 1  # the one (reliable) publisher
    node.shutdown()
    node.shutdown()
    assert state["shutdowns"] == 1 and not state["ok"]


def test_rclpy_values_are_adapted_to_generated_setters():
    """numpy sequences -> lists (rclpy rejects ndarrays for unbounded sequences); int -> bytes for octet."""
    import numpy as np

    from ambiegen_ros.ros.transport.rclpy_backend import to_rclpy_value

    data = to_rclpy_value(np.array([0, 100, -1], dtype=np.int8), "sequence<int8>")
    assert data == [0, 100, -1] and all(type(v) is int for v in data)
    assert to_rclpy_value(np.array([1.5]), "sequence<double>") == [1.5]
    assert to_rclpy_value(0, "octet") == b"\x00"
    assert to_rclpy_value(2, "int32") == 2
    assert to_rclpy_value(True, "boolean") is True
    assert to_rclpy_value("x", "string") == "x"


def test_rclpy_backend_and_the_seam_type_check():
    """No rclpy here, so the rclpy backend is checked statically (rclpy itself typed as Any)."""
    files = ["ambiegen_ros/ros/transport/rclpy_backend.py", "ambiegen_ros/ros/transport/base.py",
             "ambiegen_ros/ros/transport/params.py", "ambiegen_ros/ros/transport/__init__.py"]
    out = subprocess.run([sys.executable, "-m", "mypy", "--ignore-missing-imports", "--follow-imports=silent", *files],
                         cwd=Path(__file__).resolve().parents[2], capture_output=True, text=True, timeout=240)
    assert out.returncode == 0, out.stdout + out.stderr
