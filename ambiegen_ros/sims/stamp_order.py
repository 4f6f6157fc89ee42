"""Several streams merged in stamp order, so that a verdict never depends on arrival order (ROS-free).

A judge that listens to several topics (a robot's odometry, the stack's status, the world's
collision report) gets them in whatever order the middleware delivers: DDS keeps the order of one
writer's samples, never the order across writers, and a loaded machine shuffles them further. So
pose *samples* are held until every *event stream* has passed their stamp:

* a stream has passed stamp t once a message stamped t or later arrived on it (its watermark;
  each writer's samples arrive in order, so nothing older can follow), or once it closed: its
  first event arrived (the first event of a stream decides; later ones cannot change the verdict)
  or its publisher left the graph;
* a released sample carries the events that apply to it. A *state* event (the world: "touching a
  wall at t") applies to the samples stamped t or later. A *decision* event (the stack: "I gave up,
  seeing the world at t") applies to the samples stamped after t: the stack decided on what it saw
  at t, and its command drives the next period, as the in-process full model labels it.

Events stamped before the run's first sample belong to an earlier run and are ignored. The judge
then applies one fixed priority at each sample (see ``RobotJudge.add``), so the same streams give
the same verdict in any arrival order: live, on a loaded machine, or replayed from a bag.
"""
from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import Any, Iterable

STATE, DECISION = "state", "decision"


@dataclass
class EventStream:
    """One stream of stamped events and heartbeats (stamps in nanoseconds)."""

    name: str
    applies: str = STATE  # STATE: to samples stamped >= the event; DECISION: to samples stamped after it
    mark: float = -math.inf  # watermark: the newest stamp seen
    event: tuple[int, Any] | None = None  # the first event of this run: (stamp, what it says)
    first: int | None = None  # stamp of this run's first message
    closed: str | None = None  # why nothing more is awaited on it

    def applies_to(self, stamp: int) -> bool:
        if self.event is None:
            return False
        return stamp > self.event[0] if self.applies == DECISION else stamp >= self.event[0]


class StampOrder:
    """Pose samples held until every open event stream has passed their stamps.

    ``sample(stamp, row)`` queues a sample, ``message(stream, stamp, event)`` advances a stream
    (``event`` None: a heartbeat), ``close(stream, why)`` stops waiting for it, ``release()``
    returns the samples that are final now, in stamp order, each with the events that apply to it.
    """

    def __init__(self, streams: Iterable[tuple[str, str]] = ()):
        self.streams: dict[str, EventStream] = {name: EventStream(name, applies) for name, applies in streams}
        self.pending: deque[tuple[int, Any]] = deque()
        self.start: int | None = None  # stamp of the run's first sample
        self.newest: int | None = None  # stamp of the newest sample received

    def reset(self) -> None:
        """A new run: no samples, no events; every stream open and waited for again."""
        self.pending.clear()
        self.start = self.newest = None
        for s in self.streams.values():
            s.mark, s.event, s.closed, s.first = -math.inf, None, None, None

    def sample(self, stamp: int, row: Any) -> None:
        if self.start is None:
            self.start = stamp
            for s in self.streams.values():  # an earlier run's message (it reached us late) is not this run's
                if s.event is not None and s.event[0] < stamp:
                    s.event, s.closed = None, None
                if s.first is not None and s.first < stamp:
                    s.first = None
        self.pending.append((stamp, row))
        self.newest = stamp if self.newest is None else max(self.newest, stamp)

    def message(self, name: str, stamp: int, event: Any = None) -> None:
        s = self.streams[name]
        s.mark = max(s.mark, stamp)
        if s.first is None and (self.start is None or stamp >= self.start):
            s.first = stamp
        if event is not None and s.event is None and (self.start is None or stamp >= self.start):
            s.event, s.closed = (stamp, event), "its first event"

    def start_at_first(self, name: str) -> bool:
        """The run starts with the state stream ``name`` first acted on: the newest pending sample
        stamped at or before its first message; older ones are dropped (a world that showed the
        start twice, once per reset, before the stack began). False while that message is unknown."""
        s = self.streams[name]
        if s.first is None or not self.pending:
            return False
        begin = max((stamp for stamp, _ in self.pending if stamp <= s.first), default=None)
        if begin is not None:
            while self.pending[0][0] < begin:
                self.pending.popleft()
            self.start = begin
        return True

    def close(self, name: str, why: str) -> None:
        s = self.streams[name]
        if s.closed is None:
            s.closed = why

    @property
    def watermark(self) -> float:
        """Samples stamped up to here are final: every open stream has passed it."""
        return min((s.mark for s in self.streams.values() if s.closed is None), default=math.inf)

    def waiting_for(self) -> list[str]:
        """The open streams that hold the oldest pending sample back."""
        if not self.pending:
            return []
        oldest = self.pending[0][0]
        return [s.name for s in self.streams.values() if s.closed is None and s.mark < oldest]

    def release(self) -> list[tuple[int, Any, dict[str, Any]]]:
        """The samples that are final now, oldest first: (stamp, row, {stream: event that applies})."""
        mark = self.watermark
        out = []
        while self.pending and self.pending[0][0] <= mark:
            stamp, row = self.pending.popleft()
            out.append((stamp, row, {s.name: s.event[1] for s in self.streams.values() if s.applies_to(stamp)}))
        return out
