"""Work sharing among sim workers: assignment, death, timeouts, duplicates (clock injected)."""
from __future__ import annotations

import pytest

from ambiegen_ros.core.dispatch import Dispatcher


def make(**kw):
    d = Dispatcher(result_timeout=10, worker_timeout=2, worker_wait=1, max_attempts=2, max_in_flight=2, **kw)
    for i in range(6):
        d.add(i, f"scenario-{i}")
    return d


def prove(d, now, *workers):
    """Workers pass probation: each is sent one scenario and answers it."""
    for w in workers:
        d.heartbeat(w, now)
    sent, _ = d.tick(now)
    assert sorted(a.worker for a in sent) == sorted(workers)  # probation: one each
    for a in sent:
        assert d.result(a.scenario_id, a.worker)


def test_scenarios_are_shared_without_overlap_and_respect_in_flight_limit():
    d = make()
    d.heartbeat("a", 0)
    d.heartbeat("b", 0)
    sent, gone = d.tick(0)
    assert not gone
    assert sorted(a.worker for a in sent) == ["a", "b"]  # new workers: one scenario each until they answer
    for a in sent:
        assert d.result(a.scenario_id, a.worker)
    sent, _ = d.tick(0.1)
    assert len(sent) == 4  # proven: two workers x max_in_flight 2
    assert sorted(a.worker for a in sent) == ["a", "a", "b", "b"]
    assert len({a.scenario_id for a in sent}) == 4
    for a in sent:
        assert d.result(a.scenario_id, a.worker)
    assert d.done() and sorted(d.settled) == list(range(6))


def test_dead_worker_scenarios_go_to_the_live_one():
    d = make()
    for i in range(6, 8):
        d.add(i, f"scenario-{i}")
    prove(d, 0, "a", "b")
    first, _ = d.tick(0)
    of_b = {a.scenario_id for a in first if a.worker == "b"}
    d.heartbeat("a", 2.5)  # b falls silent
    again, gone = d.tick(3)
    assert not gone
    reassigned = {a.scenario_id for a in again}
    # a is still busy with its own two, so nothing fits until it answers
    assert reassigned == set()
    for a in first:
        if a.worker == "a":
            d.result(a.scenario_id, "a")
    again, _ = d.tick(3.1)
    assert of_b <= {a.scenario_id for a in again}
    assert all(a.worker == "a" and a.attempt == 2 for a in again if a.scenario_id in of_b)


def test_give_up_after_max_attempts_and_report_each_once():
    d = make()
    d.heartbeat("a", 0)
    t = 0.0
    gone_all = []
    while not d.done() and t < 200:
        d.heartbeat("a", t)
        _, gone = d.tick(t)
        gone_all += gone
        t += 1.0
    assert d.done()
    assert sorted(g.scenario_id for g in gone_all) == list(range(6))
    # late twice each; a scenario queued behind a late one was re-sent without counting against it
    assert all(g.late == 2 and g.attempts >= 2 for g in gone_all)
    assert all(w == "" for w in d.settled.values())


def test_no_worker_means_offer_to_anyone_after_wait():
    d = make()
    sent, _ = d.tick(0.5)
    assert sent == []
    sent, _ = d.tick(1.0)
    assert len(sent) == 6 and all(a.worker == "" for a in sent)


def test_duplicate_and_late_results_are_not_used_twice():
    d = make()
    d.heartbeat("a", 0)
    sent, _ = d.tick(0)
    sid = sent[0].scenario_id
    assert d.result(sid, "a") is True
    assert d.result(sid, "b") is False
    assert d.duplicates == 1
    with pytest.raises(ValueError):
        d.add(sid, "again")


def test_a_host_losing_its_link_strands_no_scenario_as_a_timeout():
    """The issue's case: two workers of one host fall silent together (their last heartbeats a
    little apart) while a worker elsewhere is alive but busy. Each stranded scenario must end on
    the live worker, never on the neighbour about to be declared dead, and never as a timeout,
    even with max_attempts=1 (a worker's death is not the scenario's fault)."""
    d = Dispatcher(result_timeout=30, worker_timeout=3, worker_wait=1, max_attempts=1, max_in_flight=2)
    for i in range(12):
        d.add(i, i)
    prove(d, 0, "a", "b1", "b2")
    sent, _ = d.tick(0.1)
    held = {w: {x.scenario_id for x in sent if x.worker == w} for w in ("a", "b1", "b2")}
    assert all(len(ids) == 2 for ids in held.values())
    t, gone_all, moved_to = 0.1, [], {}
    while t < 20:
        d.heartbeat("a", t)
        if t <= 1.0:
            d.heartbeat("b1", t)  # b1 last heard at 1.0, b2 at 1.4: then the cable is pulled
        if t <= 1.4:
            d.heartbeat("b2", t)
        sent, gone = d.tick(t)
        gone_all += gone
        for x in sent:
            moved_to[x.scenario_id] = x.worker
            if x.worker == "a":
                d.result(x.scenario_id, "a")
        if t == 5.0:  # a answers what it held all along; until then it was full
            for sid in held["a"]:
                d.result(sid, "a")
        t = round(t + 0.1, 1)
    assert gone_all == []
    assert all(moved_to[sid] == "a" for sid in held["b1"] | held["b2"])
    assert d.done()
    lost = {e.worker: e for e in d.drain_events() if e.kind == "lost"}
    assert set(lost) == {"b1", "b2"} and all(e.requeued == 2 for e in lost.values())
    assert 3.0 < lost["b1"].silent_s <= 3.1


