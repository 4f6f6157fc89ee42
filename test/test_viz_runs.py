"""Run-directory pictures draw only what the algorithm has (issue 18: GA has no Pareto front)."""
from __future__ import annotations

import matplotlib.pyplot as plt
import pytest

from ambiegen_ros.core.runs import read_run, write_run
from ambiegen_ros.core.search import Search, SearchSettings
from ambiegen_ros.problems import get_problem
from ambiegen_ros.viz.runs import convergence_figure, plot_run

FRONT_LABEL = "non-dominated feasible scenarios"


def _run_dir(tmp_path, algorithm: str):
    problem = get_problem("thermostat")
    result = Search(problem, SearchSettings(algorithm=algorithm, evaluations=300, population=20, offspring=10,
                                            seed=3)).run()
    out = tmp_path / algorithm
    write_run(out, problem, result)
    return problem, out


@pytest.mark.parametrize("algorithm, front_axis", [("ga", False), ("random", False), ("nsga2", True)])
def test_convergence_has_a_front_axis_only_for_nsga2(tmp_path, algorithm, front_axis):
    problem, out = _run_dir(tmp_path, algorithm)
    run = read_run(out)
    fig = convergence_figure(problem, run["history"], run["suite"]["algorithm"], run["suite"]["seed"])
    try:
        ylabels = [ax.get_ylabel() for ax in fig.axes]
        legend = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    finally:
        plt.close(fig)
    assert (FRONT_LABEL in ylabels) is front_axis
    assert len(fig.axes) == (2 if front_axis else 1)
    assert ("front size" in legend) is front_axis
    assert "best F1" in legend and ylabels[0] == problem.f1_label


def test_plot_run_writes_the_pictures_for_ga(tmp_path):
    _, out = _run_dir(tmp_path, "ga")
    written = plot_run(out)
    assert [p.name for p in written] == ["convergence.png", "suite.png"]
    assert all(p.stat().st_size > 1000 for p in written)
