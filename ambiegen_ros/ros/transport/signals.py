"""SIGINT/SIGTERM for nodes of either backend: stop spinning, keep the middleware alive.

A stop must leave the node able to finish its work: a recorder still takes what is on its way,
and every publisher waits until its reliable samples are acknowledged (``Node.finish_io``)
before the node is destroyed. rclpy's own handler would shut its context down at once (samples
in flight are then lost, which Fast DDS showed), so the rclpy backend starts without it and both
backends register here. A second Ctrl-C raises ``KeyboardInterrupt`` to escape a stuck callback.
"""
from __future__ import annotations

import signal
import threading
from typing import Any, Callable

_stoppers: dict[int, Callable[[], None]] = {}  # id(node) -> its stop request
_prev_handlers: dict[int, Any] = {}
_signal_count = 0


def _on_signal(signum, frame) -> None:
    global _signal_count
    _signal_count += 1
    if _signal_count > 1 and signum == signal.SIGINT:
        raise KeyboardInterrupt  # a second Ctrl-C escapes a stuck callback
    for stop in list(_stoppers.values()):
        stop()


def register(node: Any, stop: Callable[[], None]) -> None:
    """Call ``stop`` on SIGINT/SIGTERM (handlers installed with the first node, main thread only)."""
    _stoppers[id(node)] = stop
    if threading.current_thread() is not threading.main_thread() or _prev_handlers:
        return
    for sig in (signal.SIGINT, signal.SIGTERM):
        try:
            _prev_handlers[sig] = signal.signal(sig, _on_signal)
        except (ValueError, OSError):  # pragma: no cover - embedded interpreters
            pass


def unregister(node: Any) -> None:
    """Forget a node; the previous handlers come back with the last one."""
    global _signal_count
    _stoppers.pop(id(node), None)
    if _stoppers or threading.current_thread() is not threading.main_thread():
        return
    for sig, handler in list(_prev_handlers.items()):
        try:
            signal.signal(sig, handler if handler is not None else signal.SIG_DFL)
        except (ValueError, OSError):  # pragma: no cover
            pass
    _prev_handlers.clear()
    _signal_count = 0


__all__ = ["register", "unregister"]
