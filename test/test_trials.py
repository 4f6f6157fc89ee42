"""Trials without a stack: suites, configurations, the results file and every table, on recorded rows.

``ambiegen rerun`` and ``compare`` (``ambiegen_ros.trials``) answer a Nav2 engineer's three questions
about a failure; the runs themselves are tested on our ND stack (``test/ros/test_trials_nd.py``).
Here: the rows a run appends decide the tables, so the tables are checked on rows built by hand,
where the right answer is known (k of N, fixed / kept / broken, Fisher's p, the cost, contact speeds).
"""
from __future__ import annotations

import json
from pathlib import Path

import pytest
from scipy.stats import fisher_exact

from ambiegen_ros.core.errors import BadInput
from ambiegen_ros.sims.obstacles import person_contact_detail
from ambiegen_ros.trials import configs, report, tables, trees
from ambiegen_ros.trials.rows import TrialLog, counted
from ambiegen_ros.trials.suite import load_suite, scenario_key

REPO = Path(__file__).resolve().parents[1]
CASES = json.loads((REPO / "test" / "data" / "robot_hazards_nd.json").read_text())
CONFIG = str(REPO / CASES["config"])


def row(label: str, key: str, kind: str = "none", repeat: int = 1, time_s: float = 60.0, recoveries: int = 0,
        detail: str = "", known: str | None = None, digest: str = "d") -> dict:
    failed = kind not in ("none", "invalid_test", "error", "sim_timeout")
    return {"label": label, "key": key, "failure_kind": kind, "failed": failed, "repeat": repeat, "time_s": time_s,
            "recoveries": recoveries, "detail": detail, "known_failure": known, "config_digest": digest}


# --- tables ----------------------------------------------------------------------------------------
def test_k_of_n_counts_the_stacks_runs_by_kind_and_leaves_our_errors_out():
    rows = [row("jazzy", "a", "collision"), row("jazzy", "a", "collision", 2), row("jazzy", "a", "none", 3, recoveries=4),
            row("jazzy", "a", "error", 4), row("jazzy", "b", "nav2_aborted", known="mppi_unmapped")]
    md, data = tables.rerun_table(rows, "jazzy", {"a": "s4:6", "b": "s4:7"})
    a = data["scenarios"]["s4:6"]
    assert (a["runs"], a["failures"], a["errors"], a["status"]) == (3, 2, 1, "fails")
    assert a["kinds"] == {"collision": 2, "near_miss": 1}
    assert data["scenarios"]["s4:7"]["kinds"] == {"known:nav2_aborted": 1}  # known, and still Nav2's failure
    line = next(line for line in md if line.startswith("| s4:6"))
    assert "2 of 3: collision 2" in line and "| 1 (1) |" in line  # passed once, after recoveries
    assert not counted(row("x", "a", "sim_timeout")) and counted(row("x", "a", "invalid_test"))


def test_reproduction_uses_the_two_in_three_bar():
    rows = [row("j", "a", "collision"), row("j", "a", "collision", 2), row("j", "a", "none", 3),
            row("j", "b", "collision"), row("j", "b", "none", 2), row("j", "b", "none", 3),
            row("j", "c", "none"), row("j", "c", "none", 2), row("j", "c", "none", 3)]
    out = tables.reproduction(rows, "j", {"a": "a", "b": "b", "c": "c"})
    assert out == {"scenarios_run": 3, "reproduce": 1, "ever_fail": 2, "never_fail": 1, "bar": pytest.approx(2 / 3)}


def fix_rows() -> list[dict]:
    """Baseline fails 'hit' 3 of 3 and passes 'easy' and 'wall'; the fix passes 'hit' 3 of 3, is slower
    on 'easy' and breaks 'wall' once."""
    rows = []
    for r in (1, 2, 3):
        rows += [row("jazzy", "hit", "collision", r), row("fix", "hit", "none", r, time_s=80.0),
                 row("jazzy", "easy", "none", r, time_s=50.0 + r), row("fix", "easy", "none", r, time_s=75.0 + r,
                                                                        recoveries=r),
                 row("jazzy", "wall", "none", r, time_s=40.0),
                 row("fix", "wall", "nav2_aborted" if r == 1 else "none", r, time_s=44.0)]
    return rows


