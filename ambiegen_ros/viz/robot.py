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
    draw_hazards(ax, env)
    summary = f"A* path length {env.path_length:.2f} m" if env.reachable else "no path from start to goal"
    ax.set_title(summary if title is None else f"{title}\n{summary}")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_aspect("equal")
    ax.legend(loc="upper left", fontsize=8, framealpha=0.8)
    return ax


def draw_hazards(ax, env, t: float | None = None) -> None:
    """What a hazards scenario (issue 48) adds to the map: the start's and goal's yaw, a planner's
    vias (issue 68, numbered in the order flown through), and what is in the world but not in the map (orange: boxes and posts; purple: people, their path from where
    they stand to where they stop, and the second they set off; with ``t`` where they are then).
    Zooms to the part of the map they and the route occupy."""
    from matplotlib.patches import Circle, Rectangle

    if env.start_yaw is None:
        return
    for (x, y), yaw, color in ((env.start_m, env.start_yaw, "tab:green"), (env.goal_m, env.goal_yaw, "tab:red")):
        ax.annotate("", xy=(x + 0.8 * np.cos(yaw), y + 0.8 * np.sin(yaw)), xytext=(x, y),
                    arrowprops={"arrowstyle": "->", "color": color, "lw": 1.8})
    for k, (x, y, yaw) in enumerate(getattr(env, "via_poses", [])):  # a planner's vias, numbered in order
        ax.annotate("", xy=(x + 0.6 * np.cos(yaw), y + 0.6 * np.sin(yaw)), xytext=(x, y),
                    arrowprops={"arrowstyle": "->", "color": "tab:cyan", "lw": 1.5})
        ax.plot(x, y, "D", color="tab:cyan", ms=7, label="via (in order)" if k == 0 else None)
        ax.text(x, y + 0.3, str(k + 1), fontsize=7, color="tab:cyan", ha="center")
    hz = env.unmapped or {}
    pts = [np.asarray(env.start_m), np.asarray(env.goal_m)] + [np.asarray(env.path_m)]
    pts += [np.asarray(p[:2]) for p in getattr(env, "via_poses", [])]
    for k, (x0, y0, x1, y1) in enumerate(hz.get("boxes", [])):
        ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, color="tab:orange", alpha=0.8,
                               label="box, not in the map" if k == 0 else None))
        pts.append(np.array([[x0, y0], [x1, y1]]))
    for k, (x, y, r) in enumerate(hz.get("posts", [])):
        ax.add_patch(Circle((x, y), max(r, 0.06), color="darkorange", label="post, not in the map" if k == 0 else None))
        pts.append(np.array([[x, y]]))
    for k, person in enumerate(hz.get("people", [])):
        path = np.asarray(person["path"], dtype=float)
        ax.annotate("", xy=path[-1], xytext=path[0],
                    arrowprops={"arrowstyle": "->", "color": "tab:purple", "lw": 1.2, "ls": "--"})
        ax.add_patch(Circle(path[0], person["radius"], fill=False, color="tab:purple",
                            label="person (path, start time)" if k == 0 else None))
        ax.text(path[0][0], path[0][1] + person["radius"] + 0.15, f"{person['delay']:.0f} s, {person['speed']:.1f} m/s",
                fontsize=6, color="tab:purple", ha="center")
        if t is not None:
            from ..sims.obstacles import Person

            where = Person.from_dict(person).position(t)
            ax.add_patch(Circle(where, person["radius"], color="tab:purple", alpha=0.7))
        pts.append(path)
    every = np.concatenate([np.asarray(p, dtype=float).reshape(-1, 2) for p in pts if len(np.asarray(p))])
    lo, hi = every.min(axis=0) - 3.0, every.max(axis=0) + 3.0
    side = max(hi - lo)
    mid = (lo + hi) / 2
    ax.set_xlim(mid[0] - side / 2, mid[0] + side / 2)
    ax.set_ylim(mid[1] - side / 2, mid[1] + side / 2)
