"""Experiment pictures: the paper's convergence boxplots, final F1 and diversity, RQ3 failures,
and the RQ3 failure gallery (one picture per distinct failure, ``gallery/``).

Colours follow the paper's figures: GA (SO) red, NSGA-II (MO) blue, random green. Every title
names the problem and the fidelity profile that made the numbers.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

COLOURS = {"ga": "tab:red", "nsga2": "tab:blue", "random": "tab:green"}
LABELS = {"ga": "GA (SO)", "nsga2": "NSGA-II (MO)", "random": "random"}


FULL_MODEL_OBJECTIVES = {
    "robot": "time to the goal, or the time limit when not reached [s]",
    "vehicle": "largest fraction of the car outside its lane",
    "thermostat": "RMSE to schedule [degC]",
}
"""What each full model's objective (``sims``: ``robot_time``, ``vehicle_max_oob``,
``thermostat_rmse``) measures, for the surrogate-against-full-model axes."""


def _f1_label(config: dict[str, Any]) -> str:
    """The F1 of the experiment's own problem config: an objective other than the paper's (e.g. the
    thermostat's ``certified`` or ``reference_relative``) is another quantity with its own label."""
    from dataclasses import fields

    from ..problems import get_problem, problem_class

    cls = problem_class(config["problem"])
    given = dict((config.get("identity") or {}).get("problem_config") or {})
    known = {f.name for f in fields(cls.Config)}
    for problem_config in (given, {k: v for k, v in given.items() if k in known}):  # a field since removed
        try:
            return get_problem(config["problem"], problem_config).f1_label
        except (TypeError, ValueError):
            continue
    return cls.f1_label


def _boxes(ax, groups: list[list[float]], positions, colour: str, width: float) -> None:
    data = [[v for v in g if v is not None and np.isfinite(v)] or [np.nan] for g in groups]
    bp = ax.boxplot(data, positions=positions, widths=width, patch_artist=True, manage_ticks=False,
                    medianprops={"color": "black"}, flierprops={"markersize": 3})
    for box in bp["boxes"]:
        box.set_facecolor(colour)
        box.set_alpha(0.6)


def _per_algorithm(ax, records: list[dict], algorithms: list[str], key: str, ylabel: str) -> None:
    for i, alg in enumerate(algorithms):
        _boxes(ax, [[r.get(key) for r in records if r["algorithm"] == alg]], [i], COLOURS.get(alg, "grey"), 0.6)
    ax.set_xticks(range(len(algorithms)))
    ax.set_xticklabels([LABELS.get(a, a) for a in algorithms])
    ax.set_ylabel(ylabel)
    ax.grid(axis="y", alpha=0.3)


def _save(fig, path: Path) -> Path:
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_experiment(out: Path, config: dict[str, Any], records: list[dict], checkpoints: list[dict]) -> list[Path]:
    """Write the experiment's pictures into ``out``; returns their paths."""
    out = Path(out)
    problem, profile = config["problem"], config["profile"]
    algorithms = [a for a in config["algorithms"] if any(r["algorithm"] == a for r in records)]
    tag = f"{problem}, profile {profile}, {max(sum(r['algorithm'] == a for r in records) for a in algorithms)} runs"
    f1_label = _f1_label(config)
    written = []

    if checkpoints:
        marks = sorted({c["checkpoint"] for c in checkpoints})
        axis = checkpoints[0]["axis"]
        fig, ax = plt.subplots(figsize=(10, 4.5))
        n = len(algorithms)
        width = 0.8 / n
        for j, alg in enumerate(algorithms):
            groups = [[c["best_f1"] for c in checkpoints if c["algorithm"] == alg and c["checkpoint"] == m] for m in marks]
            _boxes(ax, groups, np.arange(len(marks)) + (j - (n - 1) / 2) * width, COLOURS.get(alg, "grey"), width * 0.9)
            ax.plot([], [], color=COLOURS.get(alg, "grey"), linewidth=8, alpha=0.6, label=LABELS.get(alg, alg))
        ax.set_xticks(range(len(marks)))
        ax.set_xticklabels([f"{m:g}" for m in marks], rotation=30)
        ax.set_xlabel(axis)
        ax.set_ylabel(f"best F1: {f1_label}")
        ax.grid(axis="y", alpha=0.3)
        ax.legend(loc="center left", bbox_to_anchor=(1.0, 0.5))  # outside: boxes fill the axes
        ax.set_title(f"Best F1 over the budget ({tag})")
        written.append(_save(fig, out / "convergence.png"))

    full = "full_model" in config["identity"]
    if not full:
        fig, axes = plt.subplots(1, 2, figsize=(10, 4.2))
        _per_algorithm(axes[0], records, algorithms, "best_f1", f"best F1: {f1_label}")
        axes[0].set_title("RQ1: final best F1")
        _per_algorithm(axes[1], records, algorithms, "diversity", "mean pairwise Jaccard distance")
        axes[1].set_title("RQ2: diversity (10 best / Pareto front)")
        fig.suptitle(tag)
        written.append(_save(fig, out / "final_f1_diversity.png"))
        return written

    fig, axes = plt.subplots(1, 3, figsize=(13, 4.2))
    _per_algorithm(axes[0], records, algorithms, "failures_per_hour", "failures per hour")
    axes[0].set_title("RQ3: failures per hour")
    _per_algorithm(axes[1], records, algorithms, "distinct_per_hour", "distinct failures per hour")
    axes[1].set_title("distinct failures per hour")
    _per_algorithm(axes[2], records, algorithms, "failure_rate", "failures / executions")
    axes[2].set_title("failure rate of executed scenarios")
    fig.suptitle(f"{tag}, {config['identity']['full_model']['time_budget_s']:g} s per run")
    written.append(_save(fig, out / "failures.png"))

    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    for alg in algorithms:
        f1, obj, failed = [], [], []
        for r in records:
            if r["algorithm"] != alg:
                continue
            s = r.get("sample") or {}
            f1 += s.get("surrogate_f1", [])
            obj += s.get("objective", [None] * len(s.get("surrogate_f1", [])))
            failed += s.get("failed", [0] * len(s.get("surrogate_f1", [])))
        f1a = np.asarray(f1, dtype=float)
        oba = np.asarray([np.nan if v is None else v for v in obj], dtype=float)
        fa = np.asarray(failed, dtype=bool)
        colour = COLOURS.get(alg, "grey")
        ax.scatter(f1a[~fa], oba[~fa], s=6, alpha=0.3, color=colour, label=f"{LABELS.get(alg, alg)} passed")
        ax.scatter(f1a[fa], oba[fa], s=18, marker="x", color=colour, label=f"{LABELS.get(alg, alg)} failed")
    ax.set_xlabel(f"surrogate F1: {f1_label}")
    ax.set_ylabel(f"full model: {FULL_MODEL_OBJECTIVES.get(problem, 'objective')}")
    ax.legend(fontsize=7)
    ax.set_title(f"Surrogate vs full model ({problem}, {profile})")
    written.append(_save(fig, out / "surrogate_vs_full_model.png"))
    return written


GALLERY_PER_ALGORITHM = 12


def _gallery_picks(records: list[dict], algorithm: str, radius: float | None, limit: int) -> list[tuple[dict, dict]]:
    """Up to ``limit`` distinct failures of one algorithm: taken in turn from its runs, dropping any
    that is the same failure (``sims.signature``) as one already picked from another run."""
    from ..sims.signature import FailureSignature, same_failure

    runs = sorted((r for r in records if r["algorithm"] == algorithm), key=lambda r: r["run"])
    queues = [[(r, e) for e in r.get("distinct_examples") or []] for r in runs]
    picks: list[tuple[dict, dict]] = []
    signatures: list[FailureSignature] = []
    while len(picks) < limit and any(queues):
        for q in queues:
            if not q or len(picks) >= limit:
                continue
            rec, entry = q.pop(0)
            sig = entry["signature"]
            sig = FailureSignature(sig["problem"], sig["kind"], None if sig["place"] is None else tuple(sig["place"]))
            if any(same_failure(sig, other, radius) for other in signatures):
                continue
            signatures.append(sig)
            picks.append((rec, entry))
    return picks


def plot_gallery(out: Path, config: dict[str, Any], records: list[dict],
                 per_algorithm: int = GALLERY_PER_ALGORITHM) -> list[dict[str, Any]]:
    """One picture per distinct failure (up to ``per_algorithm`` each) under ``out/gallery``, the
    scenario JSON next to it. The failure is executed again with its recorded simulator seed, which
    reproduces the outcome (``FullModelExecutor`` is deterministic given the seed)."""
    import json

    from ..problems import get_problem
    from ..sims.full_model import FullModelExecutor, sim_config
    from .execution import save_execution_plot

    identity = config["identity"]
    fm = identity["full_model"]
    problem = get_problem(identity["problem"], identity["problem_config"])
    executor = FullModelExecutor(problem, sim_config(problem.name, fm["simulator"]))
    folder = Path(out) / "gallery"
    entries = []
    for alg in config["algorithms"]:
        for i, (rec, entry) in enumerate(_gallery_picks(records, alg, fm.get("signature_radius"), per_algorithm)):
            scenario = problem.parse(entry["scenario"])
            outcome = executor.execute(scenario, seed=entry["sim_seed"])
            stem = f"{alg}-{i + 1:02d}"
            png = save_execution_plot(problem, scenario, outcome, folder / f"{stem}.png")
            doc = {"algorithm": alg, "run": rec["run"], "sim_seed": entry["sim_seed"], "signature": entry["signature"],
                   "failure": entry["describe"], "verdict_in_run": entry["verdict"], "verdict_again": outcome.verdict,
                   "detail": entry["detail"], "surrogate_f1": entry["surrogate_f1"], "time_s": entry["time_s"],
                   "scenario": entry["scenario"]}
            (folder / f"{stem}.json").write_text(json.dumps(doc, indent=1) + "\n")
            entries.append({"algorithm": alg, "run": rec["run"], "png": png, "json": folder / f"{stem}.json",
                            "failure": entry["describe"], "verdict": outcome.verdict})
    return entries


__all__ = ["FULL_MODEL_OBJECTIVES", "GALLERY_PER_ALGORITHM", "plot_experiment", "plot_gallery"]
