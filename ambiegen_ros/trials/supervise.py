"""Watching the processes of a stack session: who died, how, and whose they were. No ROS.

A process of ours (``robot_world``, ``sut_adapter``, the recorder) or of the stack (``nd_driver``,
Nav2's servers, the ``ros2 launch`` that holds them) can exit, be killed, or be stopped. The
session's processes are its own children, so their exit codes say how (a negative code is the
signal); Nav2's servers are children of ``ros2 launch``, which prints a line for each one that
dies (``[ERROR] [controller_server-2]: process has died [pid 1234, exit code -9, ...]``); a stopped
process (SIGSTOP: state ``T`` in ``/proc/<pid>/stat``) is a hang. ``Watch.poll`` returns each such
event once, as a ``Death``; the session publishes it on ``/ambiegen/stack_events`` and restarts
what it must. ``Scheduling.poll`` adds the nodes of the stack that stop being scheduled while a run
is on (their threads run no more, which no state letter need show), judged by ``/proc``'s
nanoseconds of run time (``run_ns``).
"""
from __future__ import annotations

import os
import re
import signal
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..ros.transport.signals import alive

OURS = ("robot_world", "sut_adapter", "recorder")
TICKS = os.sysconf("SC_CLK_TCK")
LAUNCH_DIED = re.compile(r"\[ERROR\] \[(?P<process>[A-Za-z0-9_./-]+?)-\d+\]: process has died "
                         r"\[pid (?P<pid>\d+), exit code (?P<code>-?\d+)")


def part_of(name: str) -> str:
    """"ours" for the world, the adapter and the recorder, "stack" for anything else."""
    return "ours" if name in OURS else "stack"


def exit_words(code: int | None) -> str:
    """'killed by SIGKILL', 'exited with code 1' (a shell's 128 + n is the signal n too)."""
    if code is None:
        return "is gone"
    number = -code if code < 0 else code - 128 if 128 < code < 160 else None
    if number:
        try:
            return f"killed by {signal.Signals(number).name}"
        except ValueError:
            return f"killed by signal {number}"
    return f"exited with code {code}"


@dataclass
class Death:
    process: str  # the node or process name
    part: str  # stack | ours
    what: str  # killed by SIGKILL, exited with code 1, stopped (hung)
    group: str  # the session's process it belongs to (the launch, for a Nav2 server)
    code: int | None = None  # its exit status, when the session saw it exit
    at: float = field(default_factory=time.monotonic)

    def words(self) -> str:
        return f"{self.process} {self.what}"


def node_name(pid: int) -> str | None:
    """The ROS node name a process runs (``__node:=NAME`` on its command line), else its executable's
    name (Jazzy's ``navigation_launch.py`` starts ``controller_server`` without ``__node``; /proc's
    ``comm`` would say ``controller_serv``, cut at 15 characters)."""
    try:
        args = Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0")
    except OSError:
        return None
    for arg in args:
        if arg.startswith(b"__node:="):
            return arg[8:].decode(errors="replace")
    if args and args[0]:
        return Path(args[0].decode(errors="replace")).name
    try:
        return Path(f"/proc/{pid}/comm").read_text().strip()
    except OSError:
        return None


def descendants(pid: int) -> list[int]:
    """Every process below ``pid`` (children first, then theirs)."""
    out, todo = [], [pid]
    while todo:
        parent = todo.pop()
        try:
            tasks = list(Path(f"/proc/{parent}/task").iterdir())
        except OSError:
            continue
        for task in tasks:
            try:
                kids = [int(k) for k in (task / "children").read_text().split()]
            except OSError:
                continue
            out += kids
            todo += kids
    return out


