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


def via_scenario() -> dict:
    """config/robot_planner_vias.yaml's room (0.25 m cells) with its walls stacked on column 48:
    start (2, 2), one via at (40, 6), the goal at (2, 40). The straight legs start -> via -> goal
    cross nothing; the straight line start -> goal passes 9.5 m from the via."""
    filler = {"size": 5, "position": 1, "row": 1, "along": 0, "offset": 0, "heading": 0, "extent": 0,
              "speed": 0.3, "delay": 0.0}
    elements = [{**filler, "type": "vertical", "position": 48} for _ in range(48)]
    for kind, x, y, yaw in (("start", 2, 2, 0), ("goal", 2, 40, 90), ("via", 40, 6, 90)):
        elements.append({**filler, "type": kind, "position": x, "row": y, "heading": yaw})
    return {"problem": "robot", "elements": elements}
