"""Faults injected on purpose, to see a session survive them: ``--inject TARGET:SIGNAL@RUN[+S][/HOLD]``.

``nd_driver:SIGKILL@2`` kills ``nd_driver`` when the second run of this invocation has its robot
moving (the first odometry faster than 5 cm/s, within 1 m of the run's start, after the scenario
went out: the last run's robot, still driving when a loaded machine delivers its odometry late, is
not this run's); ``+S`` waits S seconds more; ``controller_server:SIGSTOP@3/30`` stops Nav2's
controller for 30 s, then continues it. The
target is a process of the session (``robot_world``, ``sut_adapter``, ``recorder``, ``nd_driver``,
``nav2``: the launch) or a node below one (a Nav2 server, by its node name). Faults fire on the run's
events, never at a wall-clock time, so a test sees the same fault on a fast or a slow machine; the
chaos bench (``bench/nav2_chaos.py``) draws them at random. No ROS.
"""
from __future__ import annotations

import os
import re
import signal
import time
from dataclasses import dataclass
from typing import Any

from ..core.errors import BadInput
from .supervise import descendants, node_name

SPEC = re.compile(r"(?P<target>[A-Za-z0-9_./-]+):(?P<signal>SIG[A-Z0-9]+)@(?P<run>\d+)(\+(?P<after>[0-9.]+))?"
                  r"(/(?P<hold>[0-9.]+))?")


@dataclass
class Fault:
    target: str
    signal: signal.Signals
    run: int  # the invocation's run number (1-based) it fires in
    after_s: float = 0.0  # seconds after that run's robot first moves
    hold_s: float = 0.0  # SIGSTOP: SIGCONT after this long (0: never)
    fired_at: float | None = None
    pid: int | None = None
    continued: bool = False

    def spec(self) -> str:
        return f"{self.target}:{self.signal.name}@{self.run}" + (f"+{self.after_s:g}" if self.after_s else "") + \
            (f"/{self.hold_s:g}" if self.hold_s else "")


def parse_fault(text: str) -> Fault:
    found = SPEC.fullmatch(text.strip())
    if found is None:
        raise BadInput(f"--inject {text!r}: TARGET:SIGNAL@RUN[+SECONDS][/HOLD], e.g. nd_driver:SIGKILL@2")
    try:
        sig = signal.Signals[found["signal"]]
    except KeyError:
        raise BadInput(f"--inject {text!r}: no signal {found['signal']}") from None
    if int(found["run"]) < 1:
        raise BadInput(f"--inject {text!r}: runs count from 1")
    return Fault(found["target"], sig, int(found["run"]), float(found["after"] or 0), float(found["hold"] or 0))


def find_pid(group: Any, target: str) -> int | None:
    """The pid of ``target``: a process of the group by its name, else a node below one by its node name."""
    proc = group.procs.get(target)
    if proc is not None and proc.poll() is None:
        return proc.pid
    for proc in group.procs.values():
        if proc.poll() is not None:
            continue
        for pid in descendants(proc.pid):
            if node_name(pid) == target:
                return pid
    return None


class Injector:
    """Fires each fault once, when its run's robot has moved for ``after_s``; continues held stops."""

    def __init__(self, faults: list[Fault], say: Any = print):
        self.faults = faults
        self.say = say

    def tick(self, group: Any, run: int, moved_at: float | None) -> list[Fault]:
        """Fire what is due now; returns the faults fired in this call."""
        now = time.monotonic()
        fired = []
        for fault in self.faults:
            if fault.fired_at is None and fault.run == run and moved_at is not None and now >= moved_at + fault.after_s:
                fault.pid = find_pid(group, fault.target)
                fault.fired_at = now
                if fault.pid is None:
                    self.say(f"inject {fault.spec()}: no process {fault.target!r} to signal")
                    continue
                os.kill(fault.pid, fault.signal)
                self.say(f"inject {fault.spec()}: {fault.signal.name} to {fault.target} (pid {fault.pid})")
                fired.append(fault)
            if fault.fired_at is not None and fault.hold_s and not fault.continued and now >= fault.fired_at + fault.hold_s:
                fault.continued = True
                if fault.pid is not None:
                    try:
                        os.kill(fault.pid, signal.SIGCONT)
                    except ProcessLookupError:
                        pass
        return fired


__all__ = ["Fault", "Injector", "find_pid", "parse_fault"]
