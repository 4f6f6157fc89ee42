"""bench/block_probes.py (issue 49): a probe is a scenario whose standing person leaves the true world
no route, which the reference still passes by waiting; the suite file is never overwritten."""
from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
NAV2 = REPO / "docs" / "results" / "nav2"


def builder():
    spec = importlib.util.spec_from_file_location("block_probes", REPO / "bench" / "block_probes.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def first_scenario(path: Path) -> dict:
    return json.loads(path.read_text())["suite"][0]["scenario"]


def test_a_person_in_the_only_gap_shuts_the_world_and_a_walker_does_not():
    from ambiegen_ros.core.config import load_config_file
    from ambiegen_ros.problems import get_problem
    from ambiegen_ros.sims.full_model import full_model_executor

    bp = builder()
    problem = get_problem("robot", dict(load_config_file(REPO / "config" / "robot_hazards.yaml")["problem_config"]))
    config = full_model_executor(problem).config
    blocked = problem.parse(first_scenario(NAV2 / "mppi_gives_up_blocked_suite.json"))  # Nav2 gave up here (208)
    walker = problem.parse(first_scenario(NAV2 / "mppi_person_collision_scenario.json"))  # a person walking a corridor
    assert bp.shuts_the_world(problem.environment(blocked), config)
    assert not bp.shuts_the_world(problem.environment(walker), config)
    assert bp.seed_list("3-5") == [3, 4, 5] and bp.seed_list("7") == [7]


def test_an_existing_suite_file_is_never_overwritten(tmp_path):
    taken = tmp_path / "probes.json"
    taken.write_text("mine")
    with pytest.raises(SystemExit, match="not overwritten"):
        builder().main(["--seeds", "1", "-o", str(taken)])
    assert taken.read_text() == "mine"
