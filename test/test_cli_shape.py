"""`ambiegen --help` and every subcommand's options stay what users learned (issue 15's promise).

``test/data/cli_shape.json`` is the parser's shape frozen before the command line became a package.
A deliberate change to an option updates it with:
``python -c "import json,sys; sys.path.insert(0,'test/helpers'); from cli_shape import parser_shape;
from ambiegen_ros.cli import build_parser; print(json.dumps(parser_shape(build_parser()), indent=1, sort_keys=True))"
> test/data/cli_shape.json``.
"""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from cli_shape import parser_shape

from ambiegen_ros.cli import build_parser

GOLDEN = Path(__file__).parent / "data" / "cli_shape.json"
ROOT = Path(__file__).resolve().parents[1]


def test_every_command_and_option_is_unchanged():
    golden = json.loads(GOLDEN.read_text())
    shape = json.loads(json.dumps(parser_shape(build_parser())))
    assert sorted(shape["commands"]) == sorted(golden["commands"])
    for name, expected in golden["commands"].items():
        assert shape["commands"][name] == expected, f"`ambiegen {name}` changed its options or help"
    assert shape == golden


def test_help_lists_the_commands_in_their_usual_order():
    run = subprocess.run([sys.executable, "-m", "ambiegen_ros", "--help"], cwd=ROOT, capture_output=True,
                         text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    listed = [line.split()[0] for line in run.stdout.splitlines()
              if line.startswith("    ") and not line.startswith("     ")]
    assert listed == ["search", "evaluate", "show", "execute", "campaign", "replay", "recover", "rerun", "compare",
                      "stack-search", "shrink", "planner-report", "experiment",
                      "nav2-params", "robot-profile", "doctor"]
