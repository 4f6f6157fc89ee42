"""The one transport seam of AmbieGen-ROS: nodes never import rclpy or cyclonedds themselves.

``create_node`` returns a ``Node`` backed by

* ``rclpy`` -- a real ROS 2 (Jazzy) node, whenever rclpy imports;
* ``dds``   -- Cyclone DDS from PyPI speaking the ROS 2 wire protocol (topic ``rt/...``, type
  ``pkg::msg::dds_::Type_``, XCDR1, RMW-like QoS, type hash in USER_DATA).

Choose with ``AMBIEGEN_TRANSPORT=rclpy|dds|auto`` (default auto: rclpy if it imports, else dds) or
the ``backend`` argument. See docs/transport.md.
"""
from __future__ import annotations

import os
from typing import Any, Sequence

from .base import (ActionClient, BackendUnavailable, EndpointInfo, Logger, Node, ParameterError, Publisher,
                   ServiceClient, Subscription, Timer, TransportError)

__all__ = [
    "create_node", "available_backends", "select_backend", "shutdown",
    "Node", "Publisher", "Subscription", "Timer", "ServiceClient", "ActionClient", "Logger", "EndpointInfo",
    "TransportError", "BackendUnavailable", "ParameterError", "BACKENDS", "ENV_VAR",
]

ENV_VAR = "AMBIEGEN_TRANSPORT"
BACKENDS = ("rclpy", "dds")
_nodes: list = []


def _rclpy_ok() -> tuple[bool, str]:
    from . import rclpy_backend
    return rclpy_backend.is_available(), rclpy_backend.unavailable_reason()


def _dds_ok() -> tuple[bool, str]:
    from . import dds_backend
    return dds_backend.is_available(), dds_backend.unavailable_reason()


def available_backends() -> list[str]:
    """Backends that import on this machine, in auto-selection order."""
    out = []
    for name, probe in (("rclpy", _rclpy_ok), ("dds", _dds_ok)):
        if probe()[0]:
            out.append(name)
    return out


def select_backend(backend: str | None = None) -> str:
    """Resolve ``backend`` (or $AMBIEGEN_TRANSPORT, default 'auto') to an importable backend name.

    Raises BackendUnavailable naming the missing package, or ValueError for an unknown name.
    """
    choice = (backend or os.environ.get(ENV_VAR, "") or "auto").strip().lower()
    if choice == "auto":
        for name, probe in (("rclpy", _rclpy_ok), ("dds", _dds_ok)):
            if probe()[0]:
                return name
        raise BackendUnavailable(
            "no transport backend available: install ROS 2 (rclpy) or `pip install cyclonedds==11.0.1`")
    if choice not in BACKENDS:
        raise ValueError(f"{ENV_VAR}={choice!r}: use one of rclpy, dds, auto")
    ok, why = (_rclpy_ok if choice == "rclpy" else _dds_ok)()
    if not ok:
        hint = ("source a ROS 2 Jazzy installation (rclpy) or set AMBIEGEN_TRANSPORT=dds"
                if choice == "rclpy" else "pip install cyclonedds==11.0.1")
        raise BackendUnavailable(f"transport backend {choice!r} is not available ({why}); {hint}")
    return choice


def create_node(name: str, namespace: str = "", argv: Sequence[str] | None = None,
                parameter_overrides: dict[str, Any] | None = None,
                backend: str | None = None) -> Node:
    """Create a node on the selected backend.

    ``argv`` defaults to ``sys.argv``; its ``--ros-args`` sections supply parameters
    (``-p``, ``--params-file``), remaps (``-r``, ``__node``, ``__ns``) and ``--log-level``.
    ``parameter_overrides`` (tests) win over argv.
    """
    chosen = select_backend(backend)
    cls: type[Node]
    if chosen == "rclpy":
        from .rclpy_backend import RclpyNode

        cls = RclpyNode
    else:
        from .dds_backend import DdsNode

        cls = DdsNode
    node = cls(name, namespace=namespace, argv=argv, parameter_overrides=parameter_overrides)
    _nodes.append(node)
    return node


def shutdown() -> None:
    """Shut down every node created through ``create_node`` (idempotent)."""
    while _nodes:
        _nodes.pop().shutdown()