def test_compare_says_what_a_fix_fixes_keeps_and_breaks_with_fishers_test():
    names = {"hit": "hit", "easy": "easy", "wall": "wall"}
    md, data = tables.compare_tables(fix_rows(), ["jazzy", "fix"], names)
    fix = data["configurations"]["fix"]
    assert fix["fixed"] == ["hit"] and fix["kept"] == [] and fix["broken"] == ["wall"]
    assert (fix["failures"], fix["runs"]) == (1, 9)
    assert fix["p_pooled"] == pytest.approx(fisher_exact([[3, 6], [1, 8]])[1])
    per = next(line for line in md if line.startswith("| hit"))
    assert "3 of 3: collision 3" in per and "0 of 3" in per
    assert per.endswith(f"| {fisher_exact([[3, 0], [0, 3]])[1]:.2g} |")  # 0.1: three runs a side cannot do better


def test_the_cost_of_a_fix_is_measured_where_the_baseline_passes():
    _, data = tables.compare_tables(fix_rows(), ["jazzy", "fix"], {"hit": "hit", "easy": "easy", "wall": "wall"})
    cost = data["cost"]
    assert cost["jazzy"]["scenarios"] == 2 and cost["jazzy"]["time_median_s"] == pytest.approx(45.5)
    fix = cost["fix"]
    assert (fix["failures"], fix["runs"], fix["scenarios_broken"]) == (1, 6, 1)
    assert fix["recoveries_median"] == pytest.approx(1.0)  # 0, 0 on 'wall', 1, 2, 3 on 'easy'
    assert fix["time_vs_baseline_median"] == pytest.approx(((77 / 52) + (44 / 40)) / 2)  # medians per scenario


def test_contacts_report_both_speeds_and_what_a_threshold_would_drop():
    detail = "collision at (1.00, 2.00) (reported on /collision: '{}')"
    rows = [row("j", "a", "collision", detail=detail.format(person_contact_detail(0, (1, 2), 0.08, 0.07, 1.1))),
            row("j", "a", "collision", 2, detail=detail.format(person_contact_detail(0, (1, 2), 0.31, 0.3, -0.2))),
            row("j", "b", "collision", detail="collision at (3.00, 3.00) (reported on /collision: 'touching a wall')")]
    md, data = tables.contact_table(rows, {"a": "a", "b": "b"})
    assert data["collisions_with_people"] == 2  # the wall is not a contact with a person
    assert data["dropped_by_threshold"] == {"0.05": 0, "0.1": 1, "0.2": 1}
    assert data["speeds"][0]["person_along_mps"] == pytest.approx(1.1)
    assert any("0.1 m/s drops 1" in line for line in md)


# --- suites -----------------------------------------------------------------------------------------
def test_a_suite_file_names_its_scenarios_and_its_problem_settings(tmp_path):
    suite_file = tmp_path / "people_suite.json"
    cases = CASES["cases"][:2]
    suite_file.write_text(json.dumps({"problem_config": {"profile": "refined", "scenario": "hazards", "goal": [14, 14],
                                                         "start_area": [[1, 1], [4, 4]], "max_hazards": 6,
                                                         "route_cap": 100.0},
                                      "suite": [{"scenario": c["scenario"]} for c in cases] + [cases[0]["scenario"]]}))
    suite = load_suite([str(suite_file)])
    assert [e.name for e in suite.entries] == ["people:0", "people:1"] and suite.duplicates == 1
    assert suite.problem_config["scenario"] == "hazards"
    given = load_suite([str(suite_file)], CONFIG)  # --config gives the same settings: the same keys
    assert [e.key for e in given.entries] == [e.key for e in suite.entries]
    assert suite.entries[0].key == scenario_key(suite.entries[0].scenario, suite.problem_config)


