"""The `ambiegen` command line as a user runs it: real subprocesses, real files."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

ROBOT_ELEMENT = {"type": "horizontal", "size": 10, "position": 12}


def ambiegen(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "ambiegen_ros", *args], capture_output=True, text=True, timeout=300, cwd=cwd
    )


def robot_scenario(**changes) -> dict:
    elements = [dict(ROBOT_ELEMENT, position=1 + (i * 7) % 48) for i in range(48)]
    elements[3].update(changes)
    return {"problem": "robot", "elements": elements}


def write(tmp_path: Path, name: str, content) -> Path:
    path = tmp_path / name
    path.write_text(content if isinstance(content, str) else json.dumps(content))
    return path


def test_evaluate_json_output(tmp_path):
    path = write(tmp_path, "s.json", robot_scenario())
    out = ambiegen("evaluate", str(path), "--json")
    assert out.returncode == 0, out.stderr
    doc = json.loads(out.stdout)
    assert doc["problem"] == "robot"
    assert isinstance(doc["valid"], bool)
    assert (doc["reason"] is None) == doc["valid"]
    assert doc["f1"] == 0.0 or doc["f1"] >= 47 * 2**0.5 - 1e-9


def test_evaluate_thermostat_invalid_names_the_rule(tmp_path):
    schedule = {
        "problem": "thermostat",
        "elements": [{"temperature": 16, "duration": 240, "model": 1}, {"temperature": 24, "duration": 240, "model": 2}],
    }
    out = ambiegen("evaluate", str(write(tmp_path, "t.json", schedule)), "--json")
    assert out.returncode == 0, out.stderr
    doc = json.loads(out.stdout)
    assert doc["valid"] is False and doc["f1"] == 0.0
    assert "R2" in doc["reason"]


@pytest.mark.parametrize(
    "content, expected",
    [
        ('{"problem": "robot", "elements": [', "malformed JSON"),
        ({"problem": "submarine", "elements": []}, "unknown problem"),
        (robot_scenario(colour="red"), "elements[3].colour"),
        (robot_scenario(size=99), "elements[3].size"),
        (robot_scenario(size="ten"), "elements[3].size"),
        (robot_scenario(type="diagonal"), "elements[3].type"),
        ('{"problem": "robot", "elements": [{"type": "horizontal", "size": NaN, "position": 3}]}', "NaN"),
        ({"problem": "thermostat", "elements": [{"temperature": 21.5, "duration": 60, "model": 1}]}, "elements[0].temperature"),
        ({"problem": "robot", "elements": []}, "elements"),
    ],
)
def test_bad_input_exits_2_with_a_named_field(tmp_path, content, expected):
    out = ambiegen("evaluate", str(write(tmp_path, "bad.json", content)))
    assert out.returncode == 2
    assert expected in out.stderr
    assert "Traceback" not in out.stderr
    assert "allowed" in out.stderr or "malformed" in out.stderr or "NaN" in out.stderr


def test_missing_file_and_bad_options_exit_2(tmp_path):
    assert ambiegen("evaluate", str(tmp_path / "nope.json")).returncode == 2
    out = ambiegen("search", "--problem", "robot", "--evaluations", "0", "--out", str(tmp_path / "r"))
    assert out.returncode == 2 and "evaluations" in out.stderr
    out = ambiegen("search", "--problem", "plane", "--out", str(tmp_path / "r"))
    assert out.returncode == 2


def test_search_writes_a_complete_run_directory_and_same_seed_same_suite(tmp_path):
    runs = []
    for name in ("a", "b"):
        out = ambiegen(
            "search", "--problem", "thermostat", "--algorithm", "ga", "--evaluations", "600",
            "--population", "50", "--offspring", "50", "--seed", "11", "--out", str(tmp_path / name),
        )
        assert out.returncode == 0, out.stderr
        assert "600 evaluations" in out.stdout and "best F1" in out.stdout
        runs.append(tmp_path / name)
    for name in ("config.json", "suite.json", "history.csv", "convergence.png", "suite.png"):
        assert (runs[0] / name).stat().st_size > 0, name
    assert (runs[0] / "suite.json").read_bytes() == (runs[1] / "suite.json").read_bytes()
    config = json.loads((runs[0] / "config.json").read_text())
    assert config["seed"] == 11 and config["search"]["population"] == 50
    assert config["problem_config"]["alpha"] == 1.5
    suite = json.loads((runs[0] / "suite.json").read_text())["suite"]
    assert len(suite) == 10 and all({"f1", "f2", "valid", "scenario"} <= set(e) for e in suite)
    # a suite scenario is a valid input of `evaluate` and gets the same F1
    path = write(tmp_path, "best.json", suite[0]["scenario"])
    doc = json.loads(ambiegen("evaluate", str(path), "--json").stdout)
    assert doc["f1"] == pytest.approx(suite[0]["f1"])
    assert config["profile"] == doc["profile"] == "replication"
    # the run is never overwritten silently
    before = (runs[0] / "suite.json").read_bytes()
    again = ambiegen("search", "--problem", "thermostat", "--evaluations", "300", "--seed", "12", "--out", str(runs[0]))
    assert again.returncode == 2 and "--overwrite" in again.stderr
    assert (runs[0] / "suite.json").read_bytes() == before


def test_evaluate_a_suite_file_line_by_line(tmp_path):
    """JSON Lines in, one JSON object per line out, same order; bad lines answered in place."""
    day = {"problem": "thermostat", "elements": [{"temperature": t, "duration": 240, "model": m}
                                                for t, m in [(20, 1), (24, 7), (20, 2), (24, 7), (20, 3), (24, 1)]]}
    lines = [
        json.dumps(day),
        json.dumps(robot_scenario()),
        "{not json",
        "",
        json.dumps({"sampler": "x", "scenario": day}),  # a record holding its scenario
        json.dumps(robot_scenario(size=99)),
    ]
    path = write(tmp_path, "suite.jsonl", "\n".join(lines) + "\n")
    out = ambiegen("evaluate", str(path), "--json")
    assert out.returncode == 2, out.stderr
    docs = [json.loads(line) for line in out.stdout.splitlines()]
    assert [d["line"] for d in docs] == [1, 2, 3, 5, 6]
    assert "error" in docs[2] and "malformed" in docs[2]["error"]
    assert "elements[3].size" in docs[4]["error"]
    assert docs[0]["problem"] == "thermostat" and docs[1]["problem"] == "robot"
    assert docs[0]["f1"] == docs[3]["f1"] > 0 and docs[0]["profile"] == "replication"
    one = json.loads(ambiegen("evaluate", str(write(tmp_path, "day.json", day)), "--json").stdout)
    assert one["f1"] == docs[0]["f1"]
    refined = ambiegen("evaluate", str(path), "--json", "--profile", "refined")
    rdocs = [json.loads(line) for line in refined.stdout.splitlines()]
    assert rdocs[0]["profile"] == "refined" and rdocs[0]["f1"] != docs[0]["f1"]
    good = write(tmp_path, "good.jsonl", lines[0] + "\n" + lines[1] + "\n")
    assert ambiegen("evaluate", str(good), "--json").returncode == 0


def test_show_draws_scenarios_and_runs(tmp_path):
    path = write(tmp_path, "s.json", robot_scenario())
    out = ambiegen("show", str(path), "-o", str(tmp_path / "map.png"))
    assert out.returncode == 0, out.stderr
    assert (tmp_path / "map.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    run = tmp_path / "run"
    assert ambiegen("search", "--problem", "robot", "--evaluations", "150", "--seed", "1", "--out", str(run), "--no-plots").returncode == 0
    out = ambiegen("show", str(run), "-o", str(tmp_path / "fig.png"))
    assert out.returncode == 0, out.stderr
    assert (tmp_path / "fig_convergence.png").exists() and (tmp_path / "fig_suite.png").exists()


def test_config_file_sets_problem_numbers(tmp_path):
    cfg = write(tmp_path, "c.yaml", "problem: robot\nalgorithm: ga\nproblem_config:\n  alpha: 100.0\n")
    out = ambiegen("search", "--config", str(cfg), "--evaluations", "120", "--seed", "2", "--out", str(tmp_path / "r"), "--no-plots")
    assert out.returncode == 0, out.stderr
    config = json.loads((tmp_path / "r" / "config.json").read_text())
    assert config["problem_config"]["alpha"] == 100.0 and config["search"]["algorithm"] == "ga"
    bad = write(tmp_path, "bad.yaml", "problem: robot\nproblem_config:\n  gravity: 9.8\n")
    out = ambiegen("search", "--config", str(bad), "--out", str(tmp_path / "r2"))
    assert out.returncode == 2 and "gravity" in out.stderr


ROOT = Path(__file__).resolve().parents[1]
SMALL = ROOT / "config" / "robot_small.yaml"  # robot maps with the nearer goal (14, 14)


def test_evaluate_scores_with_the_config_files_problem_config(tmp_path):
    """`--config` gives `evaluate` the run config's problem_config: the same map scored with
    config/robot_small.yaml's nearer goal gets another F1, the one `get_problem` with that file's
    problem_config gives; a suite line and `show` take the same file, one of another problem is refused."""
    import yaml

    from ambiegen_ros.core.scenario import Scenario
    from ambiegen_ros.problems import get_problem

    scenario = robot_scenario()
    path = write(tmp_path, "map.json", scenario)
    plain = ambiegen("evaluate", str(path), "--json")
    small = ambiegen("evaluate", str(path), "--json", "--config", str(SMALL))
    assert plain.returncode == 0 and small.returncode == 0, plain.stderr + small.stderr
    f1_plain, f1_small = json.loads(plain.stdout)["f1"], json.loads(small.stdout)["f1"]
    problem_config = yaml.safe_load(SMALL.read_text())["problem_config"]
    assert problem_config["goal"] == [14, 14]
    expected = get_problem("robot", problem_config)
    row = expected.evaluate_scenarios([expected.parse(Scenario.parse_json(json.dumps(scenario)))]).row(0)
    assert f1_small == pytest.approx(row["f1"]) and f1_small != pytest.approx(f1_plain)
    # a suite line is scored with the same file
    suite = write(tmp_path, "maps.jsonl", json.dumps(scenario) + "\n")
    line = json.loads(ambiegen("evaluate", str(suite), "--json", "--config", str(SMALL)).stdout)
    assert line["f1"] == pytest.approx(f1_small)
    # a config of another problem is one line, exit 2; in a suite that line alone is refused
    other = ambiegen("evaluate", str(path), "--config", str(ROOT / "config" / "thermostat.yaml"))
    assert other.returncode == 2 and "thermostat" in other.stderr and "Traceback" not in other.stderr
    assert len(other.stderr.strip().splitlines()) == 1
    lines = ambiegen("evaluate", str(suite), "--json", "--config", str(ROOT / "config" / "thermostat.yaml"))
    assert lines.returncode == 2 and "thermostat" in json.loads(lines.stdout)["error"]
    missing = ambiegen("evaluate", str(path), "--config", str(tmp_path / "none.yaml"))
    assert missing.returncode == 2 and "no such file" in missing.stderr
    drawn = ambiegen("show", str(path), "--config", str(SMALL), "-o", str(tmp_path / "map.png"))
    assert drawn.returncode == 0 and (tmp_path / "map.png").exists(), drawn.stderr


LIGHT_EVALUATE_NEVER_IMPORTS = ("pymoo", "scipy", "numba", "matplotlib", "cyclonedds", "rclpy", "rosbags", "mcap")
"""What `ambiegen evaluate` of one line must start without: the search (pymoo, and scipy through
it), numba (one line runs the kernels uncompiled), the pictures and the DDS / ROS log stack."""


@pytest.mark.parametrize("problem", ["thermostat", "robot", "vehicle"])
def test_evaluate_of_one_line_imports_no_search_plot_or_dds_library(tmp_path, problem):
    """Issue 47: `--config` made `evaluate` import the whole search (run_config -> core.search ->
    pymoo's NSGA-II -> scipy.spatial), 5x `import numpy`. Read from `python -X importtime` of the
    command, a one-line file and a one-line suite, with and without the problem's run config
    (bench/startup.py times the same command; a test never asserts a speed)."""
    import numpy as np

    from ambiegen_ros.problems import get_problem

    case = get_problem(problem)
    scenario = case.codec.from_rows(case.sample_rows(1, np.random.default_rng(0)))[0].to_dict()
    one = write(tmp_path, "one.json", scenario)
    suite = write(tmp_path, "one.jsonl", json.dumps(scenario) + "\n")
    config = ROOT / "config" / f"{problem}.yaml"
    for argv in ([str(one)], [str(one), "--config", str(config)], [str(suite), "--json", "--config", str(config)]):
        out = subprocess.run([sys.executable, "-X", "importtime", "-m", "ambiegen_ros", "evaluate", *argv],
                             capture_output=True, text=True, timeout=120)
        assert out.returncode == 0, out.stderr[-2000:]
        assert problem in out.stdout
        imported = {line.split("|")[-1].strip().split(".")[0] for line in out.stderr.splitlines()
                    if line.startswith("import time:")}
        assert "numpy" in imported and "ambiegen_ros" in imported  # the reading itself works
        heavy = sorted(imported & set(LIGHT_EVALUATE_NEVER_IMPORTS))
        assert not heavy, f"evaluate {' '.join(argv)} imported {heavy}"


def test_a_command_is_built_alone_with_the_same_parser_as_in_the_whole_command_line():
    """`ambiegen COMMAND` builds only COMMAND's module (cli.COMMANDS): every command is there, and
    its options are the whole parser's, so a user sees no difference but the start-up."""
    from cli_shape import parser_shape  # test/helpers (pytest.ini's pythonpath)

    from ambiegen_ros.cli import COMMANDS, build_parser

    whole = parser_shape(build_parser())["commands"]
    assert set(whole) == set(COMMANDS)
    for command in COMMANDS:
        alone = parser_shape(build_parser(command))["commands"]
        assert command in alone and alone[command] == whole[command], command


def test_every_command_that_scores_or_runs_a_scenario_takes_the_same_config_option():
    """One `--config` (cli/common.add_config_option) on every command that searches, scores or runs."""
    from cli_shape import parser_shape  # test/helpers (pytest.ini's pythonpath)

    from ambiegen_ros.cli import build_parser

    commands = parser_shape(build_parser())["commands"]
    options = {name: next((a for a in cmd["actions"] if a["dest"] == "config"), None) for name, cmd in commands.items()}
    takes = sorted(name for name, action in options.items() if action)
    assert takes == ["campaign", "compare", "evaluate", "execute", "experiment", "planner-report", "rerun", "search",
                     "show", "shrink", "stack-search"]
    assert len({json.dumps(options[name], sort_keys=True) for name in takes}) == 1


def test_execute_runs_with_the_config_files_goal(tmp_path):
    path = write(tmp_path, "map.json", robot_scenario())
    runs = [json.loads(ambiegen("execute", str(path), "--json", *extra).stdout)
            for extra in ([], ["--config", str(SMALL)])]
    assert runs[0]["metrics"]["route_length"] != runs[1]["metrics"]["route_length"]


@pytest.mark.parametrize("module", ["ambiegen_ros.nodes.generator", "ambiegen_ros.nodes.recorder",
                                    "ambiegen_ros.nodes.replay", "sim_nodes.car_sim", "sim_nodes.sut_adapter"])
def test_every_node_answers_help_without_starting(module):
    out = subprocess.run([sys.executable, "-m", module, "--help"], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0 and out.stdout.startswith("usage:")
    assert "Parameters" in out.stdout or "parameters" in out.stdout or "-p " in out.stdout


def test_recover_bad_input_is_one_line_and_writes_nothing(tmp_path):
    text = write(tmp_path, "notes.mcap", "not an MCAP file")
    for args in ([str(text)], [str(tmp_path / "missing.mcap")]):
        out = ambiegen("recover", *args)
        lines = out.stderr.strip().splitlines()
        assert out.returncode == 2 and len(lines) == 1 and "Traceback" not in out.stderr, out.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.mcap"] and text.read_text() == "not an MCAP file"
