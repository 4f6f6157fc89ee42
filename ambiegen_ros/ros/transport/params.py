"""ROS 2 command-line arguments and parameter files, parsed without rcl.

Both backends share this module: the DDS backend uses it to read ``--ros-args`` itself, and the
rclpy backend uses the same type rules so a node sees identical parameter values whichever
backend runs it. Syntax follows the ROS 2 design (rcl ``arguments.c`` / ``rcl_yaml_param_parser``):

* ``--ros-args ... [--]`` opens a ROS section (there may be several); ``--`` closes it;
* ``-p/--param name:=value`` with a YAML-typed value (``1`` int, ``1.0`` float, ``true`` bool,
  ``[1, 2]`` list, anything unparsable stays a string);
* ``--params-file FILE`` with ``<node pattern>: {ros__parameters: {...}}`` entries, nested maps
  flattened with ``.``, node patterns ``/ns/node``, ``node``, ``/**``, ``/**/node``, ``*``;
* ``-r/--remap [node:]from:=to`` including ``__node``/``__name`` and ``__ns``;
* ``--log-level [name:=]LEVEL``.

Later sources win (order of appearance); ``parameter_overrides`` given in code win over all.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Any, Sequence

import yaml

__all__ = [
    "ParameterError",
    "RosArgs",
    "parse_ros_args",
    "strip_ros_args",
    "parse_param_value",
    "load_params_file",
    "node_pattern_matches",
    "resolve_parameters",
    "coerce_parameter",
    "ros_type_name_of",
]

_FLAGS_WITH_ARG = {"-p", "--param", "-r", "--remap", "--params-file", "--log-level", "-e", "--enclave",
                   "--log-file-name", "--log-config-file"}
_FLAGS_NO_ARG = {"--enable-rosout-logs", "--disable-rosout-logs", "--enable-stdout-logs",
                 "--disable-stdout-logs", "--enable-external-lib-logs", "--disable-external-lib-logs"}


class ParameterError(ValueError):
    """A parameter value or a command-line argument that a ROS 2 node would reject."""


@dataclass
class RosArgs:
    """What ``--ros-args`` sections of one argv contain, in order of appearance."""

    # ("file", path) or ("param", name, value): applied in this order, later wins.
    param_sources: list[tuple] = field(default_factory=list)
    # (node_name or None, from, to) in order of appearance.
    remaps: list[tuple[str | None, str, str]] = field(default_factory=list)
    log_level: str | None = None
    unknown: list[str] = field(default_factory=list)

    def node_name_override(self, node_name: str) -> str | None:
        """``-r __node:=x`` (or ``__name``), optionally restricted to ``node_name:``."""
        return self._special(node_name, ("__node", "__name"))

    def namespace_override(self, node_name: str) -> str | None:
        return self._special(node_name, ("__ns",))

    def _special(self, node_name: str, keys: Sequence[str]) -> str | None:
        found = None
        for target, src, dst in self.remaps:
            if src in keys and (target is None or target == node_name):
                found = dst
        return found

    def topic_remaps(self, node_name: str) -> list[tuple[str, str]]:
        """(from, to) pairs that apply to this node, excluding the ``__`` specials."""
        return [(src, dst) for target, src, dst in self.remaps
                if not src.startswith("__") and (target is None or target == node_name)]


def _split_assignment(text: str, flag: str) -> tuple[str, str]:
    if ":=" not in text:
        raise ParameterError(f"{flag} expects NAME:=VALUE, got {text!r}")
    name, value = text.split(":=", 1)
    if not name:
        raise ParameterError(f"{flag} has an empty name in {text!r}")
    return name, value


def parse_param_value(text: str) -> Any:
    """Type a command-line value the way rcl does: YAML scalars and flow lists, else a string."""
    if text == "":
        return ""
    try:
        value = yaml.safe_load(text)
    except yaml.YAMLError:
        return text
    return _normalise_value(value, fallback=text)


def _normalise_value(value: Any, fallback: Any) -> Any:
    if isinstance(value, (bool, int, float, str)):
        return value
    if isinstance(value, list):
        if all(isinstance(v, (bool, int, float, str)) for v in value):
            return value
        return fallback
    # None, dates, maps: rcl keeps those as plain strings on the command line.
    return fallback if isinstance(fallback, str) else str(value)


def parse_ros_args(argv: Sequence[str] | None) -> RosArgs:
    """Collect the ROS part of ``argv`` (program name may be included; it is ignored)."""
    out = RosArgs()
    if not argv:
        return out
    args = list(argv)
    inside = False
    i = 0
    while i < len(args):
        a = args[i]
        if a == "--ros-args":
            inside = True
            i += 1
            continue
        if not inside:
            i += 1
            continue
        if a == "--":
            inside = False
            i += 1
            continue
        if a in _FLAGS_NO_ARG:
            i += 1
            continue
        if a in _FLAGS_WITH_ARG:
            if i + 1 >= len(args):
                raise ParameterError(f"{a} expects an argument")
            val = args[i + 1]
            i += 2
            if a in ("-p", "--param"):
                name, text = _split_assignment(val, a)
                out.param_sources.append(("param", name, parse_param_value(text)))
            elif a == "--params-file":
                out.param_sources.append(("file", val))
            elif a in ("-r", "--remap"):
                lhs, rhs = _split_assignment(val, a)
                target, _, src = lhs.rpartition(":") if ":" in lhs else (None, "", lhs)
                out.remaps.append((target or None, src, rhs))
            elif a == "--log-level":
                out.log_level = val.split(":=", 1)[1] if ":=" in val else val
            continue
        out.unknown.append(a)
        i += 1
    return out


def strip_ros_args(argv: Sequence[str]) -> list[str]:
    """argv without its ``--ros-args`` sections (what ``rclpy.utilities.remove_ros_args`` does)."""
    out: list[str] = []
    inside = False
    for a in argv:
        if a == "--ros-args":
            inside = True
        elif inside and a == "--":
            inside = False
        elif not inside:
            out.append(a)
    return out


def _flatten(prefix: str, mapping: dict, out: dict) -> None:
    for key, value in mapping.items():
        name = f"{prefix}.{key}" if prefix else str(key)
        if isinstance(value, dict):
            _flatten(name, value, out)
        else:
            out[name] = _normalise_value(value, fallback=value if isinstance(value, str) else str(value))


def load_params_file(path: str) -> dict[str, dict[str, Any]]:
    """Read a ROS 2 parameter file into ``{node pattern: {flat.name: value}}``.

    Raises ParameterError on the shapes rcl rejects (no ``ros__parameters`` level).
    """
    try:
        with open(path, encoding="utf-8") as fh:
            doc = yaml.safe_load(fh)
    except OSError as exc:
        raise ParameterError(f"cannot read parameter file {path!r}: {exc}") from exc
    except yaml.YAMLError as exc:
        raise ParameterError(f"parameter file {path!r} is not valid YAML: {exc}") from exc
    if doc is None:
        return {}
    if not isinstance(doc, dict):
        raise ParameterError(f"parameter file {path!r}: top level must be a map of node names")
    result: dict[str, dict[str, Any]] = {}
    for key, body in doc.items():
        _collect_node_entries(str(key), body, path, result)
    return result


def _collect_node_entries(key: str, body: Any, path: str, result: dict) -> None:
    if not isinstance(body, dict):
        raise ParameterError(f"parameter file {path!r}: entry {key!r} must be a map")
    if "ros__parameters" in body:
        params = body["ros__parameters"]
        flat: dict[str, Any] = {}
        if params is not None:
            if not isinstance(params, dict):
                raise ParameterError(f"parameter file {path!r}: {key}.ros__parameters must be a map")
            _flatten("", params, flat)
        result.setdefault(key, {}).update(flat)
        return
    # A namespace level: "ns: {node: {ros__parameters: ...}}" means /ns/node.
    for sub, sub_body in body.items():
        _collect_node_entries(f"{key.rstrip('/')}/{sub}", sub_body, path, result)


def _pattern_regex(pattern: str) -> re.Pattern:
    pat = pattern if pattern.startswith("/") else "/" + pattern
    tokens = [t for t in pat.split("/") if t]
    parts = []
    for tok in tokens:
        if tok == "**":
            parts.append(r"(?:/[^/]+)*")
        else:
            parts.append("/" + re.escape(tok).replace(r"\*", r"[^/]*"))
    return re.compile("^" + "".join(parts) + "$")


def node_pattern_matches(pattern: str, node_fqn: str) -> bool:
    """Does a parameter-file key (``/ns/node``, ``node``, ``/**``, ``/**/node``, ``*``) name this node?"""
    if pattern in ("/**", "**"):
        return True
    return bool(_pattern_regex(pattern).match(node_fqn))


def resolve_parameters(ros_args: RosArgs, node_fqn: str,
                       overrides: dict[str, Any] | None = None) -> dict[str, Any]:
    """All parameter values that apply to ``node_fqn`` (``/ns/name``), in precedence order."""
    values: dict[str, Any] = {}
    for source in ros_args.param_sources:
        if source[0] == "file":
            for pattern, params in load_params_file(source[1]).items():
                if node_pattern_matches(pattern, node_fqn):
                    values.update(params)
        else:
            values[source[1]] = source[2]
    if overrides:
        values.update(overrides)
    return values


def ros_type_name_of(value: Any) -> str:
    """Name of a value's ROS parameter type, for error messages."""
    if isinstance(value, bool):
        return "bool"
    if isinstance(value, int):
        return "integer"
    if isinstance(value, float):
        return "double"
    if isinstance(value, str):
        return "string"
    if isinstance(value, (list, tuple)):
        inner = {ros_type_name_of(v) for v in value}
        return (inner.pop() + "_array") if len(inner) == 1 else "array"
    return type(value).__name__


def _coerce_scalar(name: str, value: Any, default: Any) -> Any:
    if isinstance(default, bool):
        if isinstance(value, bool):
            return value
    elif isinstance(default, int):
        if isinstance(value, int) and not isinstance(value, bool):
            return value
    elif isinstance(default, float):
        # ROS rejects "-p rate:=1" for a double; accepting the integer is the one leniency we allow.
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            return float(value)
    elif isinstance(default, str):
        if isinstance(value, str):
            return value
    else:
        return value
    raise ParameterError(
        f"parameter {name!r}: got {value!r} of type {ros_type_name_of(value)}, "
        f"expected {ros_type_name_of(default)} (like the default {default!r})")


def coerce_parameter(name: str, value: Any, default: Any) -> Any:
    """Check ``value`` against the type of ``default`` (None or [] accept anything)."""
    if default is None:
        return value
    if isinstance(default, (list, tuple)):
        if not isinstance(value, (list, tuple)):
            raise ParameterError(
                f"parameter {name!r}: got {value!r} of type {ros_type_name_of(value)}, expected an array")
        if not default:
            return list(value)
        return [_coerce_scalar(name, v, default[0]) for v in value]
    return _coerce_scalar(name, value, default)