def test_the_failures_of_a_results_file_are_a_suite(tmp_path):
    """``rerun RESULTS.jsonl``: a search's failing rows, once each, by their rows' names; a pass, a
    known failure and a repeat are left out, and rows without a failure are one clear line."""
    settings = {"profile": "refined", "scenario": "hazards", "goal": [14, 14], "start_area": [[1, 1], [4, 4]],
                "max_hazards": 6, "route_cap": 100.0}
    made = [dict(key=f"k{i}", label="nd", scenario=c["scenario"], scenario_name=f"g1-{i}", problem="robot",
                 problem_config=settings,
                 failed=i != 1, known_failure=("navfn_cap" if i == 2 else None), verdict="FAIL(collision)", detail="d")
            for i, c in enumerate(CASES["cases"][:4])]
    rows = tmp_path / "search.jsonl"
    rows.write_text("".join(json.dumps(r) + "\n" for r in made + [made[0]]))
    suite = load_suite([str(rows)])
    assert [e.name for e in suite.entries] == ["g1-0", "g1-3"]  # the pass, the known one, the repeat: out
    assert suite.problem_config["scenario"] == "hazards"
    none = tmp_path / "passes.jsonl"
    none.write_text(json.dumps(made[1]) + "\n")
    with pytest.raises(BadInput, match="no failure in these rows"):
        load_suite([str(none)])


def test_a_bad_suite_is_one_line_naming_the_entry(tmp_path):
    bad = tmp_path / "bad.json"
    broken = json.loads(json.dumps(CASES["cases"][0]["scenario"]))
    broken["elements"][0]["type"] = "teleporter"
    bad.write_text(json.dumps({"suite": [{"scenario": CASES["cases"][1]["scenario"]}, {"scenario": broken}]}))
    with pytest.raises(BadInput, match=r"bad.json: scenario bad:1: "):
        load_suite([str(bad)], CONFIG)
    with pytest.raises(BadInput, match="no such file"):
        load_suite([str(tmp_path / "none.json")])
    a, b = tmp_path / "a.json", tmp_path / "b.json"
    a.write_text(json.dumps({"problem_config": {"scenario": "hazards"}, "suite": [CASES["cases"][0]["scenario"]]}))
    b.write_text(json.dumps({"problem_config": {}, "suite": [CASES["cases"][1]["scenario"]]}))
    with pytest.raises(BadInput, match="different problem settings"):
        load_suite([str(a), str(b)])


# --- configurations -----------------------------------------------------------------------------------
def test_a_fix_has_the_last_word_and_the_world_part_is_recorded(tmp_path):
    base = tmp_path / "nav2.yaml"
    base.write_text("controller_server:\n  ros__parameters:\n    controller_plugins: [FollowPath]\n    FollowPath:\n"
                    "      vx_min: -0.35\n      vx_max: 0.5\n")
    fix = tmp_path / "fix.yaml"
    fix.write_text("controller_server:\n  ros__parameters:\n    FollowPath:\n      vx_min: 0.0\n"
                   "robot_world:\n  ros__parameters:\n    sim:\n      fov_deg: 360.0\n")
    config = configs.parse_config(f"{base}+{fix}")
    assert config.label == "nav2+fix"
    ready = configs.prepare(config, "bringup", None, 1.0, tmp_path / "out")
    assert ready.params["controller_server"]["ros__parameters"]["FollowPath"] == {"vx_min": 0.0, "vx_max": 0.5}
    assert ready.world == {"fov_deg": 360.0} and ready.speed == 0.5
    again = configs.prepare(config, "bringup", None, 1.0, tmp_path / "out")
    assert again.digest == ready.digest and again.path == ready.path  # written once per content
    with pytest.raises(BadInput, match="no such fix"):
        configs.resolve("fix:teleport")
    assert configs.resolve("fix:people_approach").parent == configs.fixes_dir()
    with pytest.raises(BadInput, match="needs a params file"):
        configs.prepare(configs.StackConfig("x", ()), "bringup", None, 1.0, tmp_path)


