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
from ambiegen_ros.experiment import ExperimentSpec, run_experiment

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
    assert "too few runs to decide: with 3 and 3 runs" in proc.stdout  # 3 runs cannot show a difference
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
    assert "profile `replication`" in report
    assert "| 3.024 (30) |" in report  # ours next to the replication code's stored median (30 runs)
    # three runs against three cannot give p < 0.05 whatever the values: the report says so
    assert "**Too few runs to decide:** with 3 and 3 runs the two-sided Mann-Whitney p cannot fall below 0.1," in report
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


def test_full_model_experiment_on_the_vehicle_counts_failures(tmp_path):
    """End to end; the schedule itself is tested on a fake clock in test/experiment/test_rq3_pipeline.py."""
    out = tmp_path / "rq3"
    budget, cost = 2.0, 0.5
    # a driver who corners beyond the tyres' grip leaves the lane on most roads: failures to count
    code = ambiegen_main(["experiment", "--problem", "vehicle", "--algorithms", "nsga2,random", "--runs", "1",
                          "--jobs", "1", "--full-model", "--time-budget", str(budget), "--set", "corner_lat_accel=12",
                          "--execution-cost", str(cost), "--clock", "cpu",  # what a run gets does not depend on load
                          "--seed", "4", "--profile", "refined",  # its roads are never cut: executions in 2 s
                          "--out", str(out), "-q"])
    assert code == 0
    rows = {r["algorithm"]: r for r in read_csv(out / "results.csv")}
    assert set(rows) == {"nsga2", "random"}
    for alg, r in rows.items():
        executions, failures, invalid = int(r["executions"]), int(r["failures"]), int(r["invalid_tests"])
        screened = int(r["screened_out"])  # invalid tests decided before the car ran: not executions
        kinds = dict(item.split(":") for item in r["failure_kinds"].split(";"))
        # random vehicle roads mostly leave the map: screened out for free, perhaps none executed in 2 s
        assert executions <= budget / cost and sum(map(int, kinds.values())) == executions + screened > 0
        assert invalid == int(kinds.get("invalid_test", 0)) >= screened
        assert failures == executions - (invalid - screened) - int(kinds.get("none", 0)) - int(kinds.get("error", 0))
        assert float(r["failures_per_hour"]) == pytest.approx(failures * 3600 / budget, rel=1e-4)
        assert float(r["charged_s"]) <= budget
        record = json.loads((out / "runs" / f"{alg}-000.json").read_text())
        assert int(r["distinct_failures"]) == len(record["distinct_examples"]) <= failures
        assert sum(record["sample"].get("failed", [])) == failures  # fewer executions than the sample cap
    assert int(rows["nsga2"]["executions"]) > 0 and int(rows["nsga2"]["failures"]) > 0
    assert int(rows["nsga2"]["search_steps"]) >= 1
    stats = json.loads((out / "stats.json").read_text())
    assert {"distinct_per_hour", "distinct_failures", "invalid_tests"} <= {t["metric"] for t in stats["tests"]}
    report = (out / "report.md").read_text()
    assert "RQ3" in report and "profile `refined`" in report and "out_of_lane" in report
    assert (out / "failures.png").exists()
    gallery = sorted(p.name for p in (out / "gallery").iterdir())
    assert gallery and all(f"(gallery/{name})" in report for name in gallery if name.endswith(".png"))


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


@pytest.mark.parametrize("runs, warned", [(3, True), (5, False)])
def test_report_warns_only_when_the_runs_cannot_decide(runs, warned):
    from ambiegen_ros.core.stats import compare
    from ambiegen_ros.experiment.report import report

    rng = np.random.default_rng(runs)
    records = [{"algorithm": a, "run": k, "best_f1": float(rng.random() + (2 if a == "ga" else 0)),
                "diversity": float(rng.random()), "suite_size": 10} for a in ("ga", "random") for k in range(runs)]
    by = {a: [r for r in records if r["algorithm"] == a] for a in ("ga", "random")}
    doc = {"runs": {"ga": runs, "random": runs},
           "tests": [compare(m, "ga", [r[m] for r in by["ga"]], "random", [r[m] for r in by["random"]])
                     for m in ("best_f1", "diversity")]}
    settings = {"evaluations": 400, "population": 20, "offspring": 20}
    config = {"problem": "vehicle", "profile": "replication", "runs": runs, "command": ["ambiegen", "experiment"],
              "identity": {"ambiegen_ros": "0", "seed": 0, "settings": {"ga": settings, "random": settings}}}
    text = report(config, records, doc, plots=[])
    assert ("Too few runs to decide" in text) is warned
    assert "| 16.3 (16) |" in text and "| 7.874 (30) |" in text  # the stored medians, with their run counts


def test_full_model_searches_for_certified_failures_unless_told_the_papers_way():
    """Issue 26: --full-model's default search climbs each problem's certified objective; RQ1/RQ2 and
    --search-for paper keep the paper's objective and the replication profile; the user's own
    --profile and problem_config win key by key."""
    from ambiegen_ros.experiment.spec import resolve

    def identity(**kw):
        return resolve(ExperimentSpec(**{"problem": "vehicle", "algorithms": ("nsga2",), "runs": 1, **kw}))

    certified = identity(full_model=True, time_budget=60)
    assert (certified["profile"], certified["problem_config"]["objective"]) == ("refined", "certified")
    assert certified["full_model"]["search_for"] == "certified" and certified["full_model"]["novelty"] is True
    paper = identity(full_model=True, time_budget=60, search_for="paper")
    assert (paper["profile"], paper["problem_config"]["objective"]) == ("replication", "max_deviation")
    rq1 = identity(evaluations=100)
    assert (rq1["profile"], rq1["problem_config"]["objective"]) == ("replication", "max_deviation")
    mine = identity(full_model=True, time_budget=60, profile="replication")
    assert (mine["profile"], mine["problem_config"]["objective"]) == ("replication", "certified")
    thermostat = resolve(ExperimentSpec(problem="thermostat", algorithms=("ga",), runs=1, full_model=True,
                                        time_budget=60))
    assert thermostat["problem_config"]["objective"] == "certified" and thermostat["profile"] == "refined"
    assert resolve(ExperimentSpec(problem="robot", algorithms=("ga",), runs=1, full_model=True,
                                  time_budget=60))["profile"] == "refined"
    with pytest.raises(ValueError, match="--search-for"):
        identity(full_model=True, time_budget=60, search_for="fast")
