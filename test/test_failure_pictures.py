"""Pictures tell the truth (issue 47): a robot run's colour bar of seconds spans the run's duration,
a logged path without times never claims seconds, and a picture names the system that drove the run.

`docs/results/nav2/dwb_narrow_slot.png` once had a colour bar of "time [s]" up to 13,700 for a run of
274 s: the pose count of a Nav2 result read from its bag, under the label of seconds, and "full
model" in the title of a Nav2 run.
"""
from __future__ import annotations

import json
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pytest

from ambiegen_ros.problems import get_problem
from ambiegen_ros.sims.outcome import Outcome

REPO = Path(__file__).resolve().parents[1]
EASY = [{"type": "vertical", "size": 5, "position": 48} for _ in range(48)]  # walls away from the diagonal
EASY[9], EASY[29] = {"type": "horizontal", "size": 5, "position": 40}, {"type": "horizontal", "size": 5, "position": 8}


def drawn(ax, close: bool = True) -> dict:
    """What a reader sees of a robot picture: its title, and its colour bar's label and range."""
    (path,) = [c for c in ax.collections if c.get_array() is not None]  # the path, coloured
    bar = ax.figure.axes[-1]
    facts = {"title": ax.get_title(), "bar_label": bar.get_ylabel(), "bar_range": tuple(path.get_clim())}
    if close:
        plt.close(ax.figure)
    return facts


def recording(monkeypatch) -> list[dict]:
    """What every picture drawn from now on shows (``viz.execution.plot_execution``, as saved)."""
    from ambiegen_ros.viz import execution

    seen, plot = [], execution.plot_execution

    def plot_and_record(*args, **kwargs):
        ax = plot(*args, **kwargs)
        seen.append(drawn(ax, close=False))
        return ax

    monkeypatch.setattr(execution, "plot_execution", plot_and_record)
    return seen


@pytest.fixture(scope="module")
def robot():
    problem = get_problem("robot")
    return problem, problem.parse({"problem": "robot", "elements": EASY})


def test_a_full_model_run_is_coloured_in_seconds_over_its_duration(robot):
    from ambiegen_ros.sims.full_model import full_model_executor
    from ambiegen_ros.viz.execution import plot_execution

    problem, scenario = robot
    out = full_model_executor(problem, timeout=20.0, timeout_route_factor=0.0, timeout_margin=0.0).execute(scenario)
    facts = drawn(plot_execution(problem, scenario, out))
    assert facts["bar_label"] == "time [s]" and "full model" in facts["title"]
    assert facts["bar_range"] == pytest.approx((0.0, float(out.metrics["time"])))


def test_a_logged_path_without_times_never_claims_seconds(robot):
    """13,700 poses of a 274 s run, as a result read from a bag carries them (no stamps)."""
    from ambiegen_ros.viz.execution import plot_execution

    problem, scenario = robot
    poses = np.linspace([1.5, 1.5], [7.4, 20.8], 13_700)
    out = Outcome({}, True, "nav2_aborted", "Nav2 aborted its goal after 274.3 s (error 105)", trajectory=poses)
    facts = drawn(plot_execution(problem, scenario, out, system="Nav2 (time scale 2)"))
    assert facts["bar_label"] != "time [s]" and facts["bar_range"] == (0.0, 13_699.0)


def test_a_long_verdict_stays_inside_the_picture(robot):
    """The campaign gallery's title of a person collision once ran off both sides of the PNG."""
    from ambiegen_ros.viz.execution import plot_execution

    problem, scenario = robot
    detail = ("collision at (11.83, 14.62) after 42.1 s (reported on /collision: 'the robot drove into person 1 "
              "at (11.99, 14.50) moving at 0.48 m/s towards it')")
    out = Outcome({}, True, "collision", detail, trajectory=np.linspace([1.5, 1.5], [11.8, 14.6], 50))
    ax = plot_execution(problem, scenario, out, system="Nav2 (time scale 1)")
    ax.figure.canvas.draw()
    box, page = ax.title.get_window_extent(), ax.figure.bbox
    plt.close(ax.figure)
    assert page.x0 <= box.x0 and box.x1 <= page.x1 and "towards it" in ax.get_title()


