"""Run pictures: convergence (best / mean F1, and the front size for NSGA-II) and the best scenarios."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from ..core.runs import read_run  # noqa: E402
from ..core.scenario import Scenario  # noqa: E402
from ..problems import get_problem  # noqa: E402


# Only NSGA-II keeps a Pareto front (core.search: the one two-objective algorithm); GA and random
# search have none, so their "front size" is not a quantity worth an axis (issue 18).
FRONT_ALGORITHMS = ("nsga2",)


def convergence_figure(problem, history: list[dict], algorithm: str, seed: Any):
    """Best / mean F1 over evaluations, plus the feasible front's size for algorithms that have one."""
    fig, ax = plt.subplots(figsize=(7, 4))
    evals = [h["evaluations"] for h in history]
    ax.plot(evals, [h["best_f1"] for h in history], label="best F1")
    ax.plot(evals, [h["mean_f1"] for h in history], label="mean F1 (population)", alpha=0.7)
    ax.axhline(problem.alpha, color="grey", linestyle=":", label=f"alpha = {problem.alpha:g}")
    ax.set_xlabel("evaluations")
    ax.set_ylabel(problem.f1_label)
    handles, labels = ax.get_legend_handles_labels()
    if algorithm in FRONT_ALGORITHMS:
        ax2 = ax.twinx()
        ax2.plot(evals, [h["front_size"] for h in history], color="tab:green", alpha=0.5, label="front size")
        ax2.set_ylabel("non-dominated feasible scenarios", color="tab:green")
        handles2, labels2 = ax2.get_legend_handles_labels()
        handles, labels = handles + handles2, labels + labels2
    ax.legend(handles, labels, loc="lower right", fontsize=8)
    ax.set_title(f"{problem.name} / {algorithm} (seed {seed}): convergence")
    return fig


def plot_run(run_dir: Path, out: Path | None = None, max_scenarios: int = 6) -> list[Path]:
    """Write ``convergence.png`` and ``suite.png`` (or ``<out>_convergence.png`` ...)."""
    run_dir = Path(run_dir)
    run = read_run(run_dir)
    config, suite_doc, history = run["config"], run["suite"], run["history"]
    problem = get_problem(config["problem"], config.get("problem_config") or {})
    prefix = Path(out) if out else None

    def target(name: str) -> Path:
        if prefix is None:
            return run_dir / f"{name}.png"
        return prefix.with_name(f"{prefix.stem}_{name}.png")

    written = []
    fig = convergence_figure(problem, history, suite_doc["algorithm"], suite_doc["seed"])
    fig.tight_layout()
    fig.savefig(target("convergence"), dpi=110)
    plt.close(fig)
    written.append(target("convergence"))

    entries = suite_doc["suite"][:max_scenarios]
    if entries:
        cols = min(3, len(entries))
        rows = (len(entries) + cols - 1) // cols
        fig, axes = plt.subplots(rows, cols, figsize=(5 * cols, 4.4 * rows), squeeze=False)
        for ax, entry in zip(axes.flat, entries):
            scenario = Scenario(problem.name, entry["scenario"]["elements"])
            from . import plot_scenario

            plot_scenario(problem, scenario, ax=ax, title=f"#{entry['rank']}  F1 {entry['f1']:.2f}  F2 {entry['f2']:.2f}")
        for ax in list(axes.flat)[len(entries):]:
            ax.axis("off")
        fig.tight_layout()
        fig.savefig(target("suite"), dpi=90)
        plt.close(fig)
        written.append(target("suite"))
    return written
