"""The rules that read Nav2's own answer to a goal (pure; the verdict table: docs/external_sut.md).

* **Ours, not the stack's.** An abort with an error code in ``ours_error_codes`` (the Nav2 launch:
  107, the controller's costmap got no current data from our world in time; 102 and 202, a
  transform of our world's too old) is an ``error`` record, to be run again, with what Nav2 said
  kept in its detail and metrics (``ours_not_the_stack``).
* **The stack's own time per goal.** A give-up at ``goal_time_budget`` (a ``Timeout`` at the root
  of bt_navigator's tree, read by the launch), within 10 %, counts only when the reference reaches
  the goal within that time too (``budget_spent`` gives the reference that budget).
* **Near misses.** A PASS after Nav2's recoveries (its feedback's ``number_of_recoveries``:
  costmap clearings, spins, waits, back-ups) says so in its detail (``near_miss``).
* **A goal refused at once.** After a world reset Nav2's controller may still see the robot where
  it was: a refusal within ``NAV2_NOT_READY_S`` simulated seconds sends the goal once more
  (``sim_nodes.adapter.robot_nav2``; docs/choices.md); the first answer is recorded.
* **A starved stack is never a failure.** A run in which the stack did not get its computer
  (``ambiegen_ros.sims.timing.starved``: its controller's worst window under the threshold, a late
  acknowledgement, a lapsed bond) is an ``error`` record of the kind ``starved``
  (``metrics["error_kind"]``), run again, whatever Nav2 answered (``starved_not_failed``); every
  Nav2 run carries its figures (``timing.*``).
* **Nav2's word beside the verdict.** Every result of a Nav2 run carries ``nav2_status``,
  ``nav2_error_code``, ``nav2_error_msg``, ``nav2_first_abort``, ``nav2_resend_wait_s`` and
  ``nav2_recoveries`` (``with_stack_word``); a goal still running is cancelled.
"""
from __future__ import annotations

from typing import Any

from ambiegen_ros.sims import Outcome

NAV2_NOT_READY_S = 1.0  # simulated s judged: Nav2 refusing its goal sooner gets it once more


def near_miss(recoveries: int) -> str:
    """What a PASS detail adds when Nav2 got there only through its recovery branch."""
    return f" (a near miss: after {recoveries} recover{'y' if recoveries == 1 else 'ies'})" if recoveries else ""


def ours_not_the_stack(outcome: Outcome) -> Outcome:
    """A Nav2 abort whose error code says our side failed it (``ours_error_codes``): an error record,
    to be run again, with what Nav2 said kept in its detail and metrics."""
    code = outcome.metrics.get("nav2_error_code")
    return Outcome(objectives=dict(outcome.objectives), failed=False, failure_kind="error",
                   detail=f"{outcome.detail}: error {code} is ours (ours_error_codes), not the stack's failure; "
                          "run it again",
                   metrics={**outcome.metrics, "sut_failure_kind": outcome.failure_kind},
                   trajectory=outcome.trajectory, timeline=outcome.timeline, failure_point=outcome.failure_point)


def starved_not_failed(outcome: Outcome, figures: dict, reason: str | None) -> Outcome:
    """The run's timing figures in its metrics; a starved run (``reason``) as an error record of the
    kind ``starved``, whatever the verdict was (kept in ``sut_failure_kind``), run again. A crash of
    the stack's process stays what it is: it has its own rerun on a fresh stack."""
    metrics = {**outcome.metrics, **figures}
    if reason is None or outcome.failure_kind == "sut_crashed":
        outcome.metrics = metrics
        return outcome
    return Outcome(objectives={}, failed=False, failure_kind="error",
                   detail=f"starved: the stack did not get its computer ({reason}); the run said: {outcome.verdict} "
                          f"{outcome.detail}; run it again",
                   metrics={**metrics, "error_kind": "starved", "starved": reason,
                            "sut_failure_kind": metrics.get("sut_failure_kind", outcome.failure_kind)},
                   trajectory=outcome.trajectory, timeline=outcome.timeline, failure_point=outcome.failure_point)


def ours_or_the_stacks(outcome: Outcome, ours_error_codes: set[int]) -> Outcome:
    """``ours_not_the_stack`` for a Nav2 abort with one of ``ours_error_codes``; any other outcome as it is."""
    if outcome.failure_kind == "nav2_aborted" and outcome.metrics.get("nav2_error_code") in ours_error_codes:
        return ours_not_the_stack(outcome)
    return outcome


def budget_spent(kind: str, elapsed: float, budget: float) -> float | None:
    """The stack's own time per goal (``goal_time_budget``) when it gave up at it, within 10 % (the
    world's clock may lag the tree's wall clock on a loaded machine): the time the reference gets
    too. None otherwise."""
    if budget > 0 and kind == "nav2_aborted" and elapsed >= 0.9 * budget:
        return budget
    return None


def nav2_answer(result: dict, elapsed: float) -> str:
    """Nav2's result in words: '<status> its goal after <t> s (error <code>[: <message>])'."""
    message = f": {result['error_msg']}" if result["error_msg"] else ""
    return f"{result['status']} its goal after {elapsed:.1f} s (error {result['error_code']}{message})"


def parse_codes(text: Any) -> set[int]:
    """``ours_error_codes``: comma separated integers ('' = none); ValueError on anything else."""
    return {int(c) for c in str(text).replace(" ", "").split(",") if c}


def with_stack_word(outcome: Outcome, nav2: Any, job: Any) -> Outcome:
    """Nav2's own word recorded beside our verdict, and its goal cancelled (no Nav2: as it is)."""
    if nav2 is None:
        return outcome
    r = nav2.result or {"status": "running (cancelled: the oracle decided first)" if nav2.handle else "no goal",
                        "error_code": 0, "error_msg": ""}
    outcome.metrics = {**outcome.metrics, "nav2_status": r["status"], "nav2_error_code": r["error_code"],
                       "nav2_error_msg": r["error_msg"], "nav2_first_abort": job.nav2_first_abort,
                       "nav2_resend_wait_s": job.nav2_resend_wait_s, "nav2_recoveries": nav2.recoveries}
    nav2.cancel()
    return outcome
