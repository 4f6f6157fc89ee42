"""Plot a lane-keeping road: map, two lanes, the surrogate car's path and its worst deviation."""
from __future__ import annotations

from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def _left_normals(nodes: np.ndarray) -> np.ndarray:
    """Unit normals pointing left of the direction of travel (central differences)."""
    tangent = np.gradient(nodes, axis=0)
    tangent /= np.maximum(np.linalg.norm(tangent, axis=1, keepdims=True), 1e-12)
    return np.column_stack([-tangent[:, 1], tangent[:, 0]])


def plot_scenario(problem: Any, scenario: Any, ax=None, title: str | None = None):
    """Draw one scenario of a ``VehicleProblem``; returns the axes (a new figure when ``ax`` is None).

    The centre line is the road's middle (dashed, the surrogate's reference: in the replication
    profile the polyline of its ~8 m nodes); the two outer edges are one ``lane_width`` to each
    side, i.e. two lanes. Axes are map metres.
    """
    road = problem.environment(scenario)
    if ax is None:
        _, ax = plt.subplots(figsize=(7, 7))
    size, margin = road.map_size, road.margin
    ax.add_patch(plt.Rectangle((0, 0), size, size, fill=False, color="black", lw=1.2))
    ax.add_patch(plt.Rectangle((margin, margin), size - 2 * margin, size - 2 * margin, fill=False,
                               color="grey", lw=0.8, ls=":"))
    nodes = road.nodes
    normal = _left_normals(nodes)
    left = nodes + road.lane_width * normal
    right = nodes - road.lane_width * normal
    ax.fill(np.concatenate([left[:, 0], right[::-1, 0]]), np.concatenate([left[:, 1], right[::-1, 1]]),
            color="0.85", lw=0)
    ax.plot(left[:, 0], left[:, 1], "-", color="0.3", lw=1)
    ax.plot(right[:, 0], right[:, 1], "-", color="0.3", lw=1)
    ax.plot(nodes[:, 0], nodes[:, 1], "--", color="goldenrod", lw=1, label="centre line")
    ax.plot(road.spine[:, 0], road.spine[:, 1], ".", color="black", ms=3, label="spine points")
    ax.plot(*nodes[0], "o", color="tab:green", ms=7, label="start")
    ax.plot(*nodes[-1], "s", color="tab:red", ms=6, label="end")
    if len(road.path):
        ax.plot(road.path[:, 0], road.path[:, 1], "-", color="tab:blue", lw=1.5, label="surrogate car")
        worst = int(np.argmax(np.abs(road.deviations)))
        ax.plot(*road.path[worst], "x", color="tab:red", ms=11, mew=2.5,
                label=f"max |d| = {abs(road.deviations[worst]):.2f} m")
    if road.valid and not getattr(road, "car_path_simple", True):
        summary = f"F1 = 0: the car's path crosses itself (max deviation {road.max_deviation:.2f} m)"
    elif road.valid:
        summary = f"F1 = max deviation {road.max_deviation:.2f} m (road {road.length:.0f} m)"
    else:
        summary = f"invalid ({road.reason}): F1 = 0"
    ax.set_title(summary if title is None else f"{title}\n{summary}")
    ax.set_xlim(-2, size + 2)
    ax.set_ylim(-2, size + 2)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_aspect("equal")
    ax.legend(loc="upper left", fontsize=8, framealpha=0.8)
    return ax
