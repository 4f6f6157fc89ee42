"""The timing record of a Nav2 run and its rule ``starved`` (``ambiegen_ros.sims.timing``), on crafted
event streams: a clean run, one bad window the mean hides, a stall the controller owned up to, a
recovery's silence, a late acknowledgement (ours and the tree's), a lapsed bond, the world's stall.
The log lines are navigation2 jazzy's own words (controller_server.cpp, bt_action_node.hpp,
lifecycle_manager.cpp)."""
from __future__ import annotations

import pytest

from ambiegen_ros.sims.timing import Thresholds, TimingRecord, starved, summary, worst_window_hz

MISSED = "Control loop missed its desired rate of 20.0000 Hz. Current loop rate is 7.1000 Hz."
LATE = "Timed out while waiting for action server to acknowledge goal request for follow_path"
HEARTBEAT = "\x1b[34m\x1b[1mHave not received a heartbeat from controller_server.\x1b[0m\x1b[0m"
DOWN = ("CRITICAL FAILURE: SERVER controller_server IS DOWN after not receiving a heartbeat for 4000 ms. "
        "Shutting down related nodes.")


def ticks(start: float, seconds: float, hz: float) -> list[float]:
    return [start + k / hz for k in range(int(round(seconds * hz)))]


def record(*streams: list[float], lines=(), acks=()) -> TimingRecord:
    r = TimingRecord(controller_hz=20.0)
    for t in sorted(t for s in streams for t in s):
        r.loop(t)
    for t, name, text in lines:
        r.log(t, name, text)
    for a in acks:
        r.ack(a)
    return r


def test_a_clean_run_is_not_starved_and_its_worst_window_is_its_rate():
    r = record(ticks(0.0, 30.0, 20.0), acks=[0.02])
    assert starved(r) is None
    s = summary(r)
    assert s["timing.worst_window_hz"] == pytest.approx(20.0)
    assert s["timing.loop_windows"] > 500 and s["timing.missed_loops"] == 0 and s["timing.ack_s"] == 0.02
    assert all(isinstance(v, (int, float)) for v in s.values()), "flat numbers, so tables can read them"


def test_one_bad_window_starves_the_run_though_the_mean_is_fine():
    slow = ticks(10.0, 3.0, 5.0)  # 3 s at 5 Hz inside 23 s at 20 Hz: the mean stays above 17 Hz
    r = record(ticks(0.0, 10.0, 20.0), slow, ticks(13.0, 10.0, 20.0))
    assert len(r.loops) / 23.0 > 15.0
    worst, _ = worst_window_hz(r.loops, r.missed, 20.0, Thresholds())
    assert worst == pytest.approx(5.0)
    assert "5.0 Hz in its worst 2 s" in starved(r)
    assert starved(record(ticks(0.0, 10.0, 20.0), ticks(10.0, 3.0, 12.0), ticks(13.0, 10.0, 20.0))) is None


def test_a_silence_is_idle_unless_the_controller_says_it_missed_its_rate():
    before, after = ticks(0.0, 5.0, 20.0), ticks(8.0, 5.0, 20.0)  # 3 s without a command: a recovery (a spin)
    assert starved(record(before, after)) is None
    stalled = record(before, after, lines=[(8.01, "controller_server", MISSED)])
    assert "worst 2 s" in starved(stalled), "a cycle that overran by 3 s is the controller starved, not idle"


def test_missed_rate_lines_alone_starve_a_run_without_cmd_vel_nav():
    lines = [(t, "controller_server", MISSED) for t in ticks(4.0, 1.0, 20.0)]  # 20 of 40 cycles in 2 s
    r = record(lines=lines)
    assert "missed 50% of its cycles" in starved(r) and summary(r)["timing.missed_loops"] == 20
    assert "timing.worst_window_hz" not in summary(r)
    assert starved(record(lines=lines[:15])) is None


def test_the_rate_the_controller_names_is_its_frequency():
    r = record(ticks(0.0, 10.0, 10.0), lines=[(5.0, "controller_server",
                                              "Control loop missed its desired rate of 10.0000Hz")])
    assert r.controller_hz == 10.0 and starved(r) is None


def test_a_late_acknowledgement_starves_the_run_ours_or_the_trees():
    assert starved(record(ticks(0.0, 10.0, 20.0), acks=[0.05, 0.9])) is None
    ours = starved(record(ticks(0.0, 10.0, 20.0), acks=[0.05, 1.4]))
    assert "1.40 s to acknowledge our goal" in ours
    tree = record(ticks(0.0, 10.0, 20.0), lines=[(3.0, "bt_navigator", LATE)])
    assert "late acknowledgement (follow_path)" in starved(tree) and summary(tree)["timing.late_acks"] == 1


def test_a_lapsed_bond_starves_the_run_and_its_two_lines_are_one_lapse():
    r = record(ticks(0.0, 10.0, 20.0), lines=[(6.0, "lifecycle_manager_navigation", HEARTBEAT),
                                              (6.001, "lifecycle_manager_navigation", DOWN)])
    assert r.lapses == [(6.0, "controller_server")]
    assert "lost the bond of controller_server" in starved(r)
    lenient = Thresholds(max_bond_lapses=1)
    assert starved(r, lenient) is None


