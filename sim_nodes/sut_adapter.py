"""`sut_adapter`: an existing ROS stack as the system under test, judged by our oracles.

To the generator it is one more sim worker (heartbeats on ``/ambiegen/workers``, scenarios from
``/ambiegen/<problem>/scenarios``, one ``ambiegen_msgs/ScenarioResult`` per scenario on
``/ambiegen/results``). To the system under test it is a user with standard topics. One scenario
runs at a time; others queue (the heartbeat reports how many).

Where each rule lives (``sim_nodes/adapter/``; the verdict tables: docs/external_sut.md):

* the node, its queue, stamp order, watchdogs (``start_timeout``, ``silence_timeout``,
  ``wall_slack``), stack events (``stack_events_topic``: the stack's crash = FAIL(sut_crashed), ours
  = an error record) and the result: ``node``;
* a robot on its topics (map, start, goal, odometry, collision and stall streams by stamp, plans):
  ``robot_topic``; a robot through Nav2's ``navigate_to_pose`` (Nav2's own outcome is the verdict,
  its lifecycle, crash grace): ``robot_nav2``; the rules that read Nav2's answer
  (``ours_error_codes``, ``goal_time_budget``, near misses, a goal refused at once): ``nav2_rules``;
* the vehicle (the road out, odometry in): ``vehicle``; the thermostat (set points on their
  schedule, temperatures in): ``thermostat``;
* how sample times are read (``stamp_clock`` sim | wall | receive) and ``odom_frame:=start``:
  ``samples``; the reference's certificate (a failure counts only when the problem's reference
  passes the same scenario): ``ambiegen_ros.sims.reference``; known failures:
  ``ambiegen_ros.sims.known_failures``.

The problem (validity, the scenario's environment) follows ``config_file`` and ``profile``
(``replication`` | ``refined``; '' = the file's, else ``replication``), like the sim workers
(``sim_nodes.worker``, which also declares ``worker_id`` and the heartbeat's parameters); a run with
another profile gets ``ERROR`` results instead of executions. Everything happens in callbacks and
timers; nothing blocks the executor.
"""
from __future__ import annotations

import sys

from ambiegen_ros.nodes import run_node
from sim_nodes.adapter.job import Job
from sim_nodes.adapter.nav2_rules import NAV2_NOT_READY_S, budget_spent, nav2_answer, near_miss, ours_not_the_stack
from sim_nodes.adapter.node import ODOM_FRAMES, STAMP_CLOCKS, SutAdapter, help_doc
from sim_nodes.adapter.registry import GOAL_MODES
from sim_nodes.adapter.samples import sample_times, to_map_frame

__all__ = ["GOAL_MODES", "Job", "NAV2_NOT_READY_S", "ODOM_FRAMES", "STAMP_CLOCKS", "SutAdapter", "budget_spent",
           "main", "nav2_answer", "near_miss", "ours_not_the_stack", "sample_times", "to_map_frame"]


def main(argv: list[str] | None = None) -> int:
    return run_node("sut_adapter", lambda: SutAdapter(argv), lambda a: a.endpoint.stop(), doc=__doc__ + help_doc())


if __name__ == "__main__":
    sys.exit(main())
