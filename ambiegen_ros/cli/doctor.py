"""`ambiegen doctor`: the checks of ``ambiegen_ros.doctor`` as a subcommand.

The library owns the checks and the stand-alone ``main`` (``python -m ambiegen_ros.doctor``); this
module only adds the subcommand, and ``main`` for the launcher, which runs ``ambiegen doctor``
before anything else could break (``ambiegen_ros.entry``).
"""
from __future__ import annotations

import argparse


def cmd_doctor(args: argparse.Namespace) -> int:
    from ..doctor import report, run_checks

    return report(run_checks(), as_json=args.json)


def register(sub) -> None:
    p = sub.add_parser(
        "doctor", help="check this machine: transport backend, ROS environment, dependency versions, numba, messages"
    )
    p.add_argument("--json", action="store_true", help="print one JSON object (ok, checks[])")
    p.set_defaults(func=cmd_doctor)


def main(argv: list[str] | None = None) -> int:
    """``ambiegen doctor`` as the launcher runs it: the library's ``main`` under this name."""
    from ..doctor import main as doctor_main

    return doctor_main(argv, prog="ambiegen doctor")
