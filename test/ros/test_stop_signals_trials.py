"""``rerun``, ``compare``, ``stack-search`` and ``shrink`` stop cleanly on any stop signal (issue 70), on our ND stack.

Each command runs as a user's script runs it (under ``timeout -s TERM``, whose SIGTERM we send, or
in the background with SIGINT ignored) and is stopped once its first run's line is out: the
command is mid-run, its stack up. Then: exit status 128 + the signal, none of its stack's processes
left (``helpers.stopping``'s /proc scan), the bag finalised (the ``mcap`` reader finds its summary),
every line of the results file a whole row; the same ``rerun`` again makes only the runs missing.
Killed by SIGKILL, the command stops nothing: its nodes see it gone and stop, the recorder
finalising its bag.
"""
from __future__ import annotations

import json
import os
import signal
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]

from helpers.stopping import Command, mcap_summary, wait_gone  # noqa: E402

pytestmark = pytest.mark.skipif(os.environ.get("AMBIEGEN_TRANSPORT", "auto") == "rclpy",
                                reason="these tests drive the DDS backend")
CASES = json.loads((REPO / "test" / "data" / "robot_hazards_nd.json").read_text())
CONFIG = str(REPO / CASES["config"])
STOPS = [("timeout", signal.SIGTERM), ("ignore_int", signal.SIGINT)]


@pytest.fixture
def suite_file(tmp_path) -> Path:
    path = tmp_path / "suite.json"
    path.write_text(json.dumps({"suite": [{"scenario": CASES["cases"][i]["scenario"], "name": f"case{i}"}
                                          for i in (0, 1, 3)]}))
    return path


def whole_rows(results: Path) -> list[dict]:
    """Every line of the results file, each a whole JSON row ending in a newline."""
    text = results.read_text()
    assert text.endswith("\n")
    rows = [json.loads(line) for line in text.splitlines()]
    assert all("key" in r and "verdict" in r for r in rows)
    return rows


def bags(root: Path) -> list[Path]:
    return sorted(root.rglob("*.mcap"))


def stopped_cleanly(cmd: Command, sig: int, results: Path) -> list[dict]:
    """The checks every stopped command shares; returns the rows it kept."""
    code = cmd.finish()
    assert code == 128 + sig, f"exit {code}:\n{cmd.text()[-3000:]}"
    assert f"stopped by {signal.Signals(sig).name}" in cmd.text()
    assert wait_gone(set(cmd.left()), bound=60) == []  # a child may take a moment after its parent (multiprocessing's resource tracker)
    found = bags(results.parent / f"{results.stem}_bags")
    assert found and all(mcap_summary(b) is not None for b in found), found  # finalised, not cut short
    return whole_rows(results)


def trials(command: str, suite_file: Path, results: Path, domain: int, how: str, *extra: str) -> Command:
    args = [command, str(suite_file), "--stack", "nd", "--config", CONFIG, "--results", str(results),
            "--domain-id", str(domain), *extra]
    return Command(args, how)


@pytest.mark.parametrize("how, sig", STOPS)
def test_rerun_stops_its_stack_and_the_same_command_resumes(tmp_path, suite_file, ros_domain, how, sig):
    results = tmp_path / "trials.jsonl"
    cmd = trials("rerun", suite_file, results, ros_domain, how, "--repeat", "1")
    try:
        cmd.wait_for(cmd.said("[1/"), "first run")
        assert len(cmd.look()) >= 5  # the command, recorder, world, driver, adapter
        cmd.stop(sig)
        rows = stopped_cleanly(cmd, sig, results)
        assert 1 <= len(rows) < 3, [r["key"] for r in rows]
    finally:
        cmd.kill_all()
    if how != "timeout":
        return  # one resume is enough: the stop is the same
    again = trials("rerun", suite_file, results, ros_domain, "plain", "--repeat", "1")
    try:
        assert again.finish() == 0, again.text()[-3000:]
        assert f"{3 - len(rows)} runs to make ({len(rows)} already in" in again.text()
        keys = [r["key"] for r in whole_rows(results)]
        assert len(keys) == 3 == len(set(keys))  # each scenario once: nothing repeated, nothing missing
    finally:
        again.kill_all()


@pytest.mark.parametrize("how, sig", STOPS)
def test_compare_stops_its_stack(tmp_path, suite_file, ros_domain, how, sig):
    wide = tmp_path / "wide.yaml"
    wide.write_text("robot_world:\n  ros__parameters:\n    sim:\n      fov_deg: 360.0\n      beams: 361\n")
    results = tmp_path / "compare.jsonl"
    cmd = trials("compare", suite_file, results, ros_domain, how, "--repeat", "1", "--params", "base=",
                 "--params", f"wide={wide}")
    try:
        cmd.wait_for(cmd.said("[1/"), "first run")
        cmd.stop(sig)
        rows = stopped_cleanly(cmd, sig, results)
        assert rows and {r["label"] for r in rows} == {"base"}  # stopped in the first configuration
    finally:
        cmd.kill_all()


@pytest.mark.parametrize("how, sig", STOPS)
def test_stack_search_stops_its_stack(tmp_path, ros_domain, how, sig):
    results = tmp_path / "search.jsonl"
    cmd = Command(["stack-search", "--stack", "nd", "--config", CONFIG, "--algorithm", "random", "--seed", "3",
                   "--hours", "10", "--evaluations", "50", "--results", str(results),
                   "--domain-id", str(ros_domain)], how)
    try:
        cmd.wait_for(cmd.said("[1/"), "first run")
        cmd.stop(sig)
        assert stopped_cleanly(cmd, sig, results)
    finally:
        cmd.kill_all()


@pytest.mark.parametrize("how, sig", STOPS)
def test_shrink_stops_its_stack_and_writes_no_minimal_suite(tmp_path, suite_file, ros_domain, how, sig):
    results = tmp_path / "shrink.jsonl"
    cmd = trials("shrink", suite_file, results, ros_domain, how, "--scenario", "case0")
    try:
        cmd.wait_for(cmd.said("[1/"), "first run")
        cmd.stop(sig)
        assert stopped_cleanly(cmd, sig, results)
        assert not (tmp_path / "shrink_minimal_suite.json").exists()  # half a shrink is not a minimal map
    finally:
        cmd.kill_all()


def test_rerun_killed_by_sigkill_leaves_no_node_and_a_whole_bag(tmp_path, suite_file, ros_domain):
    results = tmp_path / "trials.jsonl"
    cmd = trials("rerun", suite_file, results, ros_domain, "plain", "--repeat", "1")
    try:
        cmd.wait_for(cmd.said("[1/"), "first run")
        nodes = cmd.look() - {cmd.pid}
        assert len(nodes) >= 4, nodes
        cmd.stop(signal.SIGKILL)
        assert cmd.finish() == -signal.SIGKILL
        assert wait_gone(nodes) == []  # each saw its parent gone
        found = bags(tmp_path / "trials_bags")
        assert len(found) == 1 and mcap_summary(found[0]) is not None
        assert whole_rows(results)
    finally:
        cmd.kill_all()
