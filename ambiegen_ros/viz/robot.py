"""Plot a robot obstacle map: walls, start/goal and the A* route, with its length in the title."""
from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def plot_scenario(problem, scenario, ax=None, title=None):
    """Draw one scenario of a ``RobotProblem``; returns the axes (a new figure when ``ax`` is None).

    Axes are metres with the origin at the grid's corner, so the picture matches the ROS map.
    """
    env = problem.environment(scenario)
    if ax is None:
        _, ax = plt.subplots(figsize=(6, 6))
    res = env.resolution
    h, w = env.grid.shape
    ax.imshow(env.grid.astype(float), cmap="Greys", vmin=0, vmax=1, origin="lower",
              extent=(0, w * res, 0, h * res), interpolation="nearest")
    if env.path:
        pts = np.asarray(env.path_m)
        ax.plot(pts[:, 0], pts[:, 1], "-", color="tab:blue", lw=2, label="A* path")
    ax.plot(*env.start_m, "o", color="tab:green", ms=9, label="start")
    ax.plot(*env.goal_m, "*", color="tab:red", ms=13, label="goal")
    summary = f"A* path length {env.path_length:.2f} m" if env.reachable else "no path from start to goal"
    ax.set_title(summary if title is None else f"{title}\n{summary}")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_aspect("equal")
    ax.legend(loc="upper left", fontsize=8, framealpha=0.8)
    return ax
