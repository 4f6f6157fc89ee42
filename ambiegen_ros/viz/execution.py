"""Picture of one full-model execution: the scenario, what the system did, and where it failed.

robot: walls, the A* route's waypoints, the driven trajectory (coloured by time) and the failure
point; vehicle: the road's two lanes, the car's path and the failure point; thermostat: the
schedule, the true and the measured room temperature, heater-on periods, the ideal controller's
run (the reference) and the worst error.
"""
from __future__ import annotations

import textwrap
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def _title(problem: Any, outcome: Any, system: str = "full model", width: int = 130) -> str:
    """The verdict, and its detail wrapped at ``width`` characters (what the axes hold)."""
    if outcome.failure_kind == "invalid_scenario":
        return f"{problem.name}: not executed ({outcome.detail})"
    if outcome.failure_kind == "invalid_test":
        return f"{problem.name}: INVALID TEST, not a failure\n" + textwrap.fill(outcome.detail, width, max_lines=3)
    verdict = f"FAILED: {outcome.failure_kind}" if outcome.failed else "passed"
    return f"{problem.name} {system} {verdict}\n" + textwrap.fill(outcome.detail, width, max_lines=3)


def _mark_failure(ax, outcome: Any) -> None:
    if outcome.failure_point is not None:
        x, y = outcome.failure_point
        ax.plot([x], [y], "X", color="red", ms=14, mec="black", zorder=6, label=f"failure ({outcome.failure_kind})")


def _robot(problem, scenario, outcome, ax) -> None:
    from ..sims.robot import RobotSimConfig, plan_route
    from .robot import draw_hazards

    env = problem.environment(scenario)
    res = env.resolution
    h, w = env.grid.shape
    ax.imshow(env.grid.astype(float), cmap="Greys", vmin=0, vmax=1, origin="lower",
              extent=(0, w * res, 0, h * res), interpolation="nearest")
    metrics = outcome.metrics or {}
    defaults = RobotSimConfig()
    config = RobotSimConfig(radius=float(metrics.get("radius", defaults.radius)),
                            reference=metrics.get("route", "clearance") != "astar",  # the route it drove
                            clearance_margin=float(metrics.get("reference_clearance_margin_m", defaults.clearance_margin)))
    waypoints, _ = plan_route(env.grid, res, env.start, env.goal, config, problem.config.diagonal)
    if len(waypoints):
        ax.plot(waypoints[:, 0], waypoints[:, 1], "--o", color="tab:blue", lw=1, ms=3, label="route")
    traj = outcome.trajectory
    if traj is not None and len(traj):
        # a logged result's path has no times (one stamp for all poses): coloured by order, said so
        timed = bool(outcome.timeline)
        t = outcome.timeline["t"] if timed else np.arange(len(traj))
        sc = ax.scatter(traj[:, 0], traj[:, 1], c=t, cmap="viridis", s=2, zorder=4)
        ax.figure.colorbar(sc, ax=ax, fraction=0.046, pad=0.04, label="time [s]" if timed else "pose, in order driven")
    ax.plot(*env.start_m, "o", color="tab:green", ms=9, label="start")
    ax.plot(*env.goal_m, "*", color="tab:red", ms=13, label="goal")
    ax.set_xlim(0, w * res)
    ax.set_ylim(0, h * res)
    draw_hazards(ax, env, t=float(outcome.timeline["t"][-1]) if outcome.timeline and env.unmapped else None)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_aspect("equal")


def _vehicle(problem, scenario, outcome, ax) -> None:
    from ..sims.car import right_lane, road_of

    road, _, _ = road_of(problem, scenario)
    lane_width = float((outcome.metrics or {}).get("lane_width") or problem.config.lane_width)
    right = right_lane(road, lane_width)
    left = right_lane(road[::-1], lane_width)  # the opposite lane, seen from the other direction
    for lane, color in ((right, "0.75"), (left, "0.88")):
        poly = lane.polygon
        for part in getattr(poly, "geoms", [poly]):
            if hasattr(part, "exterior"):
                xs, ys = part.exterior.xy
                ax.fill(xs, ys, color=color, lw=0)
    ax.plot(road[:, 0], road[:, 1], "--", color="goldenrod", lw=1, label="centre line")
    ax.plot(right.centre[:, 0], right.centre[:, 1], ":", color="tab:blue", lw=1, label="right lane centre")
    traj = outcome.trajectory
    if traj is not None and len(traj):
        ax.plot(traj[:, 0], traj[:, 1], "-", color="tab:purple", lw=1.8, label="car")
    ax.plot(*road[0], "o", color="tab:green", ms=8, label="start")
    ax.plot(*road[-1], "*", color="tab:red", ms=12, label="end")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_aspect("equal")