def fake_installed_tree(tmp_path, monkeypatch):
    """A stand-in for Jazzy's installed navigate_to_pose tree (no Nav2 here), on AMENT_PREFIX_PATH."""
    folder = tmp_path / "prefix" / "share" / "nav2_bt_navigator" / "behavior_trees"
    folder.mkdir(parents=True)
    (folder / "navigate_to_pose_w_replanning_and_recovery.xml").write_text(
        '<root BTCPP_format="4"><BehaviorTree ID="MainTree"><RecoveryNode number_of_retries="6" '
        'name="NavigateRecovery"><FollowPath/><RoundRobin><Wait/><BackUp/></RoundRobin></RecoveryNode>'
        '</BehaviorTree></root>')
    monkeypatch.setenv("AMENT_PREFIX_PATH", str(tmp_path / "prefix"))


def test_the_hardened_fix_is_the_fixes_that_worked_in_order(tmp_path, monkeypatch):
    """``fix:hardened`` (issue 59) merges walls_static_local, then doorway_patient: the same stack as
    naming the two, the map's walls in the local costmap and the patient tree."""
    import xml.etree.ElementTree as ET

    from ambiegen_ros.nav2_params import goal_time_budget

    fake_installed_tree(tmp_path, monkeypatch)
    base = tmp_path / "nav2.yaml"
    base.write_text("local_costmap:\n  local_costmap:\n    ros__parameters:\n"
                    "      plugins: [voxel_layer, inflation_layer]\n")
    hardened = configs.prepare(configs.parse_config(f"{base}+fix:hardened"), "bringup", None, 1.0, tmp_path / "a")
    both = configs.prepare(configs.parse_config(f"{base}+fix:walls_static_local+fix:doorway_patient"), "bringup",
                           None, 1.0, tmp_path / "b")
    local = hardened.params["local_costmap"]["local_costmap"]["ros__parameters"]
    assert local["plugins"][0] == "static_layer" and "ambiegen_fixes" not in hardened.params

    def without_tree(params):
        bt = params["bt_navigator"]["ros__parameters"]
        return {**params, "bt_navigator": {"ros__parameters": {k: v for k, v in bt.items()
                                                               if k != "default_nav_to_pose_bt_xml"}}}

    assert without_tree(hardened.params) == without_tree(both.params)
    assert Path(hardened.behavior_tree).read_text() == Path(both.behavior_tree).read_text()
    root = ET.fromstring(Path(hardened.behavior_tree).read_text().split("-->", 1)[1])
    assert root.find("BehaviorTree/Timeout").get("msec") == "180000"
    assert goal_time_budget(hardened.params) == 180.0  # the adapter's goal_time_budget for this stack
    assert goal_time_budget(configs.prepare(configs.parse_config(f"{base}+fix:walls_static_local"), "bringup", None,
                                            1.0, tmp_path / "d").params) == 0.0
    assert root.find(".//RecoveryNode").get("number_of_retries") == "1000"
    bad = tmp_path / "bad.yaml"
    bad.write_text("ambiegen_fixes: walls_static_local\n")
    with pytest.raises(BadInput, match="a list of the package's fix names"):
        configs.prepare(configs.parse_config(f"{base}+{bad}"), "bringup", None, 1.0, tmp_path / "c")
    bad.write_text("ambiegen_fixes: [teleport]\n")
    with pytest.raises(BadInput, match="no such fix"):
        configs.prepare(configs.parse_config(f"{base}+{bad}"), "bringup", None, 1.0, tmp_path / "c")


