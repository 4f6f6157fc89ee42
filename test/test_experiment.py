"""`ambiegen experiment`: tiny experiments end to end (files, statistics, resume, refusals, RQ3)."""
from __future__ import annotations

import csv
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from ambiegen_ros.cli import main as ambiegen_main
from ambiegen_ros.core.stats import cliffs_delta, mann_whitney
from ambiegen_ros.experiment import ExperimentSpec, FullModelTally, run_experiment
from ambiegen_ros.problems import get_problem
from ambiegen_ros.sims.outcome import Outcome

TINY = ["--problem", "thermostat", "--algorithms", "ga,random", "--runs", "3", "--evaluations", "400", "--seed", "11"]
TINY_SPEC = ExperimentSpec(problem="thermostat", algorithms=("ga", "random"), runs=3, seed=11, evaluations=400)


def ambiegen(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "ambiegen_ros", *args], capture_output=True, text=True, timeout=300)


def read_csv(path: Path) -> list[dict[str, str]]:
    with path.open() as fh:
        return list(csv.DictReader(fh))


@pytest.fixture(scope="module")
def tiny(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("exp") / "tiny"
    proc = ambiegen("experiment", *TINY, "--jobs", "2", "--out", str(out))
    assert proc.returncode == 0, proc.stderr
    assert "replication profile" in proc.stdout
    return out


def test_tiny_experiment_writes_consistent_outputs(tiny):
    rows = read_csv(tiny / "results.csv")
    assert len(rows) == 6
    for col in ("problem", "algorithm", "run", "seed", "evaluations", "wall_s", "best_f1", "diversity"):
        assert col in rows[0]
    assert {(r["algorithm"], int(r["run"])) for r in rows} == {(a, k) for a in ("ga", "random") for k in range(3)}
    assert all(int(r["seed"]) == 11 + int(r["run"]) for r in rows)  # run k uses seed + k
    assert all(int(r["evaluations"]) == 400 and r["profile"] == "replication" for r in rows)
    assert sorted(p.name for p in (tiny / "runs").iterdir()) == sorted(f"{a}-{k:03d}.json" for a in ("ga", "random") for k in range(3))

    # stats.json is the statistics of results.csv
    stats = json.loads((tiny / "stats.json").read_text())
    assert {(t["metric"], t["a"], t["b"]) for t in stats["tests"]} == {("best_f1", "ga", "random"), ("diversity", "ga", "random")}
    for t in stats["tests"]:
        ga = [float(r[t["metric"]]) for r in rows if r["algorithm"] == "ga"]
        rnd = [float(r[t["metric"]]) for r in rows if r["algorithm"] == "random"]
        assert t["cliffs_delta"] == pytest.approx(cliffs_delta(ga, rnd), abs=1e-6)
        assert t["p_value"] == pytest.approx(mann_whitney(ga, rnd), abs=1e-6)
        assert t["magnitude"] in ("negligible", "small", "medium", "large")

    # checkpoints end at each run's final best F1 (the convergence boxplots' last box)
    last = {}
    for c in read_csv(tiny / "checkpoints.csv"):
        if float(c["checkpoint"]) == 400:
            last[(c["algorithm"], int(c["run"]))] = float(c["best_f1"])
    assert last == {(r["algorithm"], int(r["run"])): pytest.approx(float(r["best_f1"]), rel=1e-5) for r in rows}

    report = (tiny / "report.md").read_text()
    ga_median = float(np.median([float(r["best_f1"]) for r in rows if r["algorithm"] == "ga"]))
    assert f"| GA (SO) | 3 | {ga_median:.4g} |" in report
    assert "profile `replication`" in report and "3.01" in report  # ours next to the replication code's median
    config = json.loads((tiny / "config.json").read_text())
    assert config["seed"] == 11 and config["profile"] == "replication" and config["versions"]["ambiegen_ros"]
    for png in ("convergence.png", "final_f1_diversity.png"):
        assert (tiny / png).stat().st_size > 1000


def test_resume_reruns_only_the_missing_run(tiny, tmp_path):
    out = tmp_path / "exp"
    shutil.copytree(tiny, out)
    lost = out / "runs" / "random-001.json"
    before = json.loads(lost.read_text())
    lost.unlink()  # as if the experiment had been killed while this run was in flight
    for p in (out / "runs").iterdir():
        os.utime(p, ns=(1, 1))  # a rewrite would give a run file a time of now
    kept = {p.name: p.stat().st_mtime_ns for p in (out / "runs").iterdir()}
    result = run_experiment(TINY_SPEC, out, jobs=1, resume=True, progress=False)
    assert len(result["records"]) == 6
    assert {p.name: p.stat().st_mtime_ns for p in (out / "runs").iterdir() if p.name in kept} == kept
    again = json.loads(lost.read_text())
    assert (again["seed"], again["best_f1"], again["diversity"]) == (before["seed"], before["best_f1"], before["diversity"])
    assert len(read_csv(out / "results.csv")) == 6


def test_existing_directory_is_never_overwritten(tiny, tmp_path, capsys):
    out = tmp_path / "exp"
    shutil.copytree(tiny, out)
    snapshot = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    assert ambiegen_main(["experiment", *TINY, "--out", str(out), "-q"]) == 2
    assert "not empty" in capsys.readouterr().err
    # resuming with another budget would mix two configs
    changed = [a if a != "400" else "500" for a in TINY]
    assert ambiegen_main(["experiment", *changed, "--out", str(out), "--resume", "-q"]) == 2
    err = capsys.readouterr().err
    assert "different config" in err and "settings.ga.evaluations" in err
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} == snapshot
    stranger = tmp_path / "not_an_experiment"
    stranger.mkdir()
    (stranger / "notes.txt").write_text("mine")
    assert ambiegen_main(["experiment", *TINY, "--out", str(stranger), "--resume", "-q"]) == 2
    assert (stranger / "notes.txt").read_text() == "mine" and len(list(stranger.iterdir())) == 1


