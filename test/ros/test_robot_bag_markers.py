"""A hazards campaign's robot bag shows what is in the world but not in the map (issue 48).

One real ``ambiegen campaign --stack nd`` with ``config/robot_hazards.yaml`` (3 random scenarios,
seed 3: one of them has a box, two posts and three walking people, another posts only, one
nothing) records ``/ambiegen/world/markers`` beside the robot's topics. Read back with
``ros.robot_bag``: every scenario's boxes, posts and people are the scenario's own
(``problem.environment(scenario).unmapped``), the people walk their paths, and the animation draws
them (boxes and posts once, a disc per person where the markers put them at each frame's time).
"""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]
CONFIG = REPO / "config" / "robot_hazards.yaml"

pytestmark = pytest.mark.skipif(os.environ.get("AMBIEGEN_TRANSPORT", "auto") == "rclpy",
                                reason="the campaign's driver node runs on the DDS backend")


@pytest.fixture(scope="module")
def hazards_bag(tmp_path_factory, module_domains) -> Path:
    out = tmp_path_factory.mktemp("hazards_campaign")
    env = dict(os.environ, ROS_DOMAIN_ID=str(module_domains()))
    env.pop("AMBIEGEN_TRANSPORT", None)
    run = subprocess.run([sys.executable, "-m", "ambiegen_ros.cli", "campaign", "--problem", "robot", "--stack", "nd",
                          "--config", str(CONFIG), "--algorithm", "random", "--evaluations", "3", "--seed", "3",
                          "--out", str(out)], cwd=REPO, env=env, capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    (mcap,) = out.glob("*.mcap")
    return mcap


def scenarios_and_runs(bag: Path):
    """(environment, RobotRun) of every scenario of the bag, by id."""
    from ambiegen_ros.nodes.replay import recorded_scenarios
    from ambiegen_ros.ros.robot_bag import read_index, read_run
    from ambiegen_ros.run_config import make_run

    problem, _ = make_run(config_file=CONFIG)
    index = read_index(bag)
    recorded = recorded_scenarios(bag)
    return {sid: (problem.environment(problem.parse(recorded.scenarios[sid].to_dict())), read_run(index, sid))
            for sid in index.entries}


def on_path(point: np.ndarray, path: np.ndarray) -> float:
    """Distance from ``point`` to the polyline ``path``."""
    a, b = path[:-1], path[1:]
    step = b - a
    s = np.clip(((point - a) * step).sum(axis=1) / np.maximum((step * step).sum(axis=1), 1e-12), 0.0, 1.0)
    return float(np.hypot(*(a + s[:, None] * step - point).T).min())


def test_the_bag_holds_each_scenarios_unmapped_obstacles_and_walking_people(hazards_bag):
    runs = scenarios_and_runs(hazards_bag)
    with_people = 0
    for sid, (env, run) in runs.items():
        hz = env.unmapped or {}
        if not any(hz.get(kind) for kind in ("boxes", "posts", "people")):
            assert run.markers == [], sid  # a world without hazards shows none
            continue
        assert len(run.markers) > 10, (sid, len(run.markers))
        times = [t for t, _ in run.markers]
        assert times == sorted(times) and times[0] >= 0.0 and times[-1] <= run.poses[-1, 0] + 0.5
        shift = np.tile(run.origin, 2)  # the world shows them in the map frame
        for t, drawn in run.markers:
            assert np.allclose(drawn["boxes"], np.asarray(hz["boxes"], dtype=float).reshape(-1, 4) + shift), sid
            posts = np.asarray(hz["posts"], dtype=float).reshape(-1, 3)
            assert np.allclose(drawn["posts"], posts + [*run.origin, 0.0]), sid
            assert len(drawn["people"]) == len(drawn["people_paths"]) == len(hz["people"])
            for k, person in enumerate(hz["people"]):
                path = np.asarray(person["path"], dtype=float) + run.origin
                assert np.allclose(drawn["people_paths"][k], path)
                assert drawn["people"][k, 2] == pytest.approx(person["radius"])
                assert on_path(drawn["people"][k, :2], path) < 1e-6, (sid, t, k)  # on its path, at every stamp
        if hz["people"]:
            with_people += 1
            first, last = run.markers[0][1]["people"], run.markers[-1][1]["people"]
            assert np.hypot(*(last[:, :2] - first[:, :2]).T).max() > 1.0, sid  # they walk
    assert with_people, "seed 3 of config/robot_hazards.yaml gives no scenario with people any more: pick another"


def test_the_animation_draws_the_hazards_and_moves_the_people(hazards_bag):
    import matplotlib.pyplot as plt
    from matplotlib.colors import to_rgba
    from matplotlib.patches import Circle, Rectangle

    from ambiegen_ros.viz import animation

    runs = scenarios_and_runs(hazards_bag)
    (sid, (env, run)), *_ = [(sid, item) for sid, item in runs.items() if (item[0].unmapped or {}).get("people")]
    fig, anim, facts = animation.robot_animation(run, fps=5, speed=4)
    try:
        ax, side = fig.axes[0], fig.axes[2]
        labels = [text.get_text() for text in side.get_legend().get_texts()]
        assert {"box, not in the map", "post, not in the map", "person (dashed: path)"} <= set(labels), labels
        boxes = [p for p in ax.patches if isinstance(p, Rectangle) and p.get_label() == "box, not in the map"]
        assert len(boxes) == 1 and np.allclose(boxes[0].get_bbox().get_points().ravel(), run.markers[0][1]["boxes"][0])
        purple = to_rgba(animation.PERSON_COLOR, 0.8)
        people = [p for p in ax.patches if isinstance(p, Circle) and np.allclose(p.get_facecolor(), purple)]
        assert len(people) == len(env.unmapped["people"])
        times, _ = animation.frame_times(float(run.poses[-1, 0]), 5, 4)
        anim._init_draw()  # draws frame 0, as saving does first
        where = []
        for k in (0, len(times) - 1):
            anim._draw_frame(k)  # what saving the GIF does for frame k
            shown = np.array([p.center for p in people if p.get_visible()])
            expected = animation._latest(run.markers, float(times[k]))["people"]
            assert np.allclose(shown, expected[:, :2]), (k, shown, expected)
            where.append(shown)
        assert np.hypot(*(where[1] - where[0]).T).max() > 1.0  # the discs move with the people
        (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
        for bx0, by0, bx1, by1 in run.markers[0][1]["boxes"]:  # a box near the route is in the view
            if np.hypot(*(run.poses[:, 1:3] - [(bx0 + bx1) / 2, (by0 + by1) / 2]).T).min() < animation.HAZARD_NEAR:
                assert x0 <= bx0 and bx1 <= x1 and y0 <= by0 and by1 <= y1
    finally:
        plt.close(fig)
    plain = next((run for env, run in runs.values() if not (env.unmapped or {}).get("boxes")), None)
    if plain is not None:  # a run without boxes gets no box in its legend
        fig, anim, _ = animation.robot_animation(plain, fps=2, speed=8)
        try:
            anim._init_draw()
            assert "box, not in the map" not in [t.get_text() for t in fig.axes[2].get_legend().get_texts()]
        finally:
            plt.close(fig)


def test_the_markers_topic_of_a_stack_in_a_namespace_is_found():
    from ambiegen_ros.ros.robot_bag import world_markers_topic

    assert world_markers_topic({"/odom": 5}) is None  # an old bag: no markers, nothing to draw
    assert world_markers_topic({"/ambiegen/world/markers": 3, "/stack0/ambiegen/world/markers": 3}) == \
        "/ambiegen/world/markers"
    assert world_markers_topic({"/stack1/ambiegen/world/markers": 3}) == "/stack1/ambiegen/world/markers"
    assert world_markers_topic({"/stack0/ambiegen/world/markers": 3, "/stack1/ambiegen/world/markers": 3}) is None
