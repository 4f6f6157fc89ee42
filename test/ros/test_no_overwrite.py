"""No log or run directory is ever overwritten (issue 9): recorder, campaign, replay --record, recover.

Real processes over real DDS (the recorder node, ``ambiegen campaign``, ``ambiegen replay``,
``ambiegen recover``), each test on its own ROS_DOMAIN_ID (``ros_domain``). The shared campaign folder is
only read; the test that writes into a campaign folder works on a copy, so any order passes. A refusal is exit status 2 with
one line naming the file, and the bytes already there are unchanged.
"""
from __future__ import annotations

import hashlib
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
if str(HERE) not in sys.path:
    sys.path.insert(0, str(HERE))

import pytest  # noqa: E402
from mcap.reader import make_reader  # noqa: E402

from test_nodes import REPO, _env, nodes_factory  # noqa: E402,F401  (the fixture is used by name)

from ambiegen_ros.ros.mcap_log import McapLog, create_file  # noqa: E402
from ambiegen_ros.ros.runlog import summarize  # noqa: E402

pytestmark = pytest.mark.skipif(
    os.environ.get("AMBIEGEN_TRANSPORT", "auto") == "rclpy", reason="these tests drive the DDS backend"
)


def ambiegen(domain: int, *args: str, timeout: float = 480) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "ambiegen_ros", *args], cwd=REPO, env=_env(domain),
                          capture_output=True, text=True, timeout=timeout)


def digest(path: Path) -> dict[str, str]:
    """sha256 of a file, or of every file under a directory (relative path -> hash)."""
    if path.is_file():
        return {path.name: hashlib.sha256(path.read_bytes()).hexdigest()}
    return {str(p.relative_to(path)): hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(path.rglob("*")) if p.is_file()}


def one_error_line(proc: subprocess.CompletedProcess) -> str:
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert proc.returncode == 2 and len(lines) == 1 and "Traceback" not in proc.stderr, proc.stderr[-2000:]
    return lines[0]


CAMPAIGN = ["campaign", "--problem", "thermostat", "--algorithm", "ga", "--evaluations", "60", "--population", "20",
            "--offspring", "20", "--seed", "3", "--sim-model", "surrogate", "--timeout", "400"]  # a safety net


@pytest.fixture(scope="module")
def campaign_dir(tmp_path_factory, module_domains) -> tuple[Path, subprocess.CompletedProcess]:
    """One campaign's folder, shared read-only: a test that writes into it works on a copy."""
    out = tmp_path_factory.mktemp("campaign") / "run"
    domain = module_domains()
    run = ambiegen(domain, *CAMPAIGN, "--domain-id", str(domain), "--out", str(out))
    assert run.returncode == 0, run.stdout[-2000:] + run.stderr[-2000:]
    return out, run


# --- the recorder node --------------------------------------------------------------------------
def test_recorder_refuses_an_existing_file_and_leaves_its_bytes(nodes_factory, tmp_path, ros_domain):
    nodes = nodes_factory(ros_domain)
    log = tmp_path / "campaign.mcap"
    log.write_bytes(b"\x89MCAP0\r\n" + os.urandom(50_000))  # an earlier run's log, as far as anyone knows
    before = digest(log)
    nodes.start("recorder", "ambiegen_ros.nodes.recorder", output=str(log))
    assert nodes.wait("recorder", 60) == 2
    text = nodes.log("recorder").strip().splitlines()
    assert len(text) == 1 and "already exists" in text[0] and str(log) in text[0] and "overwrite:=true" in text[0], text
    assert digest(log) == before


def test_recorder_overwrite_true_replaces_the_file_and_finalises_it_on_sigint(nodes_factory, tmp_path, ros_domain):
    nodes = nodes_factory(ros_domain)
    log = tmp_path / "old.mcap"
    log.write_bytes(b"old bytes " * 1000)
    nodes.start("recorder", "ambiegen_ros.nodes.recorder", output=str(log), overwrite=True)
    deadline = time.monotonic() + 60
    while "recording to" not in nodes.log("recorder") and time.monotonic() < deadline:
        assert nodes.procs["recorder"].poll() is None, nodes.log("recorder")
        time.sleep(0.2)
    assert nodes.stop("recorder", timeout=30) == 0
    with open(log, "rb") as fh:
        assert make_reader(fh).get_summary() is not None  # a complete MCAP (summary + footer), not the old bytes


def test_two_recorders_on_one_new_path_one_gets_it_the_other_is_refused(nodes_factory, tmp_path, ros_domain):
    nodes = nodes_factory(ros_domain)
    log = tmp_path / "race.mcap"
    for name in ("rec_a", "rec_b"):  # started together: only one O_EXCL create can succeed
        nodes.start(name, "ambiegen_ros.nodes.recorder", output=str(log))
    deadline = time.monotonic() + 60
    while all(p.poll() is None for p in nodes.procs.values()) and time.monotonic() < deadline:
        time.sleep(0.2)
    refused = [n for n, p in nodes.procs.items() if p.poll() is not None]
    assert len(refused) == 1 and nodes.procs[refused[0]].returncode == 2, {n: nodes.log(n) for n in nodes.procs}
    winner = next(n for n in nodes.procs if n not in refused)
    assert nodes.stop(winner, timeout=30) == 0
    with open(log, "rb") as fh:
        assert make_reader(fh).get_summary() is not None