def test_a_scenario_sent_before_the_worker_could_hear_us_is_sent_again_and_the_worker_still_gets_work():
    """A new worker's first scenario may be lost in discovery (its reader not yet matched). It holds
    one until worker_timeout (probation), then gets its full share; its answer to a later
    scenario shows the first never arrived (a worker executes in the order sent), which then goes
    back to the queue, uncounted, even with max_attempts=1."""
    d = Dispatcher(result_timeout=30, worker_timeout=2, worker_wait=1, max_attempts=1, max_in_flight=3)
    for i in range(10):
        d.add(i, i)
    prove(d, 0, "old")
    d.heartbeat("new", 0.5)
    sent, _ = d.tick(0.5)
    first = [x.scenario_id for x in sent if x.worker == "new"]
    assert len(first) == 1  # probation: one at a time
    for x in sent:
        if x.worker == "old":
            d.result(x.scenario_id, "old")
    for t in (1.5, 2.6):
        d.heartbeat("old", t)
        d.heartbeat("new", t)
    sent, gone = d.tick(2.6)  # 2.1 s without an answer: probation over, the first stays with it
    later = [x.scenario_id for x in sent if x.worker == "new"]
    assert not gone and len(later) == 2 and first[0] not in {x.scenario_id for x in sent}
    d.result(later[0], "new", executed=False)  # a rejection, answered on arrival: proves nothing
    sent, _ = d.tick(2.7)
    assert first[0] not in {x.scenario_id for x in sent}
    d.result(later[1], "new")  # executed: the first, sent before it, never reached "new"
    sent, gone = d.tick(2.8)
    assert not gone and (first[0], 2) in {(x.scenario_id, x.attempt) for x in sent}  # sent again
    assert [e.kind for e in d.drain_events()] == ["joined", "joined", "unanswered", "skipped"]


def test_a_slow_first_run_is_not_executed_twice():
    d = Dispatcher(result_timeout=30, worker_timeout=2, worker_wait=1, max_attempts=1, max_in_flight=3)
    for i in range(6):
        d.add(i, i)
    sends = []
    t = 0.0
    while not d.done() and t < 20:
        d.heartbeat("slow", t)
        sent, gone = d.tick(t)
        assert not gone
        sends += [x.scenario_id for x in sent]
        if t == 6.0:  # the first run (a JIT compile) took 6 s; then every one is answered at once
            for sid in list(sends):
                d.result(sid, "slow")
        elif t > 6.0:
            for x in sent:
                d.result(x.scenario_id, "slow")
        t = round(t + 0.5, 1)
    assert d.done() and sorted(sends) == list(range(6)) and d.duplicates == 0  # each sent once


def test_a_worker_that_comes_back_is_reported_and_gets_work_again():
    d = make()
    prove(d, 0, "a", "b")
    d.heartbeat("a", 2.5)
    d.tick(2.5)  # b silent 2.5 s > 2: lost
    d.heartbeat("b", 6.0)
    d.heartbeat("a", 6.0)
    sent, _ = d.tick(6.0)
    assert "b" in {x.worker for x in sent}
    kinds = [(e.kind, e.worker) for e in d.drain_events()]
    assert ("lost", "b") in kinds and ("back", "b") in kinds


def test_a_pause_of_the_caller_does_not_kill_its_workers_nor_offer_to_anyone():
    """The generator was busy for 5 s (a first JIT compile) while heartbeats queued up unread:
    on its next tick no worker is lost and nothing is offered to anyone (every worker would
    execute it)."""
    d = make()
    prove(d, 0, "a", "b")
    d.tick(0.5)
    sent, gone = d.tick(5.5)
    assert not gone and all(x.worker in ("a", "b") for x in sent)
    assert not [e for e in d.drain_events() if e.kind == "lost"]
    t = 5.5
    while t < 8.0:  # now listening all along (a tick every 0.1 s): 2.5 s more of silence is theirs
        t = round(t + 0.1, 1)
        d.tick(t)
    assert [e.worker for e in d.drain_events() if e.kind == "lost"] == ["a", "b"]


def test_a_long_first_ask_after_begin_neither_loses_the_worker_nor_offers_the_batch_to_anyone():
    """MPPI random seed 3: the generator began, read one more heartbeat, then asked the search for
    its batch of 100 maps (5.8 s: a first surrogate evaluation). Its first tick found the Nav2
    adapter silent, declared it lost and offered all 100 maps to anyone, so the budget could
    withdraw none of them. Told the ask was its own pause, the dispatcher sends one map, to the
    adapter."""
    d = Dispatcher(result_timeout=400, worker_timeout=3, worker_wait=2, max_attempts=2, max_in_flight=1)
    d.heartbeat("nav2", 0.0)
    d.begin(0.1)
    d.heartbeat("nav2", 0.2)  # read before the ask: the tick's own guess would see a listening pause
    for i in range(100):
        d.add(i, i)
    d.busy(0.3, 6.1)
    sent, gone = d.tick(6.1)
    assert [(x.scenario_id, x.worker) for x in sent] == [(0, "nav2")] and not gone
    assert not [e for e in d.drain_events() if e.kind == "lost"]
    assert d.withdraw() == list(range(1, 100))  # the budget can still take back what was not sent


