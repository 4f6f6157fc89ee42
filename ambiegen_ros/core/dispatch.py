"""Sharing scenarios among simulation workers, with re-assignment and explicit timeouts.

ROS-free and clock-injected (every method takes ``now`` in seconds) so it is unit-tested without
processes; the generator node drives it from timers and callbacks.

Rules:
* a worker is alive while its heartbeats arrive within ``worker_timeout``;
* each scenario is assigned to one alive worker (least loaded, ties by name), at most
  ``max_in_flight`` per worker; with no worker known after ``worker_wait`` seconds scenarios are
  offered to anyone (``worker = ""``), which suits external systems that send no heartbeat;
* a scenario whose worker died (fell silent, crashed, lost its network link) goes back to the
  front of the queue for the next live worker; that never counts against the scenario, so while
  any worker lives the scenario is executed rather than recorded as a timeout;
* a worker executes what it is sent in order, so of the scenarios a live worker holds only the
  oldest is being executed; the others wait in its queue and are not late, however long a run
  takes (a robot run of 9 s with 5 queued used to time out the last ones at 30 s and execute them
  twice). ``result_timeout`` bounds one execution: it runs from when the worker became free for
  the scenario (its send, or the worker's previous executed answer, whichever is later);
* a scenario late by that measure (a hung simulation) is re-assigned, preferring a worker that
  has not tried it, until it was late ``max_attempts`` times; then it is given up and must be
  recorded as an explicit timeout. What waited behind it at that worker goes back to the queue,
  not counted against it, and the worker is stalled: one scenario at a time, and only when no
  other worker is free, until it answers again;
* a worker whose last heartbeat is older than half of ``worker_timeout`` is suspect: it gets no
  new scenario while a worker with fresh heartbeats lives (even a busy one), so a scenario taken
  from a worker of a host that just lost its link is not handed to its neighbour on that same
  host, about to be declared dead too;
* a scenario can be lost on its way to a live worker: a heartbeat only proves that the worker
  sees our result and heartbeat readers, its reader of scenarios may not have matched our writer
  yet (DDS discovery runs per direction), and a scenario published before that match never
  reaches it. Such a worker used to look full with lost scenarios until ``result_timeout``. So a
  worker that (re)appears is on probation: it holds one scenario until it answers one, or for
  ``worker_timeout``, then gets its full share (nothing is taken from it: a slow first run, e.g.
  a JIT compile, must not be executed twice). And a worker executes what it is sent in order, so
  when it answers an executed scenario (``executed=True``: not a rejection, which is answered on
  arrival) every scenario sent to it earlier and still open never reached it: those go back to
  the queue at once, never counted against them;
* silence is counted in time we listened: a tick after a pause of our own longer than half of
  ``worker_timeout`` with no heartbeat read meanwhile (the caller was busy, e.g. a first JIT
  compile, and the heartbeats are still waiting to be read) moves every worker's last heartbeat
  forward by that pause, so a busy
  generator neither declares its workers lost nor offers their scenarios to anyone;
* the first result for a scenario settles it; later duplicates are reported as such.

What happened to workers (joined, lost, back, unanswered, skipped) is kept in ``events`` (the latest
``MAX_EVENTS``) for the node to log.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any


MAX_EVENTS = 1000  # worker events kept until drained (a node that never drains stays bounded)


@dataclass
class Ticket:
    scenario_id: int
    payload: Any
    attempts: int = 0  # times sent
    sent_seq: int = 0  # order of its last send among all sends
    late: int = 0  # times its result did not come in time from a worker that stayed alive (or anyone)
    worker: str | None = None  # None = queued; "" = offered to anyone
    sent_at: float = 0.0
    tried: list[str] = field(default_factory=list)


@dataclass
class WorkerEvent:
    """A change in the worker set: ``lost`` (with seconds silent and scenarios re-queued), ``joined``,
    ``back``; ``unanswered``: a worker on probation did not answer its first scenario in time (it
    gets its full share); ``skipped``: scenarios a worker never got, re-queued."""

    kind: str
    worker: str
    at: float
    silent_s: float = 0.0
    requeued: int = 0


@dataclass
class Assignment:
    scenario_id: int
    worker: str
    attempt: int
    payload: Any


class Dispatcher:
    def __init__(
        self,
        result_timeout: float = 30.0,
        worker_timeout: float = 3.0,
        worker_wait: float = 5.0,
        max_attempts: int = 2,
        max_in_flight: int = 8,
        start: float = 0.0,
    ):
        if max_attempts < 1 or max_in_flight < 1:
            raise ValueError("max_attempts and max_in_flight must be >= 1")
        self.result_timeout = result_timeout
        self.worker_timeout = worker_timeout
        self.worker_wait = worker_wait
        self.max_attempts = max_attempts
        self.max_in_flight = max_in_flight
        self._start = start
        self._workers: dict[str, float] = {}
        self._lost: set[str] = set()  # workers declared dead (so their return is noticed)
        self._proven: set[str] = set()  # workers past probation since they (re)appeared
        self._held: dict[str, dict[int, int]] = {}  # worker -> {scenario id: send order} it holds
        self._free_at: dict[str, float] = {}  # worker -> when it last became free (executed answer, or late)
        self._stalled: set[str] = set()  # workers late with a scenario, until they answer again
        self._sends = 0
        self._last_tick: float | None = None
        self._heard = False  # a heartbeat was read since the last tick
        self.events: list[WorkerEvent] = []
        self._tickets: dict[int, Ticket] = {}
        self._queue: list[int] = []
        self.settled: dict[int, str] = {}  # scenario id -> worker that answered ("" = gave up)
        self.duplicates = 0

    def begin(self, now: float) -> None:
        """Start the ``worker_wait`` clock (when the first scenarios are about to go out), and the
        listening: a pause between here and the first tick is the caller's, not its workers'."""
        self._start = now
        self._last_tick, self._heard = now, False

    def busy(self, start: float, end: float) -> None:
        """The caller read nothing from ``start`` to ``end`` (a long step of its own: asking the
        search for a batch, whose first surrogate evaluation compiles): that stretch is no worker's
        silence. The tick's own guess (a pause with no heartbeat read) misses it when a heartbeat
        was read just before the step, and then every worker looked lost at once and a whole
        random batch of 100 Nav2 maps was offered to anyone (docs/external_sut.md)."""
        gap = end - start
        if gap <= 0:
            return
        self._workers = {w: min(end, seen + gap) for w, seen in self._workers.items()}
        self._last_tick = end if self._last_tick is None else max(self._last_tick, end)

    # --- inputs --------------------------------------------------------------------------
    def add(self, scenario_id: int, payload: Any) -> None:
        if scenario_id in self._tickets or scenario_id in self.settled:
            raise ValueError(f"scenario {scenario_id} already dispatched")
        self._tickets[scenario_id] = Ticket(scenario_id, payload)
        self._queue.append(scenario_id)

    def heartbeat(self, worker: str, now: float) -> None:
        if worker not in self._workers:
            self._event("joined", worker, now)
        elif worker in self._lost or now - self._workers[worker] > self.worker_timeout:
            self._lost.discard(worker)
            self._event("back", worker, now, silent_s=now - self._workers[worker])
        self._workers[worker] = max(now, self._workers.get(worker, now))
        self._heard = True

    def drain_events(self) -> list[WorkerEvent]:
        events, self.events = self.events, []
        return events

    def _event(self, *args, **kwargs) -> WorkerEvent:
        event = WorkerEvent(*args, **kwargs)
        self.events.append(event)
        del self.events[:-MAX_EVENTS]
        return event

    def result(self, scenario_id: int, worker: str, executed: bool = True, now: float = 0.0) -> bool:
        """Record a result; True if it is the first one for this scenario (i.e. to be used).

        ``executed``: the worker ran the scenario (False for rejections answered on arrival), so
        whatever it was sent before this one and has not answered never reached it."""
        if worker in self._workers:
            self._proven.add(worker)  # even a late duplicate shows our scenarios reach it
        if executed:
            self._free_at[worker] = now
            self._stalled.discard(worker)
        held = self._held.get(worker, {})
        if executed and scenario_id in held:
            skipped = [sid for sid, seq in held.items() if seq < held[scenario_id]]
            for sid in skipped:
                self._release(self._tickets[sid])
            if skipped:
                self._queue = sorted(skipped) + self._queue
                self._event("skipped", worker, now, requeued=len(skipped))
        if scenario_id in self.settled or scenario_id not in self._tickets:
            self.duplicates += 1
            return False
        self._release(self._tickets[scenario_id])
        self._tickets.pop(scenario_id)
        if scenario_id in self._queue:
            self._queue.remove(scenario_id)
        self.settled[scenario_id] = worker
        return True

    def withdraw(self) -> list[int]:
        """Drop the scenarios never sent (the run's budget is spent): they leave no record, as they
        were never published. Those sent at least once stay until they settle or time out."""
        never = {sid for sid in self._queue if self._tickets[sid].attempts == 0}
        for sid in never:
            self._tickets.pop(sid)
        self._queue = [sid for sid in self._queue if sid not in never]
        return sorted(never)

    def forget(self, scenario_ids: list[int]) -> None:
        """Drop settled scenarios the caller is done with, so a long run's memory stays flat.

        A late duplicate result for one of them is still counted as a duplicate (it has no ticket).
        """
        for scenario_id in scenario_ids:
            self.settled.pop(scenario_id, None)

    def _release(self, ticket: Ticket) -> None:
        """The ticket is no longer held by its worker (answered, re-queued or given up)."""
        self._held.get(ticket.worker or "", {}).pop(ticket.scenario_id, None)
        ticket.worker = None

    # --- decisions -----------------------------------------------------------------------
    def alive(self, now: float) -> list[str]:
        return sorted(w for w, seen in self._workers.items() if now - seen <= self.worker_timeout)

    def tick(self, now: float) -> tuple[list[Assignment], list[Ticket]]:
        """Advance time: returns (assignments to publish now, tickets given up -> timeout records)."""
        pause = 0.0 if self._last_tick is None else now - self._last_tick
        self._last_tick, heard, self._heard = now, self._heard, False
        if pause > self.worker_timeout / 2 and not heard:  # we were not listening: not their silence
            self._workers = {w: min(now, seen + pause) for w, seen in self._workers.items()}
        alive = self.alive(now)
        for worker, seen in self._workers.items():
            if worker not in alive and worker not in self._lost:
                self._lost.add(worker)
                self._proven.discard(worker)
                self._stalled.discard(worker)
                self._event("lost", worker, now, silent_s=now - seen)
        requeued: dict[str, int] = {}
        given_up: list[Ticket] = []
        retry: list[int] = []
        for ticket in list(self._tickets.values()):
            if ticket.worker is None:
                continue
            if ticket.worker != "" and ticket.worker not in alive:  # not the scenario's fault
                requeued[ticket.worker] = requeued.get(ticket.worker, 0) + 1
            elif ticket.worker and ticket.worker not in self._proven and now - ticket.sent_at > self.worker_timeout:
                # probation over without an answer: slow, or the scenario never reached it. Give it
                # more; an answer to a later one will tell (see ``result``)
                self._event("unanswered", ticket.worker, now)
                self._proven.add(ticket.worker)
                continue
            elif self._overdue(ticket, now):
                ticket.late += 1
                behind = self._stall(ticket.worker, now) if ticket.worker else []
                for sid in behind:  # never started: back to the queue, not counted against them
                    self._release(self._tickets[sid])
                    retry.append(sid)
                if ticket.late >= self.max_attempts:
                    self._release(ticket)
                    self._tickets.pop(ticket.scenario_id)
                    self.settled[ticket.scenario_id] = ""
                    given_up.append(ticket)
                    continue
            else:
                continue
            self._release(ticket)
            retry.append(ticket.scenario_id)
        for event in self.events:
            if event.kind == "lost" and event.worker in requeued:
                event.requeued += requeued.pop(event.worker)
        self._queue = retry + self._queue  # retries first: they have waited longest
        return self._assign(alive, now), given_up

    def _overdue(self, ticket: Ticket, now: float) -> bool:
        """Late: its execution (not its wait in the worker's queue) took over ``result_timeout``."""
        if not ticket.worker:  # offered to anyone: no queue we know of
            return now - ticket.sent_at > self.result_timeout
        held = self._held.get(ticket.worker, {})
        if held and min(held, key=held.__getitem__) != ticket.scenario_id:
            return False  # waiting behind the one its worker executes
        started = max(ticket.sent_at, self._free_at.get(ticket.worker, ticket.sent_at))
        return now - started > self.result_timeout

    def _stall(self, worker: str, now: float) -> list[int]:
        """``worker`` is late with its oldest scenario: stall it; the ids queued behind that one."""
        self._stalled.add(worker)
        self._free_at[worker] = now
        held = self._held.get(worker, {})
        oldest = min(held, key=held.__getitem__)
        return [sid for sid in sorted(held, key=held.__getitem__) if sid != oldest]

    def _assign(self, alive: list[str], now: float) -> list[Assignment]:
        out: list[Assignment] = []
        load = {w: 0 for w in alive}
        # probation and stalled: one at a time
        cap = {w: self.max_in_flight if w in self._proven and w not in self._stalled else 1 for w in alive}
        for ticket in self._tickets.values():
            if ticket.worker in load:
                load[ticket.worker] += 1
        anyone = not alive and now - self._start >= self.worker_wait
        fresh = [w for w in alive if now - self._workers[w] <= self.worker_timeout / 2]
        usable = fresh or alive
        remaining = []
        for scenario_id in self._queue:
            ticket = self._tickets[scenario_id]
            if anyone:
                worker = ""
            else:
                free = [w for w in usable if load[w] < cap[w]]
                free = [w for w in free if w not in self._stalled] or free  # a stalled one only as the last resort
                if not free:
                    remaining.append(scenario_id)
                    continue
                worker = min(free, key=lambda w: (w in ticket.tried, load[w], w))
                load[worker] += 1
            ticket.worker = worker
            self._sends += 1
            ticket.sent_seq = self._sends
            self._held.setdefault(worker, {})[scenario_id] = ticket.sent_seq
            ticket.attempts += 1
            ticket.sent_at = now
            ticket.tried.append(worker)
            out.append(Assignment(scenario_id, worker, ticket.attempts, ticket.payload))
        self._queue = remaining
        return out

    # --- state -----------------------------------------------------------------------------
    @property
    def open(self) -> int:
        """Scenarios not settled yet (queued or in flight)."""
        return len(self._tickets)

    def done(self) -> bool:
        return not self._tickets
