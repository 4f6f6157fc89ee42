"""The hazards scenarios of ``test/data/robot_hazards_nd.json``, one place for the tests that use them."""
from __future__ import annotations

import json
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]


def hazards_case(why: str):
    """The problem of that file's config and its scenario whose description starts with ``why``."""
    from ambiegen_ros.run_config import make_run

    data = json.loads((REPO / "test" / "data" / "robot_hazards_nd.json").read_text())
    problem = make_run("robot", str(REPO / data["config"]), seed=0)[0]
    case = next(c for c in data["cases"] if c["why"].startswith(why))
    return problem, problem.parse(case["scenario"])
