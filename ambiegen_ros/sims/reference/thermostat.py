"""The thermostat's reference: an ideal controller on the same full-model room and schedule.

A failing schedule counts only if an ideal controller meets the requirement on it: full power
while the room is below the goal, off at or above it, decided every integration step, with no
sensor noise, no quantisation and no hysteresis (``sims.room.ideal_config``). If even it misses
the RMSE requirement, the schedule asks the impossible of the room (a jump no heater makes in
time, a drop faster than the room cools): an invalid test, not a failure of the thermostat.
"""
from __future__ import annotations

from typing import Any

from ..outcome import Outcome
from ..room import RoomSimConfig, heat, ideal_config, schedule_of
from . import ReferenceVerdict

CHECK = "ideal_controller"


def ideal_run(problem: Any, scenario: Any, config: RoomSimConfig) -> dict[str, Any]:
    """The ideal controller's record (``sims.room.heat``) on the schedule the system under test ran."""
    setpoints, durations, models = schedule_of(problem, scenario)
    return heat(setpoints, durations, models, problem.config.room_models, ideal_config(config))


def after(problem: Any, scenario: Any, config: RoomSimConfig, outcome: Outcome, seed: int) -> ReferenceVerdict:
    """Does an ideal controller meet the requirement where the system under test failed? (No noise:
    ``seed`` does not matter.)"""
    run = ideal_run(problem, scenario, config)
    rmse, limit = run["rmse"], config.requirement_rmse
    metrics = {"rmse": rmse, "max_error": run["max_error"]}
    if rmse > limit:
        shown = f"{rmse:.2f}" if round(rmse, 2) > limit else f"{rmse:.4f}"  # never "1.00 > 1"
        reason = (f"even an ideal controller misses the requirement: RMSE {shown} degC > {limit:g} degC "
                  f"(the schedule asks the impossible of the room)")
        return ReferenceVerdict(passed=False, check=CHECK, reason=reason, metrics=metrics)
    return ReferenceVerdict(passed=True, check=CHECK, metrics=metrics)


__all__ = ["after", "ideal_run"]
