"""Trials: a suite of scenarios run N times on one or more configurations of a stack.

What a Nav2 engineer asks of a reported failure before anything else: does it reproduce, is it my
configuration, does the usual fix fix it? ``ambiegen rerun`` answers the first (each scenario N
times, k of N by kind), ``ambiegen compare`` the other two (every scenario on two or more params
files and behaviour trees: what each fixes, what remains, what breaks, at what cost).

* ``suite``: the scenarios (a suite file, or the failures of a campaign's log) and their problem;
* ``configs``: a configuration of the stack (params files merged in order, fixes on top);
* ``rows``: the results file (JSON lines, appended, resumable);
* ``tables``: k of N, Fisher's exact test, fixed / remaining / new, the cost of a fix (no ROS);
* ``runner``: the stack, started per configuration, and the scenarios sent one at a time.
"""