def test_a_tree_fix_changes_only_what_it_says(tmp_path):
    tree = tmp_path / "default.xml"
    tree.write_text('<root BTCPP_format="4"><BehaviorTree ID="MainTree"><RecoveryNode number_of_retries="6" '
                    'name="NavigateRecovery"><FollowPath/><RoundRobin><Wait/><BackUp/></RoundRobin></RecoveryNode>'
                    '</BehaviorTree></root>')
    text, source = trees.derive([({"from": "default.xml", "remove": ["BackUp"],
                                   "set": {"NavigateRecovery.number_of_retries": 1000},
                                   "wrap": {"Timeout": {"msec": 180000}}}, tmp_path)])
    assert source == str(tree)
    import xml.etree.ElementTree as ET

    root = ET.fromstring(text.split("-->", 1)[1])
    timeout = root.find("BehaviorTree/Timeout")
    assert timeout is not None and timeout.get("msec") == "180000"
    assert timeout.find("RecoveryNode").get("number_of_retries") == "1000"
    assert root.find(".//BackUp") is None and root.find(".//Wait") is not None
    with pytest.raises(BadInput, match="no Spin node"):
        trees.derive([({"from": "default.xml", "remove": ["Spin"]}, tmp_path)])
    with pytest.raises(BadInput, match="no tree"):
        trees.derive([({"from": "missing.xml"}, tmp_path)])


# --- the results file -----------------------------------------------------------------------------------
def test_the_results_file_only_grows_and_a_line_cut_short_stays(tmp_path):
    log = TrialLog(tmp_path / "r.jsonl")
    log.append(row("j", "a", "collision", digest="d1"))
    with open(log.path, "a") as fh:
        fh.write('{"label": "j", "key": "a", "fail')  # a crash in the middle of a row
    log.append(row("j", "a", "error", 2, digest="d1"))
    log.append(row("j", "a", "none", 2, digest="d1"))
    assert log.done("j") == {"a": 2} and log.skipped == 1
    assert log.path.read_text().count("\n") == 4  # nothing rewritten: the cut line is still there
    with pytest.raises(BadInput, match="was run with other params"):
        log.check_label("j", "d2")
    log.check_label("j", "d1")


def test_pictures_are_drawn_for_the_scenarios_whose_verdict_changed(tmp_path):
    suite_file = tmp_path / "s.json"
    suite_file.write_text(json.dumps({"suite": [c["scenario"] for c in CASES["cases"][:2]]}))
    suite = load_suite([str(suite_file)], CONFIG)
    a, b = (e.key for e in suite.entries)
    traj = [[2.0, 2.0], [5.0, 5.0], [9.0, 9.0]]
    rows = []
    for r in (1, 2):
        rows += [dict(row("jazzy", a, "collision", r), trajectory_every_10=traj, failure_point=[9.0, 9.0]),
                 dict(row("fix", a, "none", r), trajectory_every_10=traj),
                 dict(row("jazzy", b, "none", r), trajectory_every_10=traj),
                 dict(row("fix", b, "none", r), trajectory_every_10=traj)]
    results = tmp_path / "r.jsonl"
    log = TrialLog(results)
    for r in rows:
        log.append(r)
    assert report.changed(suite, results, ["jazzy", "fix"]) == [a]
    written = report.write(suite, results, ["jazzy", "fix"], tmp_path / "out", "T1", "compare")
    assert len(written["pictures"]) == 1 and Path(written["pictures"][0]).stat().st_size > 10_000
    assert "| s:0 | 2 of 2: collision 2 | 0 of 2 |" in Path(written["md"]).read_text()
    with pytest.raises(FileExistsError):
        report.write(suite, results, ["jazzy", "fix"], tmp_path / "out", "T1", "compare")  # never over a report


