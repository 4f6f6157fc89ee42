"""Every picture AmbieGen draws (matplotlib, headless Agg backend).

One module per case study with ``plot_scenario(problem, scenario, ax=None, title=None)``, plus
``runs`` for convergence and suite overviews.
"""
from __future__ import annotations

import importlib
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")


def plot_scenario(problem: Any, scenario: Any, ax=None, title: str | None = None):
    module = importlib.import_module(f"{__name__}.{problem.name}")
    return module.plot_scenario(problem, scenario, ax=ax, title=title)


def save_scenario_plot(problem: Any, scenario: Any, path: Path, title: str | None = None) -> Path:
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 6))
    plot_scenario(problem, scenario, ax=ax, title=title)
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