def test_mcap_log_and_create_file_refuse_an_existing_path(tmp_path):
    path = tmp_path / "x.mcap"
    path.write_bytes(b"keep me")
    with pytest.raises(FileExistsError, match="already exists"):
        McapLog(path)
    with pytest.raises(FileExistsError):
        create_file(path)
    assert path.read_bytes() == b"keep me"
    with McapLog(path, overwrite=True):
        pass
    assert path.read_bytes().startswith(b"\x89MCAP0\r\n")


# --- ambiegen campaign ----------------------------------------------------------------------------
def test_campaign_prints_a_table_names_its_log_by_run_and_time(campaign_dir):
    out, run = campaign_dir
    summary = json.loads((out / "summary.json").read_text())
    mcap = Path(summary["mcap"])
    assert mcap.parent == out and mcap.name.startswith(summary["run_id"] + "_") and mcap.name.endswith("Z.mcap")
    table = run.stdout
    for label in ("scenarios", "failures", "timeouts", "errors", "MCAP", "wall time"):
        assert f"  {label}" in table, table
    assert f"{summary['scenarios_published']} published, {summary['results_received']} results" in table
    assert str(mcap) in table and summary["run_id"] in table
    with pytest.raises(json.JSONDecodeError):
        json.loads(table)  # people's output by default; --json gives the dict (below)


def test_campaign_twice_into_one_dir_is_refused_and_overwrite_adds_a_new_log(campaign_dir, tmp_path, ros_domain):
    out = tmp_path / "run"
    shutil.copytree(campaign_dir[0], out)  # the shared folder stays as the other tests expect it, in any order
    before = digest(out)
    again = ambiegen(ros_domain, *CAMPAIGN, "--domain-id", str(ros_domain), "--out", str(out), timeout=120)
    line = one_error_line(again)
    assert str(out) in line and "--overwrite" in line
    assert digest(out) == before  # nothing written, nothing started

    forced = ambiegen(ros_domain, *CAMPAIGN, "--domain-id", str(ros_domain), "--out", str(out), "--overwrite", "--json")
    assert forced.returncode == 0, forced.stdout[-2000:] + forced.stderr[-2000:]
    printed = json.loads(forced.stdout)
    assert printed == json.loads((out / "summary.json").read_text())
    old_logs = [name for name in before if name.endswith(".mcap")]
    assert len(old_logs) == 1 and digest(out / old_logs[0]) == {old_logs[0]: before[old_logs[0]]}  # old log kept
    assert Path(printed["mcap"]).name not in before and summarize(printed["mcap"], printed["run_id"])["unresolved"] == []


def test_campaign_out_that_is_a_file_is_refused(tmp_path, ros_domain):
    target = tmp_path / "notes.txt"
    target.write_text("mine")
    line = one_error_line(ambiegen(ros_domain, *CAMPAIGN, "--domain-id", str(ros_domain), "--out", str(target), timeout=120))
    assert str(target) in line and target.read_text() == "mine"


# --- ambiegen replay --record / ambiegen recover -----------------------------------------------------
def test_replay_record_onto_an_existing_file_is_refused(campaign_dir, tmp_path, ros_domain):
    out, _ = campaign_dir
    log = Path(json.loads((out / "summary.json").read_text())["mcap"])
    existing = tmp_path / "new.mcap"
    existing.write_bytes(b"a log from yesterday")
    proc = ambiegen(ros_domain, "replay", str(log), "--execute", "--workers", "1", "--record", str(existing),
                    "--domain-id", str(ros_domain), "--report", str(tmp_path / "r.json"), timeout=120)
    assert str(existing) in one_error_line(proc)
    assert existing.read_bytes() == b"a log from yesterday" and not (tmp_path / "replay_logs").exists()


def test_recover_never_writes_over_its_input_or_an_existing_output(campaign_dir, tmp_path, ros_domain):
    out, _ = campaign_dir
    log = Path(json.loads((out / "summary.json").read_text())["mcap"])
    src = tmp_path / "cut.mcap"
    src.write_bytes(log.read_bytes()[: log.stat().st_size // 2])  # what a SIGKILL leaves
    source = digest(src)

    assert "is the input" in one_error_line(ambiegen(ros_domain, "recover", str(src), "-o", str(src)))
    link = tmp_path / "link.mcap"
    link.symlink_to(src)
    assert "is the input" in one_error_line(ambiegen(ros_domain, "recover", str(src), "-o", str(link)))
    hard = tmp_path / "hard.mcap"
    os.link(src, hard)
    assert "is the input" in one_error_line(ambiegen(ros_domain, "recover", str(src), "-o", str(hard), "--overwrite"))

    default_out = tmp_path / "cut.recovered.mcap"
    default_out.write_bytes(b"earlier recovery")
    line = one_error_line(ambiegen(ros_domain, "recover", str(src)))
    assert str(default_out) in line and "--overwrite" in line and default_out.read_bytes() == b"earlier recovery"
    assert digest(src) == source

    done = ambiegen(ros_domain, "recover", str(src), "--overwrite")
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout)["messages"] > 0 and digest(src) == source
    with open(default_out, "rb") as fh:
        assert make_reader(fh).get_summary() is not None
