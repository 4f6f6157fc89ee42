"""The runner's rerun policy (``trials.reruns``) branch by branch, and ``--start-timeout`` per stack.

No process runs here: the policy is a function of the run's row, its deaths, the restarts and its
``extra``, as the runner gives them (``runner._run_configuration``).
"""
from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import pytest

from ambiegen_ros.trials.reruns import Reruns

REPO = Path(__file__).resolve().parents[1]
POLICY = Reruns(max_errors=3, label="base", logs="/bags/base_x/logs")
CRASH = "the stack crashed: controller_server killed by SIGSEGV, 4.1 s into the run"


def row(kind: str = "none", detail: str = "", **more) -> dict:
    return {"failure_kind": kind, "detail": detail, "run_id": "trials-base-x", "scenario_id": 7, **more}


def death(part: str) -> SimpleNamespace:
    return SimpleNamespace(part=part, process="robot_world" if part == "ours" else "controller_server")


RESTARTED = [{"event": "restart", "process": "robot_world", "ok": True}]
NOT_BACK = [{"event": "restart", "process": None, "why": "robot_world did not come back", "ok": False}]


def test_a_verdict_of_the_stack_counts_is_told_and_ends_a_streak_of_errors():
    for kind in ("none", "collision", "invalid_test"):
        step = POLICY.after(row(kind), [], [], {}, errors=2)
        assert (step.count, step.tell, step.errors, step.again, step.stop) == (True, True, 0, None, None), kind


def test_a_crash_runs_once_more_first_and_its_rerun_is_not_run_again():
    first = POLICY.after(row("sut_crashed", CRASH), [death("stack")], [], {}, errors=1)
    assert first.count and first.tell and first.errors == 0 and first.stop is None
    assert first.again == {"crash_rerun_of": {"run_id": "trials-base-x", "scenario_id": 7, "detail": CRASH}}
    again = POLICY.after(row("sut_crashed", CRASH), [death("stack")], [], first.again, errors=0)
    assert again.count and again.again is None, "a crash's rerun that crashes again is filed, not run a third time"
    assert not again.tell, "the search was told the first run's verdict already"
    passed = POLICY.after(row("none"), [], [], first.again, errors=0)
    assert passed.count and not passed.tell and passed.again is None


def test_a_run_whose_part_of_ours_died_runs_again_with_its_extra_and_is_no_error_in_a_row():
    extra = {"crash_rerun_of": {"run_id": "r", "scenario_id": 1, "detail": CRASH}}
    step = POLICY.after(row("error", "robot_world killed by SIGKILL (ours)"), [death("ours")], RESTARTED, extra, 2)
    assert not step.count and not step.tell and step.errors == 2 and step.stop is None
    assert step.again == extra and step.again is not extra
    assert POLICY.after(row("error"), [death("ours")], RESTARTED, {}, 0).again == {}


def test_an_error_of_ours_that_a_restart_does_not_explain_counts_in_the_streak():
    unexplained = POLICY.after(row("error", "x"), [death("ours")], NOT_BACK, {}, errors=0)
    assert unexplained.errors == 1 and unexplained.again == {} and not unexplained.count
    lost = POLICY.after(row("sim_timeout", "the runner got no result in 300 s"), [], [], {}, errors=1)
    assert lost.errors == 2 and lost.again is None and lost.stop is None
    assert lost.tell, "no rerun follows: the search is told the error rather than left waiting"
    # the stack died before the run began (the adapter's error, no verdict): again, on the restarted stack,
    # in the streak (a stack that dies before every run stops the configuration at max_errors)
    stack_died = POLICY.after(row("error", "nd_driver killed by SIGKILL (before the run began): run it again"),
                              [death("stack")], RESTARTED, {}, errors=0)
    assert stack_died.errors == 1 and stack_died.again == {} and not stack_died.tell


