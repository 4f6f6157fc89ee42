"""What the runner does after each run: count it, run it again, or stop (no ROS, no process).

The policy, from the run's row, its deaths, the restarts they called for and the ``extra`` it ran
with (``Reruns.after``):

* a row with a verdict of the stack (``rows.counted``) counts for its scenario and ends a streak
  of errors; the search learns its verdict unless it was a crash's rerun (asked once, not twice);
* a crash of the stack (``sut_crashed``) runs once more, first, on the fresh stack the session
  started, marked ``crash_rerun_of``: does the crash come back? A crash's rerun that crashes again
  is filed, not run a third time;
* an error during which a part of ours died runs again, first, with the same ``extra``, once the
  part is back; it is no error in a row when every restart of ours came back (a dead part is not
  the kind of error that repeats);
* an error during which a part of the stack died (before the run began, as the adapter says: the
  run had no verdict) runs again too, on the restarted stack, and counts in the streak;
* an error that runs no more is told to the search as an error (a search must not wait for a
  verdict that will not come: its batch would end it);
* a starved run (an error record whose ``metrics.error_kind`` is ``starved``: the stack did not get
  its computer, ``ambiegen_ros.sims.timing``) runs again, first, with the same ``extra``: it is no
  verdict, whatever Nav2 answered. It counts in the streak all the same: a machine that starves the
  stack run after run does not hold it, and ``max_errors`` starved runs in a row stop the
  configuration saying so (rather than rerunning for ever on a machine that cannot run it);
* any other error counts in the streak, and ``max_errors`` in a row stop the configuration with
  one line naming the last error and the logs.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Sequence

from .rows import counted

STARVED = "starved"  # an error record's kind (``metrics.error_kind``): the stack did not get its computer


def starved(row: dict) -> bool:
    """Is this row a starved run (an error record of the kind ``starved``)?"""
    return row.get("failure_kind") == "error" and (row.get("metrics") or {}).get("error_kind") == STARVED


@dataclass(frozen=True)
class Step:
    """What to do after one run."""

    count: bool  # the row is a run of the stack: its scenario has one more
    tell: bool  # the search learns the verdict (``Feed.took``)
    errors: int  # errors of ours in a row, this run included
    again: dict | None = None  # the same scenario runs next, with this ``extra`` (None: it does not)
    stop: str | None = None  # the configuration stops, saying this (None: the runs go on)


@dataclass(frozen=True)
class Reruns:
    """The rerun policy of one configuration (``label``, its node logs in ``logs``)."""

    max_errors: int
    label: str
    logs: str

    def after(self, row: dict, deaths: Sequence[Any], restarts: Sequence[dict], extra: dict, errors: int) -> Step:
        """``row``: the run as filed (``failure_kind``, ``detail``, ``run_id``, ``scenario_id``);
        ``deaths``: what died or hung during it (``.part``: stack | ours); ``restarts``: the records of
        what the session restarted for them (``ok``); ``errors``: errors in a row before it."""
        ours = any(d.part == "ours" for d in deaths)
        rerun = "crash_rerun_of" in extra
        if counted(row):
            step = Step(count=True, tell=not rerun, errors=0)
        else:  # an error a restart of ours explains is not the kind that repeats (a starvation may)
            explained = ours and all(r["ok"] for r in restarts) and not starved(row)
            step = Step(count=False, tell=False, errors=errors if explained else errors + 1)
        again = None
        if row.get("failure_kind") == "sut_crashed" and not rerun:  # once more on the fresh stack
            again = {"crash_rerun_of": {"run_id": row.get("run_id"), "scenario_id": row.get("scenario_id"),
                                        "detail": row.get("detail")}}
        elif not step.count and (deaths or starved(row)):  # the same run again (on the parts restarted)
            again = dict(extra)
        stop = None
        if step.errors >= self.max_errors and starved(row):
            why = str((row.get("metrics") or {}).get("starved") or "")[:200]
            stop = (f"[{self.label}] {step.errors} errors in a row, the last a starved run: this machine does not give "
                    f"the stack its computer ({why}; timing.* in the rows, logs: {self.logs}); run fewer stacks on "
                    "it, then rerun the same command to resume")
        elif step.errors >= self.max_errors:
            stop = (f"[{self.label}] {step.errors} errors in a row, the last: {str(row.get('detail') or '')[:200]} "
                    f"(logs: {self.logs}); rerun the same command to resume")
        told = step.tell or (not step.count and again is None and not rerun)  # an error with no run to follow
        return Step(step.count, told, step.errors, again, stop)


__all__ = ["Reruns", "STARVED", "Step", "starved"]