class FakeClock:
    """The budget clock, moved only by the executor: the test sees events, never the machine's speed."""

    def __init__(self):
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


class ScriptedExecutor:
    """Stands in for a full-model executor: fails every scenario, taking ``delay`` seconds of ``clock``."""

    def __init__(self, clock: FakeClock, delay: float = 0.0):
        self.clock, self.delay = clock, delay

    def execute(self, scenario, seed=0):
        self.clock.now += self.delay
        return Outcome(objectives={"x": 1.0}, failed=True, failure_kind="collision", metrics={"m": 2.0})


def test_tally_counts_distinct_failures_and_drops_executions_past_the_budget():
    problem = get_problem("thermostat")
    rows = problem.sample_rows(2, np.random.default_rng(3))
    clock = FakeClock()
    tally = FullModelTally(problem, ScriptedExecutor(clock), clock, 60.0, seed=1, distinct_distance=0.0)
    assert not tally.seen(rows[0])
    tally.execute(rows[0], 1.0, 0.0)
    assert tally.seen(rows[0]) and not tally.seen(rows[1])
    tally.execute(rows[0], 1.0, 0.0)  # the same scenario again: a failure, not a distinct one
    tally.execute(rows[1], 2.0, 0.0)
    summary = tally.summary(budget=60)
    assert (summary["executions"], summary["failures"], summary["distinct_failures"]) == (3, 3, 2)
    assert summary["failure_nearest"][1] == 0.0 and summary["failure_nearest"][2] > 0
    assert summary["failures_per_hour"] == pytest.approx(3 * 60) and summary["failure_kinds"] == {"collision": 3}

    clock = FakeClock()
    late = FullModelTally(problem, ScriptedExecutor(clock, delay=0.05), clock, 0.01, seed=1, distinct_distance=0.0)
    late.execute(rows[0], 1.0, 0.0)
    assert (late.executions, late.failures, late.overrun) == (0, 0, 1)


