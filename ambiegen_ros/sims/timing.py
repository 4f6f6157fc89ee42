"""Did the stack get its computer? A Nav2 run's timing record, from what Nav2 shows outside (pure).

A loaded machine (a shared CI runner, K stacks on one host) starves Nav2: its controller misses
cycles, its behaviour tree gives up on an acknowledgement that came late, its lifecycle manager
takes the stack down after a bond lapsed. Such a run says nothing about the stack's navigation, so
it is an error record of its own kind (``starved``), run again, never a failure (docs/choices.md,
"A starved stack is never a failure"; the thresholds in docs/external_sut.md's verdict table).

What the record is built from (every time in seconds of one clock: the watcher's receive clock,
monotonic wall time, because the controller keeps its rate by the wall clock: ``rclcpp::WallRate``
in navigation2 jazzy's ``controller_server.cpp``; at a real-time factor under 1 a healthy controller
runs more cycles per simulated second, and counting by the sim clock would hide a starved one):

* ``loop(t)``: one message on ``/cmd_vel_nav`` (the controller publishes once per control cycle
  while it follows a path: its output before the velocity smoother and collision monitor);
* ``log(t, name, text)``: one ``/rosout`` line; read are the controller's "Control loop missed its
  desired rate of ... Hz", the BT action nodes' "Timed out while waiting for action server to
  acknowledge goal request for <action>", the lifecycle manager's "Have not received a heartbeat
  from <node>." / "CRITICAL FAILURE: SERVER <node> IS DOWN after not receiving a heartbeat" (one
  lapse, however many of its lines), and the costmaps' stale-data lines (counted, no rule);
* ``goal(t)``, ``ack(seconds, t)``, ``end(t)``: our first goal went out, Nav2 first accepted or
  refused it (``seconds`` after the goal, the acknowledgement time), the run ended;
* ``arrival(stream, t)``: one message of a stream of the world the stack lives on, ``scan`` (the
  laser the costmaps read) and ``clock`` (the world's /clock). Their longest silence while Nav2
  drives (``timing.<stream>_max_gap_s``) is the age the newest scan reached before the next one
  came, and the world's longest stall.

The loop rate is read in windows of ``window_s`` (2 s: 40 cycles at 20 Hz, enough that one slow
cycle does not decide, short enough that a starved stretch the mean hides still shows), slid over
each stretch of following: arrivals split where ``/cmd_vel_nav`` fell silent longer than
``idle_gap_s`` (a recovery or the goal's end: the controller is idle, not slow) unless the
controller said it missed its rate during that silence (a stalled cycle, not an idle one).

The world's silence (``max_world_gap_s``) is the machine's doing too: our world stood still while
Nav2's controller kept its wall-clock rate, which no real robot's world does. It is read while Nav2
drives, from its first answer to our goal (else from the goal) to the run's end, and only the part
of a silence inside that span counts. Before the answer our own judge sets the run up: in a hazards
scenario its first sample plans the route, 0.2 s in which the adapter reads no message, and that
silence is ours, not the world's (the acknowledgement's rule watches that stretch). A gap before a
stream's first message or after its last one is no silence of a stream heard (it may not have been
up yet, or the run ended): a stream never heard, or heard once, has no figure and trips no rule. On
our receive clock a silence is the world's stall and our adapter's own wait for the CPU together:
either way the machine's.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field

MISSED = re.compile(r"Control loop missed its desired rate of ([0-9.]+) ?Hz")
LATE_ACK = re.compile(r"Timed out while waiting for action server to acknowledge goal request for (\S+)")
BOND = (re.compile(r"Have not received a heartbeat from (\S+?)\.?(?:\x1b|$|\s)"),
        re.compile(r"SERVER (\S+) IS DOWN after not receiving a heartbeat"))
STALE = ("Transform data too old", "out of map bounds", "extrapolation into the future",
         "Lookup would require extrapolation", "Costmap timed out waiting for update")
SAME_LAPSE_S = 1.0  # the manager's two lines of one lapse come together


@dataclass(frozen=True)
class Thresholds:
    """When a run is ``starved`` (defaults: docs/external_sut.md). ``max_ack_s``: our goal's
    acknowledgement, bt_navigator's own ``wait_for_service_timeout`` (1000 ms in jazzy's
    nav2_params.yaml); its tree's nodes wait ``default_server_timeout`` (20 ms), and each time they
    give up they say so on /rosout (``late_acks``).

    ``max_world_gap_s``, wall seconds (docs/results/nav2/load.md, random-8 at time scale 1): the
    longest silence our adapter heard was 0.17-0.22 s for /scan and 0.16-0.18 s for /clock on a quiet
    machine (3 runs), 0.49-0.74 s and 0.49-1.37 s beside two busy loops (6 runs); 0.35 s lies between,
    0.13-0.14 s from each. Those figures span the whole record, and most of them were our judge's
    start; while Nav2 drove, the recorder heard the world's scans at most 0.11 s apart quiet and
    0.20-0.57 s apart under load. The sample is small; a laser at 5 Hz or slower leaves little margin."""

    window_s: float = 2.0
    min_rate_share: float = 0.5  # worst window's loop rate under this share of controller_frequency
    max_missed_share: float = 0.5  # or this share of a window's cycles said missed
    idle_gap_s: float = 1.0  # /cmd_vel_nav silent longer, without a missed-rate line: not following
    max_ack_s: float = 1.0
    max_late_acks: int = 0  # any BT give-up on a late acknowledgement
    max_bond_lapses: int = 0  # any lapsed bond
    max_world_gap_s: float = 0.35  # the world's /scan or /clock silent longer while Nav2 drives (0: no rule)


@dataclass
class TimingRecord:
    """One run's timing events (``controller_hz``: the controller's ``controller_frequency``; a
    missed-rate line naming another rate wins: it is the stack's own word)."""

    controller_hz: float = 20.0
    loops: list[float] = field(default_factory=list)
    missed: list[float] = field(default_factory=list)
    late_acks: list[tuple[float, str]] = field(default_factory=list)
    lapses: list[tuple[float, str]] = field(default_factory=list)
    stale: int = 0
    acks: list[float] = field(default_factory=list)
    arrivals: dict[str, list[float]] = field(default_factory=dict)
    goal_at: float | None = None  # our first goal went out
    answered_at: float | None = None  # Nav2 first accepted or refused it
    ended_at: float | None = None  # the run ended

    def arrival(self, stream: str, t: float) -> None:
        self.arrivals.setdefault(stream, []).append(float(t))

    def goal(self, t: float) -> None:
        if self.goal_at is None:  # a goal sent again does not move the run's start
            self.goal_at = float(t)

    def end(self, t: float) -> None:
        self.ended_at = float(t)

    def span(self) -> tuple[float | None, float | None]:
        """While Nav2 drives: from its first answer (else our goal) to the end (None: open)."""
        return (self.answered_at if self.answered_at is not None else self.goal_at), self.ended_at

    def loop(self, t: float) -> None:
        self.loops.append(float(t))

    def ack(self, seconds: float, t: float | None = None) -> None:
        self.acks.append(float(seconds))
        if t is not None and self.answered_at is None:
            self.answered_at = float(t)

    def log(self, t: float, name: str, text: str) -> None:
        """One /rosout line (``name``: its logger) sorted into what it says, or ignored."""
        found = MISSED.search(text)
        if found:
            self.missed.append(float(t))
            self.controller_hz = float(found.group(1)) or self.controller_hz
            return
        found = LATE_ACK.search(text)
        if found:
            self.late_acks.append((float(t), found.group(1)))
            return
        for pattern in BOND:
            found = pattern.search(text)
            if found:
                node = found.group(1)
                if not any(n == node and abs(t - s) <= SAME_LAPSE_S for s, n in self.lapses):
                    self.lapses.append((float(t), node))
                return
        self.stale += any(s in text for s in STALE)


