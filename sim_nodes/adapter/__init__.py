"""The adapter that runs scenarios on someone else's ROS stack (``sim_nodes.sut_adapter``), in parts:

* ``node``: the ROS node and its plumbing (worker topics, queue, turns, watchdogs, the result);
* ``judge``: the base of the judges, one per way of running a scenario (``registry`` lists them):
  ``robot_topic`` (a robot on its topics), ``robot_nav2`` (a robot through Nav2's action),
  ``vehicle``, ``thermostat``;
* ``nav2_rules``: the rules that read Nav2's answer (ours_error_codes, goal_time_budget, near misses);
* ``params``: the typed parameter tables and their checks; ``job``: one scenario on its way;
  ``samples``: sample times and frames.
"""