def test_full_model_experiment_on_the_vehicle_counts_failures(tmp_path):
    out = tmp_path / "rq3"
    budget = 3.0
    # a driver who corners beyond the tyres' grip leaves the lane on most roads: failures to count
    code = ambiegen_main(["experiment", "--problem", "vehicle", "--algorithms", "nsga2,random", "--runs", "1",
                          "--jobs", "1", "--full-model", "--time-budget", str(budget), "--set", "corner_lat_accel=12",
                          "--clock", "cpu",  # process time: what a run gets does not depend on other load
                          "--seed", "4", "--out", str(out), "-q"])
    assert code == 0
    rows = {r["algorithm"]: r for r in read_csv(out / "results.csv")}
    assert set(rows) == {"nsga2", "random"}
    for alg, r in rows.items():
        executions, failures = int(r["executions"]), int(r["failures"])
        kinds = dict(item.split(":") for item in r["failure_kinds"].split(";"))
        assert executions > 0 and sum(map(int, kinds.values())) == executions
        assert failures == executions - int(kinds.get("none", 0)) - int(kinds.get("error", 0))
        assert float(r["failures_per_hour"]) == pytest.approx(failures * 3600 / budget, rel=1e-4)
        assert float(r["wall_s"]) >= budget  # the run ends once its clock passes the budget
        record = json.loads((out / "runs" / f"{alg}-000.json").read_text())
        assert int(r["distinct_failures"]) == sum(d > 0 for d in record["failure_nearest"]) <= failures
        assert sum(record["sample"]["failed"]) == failures  # fewer executions than the sample cap
    assert int(rows["random"]["failures"]) > 0
    assert int(rows["nsga2"]["rounds"]) >= 1
    stats = json.loads((out / "stats.json").read_text())
    assert {"failures_per_hour", "distinct_failures", "failure_rate"} <= {t["metric"] for t in stats["tests"]}
    assert any(row["metric"] == "failed" for row in stats["spearman"])
    report = (out / "report.md").read_text()
    assert "RQ3" in report and "profile `replication`" in report and "out_of_lane" in report
    assert (out / "failures.png").exists()


def test_a_failing_run_is_reported_and_the_others_finish(tmp_path, monkeypatch):
    from ambiegen_ros.experiment import runner

    real = runner.run_task

    def flaky(task):
        if (task["algorithm"], task["run"]) == ("random", 0):
            raise RuntimeError("simulator crashed")
        return real(task)

    monkeypatch.setattr(runner, "run_task", flaky)
    spec = ExperimentSpec(problem="thermostat", algorithms=("ga", "random"), runs=1, seed=2, evaluations=300)
    result = run_experiment(spec, tmp_path / "exp", jobs=1, progress=False)
    assert [(e["algorithm"], e["run"]) for e in result["errors"]] == [("random", 0)]
    assert "simulator crashed" in result["errors"][0]["error"]
    assert [r["algorithm"] for r in result["records"]] == ["ga"]
    assert not (tmp_path / "exp" / "runs" / "random-000.json").exists()  # --resume will run it
    assert [r["algorithm"] for r in read_csv(tmp_path / "exp" / "results.csv")] == ["ga"]


def test_break_even_execution_time_by_hand():
    from ambiegen_ros.experiment import break_even_seconds

    # search: every execution fails, 1.1 s of search per execution; random: 1 in 10 fails, free to generate.
    # 1 / (1.1 + c) = 0.1 / c  ->  c = 0.11 / 0.9
    assert break_even_seconds({"rate": 1.0, "gen": 1.1}, {"rate": 0.1, "gen": 0.0}) == pytest.approx(0.11 / 0.9)
    assert break_even_seconds({"rate": 0.1, "gen": 1.0}, {"rate": 0.1, "gen": 0.0}) is None
