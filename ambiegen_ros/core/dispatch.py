"""Sharing scenarios among simulation workers, with re-assignment and explicit timeouts.

ROS-free and clock-injected (every method takes ``now`` in seconds) so it is unit-tested without
processes; the generator node drives it from timers and callbacks.

Rules:
* a worker is alive while its heartbeats arrive within ``worker_timeout``;
* each scenario is assigned to one alive worker (least loaded, ties by name), at most
  ``max_in_flight`` per worker; with no worker known after ``worker_wait`` seconds scenarios are
  offered to anyone (``worker = ""``), which suits external systems that send no heartbeat;
* a scenario whose worker died, or whose result did not come within ``result_timeout``, is
  re-assigned (preferring another worker) until ``max_attempts`` attempts were made; then it is
  given up and must be recorded as an explicit timeout;
* the first result for a scenario settles it; later duplicates are reported as such.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any


@dataclass
class Ticket:
    scenario_id: int
    payload: Any
    attempts: int = 0
    worker: str | None = None  # None = queued; "" = offered to anyone
    sent_at: float = 0.0
    tried: list[str] = field(default_factory=list)


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
        self._tickets: dict[int, Ticket] = {}
        self._queue: list[int] = []
        self.settled: dict[int, str] = {}  # scenario id -> worker that answered ("" = gave up)
        self.duplicates = 0

    def begin(self, now: float) -> None:
        """Start the ``worker_wait`` clock (when the first scenarios are about to go out)."""
        self._start = now

    # --- inputs --------------------------------------------------------------------------
    def add(self, scenario_id: int, payload: Any) -> None:
        if scenario_id in self._tickets or scenario_id in self.settled:
            raise ValueError(f"scenario {scenario_id} already dispatched")
        self._tickets[scenario_id] = Ticket(scenario_id, payload)
        self._queue.append(scenario_id)

    def heartbeat(self, worker: str, now: float) -> None:
        self._workers[worker] = now

    def result(self, scenario_id: int, worker: str) -> bool:
        """Record a result; True if it is the first one for this scenario (i.e. to be used)."""
        if scenario_id in self.settled or scenario_id not in self._tickets:
            self.duplicates += 1
            return False
        self._tickets.pop(scenario_id)
        if scenario_id in self._queue:
            self._queue.remove(scenario_id)
        self.settled[scenario_id] = worker
        return True

    # --- decisions -----------------------------------------------------------------------
    def alive(self, now: float) -> list[str]:
        return sorted(w for w, seen in self._workers.items() if now - seen <= self.worker_timeout)

    def tick(self, now: float) -> tuple[list[Assignment], list[Ticket]]:
        """Advance time: returns (assignments to publish now, tickets given up -> timeout records)."""
        alive = self.alive(now)
        given_up: list[Ticket] = []
        retry: list[int] = []
        for ticket in list(self._tickets.values()):
            if ticket.worker is None:
                continue
            worker_dead = ticket.worker != "" and ticket.worker not in alive
            late = now - ticket.sent_at > self.result_timeout
            if worker_dead or late:
                if ticket.attempts >= self.max_attempts:
                    self._tickets.pop(ticket.scenario_id)
                    self.settled[ticket.scenario_id] = ""
                    given_up.append(ticket)
                else:
                    ticket.worker = None
                    retry.append(ticket.scenario_id)
        self._queue = retry + self._queue  # retries first: they have waited longest
        return self._assign(alive, now), given_up

    def _assign(self, alive: list[str], now: float) -> list[Assignment]:
        out: list[Assignment] = []
        load = {w: 0 for w in alive}
        for ticket in self._tickets.values():
            if ticket.worker in load:
                load[ticket.worker] += 1
        anyone = not alive and now - self._start >= self.worker_wait
        remaining = []
        for scenario_id in self._queue:
            ticket = self._tickets[scenario_id]
            if anyone:
                worker = ""
            else:
                free = [w for w in alive if load[w] < self.max_in_flight]
                if not free:
                    remaining.append(scenario_id)
                    continue
                fresh = [w for w in free if w not in ticket.tried] or free
                worker = min(fresh, key=lambda w: (load[w], w))
                load[worker] += 1
            ticket.worker = worker
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
