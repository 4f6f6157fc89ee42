"""Waits of the node tests that say why when their safety net runs out.

A wait on the graph (``spin_until`` on the test's driver node) that times out is a process that
never started, died, hung or was never discovered. ``wait_for`` fails with what tells them apart:
each node process alive or its exit status, the Python stacks of those still alive (faulthandler,
``PYTHONFAULTHANDLER`` is set by ``traced``), their logs, and the topics the driver's middleware
discovered with their publishers' nodes.
"""
from __future__ import annotations

import signal
import time
from typing import Any, Callable

LOG_TAIL = 6000  # characters of each log: its last lines and the stacks dumped at the end
STACK_WAIT_S = 5.0  # a safety net for the dump's arrival in the log (faulthandler writes it at once)


def traced(procs: Any) -> Any:
    """``procs`` (``helpers.sut_graph.Procs``) with faulthandler on in the nodes it starts from now on,
    so ``stacks`` can read where a live process is."""
    procs.env["PYTHONFAULTHANDLER"] = "1"
    return procs


def stacks(procs: Any) -> None:
    """Every live node process writes its threads' Python stacks to its log and ends (SIGABRT, which
    faulthandler answers): called only once a test has failed, as the last look at them."""
    live = [p for p in procs.procs.values() if p.poll() is None]
    for proc in live:
        proc.send_signal(signal.SIGABRT)
    deadline = time.monotonic() + STACK_WAIT_S
    for proc in live:
        try:
            proc.wait(max(0.1, deadline - time.monotonic()))
        except Exception:  # still alive: its log says what it wrote
            pass


def graph_view(node: Any) -> str:
    """The topics the driver's middleware discovered, each with its publishers' node names."""
    lines = []
    try:
        for topic, types in node.topic_names_and_types():
            pubs = sorted({f"{e.node_namespace.rstrip('/')}/{e.node_name}" for e in node.publishers_info(topic)})
            lines.append(f"  {topic} [{', '.join(types)}] published by {pubs or 'nobody'}")
    except Exception as exc:  # the report must not hide the failure it explains
        lines.append(f"  (graph query failed: {type(exc).__name__}: {exc})")
    return "\n".join(lines) or "  (nothing discovered)"


def publishing(node: Any, *pairs: tuple[str, str]) -> bool:
    """Each (topic, node name) is a publisher the driver has discovered: that node is up and on the
    graph (``robot_world`` makes its endpoints once its compiled loops are ready)."""
    return all(any(e.node_name == name for e in node.publishers_info(topic)) for topic, name in pairs)


def report(node: Any, procs: Any, what: str, waited: float) -> str:
    """What a wait that ran out saw (module docstring)."""
    status = [f"  {name}: {'alive' if p.poll() is None else f'exited with {p.returncode}'} (pid {p.pid})"
              for name, p in procs.procs.items()]
    view = graph_view(node)
    stacks(procs)
    return (f"no {what} after {waited:.0f} s\nprocesses:\n" + "\n".join(status)
            + f"\nthe driver's graph ({node.fully_qualified_name}):\n{view}\nlogs:\n"
            + "\n".join(f"--- {name}\n{procs.log(name)[-LOG_TAIL:]}" for name in procs.procs))


def wait_for(node: Any, procs: Any, predicate: Callable[[], Any], timeout: float, what: str) -> None:
    """Spin ``node`` until ``predicate`` holds; on the safety net (``timeout``), fail with ``report``."""
    t0 = time.monotonic()
    if node.spin_until(predicate, timeout):
        return
    raise AssertionError(report(node, procs, what, time.monotonic() - t0))