def test_errors_in_a_row_stop_the_configuration_at_max_errors_naming_the_last_and_the_logs():
    errors, steps = 0, []
    for n in range(3):
        steps.append(POLICY.after(row("error", f"error {n} " + "x" * 300), [], [], {}, errors))
        errors = steps[-1].errors
    assert [s.stop is None for s in steps] == [True, True, False]
    stop = steps[-1].stop
    assert stop.startswith("[base] 3 errors in a row, the last: error 2 x") and "error 1" not in stop
    assert "(logs: /bags/base_x/logs); rerun the same command to resume" in stop
    assert len(stop) < 200 + 120, "the detail is cut at 200 characters"
    # a restart of ours that explains the error does not move the streak towards the stop
    assert POLICY.after(row("error"), [death("ours")], RESTARTED, {}, 2).stop is None
    assert Reruns(1, "b", "l").after(row("error"), [], [], {}, 0).stop is not None


# --- --start-timeout ------------------------------------------------------------------------------
def settings_of(*flags: str):
    from ambiegen_ros.cli import build_parser
    from ambiegen_ros.cli.trials import _settings

    args = build_parser().parse_args(["rerun", "suite.json", "--results", "r.jsonl", "--known-failures", "none",
                                      *flags])
    return _settings(args, Path("r.jsonl"))


def test_start_timeout_defaults_by_stack_and_a_value_given_holds_on_every_stack():
    from ambiegen_ros.trials.runner import DEFAULT_START_TIMEOUT, TrialSettings

    assert settings_of("--stack", "external").start_timeout == 600.0
    assert settings_of("--stack", "bringup").start_timeout == DEFAULT_START_TIMEOUT == 120.0
    assert settings_of("--stack", "nd").start_timeout == DEFAULT_START_TIMEOUT
    for stack in ("external", "bringup", "nd"):
        assert settings_of("--stack", stack, "--start-timeout", "45").start_timeout == 45.0, stack
    assert TrialSettings(stack="external", results=Path("r"), bags=Path("b")).start_timeout == 600.0
    assert TrialSettings(stack="external", results=Path("r"), bags=Path("b"), start_timeout=30).start_timeout == 30
    from ambiegen_ros.cli.common import BadInput

    with pytest.raises(BadInput, match="--start-timeout"):
        settings_of("--stack", "nd", "--start-timeout", "0")


def test_the_adapter_and_the_runners_wait_take_the_start_timeout_given_for_an_external_stack(tmp_path):
    """Both places that read it: the adapter's parameter (``stack_nodes``) and how long the runner
    waits for an answer (``StackSession.limit``), which grows by exactly the start timeout."""
    import json

    from ambiegen_ros.trials.configs import Prepared, StackConfig
    from ambiegen_ros.trials.runner import TrialSettings
    from ambiegen_ros.trials.session import StackSession, stack_nodes
    from ambiegen_ros.trials.suite import load_suite, problem_of

    cases = json.loads((REPO / "test" / "data" / "robot_hazards_nd.json").read_text())
    (tmp_path / "suite.json").write_text(json.dumps({"suite": [{"scenario": cases["cases"][0]["scenario"]}]}))
    suite = load_suite([str(tmp_path / "suite.json")], str(REPO / cases["config"]))
    session = SimpleNamespace(problem=problem_of(suite), prepared=Prepared(StackConfig("base", ()), {}, None, "d", {},
                                                                           None, 0.5))
    limits = {}
    for given in (None, 45.0, 900.0):
        session.settings = TrialSettings(stack="external", results=tmp_path / "r", bags=tmp_path, start_timeout=given)
        nodes = stack_nodes(session.settings, session.prepared, tmp_path / "p.yaml", tmp_path / "b.mcap", "t")
        adapter = [n for n in nodes if n.executable == "sut_adapter"][0]
        assert adapter.parameters["start_timeout"] == (600.0 if given is None else given)
        limits[given] = StackSession.limit(session, suite.entries[0])
    assert limits[45.0] - limits[None] == pytest.approx(45.0 - 600.0)
    assert limits[900.0] - limits[None] == pytest.approx(300.0)
