"""Starved runs in the trials (issue 70): the rerun policy runs one again at once and stops a streak of
them saying the machine does not hold the stack; every table counts them apart, never as a failure
nor as a run of the stack."""
from __future__ import annotations

from ambiegen_ros.trials import tables
from ambiegen_ros.trials.reruns import Reruns, starved
from ambiegen_ros.trials.rows import counted

POLICY = Reruns(max_errors=3, label="base", logs="/bags/base_x/logs")
WHY = "its controller ran at 4.5 Hz in its worst 2 s (under 50% of 20 Hz)"


def row(label: str = "base", key: str = "a", kind: str = "none", hungry: bool = False, **more) -> dict:
    """A row as the runner files it; ``hungry``: the error record of a starved run (what Nav2 said kept)."""
    metrics = {"error_kind": "starved", "starved": WHY, "sut_failure_kind": kind} if hungry else {}
    kind = "error" if hungry else kind
    failed = kind not in ("none", "invalid_test", "error", "sim_timeout")
    return {"label": label, "key": key, "failure_kind": kind, "failed": failed, "detail": f"starved: {WHY}",
            "run_id": "trials-base-x", "scenario_id": 7, "metrics": metrics, "time_s": 50.0, "recoveries": 0, **more}


def test_a_starved_row_is_an_error_record_not_a_run_of_the_stack():
    assert starved(row(kind="nav2_aborted", hungry=True)) and not counted(row(kind="nav2_aborted", hungry=True))
    assert not starved(row(kind="error")) and not starved(row(kind="nav2_aborted"))
    assert not starved({"failure_kind": "error", "metrics": None})


def test_a_starved_run_runs_again_first_with_its_extra_and_counts_in_the_streak():
    extra = {"crash_rerun_of": {"run_id": "r", "scenario_id": 1, "detail": "x"}}
    step = POLICY.after(row(kind="nav2_aborted", hungry=True), [], [], extra, errors=0)
    assert (step.count, step.tell, step.errors, step.stop) == (False, False, 1, None)
    assert step.again == extra and step.again is not extra
    plain = POLICY.after(row(kind="error"), [], [], {}, errors=0)
    assert plain.again is None, "an error of ours that is not starvation waits for the next invocation"


def test_a_streak_of_starved_runs_stops_saying_the_machine_does_not_hold_the_stack():
    step = POLICY.after(row(hungry=True), [], [], {}, errors=2)
    assert step.errors == 3 and "does not give the stack its computer" in step.stop and WHY in step.stop
    assert "run fewer stacks" in step.stop
    other = POLICY.after(row(kind="error"), [], [], {}, errors=2)
    assert "computer" not in other.stop
    after = POLICY.after(row(kind="collision"), [], [], {}, errors=2)
    assert after.errors == 0 and after.count, "a verdict of the stack ends the streak"


def test_every_table_counts_a_starved_run_apart_and_never_as_a_failure():
    rows = [row(kind="collision"), row(kind="none"), row(kind="nav2_aborted", hungry=True),
            row(kind="nav2_aborted", hungry=True), row(kind="error"), row(key="b", kind="none")]
    assert tables.kind_of(rows[2]) == "starved"
    md, data = tables.rerun_table(rows, "base", {"a": "s1", "b": "s2"})
    a = data["scenarios"]["s1"]
    assert (a["runs"], a["failures"], a["errors"], a["starved"]) == (2, 1, 1, 2)
    assert "starved" not in a["kinds"] and "nav2_aborted" not in a["kinds"]
    assert data["starved"] == 2 and data["failures"] == 1 and "2 starved runs not counted" in md[0]
    header = next(line for line in md if line.startswith("| scenario"))
    line = next(line for line in md if line.startswith("| s1"))
    column = header.split(" | ").index("starved")
    assert line.split(" | ")[column] == "2" and line.split(" | ")[column - 1] == "1"  # starved, then errors

    fix = [dict(r, label="fix") for r in rows[:2]] + [row(label="fix", kind="none", hungry=True)]
    md, data = tables.compare_tables(rows + fix, ["base", "fix"], {"a": "s1", "b": "s2"})
    assert data["configurations"]["base"]["starved"] == 2 and data["configurations"]["fix"]["starved"] == 1
    assert data["configurations"]["fix"]["failures"] == 1 and data["cells"]["s1"]["fix"]["starved"] == 1
    assert data["cells"]["s1"]["base"]["runs"] == 2
    assert any("starved (not counted)" in line for line in md)
