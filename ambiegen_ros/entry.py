"""The console scripts (``ambiegen``, ``ros2 run ambiegen_ros <node>``): a launcher per script.

A script's module imports pymoo, shapely, numpy ... at import time, before its ``main`` can check
them. If one is missing or too old to import at all, the user would see a traceback. The
launcher imports the module and, when that fails, prints the one-line dependency verdicts of
``deps`` instead (exit status 2). ``ambiegen doctor`` works even then.

Standard library only, like ``deps``: setup.py reads ``SCRIPTS`` before anything is installed.
"""
from __future__ import annotations

import sys
from importlib import import_module
from typing import Callable

# script name -> module whose main() it runs (setup.py makes `<name> = ambiegen_ros.entry:<name>`)
SCRIPTS: dict[str, str] = {
    "ambiegen": "ambiegen_ros.cli",
    "generator": "ambiegen_ros.nodes.generator",
    "recorder": "ambiegen_ros.nodes.recorder",
    "replay": "ambiegen_ros.nodes.replay",
    "robot_sim": "sim_nodes.robot_sim",
    "car_sim": "sim_nodes.car_sim",
    "thermostat_sim": "sim_nodes.thermostat_sim",
    "sut_adapter": "sim_nodes.sut_adapter",
    "external_sim": "sim_nodes.external_sim",
    "robot_world": "sim_nodes.robot_world",
    "nd_driver": "sim_nodes.nd_driver",
}


def launch(script: str, argv: list[str] | None = None) -> int:
    """Import the script's module and run its main; a failed import of a dependency is one line per problem."""
    args = sys.argv[1:] if argv is None else argv
    if script == "ambiegen" and args[:1] == ["doctor"]:
        module = import_module("ambiegen_ros.cli.doctor")  # needs none of the checked libraries
        return int(module.main(args[1:]) or 0)
    try:
        module = import_module(SCRIPTS[script])
    except Exception:
        from .deps import broken_environment

        if broken_environment(script):
            return 2
        raise  # not a dependency problem: a bug, shown as one
    return int(module.main() or 0)


def _entry(script: str) -> Callable[[], int]:
    def main() -> int:
        return launch(script)

    main.__name__ = script
    main.__doc__ = f"console script `{script}` -> {SCRIPTS[script]}.main"
    return main


# one module-level function per script, named as the script (what setup.py's entry points name)
globals().update({script: _entry(script) for script in SCRIPTS})
