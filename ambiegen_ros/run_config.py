"""Run configuration: a YAML file plus explicit overrides -> (problem, resolved search settings).

The file holds search settings at the top level (``algorithm``, ``evaluations``, ``seed`` ...),
optionally ``problem``, and the problem's own numbers under ``problem_config``. Explicit values
(CLI flags, ROS parameters) win over the file; a budget given explicitly replaces the file's.

The same file also builds the problem that scores or runs one scenario (``scenario_problem``:
``ambiegen evaluate``, ``show``, ``execute`` with ``--config``), so a map is judged with the goal,
weights or limits of the run that made it (e.g. ``config/robot_small.yaml``'s nearer goal).

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
from .core.settings import SearchSettings
from .problems import PROBLEM_NAMES, get_problem, problem_class

SETTING_NAMES = tuple(f.name for f in fields(SearchSettings))


def make_run(
    problem: str | None = None, config_file: str | Path | None = None, profile: str | None = None,
    problem_defaults: dict[str, Any] | None = None, **overrides: Any
) -> tuple[Problem, SearchSettings]:
    """Build the problem and the resolved settings; ``None`` overrides are ignored.

    ``profile`` (replication | refined) wins over the file's ``problem_config.profile``, which wins
    over ``problem_defaults`` (e.g. a problem's ``certified_search``). A missing seed is drawn here
    so that it can be recorded with the run.
    """
    file_cfg = load_config_file(config_file)
    name = problem or file_cfg.get("problem")
    if not name:
        raise ConfigError(f"problem is required (allowed: {'|'.join(PROBLEM_NAMES)})")
    if problem_defaults:
        file_cfg = {**file_cfg, "problem_config": {**problem_defaults, **(file_cfg.get("problem_config") or {})}}
    case = _build_problem(name, file_cfg, profile)
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


def _build_problem(name: str, file_cfg: dict[str, Any], profile: str | None) -> Problem:
    """The case study ``name`` with the file's ``problem_config``; ``profile`` wins over the file's."""
    problem_config = file_cfg.get("problem_config") or {}
    if not isinstance(problem_config, dict):
        raise ConfigError("config: problem_config must be a mapping")
    if profile is not None:
        problem_config = {**problem_config, "profile": profile}
    try:
        return get_problem(name, problem_config)
    except TypeError as exc:
        raise ConfigError(f"config: problem_config: {exc}")


def scenario_problem(data: dict[str, Any], config_file: str | Path | None = None,
                     profile: str | None = None) -> Problem:
    """The case study that scores or runs one scenario (``data``: its parsed JSON).

    The scenario names its problem; a run config adds its ``problem_config`` (the search settings
    in it are not used) and ``profile`` (replication | refined) wins over the file's. A config
    whose ``problem`` is another case study is refused (``ConfigError``), so a thermostat file
    never scores a robot map.
    """
    named = data.get("problem")
    name = named if isinstance(named, str) else repr(named)
    problem_class(name)  # an unknown problem is the scenario's error (ScenarioError), not the file's
    file_cfg = load_config_file(config_file)
    wanted = file_cfg.get("problem")
    if wanted and wanted != name:
        raise ConfigError(f"config: {config_file} is a run config of problem {wanted!r}; "
                          f"this scenario is a {name!r} scenario")
    return _build_problem(name, file_cfg, profile)


__all__ = ["ConfigError", "SETTING_NAMES", "load_config_file", "make_run", "scenario_problem"]