def _ideal_temperature(problem, scenario, tl) -> tuple[np.ndarray, np.ndarray] | None:
    """The reference's run on the same schedule and room (hours, air temperature), or None when the
    timeline is not a full-model run's (e.g. a stack's samples)."""
    from ..sims.reference.thermostat import ideal_run
    from ..sims.room import RoomSimConfig

    t = np.asarray(tl["t"], dtype=float)
    if len(t) < 2 or not hasattr(problem.config, "room_conditions"):
        return None
    run = ideal_run(problem, scenario, RoomSimConfig(dt=float(t[1] - t[0])))
    return np.asarray(run["timeline"]["t"]) / 3600.0, np.asarray(run["timeline"]["temperature"])


def _thermostat(problem, scenario, outcome, ax) -> None:
    tl = outcome.timeline or {}
    if not tl:
        ax.text(0.5, 0.5, "not executed", ha="center", va="center", transform=ax.transAxes)
        return
    hours = np.asarray(tl["t"]) / 3600.0
    heater = np.asarray(tl["heater"]) > 0.5
    padded = np.concatenate([[False], heater, [False]])
    edges = np.flatnonzero(np.diff(padded.astype(np.int8)))
    for a, b in zip(edges[0::2], edges[1::2]):
        ax.axvspan(hours[a], hours[min(b, len(hours) - 1)], color="tab:orange", alpha=0.15, lw=0)
    ax.step(hours, tl["setpoint"], where="post", color="tab:blue", lw=1.8, label="goal (schedule)")
    ax.plot(hours, tl["measured"], color="0.6", lw=0.6, label="sensor")
    ideal = _ideal_temperature(problem, scenario, tl)
    if ideal is not None:
        ax.plot(ideal[0], ideal[1], "--", color="tab:green", lw=1.0, label="ideal controller (reference)")
    ax.plot(hours, tl["temperature"], color="tab:red", lw=1.2, label="room")
    ax.fill_between([], [], color="tab:orange", alpha=0.15, label="heater on")
    ax.set_xlabel("time [h]")
    ax.set_ylabel("temperature [degC]")
    ax.grid(True, alpha=0.3)


def plot_execution(problem: Any, scenario: Any, outcome: Any, ax=None, plan: Any = None, system: str = "full model"):
    """Draw one executed scenario; returns the axes (a new figure when ``ax`` is None). ``plan``
    ((K, 2) m, robot): the path the system under test itself planned (Nav2's ``/plan``); ``system``
    names who drove it in the title."""
    if ax is None:
        figsize = (10, 3.8) if problem.name == "thermostat" else (7, 6.5)
        _, ax = plt.subplots(figsize=figsize, layout="constrained")
    draw = {"robot": _robot, "vehicle": _vehicle, "thermostat": _thermostat}[problem.name]
    draw(problem, scenario, outcome, ax)
    if plan is not None and len(plan):
        ax.plot(np.asarray(plan)[:, 0], np.asarray(plan)[:, 1], "-", color="tab:orange", lw=1.5, zorder=5,
                label="its plan")
    _mark_failure(ax, outcome)
    # characters of 9 pt text (about 5.4 pt wide each) the axes span, so that no title runs off the picture
    width = int(ax.figure.get_figwidth() * ax.get_position().width * 72 / 5.4)
    ax.set_title(_title(problem, outcome, system, max(width, 40)), fontsize=9)
    if ax.get_legend_handles_labels()[0]:  # a run with nothing drawn (not executed) has no legend
        ax.legend(loc="best", fontsize=7, framealpha=0.8)
    return ax


def save_execution_plot(problem: Any, scenario: Any, outcome: Any, path, plan: Any = None,
                        system: str = "full model") -> Any:
    """Write the picture to ``path`` (PNG); returns the path."""
    from pathlib import Path

    ax = plot_execution(problem, scenario, outcome, plan=plan, system=system)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    ax.figure.savefig(path, dpi=110)
    plt.close(ax.figure)
    return path


__all__ = ["plot_execution", "save_execution_plot"]


def save_side_by_side(problem: Any, runs: list[tuple[Any, Any]], path, title: str,
                      systems: list[str] | None = None) -> Any:
    """Executed scenarios side by side in one PNG (two failures counted as one, say); returns the
    path. ``systems`` names who drove each (default: the full model)."""
    from pathlib import Path

    wide = problem.name == "thermostat"
    fig, axes = plt.subplots(len(runs), 1, figsize=(10, 3.8 * len(runs)), layout="constrained") if wide else \
        plt.subplots(1, len(runs), figsize=(6.5 * len(runs), 6.2), layout="constrained")
    for k, (ax, (scenario, outcome)) in enumerate(zip(np.atleast_1d(axes), runs)):
        plot_execution(problem, scenario, outcome, ax=ax, system=systems[k] if systems else "full model")
    fig.suptitle(title, fontsize=10)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path