def test_a_search_report_draws_the_first_failing_scenarios_of_each_kind_only(tmp_path):
    """A search's report (``pictures_per_kind``) draws the first failing scenarios of each kind (the
    verdict's kind and the planner's oracle) and says how many it left out; a rerun's draws them all."""
    scenarios = [c["scenario"] for c in CASES["cases"][:4]]
    suite_file = tmp_path / "s.json"
    suite_file.write_text(json.dumps({"suite": scenarios}))
    suite = load_suite([str(suite_file)], CONFIG)
    keys = [e.key for e in suite.entries]
    traj = [[2.0, 2.0], [5.0, 5.0], [9.0, 9.0]]
    oracles = ["collision", "collision", "collision", "missed_path"]  # three of one kind, one of another
    log = TrialLog(tmp_path / "r.jsonl")
    for key, oracle in zip(keys, oracles):
        log.append(dict(row("j", key, "collision" if oracle == "collision" else "requirement"),
                        metrics={"plan_oracle": oracle}, trajectory_every_10=traj, failure_point=[9.0, 9.0]))
    written = report.write(suite, log.path, ["j"], tmp_path / "search", "T1", "rerun", pictures_per_kind=2)
    names = sorted(Path(p).stem for p in written["pictures"])
    assert len(names) == 3 and written["pictures_left_out"] == 1
    assert sorted(Path(p).stem for p in report.write(suite, log.path, ["j"], tmp_path / "all", "T1",
                                                      "rerun")["pictures"]) == sorted(
        names + [suite.entries[2].name.replace(":", "_")])
    assert report.first_of_each_kind(keys, [dict(row("j", k, "collision"), metrics={"plan_oracle": o})
                                            for k, o in zip(keys, oracles)], 1) == [keys[0], keys[3]]


def test_the_runner_starts_each_node_script_as_the_console_script_does():
    """``campaign.node_argv`` runs an executable of ours as ``python -m <module>``; the module is the
    one ``entry.SCRIPTS`` gives the console script (and ``ros2 run``)."""
    from ambiegen_ros.campaign import node_module
    from ambiegen_ros.entry import SCRIPTS

    assert {name: node_module(name) for name in SCRIPTS if name != "ambiegen"} == \
        {name: module for name, module in SCRIPTS.items() if name != "ambiegen"}


def test_deaths_are_named_with_their_signal_and_whose_they_are(tmp_path):
    """How a session names what died: a killed child by its signal, a Nav2 server from the launch's
    own line, a stopped one as hung; each once."""
    import signal
    import sys
    import time

    from ambiegen_ros.campaign import ProcessGroup
    from ambiegen_ros.trials.supervise import Watch, exit_words, part_of

    assert exit_words(-9) == "killed by SIGKILL" and exit_words(139) == "killed by SIGSEGV"
    assert exit_words(1) == "exited with code 1" and exit_words(0) == "exited with code 0"
    assert part_of("robot_world") == "ours" and part_of("controller_server") == "stack"
    group = ProcessGroup(tmp_path, dict())
    sleeper = [sys.executable, "-c", "import time; time.sleep(60)"]
    group.start_argv("nd_driver", sleeper)
    group.start_argv("robot_world", sleeper)
    group.start_argv("nav2", sleeper)  # stands in for `ros2 launch`: what counts is its log's lines
    watch = Watch(group)
    try:
        assert watch.poll() == []
        group.procs["nd_driver"].send_signal(signal.SIGKILL)
        group.procs["nd_driver"].wait()
        (tmp_path / "nav2.log").write_text(
            "[INFO] [launch]: ...\n[ERROR] [controller_server-3]: process has died [pid 4242, exit code -11, "
            "cmd '/opt/ros/jazzy/lib/nav2_controller/controller_server --ros-args ...'].\n")
        group.procs["robot_world"].send_signal(signal.SIGSTOP)
        found: set = set()
        deadline = time.monotonic() + 30
        while len(found) < 3 and time.monotonic() < deadline:  # until the kernel shows it stopped
            found |= {(d.process, d.part, d.what) for d in watch.poll()}
            time.sleep(0.05)
        assert found == {("nd_driver", "stack", "killed by SIGKILL"), ("controller_server", "stack", "killed by SIGSEGV"),
                         ("robot_world", "ours", "stopped (hung: SIGSTOP)")}
        assert watch.poll() == []  # each once
        group.procs["robot_world"].send_signal(signal.SIGCONT)
    finally:
        group.stop(timeout=5)
        for proc in group.procs.values():
            proc.kill() if proc.poll() is None else None


