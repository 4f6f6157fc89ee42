"""Work sharing among sim workers: assignment, death, timeouts, duplicates (clock injected)."""
from __future__ import annotations

import pytest

from ambiegen_ros.core.dispatch import Dispatcher


def make(**kw):
    d = Dispatcher(result_timeout=10, worker_timeout=2, worker_wait=1, max_attempts=2, max_in_flight=2, **kw)
    for i in range(6):
        d.add(i, f"scenario-{i}")
    return d


def test_scenarios_are_shared_without_overlap_and_respect_in_flight_limit():
    d = make()
    d.heartbeat("a", 0)
    d.heartbeat("b", 0)
    sent, gone = d.tick(0)
    assert not gone
    assert len(sent) == 4  # two workers x max_in_flight 2
    assert sorted(a.worker for a in sent) == ["a", "a", "b", "b"]
    assert len({a.scenario_id for a in sent}) == 4
    for a in sent:
        assert d.result(a.scenario_id, a.worker)
    sent2, _ = d.tick(0.5)
    assert {a.scenario_id for a in sent2} == {4, 5}
    for a in sent2:
        d.result(a.scenario_id, a.worker)
    assert d.done() and sorted(d.settled) == list(range(6))


def test_dead_worker_scenarios_go_to_the_live_one():
    d = make()
    d.heartbeat("a", 0)
    d.heartbeat("b", 0)
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
    assert all(g.attempts == 2 for g in gone_all)
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
