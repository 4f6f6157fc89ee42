"""One scenario on its way through the adapter: what it is, where it stands, what its run has said."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any


@dataclass
class Job:
    """``judge`` is the run's oracle (``ambiegen_ros.sims.oracles``: RobotJudge, CarJudge,
    ThermostatJudge), made by the adapter's judge when the scenario is set up."""

    run_id: str
    scenario_id: int
    scenario: Any
    msg: Any
    reason: str | None = None
    valid: bool = True
    judge: Any = None
    phase: str = "queued"  # queued -> connecting -> settle -> waiting -> running
    started: float = 0.0  # monotonic, job start
    go: float = 0.0  # monotonic, when the run was started on the system under test
    anchor: float | None = None  # monotonic arrival of sample 0 (= simulated time 0)
    settle_until: float = 0.0
    last_sample: float = 0.0
    first: tuple[int, int] | None = None  # (stamp ns, receive ns) of sample 0
    t_prev: float = -math.inf
    limit_sim: float = 0.0  # simulated seconds the oracle needs at most
    schedule: list[tuple[float, float, int]] = field(default_factory=list)  # (start s, set point, model)
    next_element: int = 0
    start_pose: tuple[float, float, float] = (0.0, 0.0, 0.0)
    nav2_first_abort: str = ""  # Nav2 refused the first goal at once: what it said (the goal went again)
    nav2_refused_ns: int = 0  # the node's ROS time (sim time under /clock) of that refusal
    nav2_resend_wait_s: float | None = None  # ROS-clock s from that refusal to the goal's going again
    contacts_not_at_fault: int = 0  # people who walked into the robot (the world's WARNs): recorded, not failures
    before: Any = None  # the reference's static check (passed), the word on a failure without a reference run
    grace_until: float | None = None  # monotonic: Nav2 failed; a crash reported by then explains it
    taken_down: str = ""  # a Nav2 lifecycle node left the active state during the run: what happened
    goal_sends: int = 0  # topic goals: how often the goal went out (more than once: the stack showed no sign of it)
    goal_sent: float = 0.0  # monotonic: when it last went out
    heard: dict = field(default_factory=dict)  # status stream -> messages received since the goal went out

    @property
    def nav2_resend_due(self) -> bool:
        """Nav2 refused the first goal and it has not gone again yet."""
        return bool(self.nav2_first_abort) and self.nav2_resend_wait_s is None
