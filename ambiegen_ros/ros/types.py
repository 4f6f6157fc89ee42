"""ROS 2 message types without a ROS install: the Jazzy type store plus our own ``.msg`` files.

Everything here is pure Python on ``rosbags`` (one pinned version): building messages with
defaults, ROS 2 CDR (little-endian, with the 4-byte encapsulation header ``00 01 00 00``), the
MCAP/rosbag2 schema text (``ros2msg``), RIHS01 type hashes (REP 2011) and DDS type names. The
transport backends and the recorder use it so that they never need rclpy.

Type names are always ``pkg/msg/Type``. ``get_registry()`` returns one shared, lazily built
registry; tests may build their own ``TypeRegistry(msg_dir)``.
"""
from __future__ import annotations

import os
import sys
import threading
from pathlib import Path
from typing import Any, Iterable

import numpy as np
from rosbags.interfaces import Nodetype
from rosbags.serde.utils import ndtype
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

MSGS_PACKAGE = "ambiegen_msgs"
MSGS_ENV = "AMBIEGEN_MSGS_DIR"
DEFINITION_SEPARATOR = "=" * 80

_PY_DEFAULTS = {"string": "", "bool": False, "float32": 0.0, "float64": 0.0, "float128": 0.0}


class MessageTypeError(KeyError):
    """An unknown type name or a field that does not belong to the type."""

    def __str__(self) -> str:  # KeyError would print the repr of the message
        return str(self.args[0]) if self.args else ""


def dds_type_name(typename: str) -> str:
    """``pkg/msg/Type`` -> ``pkg::msg::dds_::Type_`` (the name ROS 2 RMWs register in DDS)."""
    pkg, kind, name = _split(typename)
    return f"{pkg}::{kind}::dds_::{name}_"


def ros_type_name(dds_name: str) -> str:
    """Inverse of :func:`dds_type_name` (for discovery data seen on the wire)."""
    parts = dds_name.split("::")
    if len(parts) != 4 or parts[2] != "dds_" or not parts[3].endswith("_"):
        raise ValueError(f"not a ROS 2 DDS type name: {dds_name!r}")
    return f"{parts[0]}/{parts[1]}/{parts[3][:-1]}"


def _split(typename: str) -> tuple[str, str, str]:
    parts = typename.split("/")
    if len(parts) != 3 or not all(parts):
        raise MessageTypeError(f"type names look like 'pkg/msg/Type', got {typename!r}")
    return parts[0], parts[1], parts[2]


def _short(typename: str) -> str:
    """``pkg/msg/Type`` -> ``pkg/Type`` (the form used inside .msg files and MSG: lines)."""
    pkg, _, name = _split(typename)
    return f"{pkg}/{name}"


def find_msgs_dir() -> Path:
    """Locate our .msg files: $AMBIEGEN_MSGS_DIR, the source tree, or an installed share dir."""
    env = os.environ.get(MSGS_ENV)
    if env:
        path = Path(env)
        if not any(path.glob("*.msg")):
            raise FileNotFoundError(f"{MSGS_ENV}={env} holds no .msg files")
        return path
    candidates = [Path(__file__).resolve().parents[2] / MSGS_PACKAGE / "msg"]
    for prefix in dict.fromkeys([sys.prefix, sys.base_prefix]):
        candidates.append(Path(prefix) / "share" / MSGS_PACKAGE / "msg")
        candidates.append(Path(prefix) / "share" / "ambiegen_ros" / MSGS_PACKAGE / "msg")
    for prefix in filter(None, os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep)):
        candidates.append(Path(prefix) / "share" / MSGS_PACKAGE / "msg")
    for path in candidates:
        if any(path.glob("*.msg")):
            return path
    tried = "\n  ".join(str(p) for p in candidates)
    raise FileNotFoundError(
        f"cannot find the {MSGS_PACKAGE} .msg files; set {MSGS_ENV} to their folder. Tried:\n  {tried}"
    )


