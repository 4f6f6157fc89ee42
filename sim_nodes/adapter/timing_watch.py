"""Watch a Nav2 run's timing from outside: /rosout, /cmd_vel_nav, /scan and /clock into a ``TimingRecord``.

The record and its rule are ``ambiegen_ros.sims.timing`` (pure); this only feeds them, on the
adapter's node (either backend): every /rosout line (``rcl_interfaces/msg/Log``), every message on
the controller's own output (``/cmd_vel_nav``, remapped so by nav2_bringup's navigation_launch.py),
the arrivals of the laser scans and the world's clock (best effort, as any writer matches), and the
acknowledgement time of our goal, each at its arrival on the monotonic clock. A run's record starts
with its scenario (``begin``), Nav2 drives from its first answer to our goal (``goal_sent``,
``answered``), and the record is read and closed when the run ends (``verdict``): a starved run
becomes an error record of its own kind (``nav2_rules.starved_not_failed``).

The world's silence limit (``starved_world_gap_s``) was measured at ``time_scale`` 1. Under 1 the
world's messages come 1/k times as far apart in wall time (its 10 Hz scans 0.4 s apart at 0.25),
so the limit stretches with them (divided by k); above 1 it stays as it is, since what it must
clear (the machine's scheduling, our adapter's own work) is wall time, not simulated time.
"""
from __future__ import annotations

import time
from typing import Any

from ambiegen_ros.ros.qos import Qos
from ambiegen_ros.sims import timing

from .params import Param

# rcl's /rosout publishers: reliable, transient local, depth 1000; a volatile reader matches them
# and takes only what is said from now on (a run's lines, not the last ten seconds' history)
ROSOUT_QOS = Qos(reliable=True, transient_local=False, depth=1000)
# the controller's publisher is reliable (the system default); best effort matches any writer
CMD_VEL_QOS = Qos(reliable=False, transient_local=False, depth=50)
STREAMS = {"scan": "sensor_msgs/msg/LaserScan", "clock": "rosgraph_msgs/msg/Clock"}  # timing.<name>_max_gap_s

TIMING_PARAMS = (
    Param("timing_rosout_topic", str, "/rosout", "goal_mode action: the stack's log lines (rcl_interfaces/msg/Log) "
                                                 "read for its timing: missed control loops, late acknowledgements, "
                                                 "lapsed bonds ('' = off)"),
    Param("timing_cmd_vel_topic", str, "/cmd_vel_nav", "goal_mode action: the controller's own output, one message "
                                                       "per control cycle: its loop rate ('' = off)"),
    Param("timing_cmd_vel_type", str, "geometry_msgs/msg/Twist",
          "goal_mode action: its type (Twist; TwistStamped when Nav2 runs with enable_stamped_cmd_vel)",
          allowed=("geometry_msgs/msg/Twist", "geometry_msgs/msg/TwistStamped")),
    Param("timing_scan_topic", str, "/scan", "goal_mode action: the laser the costmaps read (LaserScan); its "
                                             "longest silence while Nav2 drives, timing.scan_max_gap_s, under "
                                             "starved_world_gap_s ('' = off)"),
    Param("timing_clock_topic", str, "/clock", "goal_mode action: the world's clock; its longest stall while Nav2 "
                                               "drives, timing.clock_max_gap_s, under starved_world_gap_s ('' = off)"),
    Param("controller_frequency", float, 20.0, "goal_mode action: Nav2's controller_frequency [Hz] (a missed-rate "
                                               "line naming another wins)", minimum=0, above=True),
    Param("starved_window_s", float, timing.Thresholds.window_s, "goal_mode action: wall seconds per window of the "
                                                                 "loop rate", minimum=0, above=True),
    Param("starved_rate_share", float, timing.Thresholds.min_rate_share,
          "goal_mode action: a run whose worst window ran under this share of controller_frequency, or said this "
          "share of its cycles missed, is starved: an error record, run again, never a failure", minimum=0),
    Param("starved_ack_s", float, timing.Thresholds.max_ack_s, "goal_mode action: a goal Nav2 took longer to "
                                                               "acknowledge starves the run [s]", minimum=0),
    Param("starved_world_gap_s", float, timing.Thresholds.max_world_gap_s,
          "goal_mode action: the world's scans or clock (timing_scan_topic, timing_clock_topic) silent longer than "
          "this while Nav2 drives (from its answer to our goal to the run's end) starve the run: our world stood "
          "still while Nav2 kept its wall-clock rate [wall s; divided by time_scale under 1] (0 = off)", minimum=0),
)


def thresholds(settings: Any) -> timing.Thresholds:
    return timing.Thresholds(window_s=settings.starved_window_s, min_rate_share=settings.starved_rate_share,
                             max_missed_share=settings.starved_rate_share, max_ack_s=settings.starved_ack_s,
                             max_world_gap_s=settings.starved_world_gap_s / min(1.0, settings.time_scale))


class TimingWatch:
    """One run's timing record at a time, fed by the node's subscriptions."""

    def __init__(self, node: Any, settings: Any):
        self.hz, self.thresholds = settings.controller_frequency, thresholds(settings)
        self.record: timing.TimingRecord | None = None
        self.sent: float | None = None
        if settings.timing_rosout_topic:
            node.create_subscription("rcl_interfaces/msg/Log", settings.timing_rosout_topic, self.on_log, ROSOUT_QOS)
        if settings.timing_cmd_vel_topic:
            node.create_subscription(settings.timing_cmd_vel_type, settings.timing_cmd_vel_topic, self.on_cmd_vel,
                                     CMD_VEL_QOS)
        for stream, msg_type in STREAMS.items():
            topic = getattr(settings, f"timing_{stream}_topic")
            if topic:
                node.create_subscription(msg_type, topic, lambda _msg, name=stream: self.on_arrival(name), CMD_VEL_QOS)

    def begin(self) -> None:
        """A new run: a record of its own."""
        self.record, self.sent = timing.TimingRecord(controller_hz=self.hz), None

    def on_log(self, msg: Any) -> None:
        if self.record is not None:
            self.record.log(time.monotonic(), str(msg.name), str(msg.msg))

    def on_cmd_vel(self, _msg: Any) -> None:
        if self.record is not None:
            self.record.loop(time.monotonic())

    def on_arrival(self, stream: str) -> None:
        if self.record is not None:
            self.record.arrival(stream, time.monotonic())

    def goal_sent(self) -> None:
        self.sent = time.monotonic()
        if self.record is not None:
            self.record.goal(self.sent)

    def answered(self) -> None:
        """Nav2 accepted or refused the goal sent last: its acknowledgement time is on record."""
        if self.record is not None and self.sent is not None:
            now = time.monotonic()
            self.record.ack(now - self.sent, now)
        self.sent = None

    def verdict(self) -> tuple[dict[str, float], str | None]:
        """The run's figures (``timing.*``) and why it was starved (None: it was not); the record ends
        here, and what comes until the next run's ``begin`` is kept by no record."""
        if self.record is None:
            return {}, None
        record, self.record = self.record, None
        record.end(time.monotonic())
        return timing.summary(record, self.thresholds), timing.starved(record, self.thresholds)
