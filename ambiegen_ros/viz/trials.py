"""A scenario's runs under several configurations, one panel each: what a fix changed, at a glance.

Each panel is the map with what it leaves out (boxes, posts, people and their paths), and every run
of that configuration drawn from its row (the path every 10th pose): green a pass, orange a pass
after recoveries (a near miss), red a failure, with an X where it failed.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

COLOURS = {"pass": "tab:green", "near_miss": "tab:orange"}  # any failure: tab:red


def save_runs_side_by_side(problem: Any, scenario: Any, panels: list[tuple[str, list[dict]]], path: str | Path,
                           title: str) -> Path:
    """``panels``: (heading, rows) per configuration; returns the PNG's path (never over another file)."""
    from ..trials.tables import kind_of
    from .robot import plot_scenario

    fig, axes = plt.subplots(1, len(panels), figsize=(5.6 * len(panels), 5.8), layout="constrained", squeeze=False)
    for ax, (heading, rows) in zip(axes[0], panels):
        plot_scenario(problem, scenario, ax=ax)
        for r in rows:
            kind = kind_of(r)
            colour = COLOURS.get(kind, "tab:red")
            traj = np.asarray(r.get("trajectory_every_10") or [], dtype=float).reshape(-1, 2)
            if len(traj):
                ax.plot(traj[:, 0], traj[:, 1], "-", color=colour, lw=1.4, alpha=0.8)
            if r.get("failed") and r.get("failure_point"):
                x, y = r["failure_point"][:2]
                ax.plot([x], [y], "X", color="red", ms=11, mec="black", zorder=6)
        ax.set_title(heading, fontsize=9)
        if ax.get_legend() is not None:
            ax.get_legend().remove()
    fig.suptitle(title + "\ngreen: pass; orange: pass after recoveries; red: failure (X where)", fontsize=10)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.exists():
        raise FileExistsError(f"{path} exists (not overwritten)")
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


__all__ = ["save_runs_side_by_side"]
