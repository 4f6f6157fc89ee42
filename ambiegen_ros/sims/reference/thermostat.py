"""The thermostat's reference: an ideal controller on the same full-model room and schedule.

A failing schedule counts only if an ideal controller meets the requirement on it: full power
while the room is below the goal, off at or above it, decided every integration step, with no
sensor noise, no quantisation and no hysteresis (``sims.room.ideal_config``). If even it misses
the RMSE requirement, the schedule asks the impossible of the room (a rise faster than the heater
warms it, a drop faster than it cools with the heater off, a goal below the ambient): an invalid
test, not a failure of the thermostat. So is a schedule the ideal controller passes by less than
``reference_margin`` (0.1 degC, the sensor's resolution): a thermostat that loses a few hundredths
of a degree to an ideal one on a schedule the room can barely follow has not failed in any sense
a controls engineer accepts. The room obeys physics (``problems.thermostat_room``), so
heating never helps it cool: the ideal controller cannot pass by heating in order to cool.
"""
from __future__ import annotations

from typing import Any

from ..outcome import Outcome
from ..room import RoomSimConfig, heat, ideal_config, room_of, schedule_of
from . import ReferenceVerdict

CHECK = "ideal_controller"


def ideal_run(problem: Any, scenario: Any, config: RoomSimConfig) -> dict[str, Any]:
    """The ideal controller's record (``sims.room.heat``) on the schedule the system under test ran."""
    setpoints, durations, models = schedule_of(problem, scenario)
    return heat(setpoints, durations, models, room_of(problem), ideal_config(config))


def after(problem: Any, scenario: Any, config: RoomSimConfig, outcome: Outcome, seed: int) -> ReferenceVerdict:
    """Does an ideal controller meet the requirement, by at least ``reference_margin``, where the
    system under test failed? (No noise: ``seed`` does not matter.)"""
    run = ideal_run(problem, scenario, config)
    rmse, limit, margin = run["rmse"], config.requirement_rmse, config.reference_margin
    metrics = {"rmse": rmse, "max_error": run["max_error"]}
    if rmse > limit:
        shown = f"{rmse:.2f}" if round(rmse, 2) > limit else f"{rmse:.4f}"  # never "1.00 > 1"
        reason = (f"even an ideal controller misses the requirement: RMSE {shown} degC > {limit:g} degC "
                  f"(the schedule asks the impossible of the room)")
        return ReferenceVerdict(passed=False, check=CHECK, reason=reason, metrics=metrics)
    if rmse > limit - margin:
        reason = (f"an ideal controller passes by only {limit - rmse:.3f} degC (RMSE {rmse:.3f} degC, less than the "
                  f"{margin:g} degC reference_margin): the schedule leaves a real thermostat no room")
        return ReferenceVerdict(passed=False, check=CHECK, reason=reason, metrics=metrics)
    return ReferenceVerdict(passed=True, check=CHECK, metrics=metrics)


__all__ = ["after", "ideal_run"]
