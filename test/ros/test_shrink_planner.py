"""``ambiegen shrink`` on the planner stack over real DDS, against a FAKE planner_server (issue 68).

``run_shrink`` starts what ``ambiegen shrink --stack planner`` starts (the recorder, our adapter in
``goal_mode:=plan`` and, through a fake ``ros2`` on PATH, test/helpers/fake_planner_dds.py, not
Nav2). The fake answers a straight line from start to goal, so the scenario whose wall crosses the
diagonal fails by collision; every try is a real run judged by our oracle on the costmap the fake
built from the map we sent. The shrink must end on a few cells of that one wall, with the other
walls and the whole border taken away, and its minimal map must still have failed on the stack.
"""
from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(Path(__file__).resolve().parent))

from ambiegen_ros.ros.transport import dds_backend  # noqa: E402
from ambiegen_ros.trials.configs import StackConfig, prepare  # noqa: E402
from ambiegen_ros.trials.rows import TrialLog  # noqa: E402
from ambiegen_ros.trials.runner import TrialSettings  # noqa: E402
from ambiegen_ros.trials.shrink import run_shrink  # noqa: E402
from ambiegen_ros.trials.suite import Entry, Suite, problem_of, scenario_key  # noqa: E402
from test_trials_planner import CONFIG, FAKE_ROS2, PARAMS, scenarios  # noqa: E402

pytestmark = pytest.mark.skipif(os.environ.get("AMBIEGEN_TRANSPORT", "auto") == "rclpy"
                                or not dds_backend.is_available(), reason="these tests drive the DDS backend")


def test_a_collision_shrinks_to_cells_of_the_one_wall_the_path_crosses(tmp_path, ros_domain, session_env):
    from ambiegen_ros.core.config import load_config_file

    scenario = scenarios()["wall"]
    problem_config = dict(load_config_file(CONFIG).get("problem_config") or {})
    suite = Suite("robot", problem_config, [])
    problem = problem_of(suite)
    entry = Entry(name="wall", scenario=scenario, key=scenario_key(scenario, problem_config))
    results, bags = tmp_path / "shrink.jsonl", tmp_path / "bags"
    bags.mkdir()
    env = {"PATH": f"{FAKE_ROS2}{os.pathsep}{os.environ['PATH']}", "FAKE_ROS2_PYTHON": sys.executable,
           "FAKE_NAV2_PLANNER": "straight", "AMBIEGEN_TRANSPORT": "dds"}
    settings = TrialSettings(stack="planner", results=results, bags=bags, repeat=1, domain_id=ros_domain,
                             start_timeout=120.0, ready_timeout=120.0, extra_env=env)
    prepared = prepare(StackConfig("fake", (str(PARAMS),)), "planner", None, 1.0, bags)
    said: list[str] = []
    feed = run_shrink(problem, entry, suite, prepared, settings, 1, said.append)
    assert feed.step == "done" and feed.minimal is not None, "\n".join(said)
    assert feed.signature == ("collision", "collision"), "\n".join(said)
    before = problem.environment(problem.parse(scenario)).grid
    after = problem.environment(problem.parse(feed.minimal)).grid
    wall = dict(problem.map_parts(problem.parse(scenario)))["wall 24"]  # the horizontal wall on row 25
    kept = {(int(x), int(y)) for y, x in zip(*np.nonzero(after))}
    assert kept and kept <= {(int(x), int(y)) for x, y in wall}, kept
    assert before.sum() > 100 and len(kept) <= 3  # the border and the other 49 walls are gone
    rows = TrialLog(results).rows()
    assert len(rows) == feed.count  # every try a row
    minimal_rows = [r for r in rows if r["key"] == scenario_key(feed.minimal, problem_config)]
    assert minimal_rows and all(r["failure_kind"] == "collision" for r in minimal_rows)
    assert any(r["failure_kind"] == "none" for r in rows)  # some tries lost the failure: it was tested
