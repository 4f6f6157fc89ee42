"""Run configuration: a YAML file plus explicit overrides -> (problem, resolved search settings).

The file holds search settings at the top level (``algorithm``, ``evaluations``, ``seed`` ...),
optionally ``problem``, and the problem's own numbers under ``problem_config``. Explicit values
(CLI flags, ROS parameters) win over the file; a budget given explicitly replaces the file's.

This module sits above ``problems`` (it instantiates a case study by name) and below the nodes
that build runs from ROS parameters (the generator) and the library/CLI; reading and checking the
file itself (``load_config_file``, ``ConfigError``) stays in ``core.config``.
"""
from __future__ import annotations

import secrets
from dataclasses import fields
from pathlib import Path
from typing import Any

from .core.config import ConfigError, load_config_file
from .core.problem import Problem
from .core.search import SearchSettings
from .problems import PROBLEM_NAMES, get_problem

SETTING_NAMES = tuple(f.name for f in fields(SearchSettings))


def make_run(
    problem: str | None = None, config_file: str | Path | None = None, profile: str | None = None, **overrides: Any
) -> tuple[Problem, SearchSettings]:
    """Build the problem and the resolved settings; ``None`` overrides are ignored.

    ``profile`` (replication | refined) wins over the file's ``problem_config.profile``. A missing
    seed is drawn here so that it can be recorded with the run.
    """
    file_cfg = load_config_file(config_file)
    name = problem or file_cfg.get("problem")
    if not name:
        raise ConfigError(f"problem is required (allowed: {'|'.join(PROBLEM_NAMES)})")
    problem_config = file_cfg.get("problem_config") or {}
    if not isinstance(problem_config, dict):
        raise ConfigError("config: problem_config must be a mapping")
    if profile is not None:
        problem_config = {**problem_config, "profile": profile}
    try:
        case = get_problem(name, problem_config)
    except TypeError as exc:
        raise ConfigError(f"config: problem_config: {exc}")
    values = {k: v for k, v in file_cfg.items() if k not in ("problem", "problem_config")}
    given = {k: v for k, v in overrides.items() if v is not None}
    unknown = set(given) - set(SETTING_NAMES)
    if unknown:
        raise ConfigError(f"unknown setting {sorted(unknown)[0]!r} (allowed: {', '.join(SETTING_NAMES)})")
    if "evaluations" in given or "time_budget" in given:
        values.pop("evaluations", None)
        values.pop("time_budget", None)
    values.update(given)
    values.setdefault("seed", secrets.randbelow(2**31))
    try:
        settings = SearchSettings(**values).resolved(case)
    except (TypeError, ValueError) as exc:
        raise ConfigError(str(exc))
    return case, settings


__all__ = ["ConfigError", "SETTING_NAMES", "load_config_file", "make_run"]