def test_a_fault_is_written_as_target_signal_and_run():
    from ambiegen_ros.trials.faults import parse_fault

    fault = parse_fault("controller_server:SIGSTOP@3+2.5/30")
    assert (fault.target, fault.signal.name, fault.run, fault.after_s, fault.hold_s) == \
        ("controller_server", "SIGSTOP", 3, 2.5, 30.0)
    assert fault.spec() == "controller_server:SIGSTOP@3+2.5/30"
    for bad in ("nd_driver", "nd_driver:KILL@1", "nd_driver:SIGNOPE@1", "nd_driver:SIGKILL@0"):
        with pytest.raises(BadInput, match="--inject"):
            parse_fault(bad)


def test_our_transport_moves_the_world_the_recorder_and_the_adapter(tmp_path, monkeypatch):
    """``--our-transport dds``: our three parts get AMBIEGEN_TRANSPORT=dds in their own environment
    (the process, not the session, so the runner and the stack keep theirs), the adapter in front of
    Nav2 too; a Nav2 that would not run on rmw_cyclonedds_cpp is refused in one line."""
    import os
    import subprocess
    import sys
    from types import SimpleNamespace

    from ambiegen_ros.campaign import ProcessGroup
    from ambiegen_ros.trials.session import lean_parts

    assert lean_parts(SimpleNamespace(our_transport=None, stack="bringup")) == ()
    for stack in ("bringup", "nd"):
        assert lean_parts(SimpleNamespace(our_transport="dds", stack=stack)) == ("robot_world", "recorder", "sut_adapter")
    group = ProcessGroup(tmp_path, {"AMBIEGEN_TRANSPORT": "rclpy"}, {"robot_world": {"AMBIEGEN_TRANSPORT": "dds"}})
    say = [sys.executable, "-c", "import os; print(os.environ['AMBIEGEN_TRANSPORT'])"]
    for name in ("robot_world", "nav2"):
        group.start_argv(name, say).wait(timeout=60)
    assert (tmp_path / "robot_world.log").read_text().strip() == "dds"
    assert (tmp_path / "nav2.log").read_text().strip() == "rclpy"
    helped = subprocess.run([sys.executable, "-m", "ambiegen_ros", "rerun", "--help"], capture_output=True, text=True)
    assert "--our-transport" in helped.stdout, helped.stdout + helped.stderr
    suite = REPO / "docs" / "results" / "nav2" / "two_passes_suite.json"
    env = {k: v for k, v in os.environ.items() if k != "RMW_IMPLEMENTATION"}
    refused = subprocess.run([sys.executable, "-m", "ambiegen_ros", "rerun", str(suite), "--stack", "bringup",
                              "--params", str(tmp_path / "nav2_params.yaml"), "--results", str(tmp_path / "r.jsonl"),
                              "--our-transport", "dds"],
                             capture_output=True, text=True, env=env, timeout=120)
    assert refused.returncode != 0 and "RMW_IMPLEMENTATION=rmw_cyclonedds_cpp" in refused.stderr, refused.stderr
    assert not (tmp_path / "r.jsonl").exists()


def test_a_crash_rerun_says_whether_the_same_crash_came_back():
    from types import SimpleNamespace

    from ambiegen_ros.trials.runner import crash_again

    first = "the stack crashed: collision_monitor killed by SIGSEGV, 10.2 s into the run"
    again = SimpleNamespace(failure_kind="sut_crashed", detail="the stack crashed: collision_monitor killed by "
                                                               "SIGSEGV, 3.0 s into the run")
    other = SimpleNamespace(failure_kind="sut_crashed", detail="the stack crashed: planner_server stopped (hung: "
                                                               "SIGSTOP), 18.8 s into the run")
    assert crash_again(first, again) == "it came back"
    assert crash_again(first, other) == ("the stack crashed again, differently: planner_server stopped (hung: SIGSTOP) "
                                         "(first collision_monitor killed by SIGSEGV)")
    assert crash_again(first, SimpleNamespace(failure_kind="none", detail="")) == "it did not come back"