def cpu_seconds(pid: int) -> float | None:
    """CPU time (user + system) a process has used so far, from ``/proc/<pid>/stat``."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / TICKS
    except (OSError, IndexError, ValueError):
        return None


def cpu_by_part(group: Any) -> dict[int, tuple[str, float]]:
    """pid -> (part, CPU seconds) of every process of a session (each launch's servers included)."""
    out = {}
    for name, proc in list(group.procs.items()):
        if proc.poll() is not None:
            continue
        for pid in [proc.pid, *descendants(proc.pid)]:
            used = cpu_seconds(pid)
            if used is not None:
                out[pid] = (part_of(name), used)
    return out


def core_shares(before: dict[int, tuple[str, float]], after: dict[int, tuple[str, float]],
                wall: float) -> dict[str, float]:
    """Cores each part used between two readings (a process alive at both), over the wall seconds."""
    used = {"ours": 0.0, "stack": 0.0}
    for pid, (part, seconds) in after.items():
        if pid in before and wall > 0:
            used[part] = used.get(part, 0.0) + seconds - before[pid][1]
    return {f"{part}_cores": round(cpu / wall, 3) if wall > 0 else None for part, cpu in used.items()}


def stopped(pid: int) -> bool:
    """Is the process stopped (SIGSTOP, state T)?"""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat[stat.rfind(")") + 2:].startswith("T")


class Watch:
    """The deaths and hangs of a process group's processes (``campaign.ProcessGroup``), each once."""

    def __init__(self, group: Any, launches: tuple[str, ...] = ("nav2",)):
        self.group = group
        self.launches = launches  # processes that are a `ros2 launch`: their log names the servers that die
        self.seen: set[tuple[str, int]] = set()  # (name, pid) already reported
        self.halted: set[int] = set()  # pids reported as stopped, until they run again
        self.offsets: dict[str, int] = {}

    def forget(self, name: str) -> None:
        """``name`` was restarted: its new process is watched afresh (its log is read from its end)."""
        self.seen = {(n, pid) for n, pid in self.seen if n != name}
        log = self.group.log_dir / f"{name}.log"
        self.offsets[name] = log.stat().st_size if log.exists() else 0

    def _launch_deaths(self, name: str) -> list[Death]:
        log = self.group.log_dir / f"{name}.log"
        try:
            with open(log, "rb") as fh:
                fh.seek(self.offsets.get(name, 0))
                text = fh.read()
        except OSError:
            return []
        self.offsets[name] = self.offsets.get(name, 0) + len(text)
        out = []
        for found in LAUNCH_DIED.finditer(text.decode(errors="replace")):
            key = (found["process"], int(found["pid"]))
            if key not in self.seen:
                self.seen.add(key)
                out.append(Death(found["process"], part_of(name), exit_words(int(found["code"])), name,
                                 int(found["code"])))
        return out

    def poll(self) -> list[Death]:
        out: list[Death] = []
        for name, proc in list(self.group.procs.items()):
            if name in self.launches:
                out += self._launch_deaths(name)
            code = proc.poll()
            if code is not None:
                if (name, proc.pid) not in self.seen:
                    self.seen.add((name, proc.pid))
                    out.append(Death(name, part_of(name), exit_words(code), name, code))
                continue
            for pid in [proc.pid, *descendants(proc.pid)]:
                if stopped(pid):
                    if pid not in self.halted:
                        self.halted.add(pid)
                        who = node_name(pid) if pid != proc.pid else name
                        out.append(Death(who or name, part_of(name), "stopped (hung: SIGSTOP)", name))
                else:
                    self.halted.discard(pid)
        return out


SCHEDULED_FLOOR_S = 2.0  # an idle node of ours runs every 0.2 s or sooner (about 1 ms a second): 10x that
TICKS_WINDOW_S = 100.0  # without schedstat, ticks of 10 ms: an idle node accrues one about every 10 s


def run_ns(pid: int) -> int | None:
    """Nanoseconds the process's threads have run (``/proc/<pid>/task/*/schedstat``), None when the
    kernel does not say or the process is gone. It moves at every wake-up: an idle DDS node of ours
    runs about 1 ms a second, which ``cpu_seconds``' 10 ms ticks show once in 10 s."""
    try:
        tasks = list(Path(f"/proc/{pid}/task").iterdir())
    except OSError:
        return None
    total, seen = 0, False
    for task in tasks:
        try:
            total += int((task / "schedstat").read_text().split()[0])
            seen = True
        except (OSError, IndexError, ValueError):
            continue
    return total if seen else None


def children(pid: int) -> list[int]:
    """The direct children of ``pid`` (every thread's)."""
    out: list[int] = []
    try:
        tasks = list(Path(f"/proc/{pid}/task").iterdir())
    except OSError:
        return out
    for task in tasks:
        try:
            out += [int(k) for k in (task / "children").read_text().split()]
        except (OSError, ValueError):
            continue
    return out


def stack_leaves(group: Any) -> list[tuple[str, int]]:
    """(session process, pid) of each live process of the stack that has no child: its nodes. A
    process that holds others (``ros2 launch``, ``ros2 run``) waits on them by design, so they are
    judged, not it."""
    out = []
    for name, proc in list(group.procs.items()):
        if part_of(name) != "stack" or proc.poll() is not None:
            continue
        out += [(name, pid) for pid in [proc.pid, *descendants(proc.pid)] if not children(pid)]
    return out


class Scheduling:
    """Nodes of the stack that stop being scheduled while a run is on: a process whose threads have
    not run at all for ``window`` s (a frozen cgroup, an uninterruptible wait, a tracer's stop) is
    hung whatever the topics say: a navigator's feedback goes on while a frozen controller holds the
    robot. A process stopped by a signal (state T) is left to ``Watch``, which names it so. Each
    process once a run; ``run`` (any value) changes with each run and starts the clocks afresh."""

    def __init__(self) -> None:
        self.run: Any = None
        self.last: dict[int, tuple[float, float]] = {}  # pid -> (its run time, when it last changed)
        self.said: set[int] = set()

    def poll(self, group: Any, run: Any, window: float, now: float | None = None) -> list[Death]:
        now = time.monotonic() if now is None else now
        if run != self.run:
            self.run, self.last, self.said = run, {}, set()
        out = []
        for name, pid in stack_leaves(group):
            precise = run_ns(pid)
            used = float(precise) if precise is not None else cpu_seconds(pid)
            if used is None or stopped(pid):
                self.last.pop(pid, None)  # a stop is Watch's; after a SIGCONT the clock starts again
                continue
            before = self.last.get(pid)
            if before is None or before[0] != used:
                self.last[pid] = (used, now)
                continue
            quiet = now - before[1]
            if quiet >= (window if precise is not None else max(window, TICKS_WINDOW_S)) and pid not in self.said:
                self.said.add(pid)
                who = name if pid == group.procs[name].pid else node_name(pid) or name  # as Watch names it
                out.append(Death(who, "stack",
                                 f"stopped being scheduled (hung: no CPU time for {quiet:.0f} s)", name))
        return out


__all__ = ["Death", "OURS", "SCHEDULED_FLOOR_S", "Scheduling", "Watch", "alive", "children", "descendants",
           "exit_words", "node_name", "part_of", "run_ns", "stack_leaves", "stopped"]
