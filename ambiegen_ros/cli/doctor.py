"""`ambiegen doctor`: the checks of ``ambiegen_ros.doctor`` as a subcommand, and ``main`` for the
launcher and ``python -m ambiegen_ros.doctor``, which run it before anything else could break."""
from __future__ import annotations

import argparse


def cmd_doctor(args: argparse.Namespace) -> int:
    from ..doctor import report, run_checks

    return report(run_checks(), as_json=args.json)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--json", action="store_true", help="print one JSON object (ok, checks[])")


def register(sub) -> None:
    p = sub.add_parser(
        "doctor", help="check this machine: transport backend, ROS environment, dependency versions, numba, messages"
    )
    add_arguments(p)
    p.set_defaults(func=cmd_doctor)


def main(argv: list[str] | None = None) -> int:
    from .. import doctor

    parser = argparse.ArgumentParser(prog="python -m ambiegen_ros.doctor", description=doctor.__doc__.split("\n")[0])
    add_arguments(parser)
    return cmd_doctor(parser.parse_args(argv))
