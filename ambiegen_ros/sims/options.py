"""Simulator options from the command line (``--set KEY=VALUE``) and the JSON of one execution.

Kept free of argparse so the command line, the experiment runner and the nodes share them.
"""
from __future__ import annotations

import json
import math
from typing import Any

import numpy as np

from ..core.errors import BadInput


def plain(value: Any) -> Any:
    """JSON-safe plain values (numpy scalars -> Python, non-finite floats -> null)."""
    if isinstance(value, dict):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return plain(value.tolist())
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def parse_options(pairs: list[str] | None) -> dict[str, Any]:
    """``["tolerance=0.95", "controller=pid"]`` -> dict; values read as JSON when they parse.

    Types and ranges are the executor's to check (``full_model.check_options``): only it knows the
    fields; errors there and here have the same form, ``option.NAME: value ... (allowed: ...)``.
    """
    out: dict[str, Any] = {}
    for pair in pairs or []:
        key, sep, text = pair.partition("=")
        if not sep or not key:
            raise BadInput(f"--set {pair!r}: expected OPTION=VALUE")
        try:
            value = json.loads(text)
        except json.JSONDecodeError:
            value = text
        if isinstance(value, float) and not math.isfinite(value):
            raise BadInput(f"option.{key.strip()}: {text} is not a finite number (allowed: finite numbers)")
        out[key.strip()] = value
    return out


def result_json(problem_name: str, outcome: Any) -> dict[str, Any]:
    """The ``--json`` object of one execution."""
    return {
        "problem": problem_name,
        "valid": bool(outcome.metrics.get("valid", outcome.failure_kind != "invalid_scenario")),
        "failed": bool(outcome.failed),
        "failure_kind": None if outcome.failure_kind == "none" else outcome.failure_kind,
        "verdict": outcome.verdict,
        "reference": getattr(outcome, "reference", None),
        "metrics": plain({**outcome.metrics, "detail": outcome.detail}),
    }


__all__ = ["parse_options", "plain", "result_json"]
