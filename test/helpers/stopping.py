"""Start an ``ambiegen`` command as a user's script would, stop it on an event, and look for what it left.

``Command`` starts ``python -m ambiegen_ros ...`` either under ``timeout -s TERM`` (the stop is a
SIGTERM sent to ``timeout``, which forwards it: the same path as its time limit, without waiting
for one) or through ``sh -c "trap '' INT; exec ..."`` (SIGINT ignored, as a non-interactive shell
leaves it for a background job). ``wait_for`` reads its output or polls a condition until an event
shows the command is mid-run. What it started is found by a /proc scan (no psutil): every process
whose environment names the command as its parent (``signals.PARENT_VAR``), and every descendant
seen while it ran.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Callable

from ambiegen_ros.ros.transport.signals import PARENT_VAR
from ambiegen_ros.trials.supervise import descendants

REPO = Path(__file__).resolve().parents[2]
SAFETY_S = 600.0  # a bound on every wait, never the trigger


def children_by_env(pid: int) -> set[int]:
    """Processes whose environment says ``pid`` started them (the nodes of a command)."""
    mark = f"{PARENT_VAR}={pid}".encode()
    out = set()
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            if mark in (entry / "environ").read_bytes().split(b"\0"):
                out.add(int(entry.name))
        except OSError:
            continue
    return out


def running(pid: int) -> bool:
    """Alive and not a zombie."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat[stat.rfind(")") + 2:][:1] not in ("Z", "X")


class Command:
    """One ``ambiegen`` command started the way ``how`` says ("timeout" or "ignore_int")."""

    def __init__(self, args: list[str], how: str, env: dict | None = None):
        env = {k: v for k, v in (env or os.environ).items() if k != "AMBIEGEN_TRANSPORT"}
        env["PYTHONUNBUFFERED"] = "1"
        cmd = [sys.executable, "-m", "ambiegen_ros", *args]
        if how == "timeout":
            argv = ["timeout", "-s", "TERM", str(int(SAFETY_S)), *cmd]
        elif how == "ignore_int":
            argv = ["sh", "-c", "trap '' INT; exec \"$@\"", "sh", *cmd]
        else:
            argv = cmd
        self.how = how
        self.proc = subprocess.Popen(argv, cwd=REPO, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                     text=True)
        self.lines: list[str] = []
        self.seen: set[int] = set()  # every process of its tree seen so far
        self._pid: int | None = None
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        for line in self.proc.stdout:
            self.lines.append(line)

    @property
    def pid(self) -> int:
        """The command's own pid (under ``timeout``: its child)."""
        if self.how != "timeout":
            return self.proc.pid
        deadline = time.monotonic() + 30
        while self._pid is None and time.monotonic() < deadline:
            kids = descendants(self.proc.pid)
            if kids:
                self._pid = kids[0]
            time.sleep(0.05)
        assert self._pid is not None, "timeout started no command"
        return self._pid

    def look(self) -> set[int]:
        """Note the processes the command runs now."""
        if self.proc.poll() is None:
            pid = self.pid
            self.seen |= {pid, *descendants(pid), *children_by_env(pid)}
        return self.seen

    def wait_for(self, event: Callable[[], bool], what: str) -> None:
        """Until ``event()`` (the command mid-run); fails if the command ends first."""
        deadline = time.monotonic() + SAFETY_S
        while not event():
            assert self.proc.poll() is None, f"ended before {what}:\n{self.text()[-3000:]}"
            assert time.monotonic() < deadline, f"no {what} in {SAFETY_S:.0f} s:\n{self.text()[-3000:]}"
            self.look()
            time.sleep(0.1)
        self.look()

    def said(self, start: str) -> Callable[[], bool]:
        return lambda: any(line.startswith(start) for line in self.lines)

    def stop(self, sig: int) -> None:
        """``sig`` as the user sends it: SIGTERM to ``timeout`` (it forwards it), else to the command."""
        os.kill(self.proc.pid if self.how == "timeout" else self.pid, sig)

    def finish(self) -> int:
        code = self.proc.wait(timeout=SAFETY_S)
        self._reader.join(timeout=10)
        return code

    def text(self) -> str:
        return "".join(self.lines)

    def left(self) -> list[int]:
        """What of its tree still runs (the command has ended)."""
        return sorted(p for p in self.seen | children_by_env(self._pid or self.proc.pid) if running(p))

    def kill_all(self) -> None:
        """Clean-up after a failed test: nothing of it outlives the test."""
        for pid in [self.proc.pid, *self.seen]:
            try:
                os.kill(pid, signal.SIGKILL)
            except OSError:
                pass
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            pass


def wait_gone(pids: set[int], bound: float = 120.0) -> list[int]:
    """Until every pid has ended (bounded); returns those still running."""
    deadline = time.monotonic() + bound
    while time.monotonic() < deadline and any(running(p) for p in pids):
        time.sleep(0.2)
    return sorted(p for p in pids if running(p))


def mcap_summary(path: Path):
    """The MCAP's summary read by the ``mcap`` package alone (None: not finalised)."""
    from mcap.reader import make_reader

    with open(path, "rb") as fh:
        return make_reader(fh).get_summary()


def signal_name(code: int) -> str:
    return signal.Signals(code - 128).name if code > 128 else f"exit {code}"