def stretches(loops: list[float], missed: list[float], hz: float, idle_gap_s: float) -> list[list[float]]:
    """Arrivals in order, split at silences longer than ``idle_gap_s`` that no missed-rate line
    explains (one within the silence or a cycle after it: the controller overran, it was not idle)."""
    out: list[list[float]] = []
    period = 1.0 / hz
    for t in sorted(loops):
        if out and t - out[-1][-1] > idle_gap_s and not any(out[-1][-1] < m <= t + 2 * period for m in missed):
            out.append([t])
        elif out:
            out[-1].append(t)
        else:
            out.append([t])
    return out


def worst_window_hz(loops: list[float], missed: list[float], hz: float, th: Thresholds) -> tuple[float | None, int]:
    """The lowest loop rate over windows of ``window_s`` wholly inside a stretch of following (None:
    no stretch as long as one window), and how many windows were read."""
    worst, windows = None, 0
    period = 1.0 / hz
    for run in stretches(loops, missed, hz, th.idle_gap_s):
        end = run[-1] + period  # the last cycle's own period is part of the stretch
        j = 0
        for i, start in enumerate(run):
            if start + th.window_s > end + 1e-9:
                break
            j = max(j, i)
            while j < len(run) and run[j] < start + th.window_s - 1e-9:
                j += 1
            rate = (j - i) / th.window_s
            windows += 1
            worst = rate if worst is None else min(worst, rate)
    return worst, windows


