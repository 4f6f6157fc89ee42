"""What every way of running a scenario on someone else's stack has in common (the judges' base).

A judge is one way of running a scenario: what it puts on the stack's topics, which samples it
reads and how they reach the oracle (``ambiegen_ros.sims.oracles``), and what it does while time
passes (send the goal, publish the next set point, take the stack's own result). The node
(``sim_nodes.adapter.node``) owns everything else: the queue, the graph checks, the stamp order,
the watchdogs and the result on ``/ambiegen/results``.

Its ways in: ``setup`` (the scenario, once the stack is on the graph), ``feed`` (samples released
in stamp order, as times and values) and ``step`` (a turn of the node: the clock, how far the
samples are judged). Its way out: the run's oracle, ``job.judge``, decided or not; ``step`` may
also tell the node to hold the turn or to end the run now. A judge reads its settings from its
own parameter table (``PARAMS``); a new way of running a scenario is a new subclass listed in
``sim_nodes.adapter.registry``, and touches no other judge.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any, Callable, ClassVar

from ambiegen_ros.ros import conversions

from .params import Param, Settings

HOLD = "hold"  # step: nothing more this turn (the stack's failure waits for a crash report, a goal is resent)
DECIDED = "decided"  # step: the oracle has its verdict from the stack, end the run now
SAMPLE_PHASES = ("settle", "waiting", "running")  # phases in which samples are read


@dataclass
class RunView:
    """What a judge's ``step`` may know of the node's turn: monotonic ``now``, the stamp order of
    samples and status streams (``ambiegen_ros.sims.stamp_order``), whether samples received are
    still unjudged, and ``crash_grace()``: True while a failure of the stack's must wait for a
    crash report that may explain it."""

    now: float
    order: Any
    unjudged: bool
    crash_grace: Callable[[], bool]


class ScenarioJudge:
    """One way of running a scenario; subclasses say which problem (and robot ``goal_mode``) it serves."""

    problem: ClassVar[str] = ""
    goal_mode: ClassVar[str] = ""  # robot: the goal_mode that selects it ('' = any)
    PARAMS: ClassVar[tuple[Param, ...]] = ()
    ORACLE_FIELDS: ClassVar[tuple[str, ...]] = ()  # oracle.<field> parameters of the problem's oracle
    STREAMS: ClassVar[tuple[tuple[str, str], ...]] = ()  # (topic key, STATE | DECISION): status streams by stamp
    SAMPLE_KEY: ClassVar[str] = "odom"  # the topic key of the samples
    SAMPLE_TYPE: ClassVar[str] = "nav_msgs/msg/Odometry"
    samples_are: ClassVar[str] = "odometry"  # in error details: "no odometry within 10 s"
    certifies_itself: ClassVar[bool] = False  # True: its failures carry their own certificate, not the problem's reference

    def __init__(self, node: Any, settings: Settings, oracle: Any, problem: Any):
        self.node, self.settings, self.oracle, self.problem = node, settings, oracle, problem
        self.topics: dict[str, str] = {}
        self.nav2 = None  # a Nav2 action client, for the judges that drive Nav2
        self._job: Callable[[], Any] = lambda: None

    @property
    def sample_topic(self) -> str:
        return self.topics[self.SAMPLE_KEY]

    def wire(self, host: Any) -> None:
        """Create the publishers and subscriptions; ``host`` is the node (``on_sample``, ``sample_qos``, ``job``)."""
        self._job = lambda: host.job
        self.node.create_subscription(self.SAMPLE_TYPE, self.sample_topic, host.on_sample, host.sample_qos)

    def needs_subscribers(self) -> list[Any]:
        """Publishers someone of the stack must subscribe to before a scenario starts."""
        return []

    def missing(self) -> list[str]:
        """What else the stack has not shown yet (beyond subscribers and the sample publisher)."""
        return []

    def with_timing(self, outcome: Any) -> Any:
        """The run's timing record in its result (a judge that keeps one: ``robot_nav2``); as it is here."""
        return outcome

    def begin(self, job: Any) -> None:
        """A new scenario is taken: forget the last one's state."""

    def setup(self, job: Any, now: float) -> None:
        """Put the scenario on the stack's topics and make the run's oracle (``job.judge``)."""
        raise NotImplementedError

    def sample_of(self, msg: Any) -> tuple:
        """(stamp ns, receive ns, x, y, yaw, v) of an odometry message; raises on non-finite values."""
        pose = msg.pose.pose
        o = pose.orientation
        conversions.require_finite((pose.position.x, pose.position.y, o.x, o.y, o.z, o.w, msg.twist.twist.linear.x),
                                   "odometry pose / twist")  # raises: the sample is dropped and counted
        return (conversions.stamp_ns(msg.header), time.monotonic_ns(), float(pose.position.x),
                float(pose.position.y), conversions.yaw_of(pose.orientation), float(msg.twist.twist.linear.x))

    def at_start(self, sample: tuple | None, job: Any) -> bool:
        """Is this sample the system at the scenario's start? Every sample of a road or a room is."""
        return sample is not None

    def send_goal(self, job: Any) -> None:
        """Start the run on a stack that waits for a goal (robot judges)."""

    def feed(self, job: Any, t: Any, values: Any, events: list[dict]) -> None:
        """Samples released in stamp order: simulated times, their values (columns after the stamps)
        and each one's status events; they go to ``job.judge``."""
        raise NotImplementedError

    def step(self, job: Any, view: RunView) -> str | None:
        """A turn of the node after the samples are judged: None, HOLD or DECIDED."""
        return None
