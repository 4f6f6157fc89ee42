"""What ROS 2 puts on the DDS wire: topic and type names, the IDL mirror of a ROS type, CDR
padding, and endpoint QoS as rmw_cyclonedds_cpp builds it.

Split from ``dds_backend`` (the node, its endpoints and the process-wide domain state) so each
reads on its own; the backend re-exports these names. cyclonedds is imported here too, and a
failed import leaves the names defined (``dds_backend.IMPORT_ERROR`` reports it).
"""
from __future__ import annotations

import threading
from typing import Any, Callable

from ambiegen_ros.ros.qos import Qos

from .base import TransportError

try:
    import cyclonedds.idl.types as _idl_t
    from cyclonedds.core import Policy
    from cyclonedds.core import Qos as _DdsQos
    from cyclonedds.idl import make_idl_struct
    from cyclonedds.internal import dds_infinity
    _WIRE_IMPORTED = True
except Exception:  # pragma: no cover - exercised only where cyclonedds is missing
    _WIRE_IMPORTED = False

_BASE_TYPES = {}
if _WIRE_IMPORTED:
    _BASE_TYPES = {
        "bool": bool, "byte": _idl_t.byte, "char": _idl_t.uint8,
        "int8": _idl_t.int8, "uint8": _idl_t.uint8, "int16": _idl_t.int16, "uint16": _idl_t.uint16,
        "int32": _idl_t.int32, "uint32": _idl_t.uint32, "int64": _idl_t.int64, "uint64": _idl_t.uint64,
        "float32": _idl_t.float32, "float64": _idl_t.float64,
    }


# --- names and types ----------------------------------------------------------------------------


def ros_topic_to_dds(fqn: str) -> str:
    """'/a/b' -> 'rt/a/b' (topics; services: ``service_topics``)."""
    return "rt" + fqn


def service_topics(fqn: str) -> tuple[str, str]:
    """'/a/s' -> ('rq/a/sRequest', 'rr/a/sReply'): rmw_cyclonedds_cpp's ``make_fqtopic`` with
    ROS_SERVICE_REQUESTER_PREFIX / ROS_SERVICE_RESPONSE_PREFIX (rmw_node.cpp, ``rmw_init_cs``)."""
    return "rq" + fqn + "Request", "rr" + fqn + "Reply"


def dds_topic_to_ros(name: str) -> str | None:
    """'rt/a/b' -> '/a/b'; None for non-topic DDS names (services, ros_discovery_info, ...)."""
    return name[2:] if name.startswith("rt/") else None


def dds_type_to_ros(type_name: str) -> str:
    """'nav_msgs::msg::dds_::OccupancyGrid_' -> 'nav_msgs/msg/OccupancyGrid'."""
    parts = [p for p in type_name.split("::") if p != "dds_"]
    if parts and parts[-1].endswith("_"):
        parts[-1] = parts[-1][:-1]
    return "/".join(parts)


def _types_module():
    from ambiegen_ros.ros import types as _types  # written by another module owner
    return _types


class IdlMirror:
    """Builds (and caches) one ``IdlStruct`` per ROS type mirroring its .msg layout."""

    def __init__(self, registry, dds_type_name: Callable[[str], str]):
        self._registry = registry
        self._dds_name = dds_type_name
        self._fields: dict[str, list] = {}
        self._classes: dict[str, type] = {}
        self._lock = threading.Lock()

    def get(self, typename: str, request_header: bool = False) -> type:
        """The struct of ``typename``; with ``request_header`` the one of a service request or
        reply sample: rmw_cyclonedds_cpp writes ``cdds_request_header_t {uint64 guid; int64 seq}``
        before the message (Serialization.cpp, ``serialize_top_level`` of a request wrapper),
        under the message's own type name."""
        with self._lock:
            if not request_header:
                return self._get(typename)
            key = typename + "#request_header"
            cls = self._classes.get(key)
            if cls is None:
                self._get(typename)
                fields = {"cdds_request_guid": _idl_t.uint64, "cdds_request_seq": _idl_t.int64}
                fields.update((fname, self._convert(typename, fname, desc)) for fname, desc in self._fields[typename])
                cls = self._classes[key] = make_idl_struct(typename.rsplit("/", 1)[-1] + "_",
                                                           self._dds_name(typename), fields)
            return cls

    def _get(self, typename: str) -> type:
        cls = self._classes.get(typename)
        if cls is not None:
            return cls
        if typename not in self._fields:
            self._load(typename)
        fields = {fname: self._convert(typename, fname, desc) for fname, desc in self._fields[typename]}
        short = typename.rsplit("/", 1)[-1] + "_"
        cls = make_idl_struct(short, self._dds_name(typename), fields)
        self._classes[typename] = cls
        return cls

    def _load(self, typename: str) -> None:
        from rosbags.typesys import get_types_from_msg
        if "/msg/" not in typename:  # services' and actions' types: rosbags' .msg parser would file
            store = getattr(self._registry, "store", None)  # them under pkg/srv/msg/ (interfaces.py)
            if store is not None and typename in store.fielddefs:
                self._fields[typename] = store.fielddefs[typename][1]
                return
        text = self._registry.msgdef(typename)
        if isinstance(text, tuple):
            text = text[0]
        for name, (_consts, fields) in get_types_from_msg(text, typename).items():
            self._fields.setdefault(name, fields)
        if typename not in self._fields:
            raise TransportError(f"message definition of {typename} does not define it")

    def _convert(self, owner: str, fname: str, desc) -> Any:
        kind, arg = desc
        kname = getattr(kind, "name", str(kind)).upper()
        if kname == "BASE":
            base, bound = arg
            if base == "string":
                return _idl_t.bounded_str[bound] if bound else str
            if base in _BASE_TYPES:
                return _BASE_TYPES[base]
            raise TransportError(f"{owner}.{fname}: type {base!r} is not supported by the DDS backend")
        if kname == "NAME":
            return self._get(arg)
        if kname == "ARRAY":
            sub, length = arg
            return _idl_t.array[self._convert(owner, fname, sub), length]
        if kname == "SEQUENCE":
            sub, bound = arg
            inner = self._convert(owner, fname, sub)
            return _idl_t.sequence[inner, bound] if bound else _idl_t.sequence[inner]
        raise TransportError(f"{owner}.{fname}: unknown field kind {kname}")


