"""Reading a run-configuration file: a YAML mapping of search settings plus the problem's numbers.

The file holds search settings at the top level (``algorithm``, ``evaluations``, ``seed`` ...),
optionally ``problem``, and the problem's own numbers under ``problem_config``. This module only
reads and checks the file; building the problem and the resolved settings from it
(``make_run``) is ``ambiegen_ros.run_config``, which sits above ``problems``.
"""
from __future__ import annotations

from dataclasses import fields
from pathlib import Path
from typing import Any

from .attributes import ScenarioError
from .errors import ConfigError
from .settings import SearchSettings  # a plain dataclass: reading a file imports no search (pymoo)


def load_config_file(path: str | Path | None) -> dict[str, Any]:
    if not path:
        return {}
    import yaml

    try:
        data = yaml.safe_load(Path(path).read_text()) or {}
    except FileNotFoundError:
        raise ConfigError(f"config: no such file {path}")
    except yaml.YAMLError as exc:
        raise ConfigError(f"config: malformed YAML in {path}: {exc}")
    if not isinstance(data, dict):
        raise ConfigError(f"config: {path} must hold a mapping")
    allowed = {f.name for f in fields(SearchSettings)} | {"problem", "problem_config"}
    unknown = set(data) - allowed
    if unknown:
        raise ConfigError(f"config: unknown key {sorted(unknown)[0]!r} (allowed: {', '.join(sorted(allowed))})")
    return data


__all__ = ["ConfigError", "ScenarioError", "load_config_file"]
