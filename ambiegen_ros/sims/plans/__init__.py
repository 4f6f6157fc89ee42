"""Nav2's global planners and smoothers under search: costmaps, rules, oracles, a reference planner.

ROS-free (floor 1): the scenario's map becomes the costmap Nav2 would build (``costmap``), each
planner's promises are ``rules.PlannerRules``, the oracles judge a returned path or an error on
that costmap (``oracles.judge_plan``), and ``reference`` finds the certificate path, or proves
there is none, that makes a planner's failure a finding. docs/planner_oracles.md says why each
rule is the one it is, with navigation2's (jazzy) source for each.
"""
