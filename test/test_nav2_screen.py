"""bench/nav2_screen.py (issue 49): the screen's AUC is measured on Nav2's recorded hazards runs,
with failures recorded before today's known-failure entries judged by them."""
from __future__ import annotations

import importlib.util
import json
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
RUNS = REPO / "docs" / "results" / "nav2" / "runs.jsonl"


def screen():
    spec = importlib.util.spec_from_file_location("nav2_screen", REPO / "bench" / "nav2_screen.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_screen_scores_every_executed_hazards_run_and_knows_the_box_stop():
    ns = screen()
    rows = ns.scored(ns.from_runs(RUNS))
    recorded = [json.loads(line) for line in RUNS.read_text().splitlines()]
    executed = [r for r in recorded if (r.get("problem_config") or {}).get("scenario") == "hazards"
                and r["failure_kind"] not in ns.NOT_RUN]
    assert len(rows) == len(executed) and all(r["features"] for r in rows)
    stops = [r for r in rows if r["kind"] == "nav2_aborted"]
    (box_stop,) = [r for r in stops if r["known"]]  # error 105 at a box: #6091, known today
    assert box_stop["scenario"] and len(stops) > 1  # the others gave up at a blocked passage (208): new
    assert all(not r["known"] for r in rows if r["kind"] == "collision")
    auc = ns.aucs(rows)
    assert auc["new_certified_failure"]["positives"] == sum(r["failed"] for r in executed) - 1
    assert all(0.0 <= v <= 1.0 for row in auc.values() for k, v in row.items() if k != "positives")
    # a batch where nothing failed has nothing to rank
    assert ns.aucs([r for r in rows if not r["failed"]])["certified_failure"]["positives"] == 0
