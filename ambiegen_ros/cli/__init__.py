"""``ambiegen``: the command line, and the only part of the package that knows argparse.

One module per command (or small group); each has ``register(sub)``, which adds its subparser,
and a ``cmd_*`` that turns flags into library calls. Heavy libraries (numba, pymoo, matplotlib,
the DDS stack) are imported inside the commands, so ``ambiegen --help`` starts fast.
"""
from __future__ import annotations

import argparse
import sys

from importlib import import_module

from .. import __version__
from .common import EXIT_BAD_INPUT

REGISTRARS = ("search", "evaluate", "execute", "campaign", "trials", "experiment", "nav2", "doctor")
"""The command modules, each with its ``register(sub)``; in ``--help`` order: search, evaluate, show,
execute, campaign, replay, recover, rerun, compare, stack-search, shrink, planner-report, experiment, nav2-params,
robot-profile, doctor."""

COMMANDS = {"search": "search", "evaluate": "evaluate", "show": "evaluate", "execute": "execute",
            "campaign": "campaign", "replay": "campaign", "recover": "campaign", "rerun": "trials",
            "compare": "trials", "stack-search": "trials", "shrink": "trials", "planner-report": "trials",
            "experiment": "experiment",
            "nav2-params": "nav2", "robot-profile": "nav2", "doctor": "doctor"}
"""Command -> the module of ``REGISTRARS`` that registers it (test/test_cli.py checks the two agree)."""


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The whole command line; given a ``command`` of ``COMMANDS``, only the parsers of the module that
    registers it: ``ambiegen evaluate`` then neither imports nor builds the campaign's options (whose
    registration imports the campaign library; issue 47: start-up)."""
    parser = argparse.ArgumentParser(
        prog="ambiegen",
        description="AmbieGen: evolutionary search for environments in which autonomous systems fail.",
    )
    parser.add_argument("--version", action="version", version=f"ambiegen-ros {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for module in ([COMMANDS[command]] if command in COMMANDS else REGISTRARS):
        import_module(f".{module}", __name__).register(sub)
    return parser


STOPPABLE = ("campaign", "replay", "experiment", "rerun", "compare", "stack-search", "shrink")
"""Commands with processes, pools or files to close: SIGTERM, SIGHUP and SIGINT stop them alike, the
children stopped and waited for, and the exit status is 128 + the signal's number."""


def main(argv: list[str] | None = None) -> int:
    """Parse, check the dependencies the command needs, run it; bad input is one line, exit status 2."""
    import signal

    if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:  # a background job of a script: Ctrl-C is ours again
        signal.signal(signal.SIGINT, signal.default_int_handler)
    argv = sys.argv[1:] if argv is None else list(argv)
    try:
        parser = build_parser(argv[0] if argv else None)
        args = parser.parse_args(argv)
    except KeyboardInterrupt:
        return 128 + signal.SIGINT
    if not getattr(args, "func", None):
        parser.print_help()
        return EXIT_BAD_INPUT
    return _run(args)


def _run(args: argparse.Namespace) -> int:
    """The command, its errors as one line, a stop signal as its exit status (``signals.install``)."""
    import signal

    stop_signal, previous = None, None
    try:
        from ..core.attributes import ScenarioError
        from ..core.errors import BadInput, ConfigError
        from ..deps import broken_environment

        if args.command != "doctor" and broken_environment(f"ambiegen {args.command}"):  # fail before any work
            return EXIT_BAD_INPUT
        if args.command in STOPPABLE:
            from ..ros.transport import signals

            previous = signals.install(raise_stop=True)
            stop_signal = signals.stop_signal
        try:
            code = int(args.func(args) or 0)
        except (BadInput, ScenarioError, ConfigError) as exc:
            print(f"ambiegen {args.command}: error: {exc}", file=sys.stderr)
            return EXIT_BAD_INPUT
        signum = stop_signal() if stop_signal else None
        if signum:  # the command stopped its work and said what it kept
            print(f"ambiegen {args.command}: stopped by {signal.Signals(signum).name}", file=sys.stderr)
            return 128 + signum
        return code
    except KeyboardInterrupt as exc:
        signum = getattr(exc, "signum", None) or (stop_signal and stop_signal()) or signal.SIGINT
        print(f"ambiegen {args.command}: interrupted ({signal.Signals(signum).name})", file=sys.stderr)
        return 128 + signum
    finally:
        if previous is not None:
            from ..ros.transport import signals

            signals.restore(previous)


__all__ = ["COMMANDS", "REGISTRARS", "STOPPABLE", "build_parser", "main"]
