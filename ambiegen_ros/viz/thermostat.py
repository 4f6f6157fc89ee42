"""Plot a thermostat scenario: the goal schedule against the simulated room temperature.

Shows at a glance why a schedule scores a high RMSE (slow cooling after a drop, overshoot after a
rise) and when the heater was on.
"""
from __future__ import annotations

from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from ..problems.thermostat import Schedule  # noqa: E402


def _on_runs(heater: np.ndarray) -> list[tuple[int, int]]:
    """Half-open step ranges [start, stop) where the heater is ON."""
    padded = np.concatenate([[False], np.asarray(heater, dtype=bool), [False]])
    edges = np.flatnonzero(np.diff(padded.astype(np.int8)))
    return list(zip(edges[0::2].tolist(), edges[1::2].tolist()))


def plot_scenario(problem: Any, scenario: Any, ax=None, title: str | None = None):
    """Draw one schedule (a ``Scenario``, a scenario dict or a ready ``Schedule``); return the Figure.

    Goal as steps, simulated temperature as a line starting at minute 0, heater-ON periods
    shaded, RMSE (and the broken rule, if invalid) in the title. Time axis in hours.
    """
    schedule = scenario if isinstance(scenario, Schedule) else problem.environment(scenario)
    if ax is None:
        fig, ax = plt.subplots(figsize=(9, 3.6), layout="constrained")
    else:
        fig = ax.figure
    step_h = schedule.step_minutes / 60.0

    for start, stop in _on_runs(schedule.heater):
        ax.axvspan(start * step_h, stop * step_h, color="tab:orange", alpha=0.15, linewidth=0)

    ends = np.cumsum(schedule.durations) / 60.0
    bounds = np.concatenate([[0.0], ends])
    goals = list(schedule.setpoints) + list(schedule.setpoints[-1:])
    ax.step(bounds, goals, where="post", color="tab:blue", linewidth=1.8, label="goal (schedule)")

    times = np.concatenate([[0.0], np.asarray(schedule.minutes, dtype=float) / 60.0])
    temps = np.concatenate([[schedule.initial_temperature], schedule.temperature])
    ax.plot(times, temps, color="tab:red", linewidth=1.2, label="room temperature")
    ax.fill_between([], [], color="tab:orange", alpha=0.15, label="heater on")  # legend entry only

    for x, model in zip(bounds[:-1], schedule.models):
        ax.annotate(f"m{model}", (x, 1.0), xycoords=("data", "axes fraction"), xytext=(2, -10),
                    textcoords="offset points", fontsize=7, color="0.35")

    ax.set_xlim(0.0, max(bounds[-1], times[-1]))
    ax.set_xlabel("time [h]")
    ax.set_ylabel("temperature [degC]")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="lower right", fontsize=8, framealpha=0.8)

    head = title or "Thermostat schedule"
    text = f"{head}: RMSE {schedule.rmse:.2f} degC"
    if not schedule.valid:
        text += f" (invalid: {schedule.reason})"
    ax.set_title(text, fontsize=10)
    return fig


__all__ = ["plot_scenario"]
