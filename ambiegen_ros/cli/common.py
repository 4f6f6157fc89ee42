"""What several `ambiegen` commands share: the ``--profile`` and ``--config`` options, the progress
line, the exit status of bad input, building a search from flags, and reading a scenario with the
problem that scores it.

Imports stay light: the command line starts before any command decides what it needs.
"""
from __future__ import annotations

import argparse
import sys
import time
from typing import Any

from ..core.errors import BadInput
from ..core.names import PROFILES

EXIT_BAD_INPUT = 2


def add_profile_option(parser: argparse.ArgumentParser) -> None:
    """``--profile``: which models score, build and draw the environment (recorded in outputs)."""
    parser.add_argument(
        "--profile", choices=PROFILES, default=None,
        help="fidelity profile: replication (default; the authors' replication code, which made the paper's "
        "tables) or refined (the paper's equations and competition road rules)",
    )


def add_config_option(parser: argparse.ArgumentParser) -> None:
    """``--config``: the one run-config option of every command that searches, scores or runs."""
    parser.add_argument(
        "--config", metavar="FILE.yaml",
        help="run config: its problem_config sets the problem's numbers (e.g. config/robot_small.yaml: a nearer "
        "robot goal); its search settings apply where the command searches",
    )


def scenario_problem(args: argparse.Namespace, data: dict[str, Any]) -> Any:
    """The problem that scores or runs a parsed scenario: its own ``problem``, with --config's
    problem_config and --profile (``run_config.scenario_problem``)."""
    from ..run_config import scenario_problem as build

    return build(data, getattr(args, "config", None), getattr(args, "profile", None))


def load_scenario(args: argparse.Namespace, path: str) -> tuple[Any, Any]:
    """Read and validate a scenario JSON file (``-``: standard input) -> (problem, scenario)."""
    from ..core.scenario import Scenario
    from ..problems.scenario_file import read_text

    data = Scenario.parse_json(read_text(path))
    problem = scenario_problem(args, data)
    return problem, problem.parse(data)


def build_search(args: argparse.Namespace) -> tuple[Any, Any]:
    """Problem + settings from --config and the flags (flags win)."""
    from ..run_config import SETTING_NAMES, make_run

    overrides = {name: getattr(args, name, None) for name in SETTING_NAMES}
    return make_run(args.problem, getattr(args, "config", None), profile=getattr(args, "profile", None), **overrides)


class Progress:
    """A one-line progress display on a terminal (stderr); silent when not a TTY."""

    def __init__(self, label: str, enabled: bool | None = None):
        self.label = label
        self.enabled = sys.stderr.isatty() if enabled is None else enabled
        self._last = 0.0

    def __call__(self, search: Any) -> None:
        if not self.enabled:
            return
        now = time.monotonic()
        if now - self._last < 0.2 and not search.done():
            return
        self._last = now
        s = search.settings
        if s.evaluations is not None:
            frac = search.evaluations / s.evaluations
            budget = f"{search.evaluations}/{s.evaluations} evals"
        else:
            frac = min(search.elapsed / s.time_budget, 1.0)
            budget = f"{search.evaluations} evals, {search.elapsed:.0f}/{s.time_budget:.0f} s"
        bar = "#" * int(frac * 24)
        last = search.history[-1] if search.history else {"front_size": 0}
        sys.stderr.write(
            f"\r{self.label} [{bar:<24}] {budget}  best F1 {search.best_f1:.3f}  front {last['front_size']}   "
        )
        sys.stderr.flush()

    def close(self) -> None:
        if self.enabled:
            sys.stderr.write("\n")


__all__ = ["BadInput", "EXIT_BAD_INPUT", "Progress", "add_config_option", "add_profile_option", "build_search",
           "load_scenario", "scenario_problem"]