class TypeRegistry:
    """The Jazzy type store plus ``ambiegen_msgs``; codec, schema text and hashes per type."""

    def __init__(self, msg_dir: str | os.PathLike | None = None, package: str = MSGS_PACKAGE):
        self.msg_dir = Path(msg_dir) if msg_dir is not None else find_msgs_dir()
        self.package = package
        self.store = get_typestore(Stores.ROS2_JAZZY)
        self._texts: dict[str, str] = {}
        typedefs: dict = {}
        for path in sorted(self.msg_dir.glob("*.msg")):
            typename = f"{package}/msg/{path.stem}"
            text = path.read_text(encoding="utf-8")
            self._texts[typename] = text
            typedefs.update(get_types_from_msg(text, typename))
        if not typedefs:
            raise FileNotFoundError(f"no .msg files in {self.msg_dir}")
        self.store.register(typedefs)
        self.own_types = tuple(sorted(self._texts))
        for typename in self.own_types:
            missing = [dep for dep in self._dependencies(typename) if dep not in self.store.fielddefs]
            if missing:
                raise MessageTypeError(f"{typename} refers to unknown type(s) {', '.join(missing)}")
        self._lock = threading.Lock()
        self._msgdefs: dict[str, str] = {}
        self._hashes: dict[str, str] = {}
        self._array_plans: dict[str, tuple] = {}

    # --- queries ---------------------------------------------------------------------------
    def has(self, typename: str) -> bool:
        return typename in self.store.fielddefs

    def _fields(self, typename: str) -> list:
        try:
            return self.store.fielddefs[typename][1]
        except KeyError:
            _split(typename)
            raise MessageTypeError(f"unknown message type {typename!r}") from None

    def field_names(self, typename: str) -> list[str]:
        return [name for name, _ in self._fields(typename)]

    def constants(self, typename: str) -> dict[str, Any]:
        """Constants declared in the type (e.g. ScenarioResult.COLLISION), name -> value."""
        self._fields(typename)
        return {name: value for name, _typ, value in self.store.fielddefs[typename][0]}

    def message_class(self, typename: str) -> type:
        self._fields(typename)
        return self.store.types[typename]

    def dds_type_name(self, typename: str) -> str:
        self._fields(typename)
        return dds_type_name(typename)

    # --- building messages -------------------------------------------------------------------
    def new(self, typename: str, **fields: Any) -> Any:
        """A message with every field not given set to its zero value (recursively).

        Lists/tuples given for numeric array fields become numpy arrays of the field's dtype,
        because rosbags' encoder writes such fields straight from the array memory.
        """
        desc = dict(self._fields(typename))
        unknown = set(fields) - set(desc)
        if unknown:
            raise MessageTypeError(
                f"{typename} has no field {sorted(unknown)[0]!r} (fields: {', '.join(desc)})"
            )
        values = {}
        for name, fdesc in desc.items():
            if name in fields:
                values[name] = self._coerce(fields[name], fdesc, f"{typename}.{name}")
            else:
                values[name] = self._default(fdesc)
        return self.store.types[typename](**values)

    def _default(self, desc: tuple) -> Any:
        kind, arg = desc
        if kind == Nodetype.BASE:
            base = arg[0]
            return _PY_DEFAULTS.get(base, "" if base.startswith("string") else 0)
        if kind == Nodetype.NAME:
            return self.new(arg)
        (subkind, subarg), length = arg
        if subkind == Nodetype.BASE:
            if subarg[0] == "string":
                return [""] * length if kind == Nodetype.ARRAY else []
            dtype = np.dtype(ndtype(subarg[0]))
            return np.zeros(length if kind == Nodetype.ARRAY else 0, dtype=dtype)
        if kind == Nodetype.ARRAY:
            return [self.new(subarg) for _ in range(length)]
        return []

    def _coerce(self, value: Any, desc: tuple, where: str) -> Any:
        kind, arg = desc
        if kind in (Nodetype.ARRAY, Nodetype.SEQUENCE):
            (subkind, subarg), length = arg
            if subkind == Nodetype.BASE and subarg[0] != "string":
                value = _as_array(value, np.dtype(ndtype(subarg[0])), where)
            elif not isinstance(value, list):
                value = list(value)
            if kind == Nodetype.ARRAY and len(value) != length:
                raise ValueError(f"{where}: fixed array needs {length} items, got {len(value)}")
        return value

    # --- CDR -------------------------------------------------------------------------------------
    def serialize(self, msg: Any, typename: str) -> bytes:
        """ROS 2 CDR, little-endian, including the encapsulation header ``00 01 00 00``."""
        self._check_arrays(msg, typename)
        return bytes(self.store.serialize_cdr(msg, typename, little_endian=True))

    def deserialize(self, data: bytes | bytearray | memoryview, typename: str) -> Any:
        """Decode CDR bytes (either endianness). Numeric arrays may be read-only views of ``data``."""
        self._fields(typename)
        return self.store.deserialize_cdr(data, typename)

    def _check_arrays(self, msg: Any, typename: str) -> None:
        """Fix numeric array fields holding lists or the wrong dtype; refuse unsafe casts.

        rosbags copies an array's raw memory, so an int64 array in a float64[] field would be
        written as garbage instead of failing. The per-type plan visits only fields that can hold
        numeric arrays, so messages like nav_msgs/Path cost nothing here.
        """
        for step, name, arg in self._array_plan(typename):
            value = getattr(msg, name)
            if step == "array":
                dtype, length = arg
                if not (isinstance(value, np.ndarray) and value.dtype == dtype):
                    value = _as_array(value, dtype, f"{typename}.{name}")
                    setattr(msg, name, value)
                if length and len(value) != length:
                    raise ValueError(f"{typename}.{name}: fixed array needs {length} items, got {len(value)}")
            elif step == "msg":
                self._check_arrays(value, arg)
            else:
                for item in value:
                    self._check_arrays(item, arg)

    def _array_plan(self, typename: str) -> tuple:
        plan = self._array_plans.get(typename)
        if plan is None:
            steps = []
            for name, (kind, arg) in self._fields(typename):
                if kind == Nodetype.NAME:
                    if self._array_plan(arg):
                        steps.append(("msg", name, arg))
                elif kind in (Nodetype.ARRAY, Nodetype.SEQUENCE):
                    (subkind, subarg), length = arg
                    if subkind == Nodetype.BASE and subarg[0] != "string":
                        fixed = length if kind == Nodetype.ARRAY else 0
                        steps.append(("array", name, (np.dtype(ndtype(subarg[0])), fixed)))
                    elif subkind == Nodetype.NAME and self._array_plan(subarg):
                        steps.append(("msgs", name, subarg))
            plan = self._array_plans[typename] = tuple(steps)
        return plan

    # --- schema text and hashes ------------------------------------------------------------------
    def _dependencies(self, typename: str) -> list[str]:
        """Directly referenced message types, sorted by their ``pkg/Type`` name like rosbag2."""
        deps = set()
        for _, (kind, arg) in self._fields(typename):
            if kind == Nodetype.NAME:
                deps.add(arg)
            elif kind in (Nodetype.ARRAY, Nodetype.SEQUENCE) and arg[0][0] == Nodetype.NAME:
                deps.add(arg[0][1])
        return sorted(deps, key=_short)

    def _own_text(self, typename: str) -> str:
        """The .msg text: our files verbatim (as rosbag2 stores them), Jazzy types regenerated."""
        text = self._texts.get(typename)
        if text is None:
            text = self.store.gendefhash(typename, {}, ros_version=2)[0]
        return text

    def msgdef(self, typename: str) -> str:
        """MCAP ``ros2msg`` schema: the type's .msg, then each dependency as rosbag2 writes it.

        Like rosbag2's LocalMessageDefinitionSource: depth-first, dependencies of each type in
        sorted order, each type once, every one preceded by ``"\\n" + 80 "=" + "\\nMSG: pkg/Type\\n"``.
        """
        cached = self._msgdefs.get(typename)
        if cached is not None:
            return cached
        self._fields(typename)
        seen: set[str] = set()

        def append(name: str) -> str:
            out = self._own_text(name)
            for dep in self._dependencies(name):
                if dep not in seen:
                    seen.add(dep)
                    out += f"\n{DEFINITION_SEPARATOR}\nMSG: {_short(dep)}\n" + append(dep)
            return out

        text = append(typename)
        with self._lock:
            self._msgdefs[typename] = text
        return text

    def type_hash(self, typename: str) -> str:
        """REP 2011 ``RIHS01_<sha256 hex>`` of the type description (what Jazzy RMWs advertise)."""
        cached = self._hashes.get(typename)
        if cached is None:
            self._fields(typename)
            cached = self.store.hash_rihs01(typename)
            with self._lock:
                self._hashes[typename] = cached
        return cached


