"""ROS nodes: thin wrappers over the core (each module has main())."""
from __future__ import annotations

import sys
from typing import Any, Callable


def wants_help(argv: list[str] | None = None) -> bool:
    """``-h``/``--help`` before any ``--ros-args`` section."""
    args = sys.argv[1:] if argv is None else argv
    head = args[: args.index("--ros-args")] if "--ros-args" in args else args
    return any(a in ("-h", "--help") for a in head)


def unusable_messages() -> str:
    """'' when the node's backend can build our messages, else the one line that says what to run.

    On the rclpy backend the messages are the classes colcon generates for ``ambiegen_msgs``,
    which a plain ``colcon build`` leaves out (``rclpy_backend.missing_messages``); the DDS backend
    reads the .msg files and needs nothing built. A backend that cannot be chosen is left to the
    node's creation to report.
    """
    from ..ros.transport import TransportError, select_backend

    try:
        if select_backend() != "rclpy":
            return ""
    except (TransportError, ValueError):
        return ""
    from ..ros.transport.rclpy_backend import missing_messages

    return missing_messages()


def run_node(
    label: str, make: Callable[[], Any], finish: Callable[[Any], int | None] | None = None, doc: str | None = None,
    drain: bool = False,
) -> int:
    """The shared ``main()`` of every node: build it, spin until SIGINT/SIGTERM/SIGHUP, its parent's
    death (``signals.watch_parent``) or done, clean up.

    ``make`` returns an object with a ``node``; a bad parameter or config, a missing or too old
    library (``deps``), or, on rclpy, an unbuilt ``ambiegen_msgs`` (``unusable_messages``: checked
    before the node exists) exits with status 2 and one line. After the spin the node lets its
    messages arrive (``Node.finish_io``: with ``drain``, a recorder first takes what is still on
    its way; every node waits until its reliable samples are acknowledged), then ``finish`` runs
    (close files, stop threads; it may return the exit code) and the node shuts down.
    """
    if doc and wants_help():
        print(f"usage: {label} [--ros-args -p NAME:=VALUE ... | --params-file FILE.yaml]\n")
        print(doc.strip())
        return 0
    from ..ros.transport import signals

    previous = signals.install()  # SIGINT/SIGTERM/SIGHUP stop the node, even when started with SIGINT ignored
    try:
        signals.watch_parent()  # the command that started it is gone: stop (its nodes never outlive it)
        return _build_and_spin(label, make, finish, drain)
    finally:
        signals.restore(previous)  # for a caller in a process of its own (a test)


def _build_and_spin(label: str, make: Callable[[], Any], finish: Callable[[Any], int | None] | None,
                    drain: bool) -> int:
    from ..deps import broken_environment

    if broken_environment(label):
        return 2
    missing = unusable_messages()
    if missing:
        print(f"{label}: error: {missing}", file=sys.stderr)
        return 2
    from ..core.attributes import ScenarioError
    from ..core.config import ConfigError
    from ..ros.transport import TransportError

    try:
        obj = make()
    except (ConfigError, ScenarioError, ValueError, TransportError, OSError) as exc:
        print(f"{label}: error: {exc}", file=sys.stderr)
        return 2
    code: int | None = 0
    try:
        obj.node.spin()
        obj.node.finish_io(drain=drain)
    finally:
        if finish is not None:
            code = finish(obj)
        obj.node.shutdown()
    return code or 0