def pad_cdr(data) -> bytes:
    """Pad CDR to a multiple of 4 and record the count in the encapsulation options' low bits.

    RTPS carries payloads in 4-byte units, so the receiver sees the padding anyway; announcing
    it (XTypes 7.6.3.1.2, as Cyclone's and Fast DDS' own serialisers do) lets receivers -- ours
    included -- recover the exact original bytes.
    """
    pad = -len(data) % 4
    if not pad or len(data) < 4:
        return data
    b = bytearray(data)
    b[3] = (b[3] & 0xFC) | pad
    b.extend(bytes(pad))
    return bytes(b)


def unpad_cdr(data: bytes) -> bytes:
    """Inverse of ``pad_cdr``: drop the announced trailing padding and clear the bits."""
    pad = data[3] & 3
    if not pad or len(data) - 4 < pad:
        return data
    b = bytearray(data[: len(data) - pad])
    b[3] &= 0xFC
    return bytes(b)


# --- QoS ----------------------------------------------------------------------------------------


def dds_qos(qos: Qos, type_hash: str = "", user_data: str = "") -> "_DdsQos":
    """Endpoint QoS as rmw_cyclonedds_cpp (Jazzy) builds it, plus the REP 2011 type hash.

    ``user_data`` goes before the hash, as rmw_cyclonedds_cpp puts a service endpoint's
    ``clientid=...;`` / ``serviceid=...;`` (``create_readwrite_qos``)."""
    policies = [
        Policy.History.KeepAll if qos.keep_all else Policy.History.KeepLast(max(1, int(qos.depth))),
        Policy.Reliability.Reliable(max_blocking_time=dds_infinity) if qos.reliable
        else Policy.Reliability.BestEffort,
        Policy.DataRepresentation(use_cdrv0_representation=True),
    ]
    if qos.transient_local:
        policies.append(Policy.Durability.TransientLocal)
        # Cyclone keeps late-joiner history per the durability service, not the writer history.
        policies.append(Policy.DurabilityService(
            cleanup_delay=0, history=Policy.History.KeepLast(max(1, int(qos.depth))),
            max_samples=-1, max_instances=-1, max_samples_per_instance=-1))
    else:
        policies.append(Policy.Durability.Volatile)
    text = user_data + (f"typehash={type_hash};" if type_hash else "")
    if text:
        policies.append(Policy.Userdata(text.encode("ascii")))
    return _DdsQos(*policies)


def user_data_value(dq, key: str) -> str | None:
    """The value of ``key`` in a discovered endpoint's USER_DATA (``k=v;`` pairs), None if absent."""
    ud = dq[Policy.Userdata] if dq is not None else None
    if ud is None:
        return None
    for item in bytes(ud.data).decode("utf-8", "replace").split(";"):
        k, sep, v = item.partition("=")
        if sep and k == key:
            return v
    return None


def qos_from_dds(dq) -> tuple[Qos, bool, str]:
    """(Qos, keep_all, type_hash) from a discovered endpoint's QoS."""
    rel = dq[Policy.Reliability] if dq is not None else None
    dur = dq[Policy.Durability] if dq is not None else None
    hist = dq[Policy.History] if dq is not None else None
    ud = dq[Policy.Userdata] if dq is not None else None
    # DDS defaults when a policy is absent: writers reliable, readers best effort; volatile; keep last 1.
    reliable = rel is not None and rel != Policy.Reliability.BestEffort
    transient = dur is not None and dur == Policy.Durability.TransientLocal
    keep_all = hist is not None and hist == Policy.History.KeepAll
    depth = getattr(hist, "depth", 1) if hist is not None and not keep_all else (0 if keep_all else 1)
    type_hash = ""
    if ud is not None:
        for item in bytes(ud.data).decode("utf-8", "replace").split(";"):
            if item.startswith("typehash="):
                type_hash = item[len("typehash="):]
    return Qos(reliable=reliable, transient_local=transient, depth=depth), keep_all, type_hash
