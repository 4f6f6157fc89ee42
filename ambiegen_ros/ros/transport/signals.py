"""SIGINT/SIGTERM/SIGHUP for nodes and commands, and a node's watch on the process that started it.

A stop must leave a node able to finish its work: a recorder still takes what is on its way,
and every publisher waits until its reliable samples are acknowledged (``Node.finish_io``)
before the node is destroyed. rclpy's own handler would shut its context down at once (samples
in flight are then lost, which Fast DDS showed), so the rclpy backend starts without it and both
backends register here. A second Ctrl-C raises ``KeyboardInterrupt`` to escape a stuck callback.

The three stop signals are handled the same way and always explicitly (``install``): a process
started in the background by a non-interactive shell inherits SIGINT as ignored, and an ignored
signal would survive ``exec`` into every child. A command (``install(raise_stop=True)``) turns the
first stop signal, while no node of its own is spinning, into ``Stopped`` (a ``KeyboardInterrupt``,
so every ``except KeyboardInterrupt`` cleanup already runs); ``stop_signal()`` tells it which
signal, for its exit status (128 + the number, as a shell says it). Later signals are only
counted: the cleanup they would interrupt is bounded already.

A node started by a command is told the command's pid (``PARENT_VAR``); ``watch_parent`` makes a
SIGTERM of its parent's death (Linux: ``PR_SET_PDEATHSIG``; elsewhere, or when a launcher such as
``ros2 run`` stands between the two: a thread polling every second), so a command killed by
SIGKILL leaves no node running.
"""
from __future__ import annotations

import os
import signal
import sys
import threading
import time
from typing import Any, Callable

STOP_SIGNALS = tuple(s for s in (getattr(signal, n, None) for n in ("SIGINT", "SIGTERM", "SIGHUP")) if s is not None)
PARENT_VAR = "AMBIEGEN_PARENT_PID"
"""The pid of the command that started a node: the node stops when that process is gone."""
PARENT_POLL_S = 1.0

_stoppers: dict[int, Callable[[], None]] = {}  # id(node) -> its stop request
_prev_handlers: dict[int, Any] = {}
_signal_count = 0
_stop_signum: int | None = None  # the first stop signal this process took
_raise_stop = False  # a command: a stop signal with no node spinning raises Stopped


class Stopped(KeyboardInterrupt):
    """A command stopped by SIGTERM, SIGHUP or SIGINT (``signum``)."""

    def __init__(self, signum: int):
        super().__init__(signal_name(signum))
        self.signum = signum


def signal_name(signum: int) -> str:
    try:
        return signal.Signals(signum).name
    except ValueError:
        return f"signal {signum}"


def _on_signal(signum, frame) -> None:
    global _signal_count, _stop_signum
    _signal_count += 1
    first = _stop_signum is None
    if first:
        _stop_signum = signum
    if _stoppers:
        if _signal_count > 1 and signum == signal.SIGINT:
            raise KeyboardInterrupt  # a second Ctrl-C escapes a stuck callback
        for stop in list(_stoppers.values()):
            stop()
        return
    if _raise_stop and first:
        raise Stopped(signum)


def install(raise_stop: bool = False) -> dict[int, Any]:
    """Handle SIGINT, SIGTERM and SIGHUP here, whatever this process inherited (main thread only).

    ``raise_stop``: this is a command, which a stop signal interrupts with ``Stopped`` when no node
    of its own is spinning. Returns the handlers replaced (``restore`` puts them back; empty where
    none could be installed: not the main thread)."""
    global _raise_stop
    previous: dict[int, Any] = {}
    if threading.current_thread() is not threading.main_thread():
        return previous
    _raise_stop = _raise_stop or raise_stop
    for sig in STOP_SIGNALS:
        try:
            previous[sig] = signal.signal(sig, _on_signal)
        except (ValueError, OSError):  # pragma: no cover - embedded interpreters
            pass
    return previous


def restore(previous: dict[int, Any]) -> None:
    """A command is over (e.g. ``cli.main`` called in a test's process): its handlers and state go."""
    global _raise_stop, _stop_signum
    if threading.current_thread() is not threading.main_thread():
        return
    for sig, handler in previous.items():
        try:
            signal.signal(sig, handler if handler is not None else signal.SIG_DFL)
        except (ValueError, OSError):  # pragma: no cover
            pass
    _raise_stop, _stop_signum = False, None


def stop_signal() -> int | None:
    """The first stop signal this process took (None: none yet)."""
    return _stop_signum


def stop_requested() -> bool:
    return _stop_signum is not None


def register(node: Any, stop: Callable[[], None]) -> None:
    """Call ``stop`` on a stop signal (handlers installed with the first node, main thread only); at
    once if one came already (a signal before the node existed must not be lost)."""
    _stoppers[id(node)] = stop
    if _stop_signum is not None:
        stop()
    if threading.current_thread() is not threading.main_thread() or _prev_handlers:
        return
    for sig in STOP_SIGNALS:
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


# --- the parent's death ---------------------------------------------------------------------------
def child_env(env: dict[str, str]) -> dict[str, str]:
    """``env`` for a node this process starts: the node stops when this process is gone."""
    return {**env, PARENT_VAR: str(os.getpid())}


def _set_pdeathsig(sig: int) -> bool:
    """Linux: ``sig`` to this process when the thread that forked it ends. False elsewhere."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        return libc.prctl(1, int(sig), 0, 0, 0) == 0  # PR_SET_PDEATHSIG = 1
    except (OSError, AttributeError):  # pragma: no cover - no libc prctl
        return False


def alive(pid: int) -> bool:
    """Is there a process ``pid`` (one of another user's counts)?"""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def watch_parent(environ: dict[str, str] | None = None) -> str:
    """Stop this process (SIGTERM to itself, so the stop handlers finish its work) once the command
    named by ``PARENT_VAR`` is gone. The variable is taken out of the environment, so that the
    node's own children do not inherit it. Returns how it watches: '' (no parent given), 'gone'
    (already gone: stopped now), 'pdeathsig' or 'poll'."""
    environ = os.environ if environ is None else environ
    value = environ.pop(PARENT_VAR, "")
    try:
        parent = int(value)
    except ValueError:
        return ""
    direct = os.getppid() == parent
    if direct and _set_pdeathsig(signal.SIGTERM) and os.getppid() == parent:
        return "pdeathsig"  # checked again after prctl: a parent that died just before is not missed
    if (direct and os.getppid() != parent) or not alive(parent):
        os.kill(os.getpid(), signal.SIGTERM)
        return "gone"

    def poll() -> None:
        while (os.getppid() == parent) if direct else alive(parent):
            time.sleep(PARENT_POLL_S)
        os.kill(os.getpid(), signal.SIGTERM)

    threading.Thread(target=poll, name="parent-watch", daemon=True).start()
    return "poll"


__all__ = ["PARENT_VAR", "STOP_SIGNALS", "Stopped", "alive", "child_env", "install", "register", "restore", "signal_name",
           "stop_requested", "stop_signal", "unregister", "watch_parent"]
