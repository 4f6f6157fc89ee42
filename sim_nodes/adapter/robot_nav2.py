"""A robot stack driven through Nav2's ``navigate_to_pose`` action (``goal_mode:=action``).

Everything of ``sim_nodes.adapter.robot_topic`` (map, start, samples, stamp order), except that
the goal is Nav2's action (``sim_nodes.nav2_client``; on the DDS backend its services speak
rmw_cyclonedds_cpp's wire format, so Nav2 must run on rmw_cyclonedds_cpp there):

* **Ready.** A scenario starts once the action server is up and every node of
  ``nav2_lifecycle_nodes`` is active; each new map clears both costmaps (``nav2_clear_costmaps``).
  A bringup that gave up (its lifecycle manager stops at the first node that fails to activate) is
  started again when ``nav2_lifecycle_manager`` names the manager (at most ``nav2_restarts``, after
  ``nav2_restart_after`` s).
* **Nav2's own outcome is the verdict** (``early_verdicts:=false``, the default in this mode), so
  its recoveries get their turn: succeeded = PASS (a near miss after recoveries); aborted or
  rejected = FAIL(nav2_aborted, with its error code and message); a collision in the world =
  FAIL(collision); no result by the time limit = FAIL(timeout). Nav2's result carries no stamp: it
  counts at the newest pose received before it, once every sample up to there is judged (an
  earlier verdict from them stands). The paper's monitors still watch and are recorded
  (``early_verdict``); with ``early_verdicts:=true`` they decide and a goal still running is cancelled.
* **A failure of Nav2's waits** ``crash_grace`` s for a crash report when someone publishes them on
  ``stack_events_topic`` (a server killed mid-run makes Nav2 abort before the report arrives).
* **A node leaving the active state** during a run (its manager takes the stack down when a bond
  lapses) ends the run as an ``error`` record, unless a crash report explains it within
  ``crash_grace``; the next scenario waits until the nodes are active again (the node's
  ``on_nav2_left_active``).
* **Its timing is on record** (``sim_nodes.adapter.timing_watch``): /rosout and /cmd_vel_nav, and
  how long Nav2 took to answer our goal; a starved run is an error record (``with_timing``).
* The rules for Nav2's answer (ours_error_codes, goal_time_budget, near misses, the refused first
  goal): ``sim_nodes.adapter.nav2_rules``.
"""
from __future__ import annotations

from typing import Any

from ambiegen_ros.ros.qos import DEFAULT

from .judge import DECIDED, HOLD, RunView
from .nav2_rules import NAV2_NOT_READY_S, nav2_answer, near_miss, parse_codes, starved_not_failed
from .params import Param
from .robot_topic import ROBOT_PARAMS, TopicRobot
from .timing_watch import TIMING_PARAMS, TimingWatch

NAV2_PARAMS = (
    Param("action_name", str, "navigate_to_pose", "Nav2 action for goal_mode action"),
    Param("goal_time_budget", float, 0.0, "robot, goal_mode action: the stack's own time limit per goal [simulated s] "
                                          "(a behaviour tree's Timeout; the Nav2 launch reads it from the tree). An "
                                          "abort at that limit is a failure only when the reference reaches the goal "
                                          "within it too (0 = none)"),
    Param("ours_error_codes", str, "", "goal_mode action: Nav2 error codes that say our side failed the stack, comma "
                                       "separated: an abort with one is an error record, run again, not the stack's "
                                       "failure (the Nav2 launch passes 102,107,202: a transform of our world's too "
                                       "old, its data late to the controller's costmap; '' = none)",
          parse=parse_codes, parse_text="comma separated integers"),
    Param("nav2_lifecycle_nodes", str, "planner_server,controller_server,bt_navigator",
          "goal_mode action: Nav2 nodes that must be active before a scenario starts"),
    Param("nav2_lifecycle_manager", str, "", "goal_mode action: Nav2's lifecycle manager (e.g. "
                                             "lifecycle_manager_navigation): when its bringup gave up (nodes inactive "
                                             "for nav2_restart_after s and it says it is not active), ask it to clean "
                                             "up and start again ('' = never; the Nav2 launch sets it for the stacks "
                                             "it starts)"),
    Param("nav2_restarts", int, 3, "goal_mode action: restarts of a failed bringup, at most"),
    Param("nav2_restart_after", float, 20.0, "goal_mode action: seconds lifecycle nodes stay inactive before the "
                                             "manager is asked"),
    Param("nav2_clear_costmaps", str, "/global_costmap/clear_entirely_global_costmap,"
                                      "/local_costmap/clear_entirely_local_costmap",
          "goal_mode action: costmap clearing services called with every new map ('' = none)"),
)