def _as_array(value: Any, dtype: np.dtype, where: str) -> np.ndarray:
    """Convert to a 1-D array of ``dtype`` without silent wrap-around or truncation."""
    try:
        array = np.asarray(value)
    except (ValueError, OverflowError) as exc:
        raise TypeError(f"{where}: not a {dtype} array: {exc}") from None
    if array.dtype == dtype:
        return np.ascontiguousarray(array).reshape(-1)
    if array.size == 0:
        return np.zeros(0, dtype=dtype)
    src = array.dtype.kind
    if dtype.kind in "iu" and src in "iub":
        info = np.iinfo(dtype)  # Python ints arrive as int64: accept them when every value fits
        if array.min() >= info.min and array.max() <= info.max:
            return array.astype(dtype).reshape(-1)
        raise ValueError(f"{where}: values outside the {dtype} range")
    if (dtype.kind == "f" and src in "iubf") or (dtype.kind == "b" and src == "b"):
        return np.ascontiguousarray(array, dtype=dtype).reshape(-1)
    raise TypeError(f"{where}: cannot store {array.dtype} values in a {dtype} array field")


_REGISTRY: TypeRegistry | None = None
_REGISTRY_LOCK = threading.Lock()


def get_registry() -> TypeRegistry:
    """The process-wide registry (built on first use; about 0.1 s)."""
    global _REGISTRY
    if _REGISTRY is None:
        with _REGISTRY_LOCK:
            if _REGISTRY is None:
                _REGISTRY = TypeRegistry()
    return _REGISTRY


def own_type_names(registry: TypeRegistry | None = None) -> Iterable[str]:
    return (registry or get_registry()).own_types


__all__ = [
    "MessageTypeError",
    "TypeRegistry",
    "dds_type_name",
    "find_msgs_dir",
    "get_registry",
    "own_type_names",
    "ros_type_name",
]