def worst_missed_share(missed: list[float], hz: float, window_s: float) -> float:
    """The largest share of a window's cycles (``hz * window_s``) the controller said it missed."""
    times = sorted(missed)
    most, j = 0, 0
    for i, start in enumerate(times):
        j = max(j, i)
        while j < len(times) and times[j] < start + window_s:
            j += 1
        most = max(most, j - i)
    return most / (hz * window_s)


def longest_gap(times: list[float], start: float | None = None, end: float | None = None) -> float | None:
    """The longest silence between two arrivals, only its part inside the run ``[start, end]``
    (None: no two arrivals around a moment of the run)."""
    lo = -float("inf") if start is None else start
    hi = float("inf") if end is None else end
    gaps = [min(b, hi) - max(a, lo) for a, b in zip(times, times[1:]) if b > lo and a < hi]
    return max(gaps) if gaps else None


def world_gaps(record: TimingRecord) -> dict[str, float]:
    """Each world stream's longest silence while Nav2 drove (streams without one left out)."""
    gaps = {s: longest_gap(t, *record.span()) for s, t in sorted(record.arrivals.items())}
    return {s: g for s, g in gaps.items() if g is not None}


def summary(record: TimingRecord, th: Thresholds = Thresholds()) -> dict[str, float]:
    """The record as flat numbers (the result's ``timing.*`` metrics; absent ones left out)."""
    hz = record.controller_hz
    worst, windows = worst_window_hz(record.loops, record.missed, hz, th)
    out: dict[str, float] = {"timing.controller_hz": hz, "timing.cmd_vel_msgs": len(record.loops),
                             "timing.loop_windows": windows, "timing.missed_loops": len(record.missed),
                             "timing.worst_missed_share": round(worst_missed_share(record.missed, hz, th.window_s), 4),
                             "timing.late_acks": len(record.late_acks), "timing.bond_lapses": len(record.lapses),
                             "timing.stale_data": record.stale, "timing.window_s": th.window_s}
    if worst is not None:
        out["timing.worst_window_hz"] = round(worst, 3)
    if record.acks:
        out["timing.ack_s"] = round(max(record.acks), 4)
    for stream, times in sorted(record.arrivals.items()):
        out[f"timing.{stream}_msgs"] = len(times)
    for stream, gap in world_gaps(record).items():
        out[f"timing.{stream}_max_gap_s"] = round(gap, 4)
    return out


def starved(record: TimingRecord, th: Thresholds = Thresholds()) -> str | None:
    """Why the stack did not get its computer during the run, in words (None: it did)."""
    hz = record.controller_hz
    worst, _ = worst_window_hz(record.loops, record.missed, hz, th)
    why = []
    if worst is not None and worst < th.min_rate_share * hz:
        why.append(f"its controller ran at {worst:.1f} Hz in its worst {th.window_s:g} s "
                   f"(under {th.min_rate_share:.0%} of {hz:g} Hz)")
    share = worst_missed_share(record.missed, hz, th.window_s)
    if share >= th.max_missed_share:
        why.append(f"its controller said it missed {share:.0%} of its cycles in {th.window_s:g} s")
    if len(record.late_acks) > th.max_late_acks:
        names = sorted({a for _, a in record.late_acks})
        why.append(f"its tree gave up {len(record.late_acks)} time(s) on a late acknowledgement ({', '.join(names)})")
    if record.acks and max(record.acks) > th.max_ack_s:
        why.append(f"it took {max(record.acks):.2f} s to acknowledge our goal (over {th.max_ack_s:g} s)")
    if len(record.lapses) > th.max_bond_lapses:
        why.append(f"its lifecycle manager lost the bond of {', '.join(sorted({n for _, n in record.lapses}))}")
    for stream, gap in world_gaps(record).items():
        if 0 < th.max_world_gap_s < gap:
            why.append(f"the world's /{stream} was silent for {gap:.2f} s (limit {th.max_world_gap_s:g} s)")
    return "; ".join(why) or None


__all__ = ["TimingRecord", "Thresholds", "longest_gap", "starved", "summary", "stretches", "world_gaps",
           "worst_window_hz", "worst_missed_share"]