class Nav2Robot(TopicRobot):
    """A robot stack whose goal is Nav2's action; Nav2's result is the verdict unless ``early_verdicts``."""

    goal_mode = "action"
    PARAMS = ROBOT_PARAMS + NAV2_PARAMS + TIMING_PARAMS

    def __init__(self, node: Any, settings: Any, oracle: Any, problem: Any):
        super().__init__(node, settings, oracle, problem)
        self.nav2_stamp: int | None = None  # Nav2's result has no stamp: the newest sample's when it came
        self.timing: TimingWatch | None = None

    def wire(self, host: Any) -> None:
        super().wire(host)
        from sim_nodes.nav2_client import Nav2Client  # either backend: the DDS one speaks rmw_cyclonedds_cpp's

        s = self.settings
        self.nav2 = Nav2Client(self.node, s.action_name, s.nav2_lifecycle_nodes.split(","),
                               s.nav2_clear_costmaps.split(","), self.node.logger, manager=s.nav2_lifecycle_manager,
                               restarts=s.nav2_restarts, restart_after=s.nav2_restart_after)
        self.nav2.watch_transitions(DEFAULT, host.on_nav2_left_active)
        self.timing = TimingWatch(self.node, s)

    def needs_subscribers(self) -> list[Any]:
        return [self.pub_initialpose]

    def missing(self) -> list[str]:
        return self.nav2.missing()

    def begin(self, job: Any) -> None:
        super().begin(job)
        self.nav2_stamp = None
        if self.timing is not None:
            self.timing.begin()

    def prepare_stack(self) -> None:
        self.nav2.clear_costmaps()  # the last scenario's walls out of both costmaps

    def send_goal(self, job: Any) -> None:
        self.nav2.send(self.goal_message(job))
        if self.timing is not None:
            self.timing.goal_sent()

    def step(self, job: Any, view: RunView) -> str | None:
        """Nav2's result as the verdict, once the samples up to it are judged; a goal refused at once
        goes again; a failure of Nav2's waits for a crash report that may explain it."""
        r = self.nav2.result
        answered = self.nav2.handle is not None or r is not None
        if self.timing is not None and self.timing.sent is not None and answered:
            self.timing.answered()  # accepted or refused: the acknowledgement time, to a turn
        if job.nav2_resend_due:  # the refusal on record is not the verdict
            self._resend_when_the_world_ran_on(job)
            return None
        failed = r is not None and r["status"] != "succeeded"
        if failed and not job.nav2_first_abort and job.judge.elapsed < NAV2_NOT_READY_S:
            # Nav2 refused the goal before the robot could move: after a world reset its controller
            # may still see the robot where it was ("Resulting plan has 0 poses", 103). Once more, when
            # the world's clock has run NAV2_NOT_READY_S simulated seconds: sent again at once, the
            # goal met the same stale view 0.1 s later (docs/choices.md). A real failure repeats and
            # is the verdict (the first answer is recorded)
            job.nav2_first_abort = nav2_answer(r, job.judge.elapsed)
            job.nav2_refused_ns = self.node.now_ns()
            self.node.logger.warning(f"Nav2 {job.nav2_first_abort} at the start; sending the goal once more "
                                     f"when the world's clock has run {NAV2_NOT_READY_S:g} s")
            return HOLD
        if failed and view.crash_grace():
            return HOLD
        if r is not None and (failed or not self.settings.early_verdicts):
            # Nav2's result carries no stamp: it counts at the newest pose received before it, once
            # every sample up to there is judged (an earlier verdict from them stands)
            if self.nav2_stamp is None:
                self.nav2_stamp = view.order.newest if view.order.newest is not None else -1
            if view.order.watermark >= self.nav2_stamp and not view.unjudged:
                elapsed = job.judge.elapsed
                if failed:
                    job.judge.stack_result(False, "nav2_aborted", f"Nav2 {nav2_answer(r, elapsed)}")
                else:
                    job.judge.stack_result(True, "none", f"Nav2 reached the goal after {elapsed:.1f} s"
                                                         + near_miss(self.nav2.recoveries))
                return DECIDED
        return None

    def _resend_when_the_world_ran_on(self, job: Any) -> None:
        """The world's clock has run on, in the robot's odometry or in ROS time (a stack whose
        odometry starts with the goal): an event of the simulation, not a wall-clock wait."""
        waited_s = (self.node.now_ns() - job.nav2_refused_ns) / 1e9
        if job.judge.elapsed >= NAV2_NOT_READY_S or waited_s >= NAV2_NOT_READY_S:
            job.nav2_resend_wait_s = waited_s
            self.send_goal(job)

    def with_timing(self, outcome: Any) -> Any:
        """The run's timing figures in its result; a starved run becomes an error record
        (``nav2_rules.starved_not_failed``), whatever Nav2 answered."""
        if self.timing is None:
            return outcome
        figures, reason = self.timing.verdict()
        return starved_not_failed(outcome, figures, reason)