def test_a_nav2_row_is_drawn_over_its_runs_simulated_time(monkeypatch, tmp_path):
    """``bench/nav2_maps.py`` (``--report``, ``--picture``) draws a row of ``runs.jsonl`` (every 10th
    pose) with its poses spread over the run's time: the bar ends at the run's duration."""
    monkeypatch.syspath_prepend(str(REPO / "bench"))
    import nav2_maps

    rows = [json.loads(line) for line in (REPO / "docs/results/nav2/runs.jsonl").read_text().splitlines()]
    row = next(r for r in rows if r["label"] == "narrow-s1-dwb-k1-confirm" and r["failed"])
    traj, timeline = nav2_maps.timed_path(row)
    assert len(timeline["t"]) == len(traj) == len(row["trajectory_every_10"])
    seen = recording(monkeypatch)
    assert nav2_maps.picture(f"narrow-s1-dwb-k1-confirm:0:{tmp_path / 'slot.png'}") == 0
    assert (tmp_path / "slot.png").read_bytes()[:4] == b"\x89PNG"
    assert seen[0]["bar_label"] == "time [s]" and seen[0]["bar_range"] == pytest.approx((0.0, float(row["time"])))
    assert seen[0]["title"].startswith("robot Nav2 (time scale 1) FAILED: nav2_aborted")



def test_the_gallery_names_the_system_under_test_and_draws_its_run_as_logged(robot, monkeypatch, tmp_path):
    """A campaign against Nav2 logs Nav2's result (through ``sut_adapter``): its failure picture is
    that run, titled Nav2 at its time scale, never our full model run again in its place."""
    from ambiegen_ros.nodes.gallery import draw_failures
    from ambiegen_ros.ros import conversions, qos, topics
    from ambiegen_ros.ros.mcap_log import McapLog
    from ambiegen_ros.ros.types import get_registry

    problem, scenario = robot
    poses = np.linspace([1.5, 1.5], [7.4, 20.8], 13_700)
    logged = Outcome({"robot_time": 274.3}, True, "nav2_aborted", "Nav2 aborted its goal after 274.3 s (error 105)",
                     metrics={"nav2_status": "aborted", "time_scale": 2.0, "stamp_clock": "sim", "time": 274.3},
                     trajectory=poses, failure_point=(7.4, 20.8))
    reg, bag = get_registry(), tmp_path / "nav2.mcap"
    with McapLog(bag) as log:
        typename = topics.SCENARIO_TYPES["robot"]
        scenarios = log.add_channel(topics.scenarios("robot"), typename, qos.DEFAULT)
        results = log.add_channel(topics.RESULTS, topics.RESULT_TYPE, qos.DEFAULT)
        msg = conversions.scenario_message(reg.new, 1000, problem, scenario, conversions.ScenarioMeta("run-1", 0))
        log.write(scenarios, reg.serialize(msg, typename), 1000)
        msg = conversions.result_message(reg.new, 2000, "run-1", 0, "robot", "nav2", logged)
        log.write(results, reg.serialize(msg, topics.RESULT_TYPE), 2000)
    seen = recording(monkeypatch)
    gallery = draw_failures(bag, tmp_path / "failures")
    assert len(gallery["failure_pictures"]) == 1 and len(seen) == 1
    (facts,) = seen
    assert facts["title"].startswith("robot Nav2 (time scale 2) FAILED: nav2_aborted"), facts
    assert "full model" not in facts["title"]
    assert facts["bar_label"] != "time [s]" and facts["bar_range"] == (0.0, 13_699.0)  # the logged poses


def test_an_experiments_f1_axis_names_its_own_objective(monkeypatch, tmp_path):
    """The certified search scores roads by another F1 than the paper's: its surrogate-against-full-
    model picture says so (not "max deviation from lane centre"), and names the full model's measure."""
    from ambiegen_ros.viz import experiment

    config = json.loads((REPO / "docs/results/experiments/vehicle-rq3-certified-30s/config.json").read_text())
    config["algorithms"] = ["nsga2"]
    records = [{"algorithm": "nsga2", "run": 0, "failures_per_hour": 12.0, "distinct_per_hour": 10.0,
                "failure_rate": 0.1, "sample": {"surrogate_f1": [1.5, 2.9], "objective": [0.1, 0.88], "failed": [0, 1]}}]
    labels, save = {}, experiment._save

    def save_and_record(fig, path):
        labels[path.name] = [(ax.get_xlabel(), ax.get_ylabel()) for ax in fig.axes]
        return save(fig, path)

    monkeypatch.setattr(experiment, "_save", save_and_record)
    experiment.plot_experiment(tmp_path, config, records, [])
    ((x, y),) = labels["surrogate_vs_full_model.png"]
    certified = get_problem("vehicle", config["identity"]["problem_config"]).f1_label
    assert x == f"surrogate F1: {certified}" and "certified" in certified
    assert y == "full model: largest fraction of the car outside its lane"
