"""Scenario files: read one (or standard input), find its problem, validate it.

Shared by the command line, the experiment runner and the nodes; the errors are one-line
``BadInput`` / ``ScenarioError`` naming the field and what is allowed.
"""
from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

from ..core.errors import BadInput
from ..core.scenario import Scenario


def read_text(path: str) -> str:
    """A file's text, or standard input for ``-``; unreadable files are a one-line error."""
    if path == "-":
        return sys.stdin.read()
    try:
        return Path(path).read_text()
    except OSError as exc:
        raise BadInput(f"{path}: cannot read ({exc.strerror})")
    except UnicodeDecodeError:
        raise BadInput(f"{path}: not a text file")


def scenario_problem(data: dict[str, Any], profile: str | None = None) -> Any:
    """The case study a scenario names, in the given fidelity profile (default: replication)."""
    from . import get_problem

    name = data.get("problem") if isinstance(data.get("problem"), str) else repr(data.get("problem"))
    return get_problem(name, {"profile": profile} if profile else None)


def load_scenario_file(path: str, profile: str | None = None) -> tuple[Any, Scenario]:
    """Read and validate a scenario JSON file -> (problem, scenario)."""
    data = Scenario.parse_json(read_text(path))
    problem = scenario_problem(data, profile)
    return problem, problem.parse(data)


__all__ = ["load_scenario_file", "read_text", "scenario_problem"]
