"""``ambiegen``: the command line, and the only part of the package that knows argparse.

One module per command (or small group); each has ``register(sub)``, which adds its subparser,
and a ``cmd_*`` that turns flags into library calls. Heavy libraries (numba, pymoo, matplotlib,
the DDS stack) are imported inside the commands, so ``ambiegen --help`` starts fast.
"""
from __future__ import annotations

import argparse
import sys

from .. import __version__
from . import campaign, doctor, evaluate, execute, experiment, nav2, search
from .common import EXIT_BAD_INPUT

REGISTRARS = (search.register, evaluate.register, execute.register, campaign.register,
              experiment.register, nav2.register, doctor.register)
"""In ``--help`` order: search, evaluate, show, execute, campaign, replay, recover, experiment,
nav2-params, doctor."""


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="ambiegen",
        description="AmbieGen: evolutionary search for environments in which autonomous systems fail.",
    )
    parser.add_argument("--version", action="version", version=f"ambiegen-ros {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for register in REGISTRARS:
        register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Parse, check the dependencies the command needs, run it; bad input is one line, exit status 2."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return EXIT_BAD_INPUT
    from ..core.attributes import ScenarioError
    from ..core.errors import BadInput, ConfigError
    from ..deps import broken_environment

    if args.command != "doctor" and broken_environment(f"ambiegen {args.command}"):  # fail before any work
        return EXIT_BAD_INPUT
    try:
        return int(args.func(args) or 0)
    except (BadInput, ScenarioError, ConfigError) as exc:
        print(f"ambiegen {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print(f"ambiegen {args.command}: interrupted", file=sys.stderr)
        return 130


__all__ = ["build_parser", "main"]