def test_the_pause_from_begin_to_the_first_tick_is_the_callers():
    """No tick before ``begin``: the stretch from it to the first tick, with no heartbeat read, is
    the caller's pause (before, the first tick measured none and judged the worker by it)."""
    d = make()
    d.heartbeat("a", 0.0)
    d.begin(0.5)
    sent, _ = d.tick(5.0)
    assert [x.worker for x in sent] == ["a"]
    assert not [e for e in d.drain_events() if e.kind == "lost"]


def test_busy_is_no_silence_before_it():
    """Silence before and after the caller's pause still counts: 1.5 s + 1.0 s > 2 s is lost."""
    d = make()
    d.heartbeat("a", 0.0)
    d.begin(0.0)
    for k in range(1, 16):  # listening, a tick every 0.1 s
        d.tick(k / 10)
    d.busy(1.5, 10.0)
    d.tick(10.0)
    assert not [e for e in d.drain_events() if e.kind == "lost"]
    d.tick(10.6)
    assert [e.worker for e in d.drain_events() if e.kind == "lost"] == ["a"]


def test_a_slow_worker_queue_is_not_a_timeout():
    """Executions of 8 s, four queued at a time, result_timeout 10: the fourth waits 32 s in the
    worker's queue, yet nothing is late, re-sent or executed twice (the launch on Fast DDS with a
    robot worker running 9 s scenarios used to time out and duplicate the last ones)."""
    d = Dispatcher(result_timeout=10, worker_timeout=2, worker_wait=1, max_attempts=2, max_in_flight=4)
    for i in range(12):
        d.add(i, i)
    prove(d, 0, "a")
    queue: list[int] = []  # the worker's own queue, executed in order
    busy_until, t, sends = 0.0, 0.0, 0
    while not d.done() and t < 400:
        d.heartbeat("a", t)
        sent, gone = d.tick(t)
        assert not gone
        sends += len(sent)
        queue += [a.scenario_id for a in sent]
        if queue and t >= busy_until:
            if busy_until:  # the one it was executing is done
                assert d.result(queue.pop(0), "a", now=t)
            busy_until = t + 8.0 if queue else 0.0
        t += 0.5
    assert d.done() and d.duplicates == 0
    assert sends == 11  # each remaining scenario sent exactly once


def test_a_hung_worker_loses_its_queue_to_a_free_one_at_once():
    d = Dispatcher(result_timeout=10, worker_timeout=2, worker_wait=1, max_attempts=2, max_in_flight=3)
    for i in range(10):
        d.add(i, i)
    prove(d, 0, "a", "b")
    first, _ = d.tick(0)
    of_a = [x.scenario_id for x in first if x.worker == "a"]
    assert len(of_a) == 3
    for x in first:  # b answers everything it gets; a hangs on its first
        if x.worker == "b":
            d.result(x.scenario_id, "b", now=1)
    d.heartbeat("a", 9.0)
    d.heartbeat("b", 9.0)
    sent, _ = d.tick(9.0)  # b gets the last two; a is not late yet (9 s < 10 s)
    assert {x.worker for x in sent} == {"b"} and len(sent) == 2
    for x in sent:
        d.result(x.scenario_id, "b", now=9.5)
    d.heartbeat("a", 10.5)
    d.heartbeat("b", 10.5)
    sent, gone = d.tick(10.5)
    assert not gone
    moved = {x.scenario_id: x.worker for x in sent}
    assert set(moved) == set(of_a) and set(moved.values()) == {"b"}  # all three to b at once
    tickets = {sid: d._tickets[sid] for sid in of_a}
    assert tickets[of_a[0]].late == 1 and tickets[of_a[1]].late == tickets[of_a[2]].late == 0
    d.heartbeat("a", 11.0)
    d.heartbeat("b", 11.0)
    d.add(99, 99)
    sent, _ = d.tick(11.0)
    assert [(x.scenario_id, x.worker) for x in sent] == [(99, "a")]  # b is full: the stalled a, one at a time


def test_withdraw_drops_only_what_was_never_sent():
    """A spent budget: the queued scenarios go, the ones in flight (or sent and re-queued) stay."""
    d = make()
    d.heartbeat("a", 0)
    (first,), _ = d.tick(0)  # probation: one scenario out
    assert d.withdraw() == [i for i in range(6) if i != first.scenario_id]
    assert d.open == 1 and not d.done()
    sent, _ = d.tick(0.1)
    assert sent == []  # nothing left to send
    assert d.result(first.scenario_id, "a") and d.done()