def test_other_lines_are_ignored_and_stale_data_only_counted():
    r = record(ticks(0.0, 10.0, 20.0), lines=[(1.0, "local_costmap", "Transform data too old when converting"),
                                              (2.0, "planner_server", "Reached the goal!")])
    assert starved(r) is None and summary(r)["timing.stale_data"] == 1


def world(r: TimingRecord, stream: str, *times: list[float]) -> TimingRecord:
    for t in sorted(t for s in times for t in s):
        r.arrival(stream, t)
    return r


def test_the_longest_silence_of_the_scans_and_the_clock_is_on_the_record():
    r = record(ticks(0.0, 4.0, 20.0))
    world(r, "scan", ticks(0.0, 1.0, 10.0), ticks(1.8, 1.0, 10.0))  # a 10 Hz laser silent from 0.9 s to 1.8 s
    world(r, "clock", ticks(0.0, 4.0, 100.0))
    out = summary(r)
    assert out["timing.scan_msgs"] == 20 and out["timing.scan_max_gap_s"] == pytest.approx(0.9)
    assert out["timing.clock_max_gap_s"] == pytest.approx(0.01)
    assert starved(r) == "the world's /scan was silent for 0.90 s (limit 0.35 s)"
    lone = record(ticks(0.0, 4.0, 20.0))
    lone.arrival("scan", 1.0)
    assert summary(lone)["timing.scan_msgs"] == 1 and "timing.scan_max_gap_s" not in summary(lone)
    assert not any(k.startswith("timing.clock") for k in summary(lone))
    assert starved(lone) is None, "a stream heard once, or never, is no stall"


def test_a_stall_of_the_worlds_clock_starves_the_run_and_says_which_stream():
    r = world(record(ticks(0.0, 10.0, 20.0)), "clock", ticks(0.0, 5.0, 50.0), ticks(5.48, 4.5, 50.0))
    world(r, "scan", ticks(0.0, 10.0, 10.0))
    r.goal(0.0)
    r.end(10.0)
    why = starved(r)
    assert why == "the world's /clock was silent for 0.50 s (limit 0.35 s)" and "/scan" not in why
    assert summary(r)["timing.clock_max_gap_s"] == pytest.approx(0.5)
    assert starved(r, Thresholds(max_world_gap_s=0.0)) is None, "0 turns the rule off"
    assert starved(r, Thresholds(max_world_gap_s=0.6)) is None


def test_a_quiet_machines_gaps_do_not_starve_a_run():
    r = world(record(ticks(0.0, 10.0, 20.0)), "clock", ticks(0.0, 10.0, 5.0))  # 0.2 s apart: a quiet stall
    world(r, "scan", [0.0, 0.35], ticks(0.55, 9.0, 5.0))  # a 5 Hz laser, one gap of 0.35 s: not longer
    assert summary(r)["timing.clock_max_gap_s"] == pytest.approx(0.2) and starved(r) is None
    assert summary(r)["timing.scan_max_gap_s"] == pytest.approx(0.35)


def test_only_the_part_of_a_silence_while_nav2_drives_counts():
    r = record(ticks(0.0, 10.0, 20.0))
    world(r, "clock", ticks(0.0, 1.0, 50.0), ticks(2.0, 6.0, 50.0), ticks(9.0, 1.0, 50.0))
    r.goal(1.0)  # 1 s silent during the scenario's setup and our judge's start,
    r.ack(1.0, 2.0)  # before Nav2's answer,
    r.end(7.99)  # and 1 s after the run's end
    assert r.span() == (2.0, 7.99) and r.acks == [1.0]
    assert starved(r) is None and summary(r)["timing.clock_max_gap_s"] == pytest.approx(0.02)
    r.ack(0.1, 5.0)
    r.goal(4.0)
    assert r.span() == (2.0, 7.99), "a goal sent and answered again does not move the run's start"
    r.answered_at = 1.5  # a stall Nav2's answer came in: its part after the answer counts
    assert "/clock was silent for 0.50 s" in starved(r)
    r.answered_at, r.ended_at = 2.0, 8.5  # ... as does the part before the run's end of one closed after it
    assert "/clock was silent for 0.52 s" in starved(r)
    r.answered_at = None  # never answered: from our goal
    assert r.span() == (1.0, 8.5) and "/clock was silent for 1.00 s" in starved(r)
    late = world(record(ticks(0.0, 10.0, 20.0)), "scan", ticks(5.0, 3.0, 10.0))
    late.goal(0.0)
    late.end(10.0)
    assert starved(late) is None, "before the first scan and after the last: not up yet, or the run over"
    early = world(record(), "clock", ticks(0.0, 1.0, 50.0))
    early.goal(2.0)
    assert "timing.clock_max_gap_s" not in summary(early) and starved(early) is None, "heard only before the run"
