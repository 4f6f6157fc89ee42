"""Run directories: ``config.json``, ``suite.json``, ``history.csv`` (pictures come from ``viz``).

``suite.json`` holds nothing that depends on the clock, so the same seed and config give a
byte-identical file; timings live in ``config.json`` (``finished``) and ``history.csv``.
"""
from __future__ import annotations

import csv
import dataclasses
import functools
import json
import platform
import sys
from datetime import datetime, timezone
from importlib import metadata
from pathlib import Path
from typing import Any

from .. import __version__
from .problem import Problem
from .search import SearchResult

DEPENDENCIES = ("pymoo", "numpy", "scipy", "shapely", "matplotlib", "PyYAML", "mcap", "rosbags", "cyclonedds")
HISTORY_COLUMNS = ("evaluations", "elapsed_s", "best_f1", "mean_f1", "front_size", "risky")


def versions() -> dict[str, str]:
    """Package and dependency versions, recorded in every output for reproducibility (read once
    per process: a row per run would otherwise scan the installed packages each time)."""
    return dict(_versions())


@functools.lru_cache(maxsize=1)
def _versions() -> tuple[tuple[str, str], ...]:
    out = {"ambiegen_ros": __version__, "python": platform.python_version()}
    for name in DEPENDENCIES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = "not installed"
    return tuple(out.items())


def run_config(problem: Problem, result_or_settings: Any, extra: dict[str, Any] | None = None) -> dict[str, Any]:
    settings = getattr(result_or_settings, "settings", result_or_settings)
    config = {
        "problem": problem.name,
        "profile": problem.profile,
        "seed": settings.seed,
        "search": dataclasses.asdict(settings),
        "problem_config": problem.config_dict(),
        "versions": versions(),
        "command": sys.argv,
    }
    if extra:
        config.update(extra)
    return config


def suite_document(problem: Problem, result: SearchResult) -> dict[str, Any]:
    return {
        "problem": problem.name,
        "profile": problem.profile,
        "algorithm": result.settings.algorithm,
        "seed": result.settings.seed,
        "evaluations": result.evaluations,
        "alpha": problem.alpha,
        "best_f1": result.best_f1,
        "diversity": result.diversity,
        "suite": result.suite,
    }


def write_run(
    out_dir: Path, problem: Problem, result: SearchResult, extra: dict[str, Any] | None = None, overwrite: bool = False
) -> dict[str, Path]:
    """Write the run's files; returns their paths by name.

    An existing run is never replaced silently: ``FileExistsError`` unless ``overwrite``.
    """
    out_dir = Path(out_dir)
    paths = {"config": out_dir / "config.json", "suite": out_dir / "suite.json", "history": out_dir / "history.csv"}
    existing = [str(p) for p in paths.values() if p.exists()]
    if existing and not overwrite:
        raise FileExistsError(f"{out_dir} already holds a run ({existing[0]}); choose another --out or pass --overwrite")
    out_dir.mkdir(parents=True, exist_ok=True)
    config = run_config(problem, result, extra)
    config["finished"] = datetime.now(timezone.utc).isoformat(timespec="seconds")
    config["elapsed_s"] = round(result.elapsed, 3)
    paths["config"].write_text(json.dumps(config, indent=2) + "\n")
    paths["suite"].write_text(json.dumps(suite_document(problem, result), indent=2) + "\n")
    with paths["history"].open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=HISTORY_COLUMNS)
        writer.writeheader()
        writer.writerows(result.history)
    return paths


def read_run(run_dir: Path) -> dict[str, Any]:
    """Load a run directory back (for ``ambiegen show`` and tests)."""
    run_dir = Path(run_dir)
    with (run_dir / "history.csv").open() as fh:
        history = [{k: float(v) for k, v in row.items()} for row in csv.DictReader(fh)]
    return {
        "config": json.loads((run_dir / "config.json").read_text()),
        "suite": json.loads((run_dir / "suite.json").read_text()),
        "history": history,
    }
