"""`ambiegen execute SCENARIO.json [--json] [--seed S] [--profile P] [--set OPTION=VALUE ...]`.

Runs one scenario on its full-model simulator (no ROS) and prints the verdict; with ``--json``
exactly one object ``{"problem", "valid", "failed", "failure_kind", "metrics", "profile"}`` (failure_kind
null when the run passed). Bad input (unreadable or malformed scenario, unknown option) raises
the CLI's ``BadInput`` / ``ScenarioError`` so ``ambiegen`` exits with status 2 and one line.
Register with ``register_cli(subparsers)``.
"""
from __future__ import annotations

import argparse
import json
import math
from typing import Any

import numpy as np


def _plain(value: Any) -> Any:
    """JSON-safe plain values (numpy scalars -> Python, non-finite floats -> null)."""
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return _plain(value.tolist())
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def parse_options(pairs: list[str]) -> dict[str, Any]:
    """``["tolerance=0.95", "controller=pid"]`` -> dict; values read as JSON when they parse."""
    from ..cli import BadInput

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
            raise BadInput(f"--set {key}: {text} is not a finite number")
        out[key.strip()] = value
    return out


def result_json(problem_name: str, outcome) -> dict[str, Any]:
    """The ``--json`` object of one execution."""
    return {
        "problem": problem_name,
        "valid": bool(outcome.metrics.get("valid", outcome.failure_kind != "invalid_scenario")),
        "failed": bool(outcome.failed),
        "failure_kind": None if outcome.failure_kind == "none" else outcome.failure_kind,
        "metrics": _plain({**outcome.metrics, "detail": outcome.detail}),
    }


def cmd_execute(args: argparse.Namespace) -> int:
    from ..cli import load_scenario_file
    from .full_model import full_model_executor

    problem, scenario = load_scenario_file(args.scenario, args.profile)
    executor = full_model_executor(problem, **parse_options(args.set))
    outcome = executor.execute(scenario, seed=args.seed)
    out = result_json(problem.name, outcome)
    out["profile"] = problem.profile
    if args.json:
        print(json.dumps(out))
        return 0
    verdict = "FAILED" if out["failed"] else ("not run (invalid)" if not out["valid"] else "passed")
    kind = f" [{out['failure_kind']}]" if out["failure_kind"] else ""
    print(f"{problem.name} [{problem.profile}]: {verdict}{kind}: {outcome.detail}")
    for key, value in out["metrics"].items():
        if key not in ("detail",):
            print(f"  {key}: {value:.4g}" if isinstance(value, float) else f"  {key}: {value}")
    print(f"  wall time: {outcome.elapsed_sec:.3f} s")
    return 0


def register_cli(sub) -> None:
    """Add the ``execute`` subcommand to ``ambiegen``'s subparsers."""
    p = sub.add_parser("execute", help="run one scenario on its full-model simulator (no ROS) and judge it")
    p.add_argument("scenario", metavar="SCENARIO.json")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--seed", type=int, default=0, help="simulator seed (sensor noise); default 0")
    p.add_argument("--set", action="append", default=[], metavar="OPTION=VALUE",
                   help="simulator option, e.g. oob_tolerance=0.95 or controller=pid (repeatable)")
    from ..cli import add_profile_option

    add_profile_option(p)
    p.set_defaults(func=cmd_execute)


def main(argv: list[str] | None = None) -> int:
    """Stand-alone entry with the same exit codes as ``ambiegen`` (for tests and scripts)."""
    from ..cli import main as ambiegen_main

    return ambiegen_main(argv)


__all__ = ["cmd_execute", "main", "parse_options", "register_cli", "result_json"]