def test_a_node_started_without_its_name_is_found_by_its_executable(tmp_path):
    """Jazzy's navigation_launch.py starts controller_server with no ``__node:=``: its process is named
    after its executable (17 characters; /proc's comm keeps 15), so a fault can target it."""
    import subprocess
    import sys

    from ambiegen_ros.trials.supervise import node_name

    exe = tmp_path / "controller_server"
    exe.symlink_to(sys.executable)
    up = "import time; print('up', flush=True); time.sleep(60)"
    named = subprocess.Popen([sys.executable, "-c", up, "--ros-args", "-r", "__node:=planner_server"],
                             stdout=subprocess.PIPE, text=True)
    plain = subprocess.Popen([str(exe), "-c", up], stdout=subprocess.PIPE, text=True)
    try:
        # Until a child has exec'd, /proc shows its parent's command line: wait for each to speak.
        assert named.stdout.readline() == plain.stdout.readline() == "up\n"
        assert node_name(named.pid) == "planner_server"
        assert node_name(plain.pid) == "controller_server"
    finally:
        for proc in (named, plain):
            proc.kill()
            proc.wait()
            proc.stdout.close()


def test_a_command_line_gives_every_node_its_parameters_with_their_planned_types(tmp_path):
    """``ros2 run`` and ``python -m`` nodes get their parameters as ``-p name:=VALUE``, which rcl
    reads as YAML: a string that reads as a number ("107", the adapter's ours_error_codes) must come
    quoted, or a node declaring a string refuses it and the rerun's stack never comes up."""
    import yaml

    from ambiegen_ros import launch_logic
    from ambiegen_ros.campaign import node_argv, ros_value

    assert [ros_value(v) for v in ("107", "true", "", "it's", "a,b", "plain", 3, 2.5, True)] == \
        ["'107'", "'true'", "''", "it's", "a,b", "plain", "3", "2.5", "true"]
    plan = launch_logic.plan_nav2_campaign({"output_dir": str(tmp_path), "seed": "3", "nav2": "ours"},
                                           share_dir=str(launch_logic.Path(__file__).resolve().parents[1]))
    checked = 0
    for node in plan.nodes:
        argv = node_argv(node, python="python3")
        given = dict(argv[i + 1].split(":=", 1) for i, a in enumerate(argv) if a == "-p")
        for name, value in node.parameters.items():
            if value is None:
                continue
            read = yaml.safe_load(given[name])
            assert read == value and type(read) is type(value), (node.name, name, given[name])
            checked += 1
    assert checked > 50


def test_a_fault_waits_for_this_runs_robot_to_move_not_the_last_runs():
    """Injected faults fire once the run's robot moves: odometry over 5 cm/s near the run's start. The
    last run's robot, still driving to its goal when its odometry comes in late, does not count (on a
    loaded machine that fired the fault before the adapter's goal went out: an error, not a crash)."""
    from types import SimpleNamespace

    from ambiegen_ros.trials.session import StackSession

    def odom(x, y, speed):
        return SimpleNamespace(pose=SimpleNamespace(pose=SimpleNamespace(position=SimpleNamespace(x=x, y=y))),
                               twist=SimpleNamespace(twist=SimpleNamespace(linear=SimpleNamespace(x=speed))))

    session = SimpleNamespace(in_flight=True, moved_at=None, run_start=(1.5, 1.5))
    StackSession._on_odom(session, odom(9.0, 9.0, 0.4))  # the last run's robot, far from this start
    assert session.moved_at is None
    StackSession._on_odom(session, odom(1.6, 1.5, 0.01))  # here, but standing
    assert session.moved_at is None
    StackSession._on_odom(session, odom(1.6, 1.5, 0.3))
    assert session.moved_at is not None
    anywhere = SimpleNamespace(in_flight=True, moved_at=None, run_start=None)  # no start known: any motion
    StackSession._on_odom(anywhere, odom(9.0, 9.0, 0.3))
    assert anywhere.moved_at is not None
