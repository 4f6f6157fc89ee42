"""Every long command stops cleanly on any stop signal (issue 70): ``campaign`` and ``experiment``.

Real commands in real subprocesses, started as a user's script starts them: under ``timeout -s
TERM`` (the stop is a SIGTERM that ``timeout`` forwards) or in the background with SIGINT ignored
(``trap '' INT``, what a non-interactive shell does). Each is stopped once an event shows it is
mid-run (a worker joined the generator; a run's file written), never after a wait. Then: the exit
status is 128 + the signal, nothing it started still runs (a /proc scan: ``helpers.stopping``),
the MCAP opens with the ``mcap`` package's reader (its summary: finalised, not recovered), the
experiment's run files parse and ``--resume`` goes on from them. Killed by SIGKILL, a command
cannot stop anything: its nodes and pool workers notice their parent is gone and stop on their own.
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]

from helpers.stopping import Command, mcap_summary, running, wait_gone  # noqa: E402

pytestmark = pytest.mark.skipif(os.environ.get("AMBIEGEN_TRANSPORT", "auto") == "rclpy",
                                reason="these tests drive the DDS backend")


def campaign(out: Path, domain: int, how: str) -> Command:
    """A thermostat campaign in the loop with a budget far beyond the test: only a signal ends it."""
    return Command(["campaign", "--problem", "thermostat", "--algorithm", "ga", "--mode", "in_the_loop",
                    "--population", "10", "--offspring", "10", "--time-budget", "900", "--timeout", "900",
                    "--domain-id", str(domain), "--out", str(out)], how)


def joined(out: Path):
    """The generator has its worker: the campaign is mid-run."""
    log = out / "logs" / "generator.log"
    return lambda: log.exists() and "joined" in log.read_text(errors="replace")


@pytest.mark.parametrize("how, sig", [("timeout", signal.SIGTERM), ("ignore_int", signal.SIGINT),
                                      ("plain", signal.SIGHUP)])
def test_a_campaign_stops_its_nodes_and_finalises_its_log(tmp_path, ros_domain, how, sig):
    out = tmp_path / "campaign"
    cmd = campaign(out, ros_domain, how)
    try:
        cmd.wait_for(joined(out), "worker joining the generator")
        nodes = set(cmd.look())
        assert len(nodes) >= 4, nodes  # the command, recorder, sim worker, generator
        cmd.stop(sig)
        code = cmd.finish()
        assert code == 128 + sig, f"exit {code}:\n{cmd.text()[-3000:]}"
        assert f"stopped by {sig.name}" in cmd.text()
        assert wait_gone(set(cmd.left()), bound=60) == []  # a child may take a moment after its parent (multiprocessing's resource tracker)
        summary = json.loads((out / "summary.json").read_text())
        assert summary["interrupted"] and summary["stopped_by"] == sig.name
        assert summary["exit_codes"]["recorder"] == 0  # it finished its file, not killed
        log = mcap_summary(Path(summary["mcap"]))
        assert log is not None and log.statistics.message_count > 0
    finally:
        cmd.kill_all()


def test_a_campaign_killed_by_sigkill_leaves_no_node_and_a_whole_log(tmp_path, ros_domain):
    """An out-of-memory kill: the command stops nothing, its nodes see their parent gone and stop."""
    out = tmp_path / "campaign"
    cmd = campaign(out, ros_domain, "plain")
    try:
        cmd.wait_for(joined(out), "worker joining the generator")
        nodes = cmd.look() - {cmd.pid}
        assert len(nodes) >= 3, nodes
        cmd.stop(signal.SIGKILL)
        assert cmd.finish() == -signal.SIGKILL
        assert wait_gone(nodes) == []  # an event with a generous bound, not a schedule
        logs = list(out.glob("*.mcap"))
        assert len(logs) == 1
        log = mcap_summary(logs[0])
        assert log is not None and log.statistics.message_count > 0
        assert "closed" in (out / "logs" / "recorder.log").read_text()  # finalised by its own stop
    finally:
        cmd.kill_all()


def test_a_node_started_with_sigint_ignored_stops_on_sigint(tmp_path, ros_domain):
    """A recorder started straight from a script's background job (SIGINT inherited as ignored)."""
    bag = tmp_path / "alone.mcap"
    env = dict(os.environ, ROS_DOMAIN_ID=str(ros_domain))
    proc = subprocess.Popen(["sh", "-c", "trap '' INT; exec \"$@\"", "sh", sys.executable, "-m",
                             "ambiegen_ros.nodes.recorder", "--ros-args", "-p", f"output:={bag}"],
                            cwd=REPO, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        for line in proc.stdout:
            if "recording to" in line:
                break
        assert not sigint_ignored(proc.pid)  # its own handler, whatever it inherited
        os.kill(proc.pid, signal.SIGINT)
        assert proc.wait(timeout=120) == 0
        assert mcap_summary(bag) is not None
    finally:
        if proc.poll() is None:
            proc.kill()


def sigint_ignored(pid: int) -> bool:
    """SIGINT in the process's ignored set (/proc/PID/status, SigIgn: bit 1)."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("SigIgn:"):
            return bool(int(line.split()[1], 16) & (1 << (signal.SIGINT - 1)))
    raise AssertionError(f"no SigIgn for {pid}")


def experiment(out: Path, how: str, *extra: str) -> Command:
    return Command(["experiment", "--problem", "thermostat", "--algorithms", "ga,random", "--runs", "3",
                    "--time-budget", "2", "--jobs", "2", "--seed", "5", "-q", "--out", str(out), *extra], how)


def run_files(out: Path) -> dict[str, str]:
    return {p.name: p.read_text() for p in sorted((out / "runs").glob("*.json"))} if (out / "runs").exists() else {}


@pytest.mark.parametrize("how, sig", [("timeout", signal.SIGTERM), ("ignore_int", signal.SIGINT)])
def test_an_experiment_stops_its_pool_and_resumes(tmp_path, how, sig):
    out = tmp_path / "experiment"
    cmd = experiment(out, how)
    try:
        cmd.wait_for(lambda: bool(run_files(out)), "run file")
        assert len(cmd.look()) >= 3  # the command and its two pool workers
        cmd.stop(sig)
        code = cmd.finish()
        assert code == 128 + sig, f"exit {code}:\n{cmd.text()[-3000:]}"
        assert wait_gone(set(cmd.left()), bound=60) == []  # a child may take a moment after its parent (multiprocessing's resource tracker)
        kept = run_files(out)
        for name, text in kept.items():
            assert json.loads(text)["run"] in (0, 1, 2), name  # whole files only
        if how != "timeout":
            return  # one resume is enough: the stop is the same
        if len(kept) == 6:
            pytest.skip("every run ended before the stop took effect: nothing left to resume")
        again = Command(["experiment", "--problem", "thermostat", "--algorithms", "ga,random", "--runs", "3",
                         "--time-budget", "2", "--jobs", "2", "--seed", "5", "-q", "--out", str(out), "--resume"],
                        "plain")
        assert again.finish() == 0, again.text()[-3000:]
        after = run_files(out)
        assert len(after) == 6 and all(after[name] == text for name, text in kept.items())  # kept, not run again
    finally:
        cmd.kill_all()


def test_an_experiment_killed_by_sigkill_leaves_no_worker(tmp_path):
    out = tmp_path / "experiment"
    cmd = experiment(out, "plain")
    try:
        cmd.wait_for(lambda: bool(run_files(out)), "run file")
        workers = cmd.look() - {cmd.pid}
        assert workers and all(running(p) for p in workers)
        cmd.stop(signal.SIGKILL)
        assert cmd.finish() == -signal.SIGKILL
        assert wait_gone(workers) == []
        for text in run_files(out).values():
            json.loads(text)
    finally:
        cmd.kill_all()


def test_a_node_whose_named_parent_is_not_its_own_watches_it_and_stops_when_it_dies(tmp_path, ros_domain):
    """A launcher between command and node (``ros2 run``): the node polls the named command's pid
    and stops, finalising its log, once that process is gone."""
    from ambiegen_ros.ros.transport.signals import PARENT_VAR

    command = subprocess.Popen(["sleep", "600"])  # stands for the command; the test is the launcher
    bag = tmp_path / "watched.mcap"
    env = dict(os.environ, ROS_DOMAIN_ID=str(ros_domain), **{PARENT_VAR: str(command.pid)})
    proc = subprocess.Popen([sys.executable, "-m", "ambiegen_ros.nodes.recorder", "--ros-args", "-p",
                             f"output:={bag}"], cwd=REPO, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True)
    try:
        for line in proc.stdout:
            if "recording to" in line:
                break
        assert proc.poll() is None  # its named parent lives: it records on
        command.kill()
        command.wait()
        assert proc.wait(timeout=120) == 0
        assert mcap_summary(bag) is not None
    finally:
        for p in (proc, command):
            if p.poll() is None:
                p.kill()


HANDLER_SCRIPT = r"""
import os, signal, sys
from ambiegen_ros.ros.transport import signals
signal.signal(signal.SIGINT, signal.SIG_IGN)  # as a script's background job inherits it
signals.install(raise_stop=True)
try:
    os.kill(os.getpid(), signal.SIGHUP)
    signal.pause()
except signals.Stopped as exc:
    print("stopped", exc.signum)
os.kill(os.getpid(), signal.SIGINT)  # counted, not raised: the cleanup it would cut is bounded
print("first", signals.stop_signal())
stops = []
signals.register(object(), lambda: stops.append(1))  # a node made after the stop stops at once
print("node stopped", len(stops))
"""


def test_the_first_stop_signal_raises_once_and_stops_a_node_made_later():
    """``signals`` in a process of its own (its handlers would otherwise stay in the test's)."""
    run = subprocess.run([sys.executable, "-c", HANDLER_SCRIPT], cwd=REPO, capture_output=True, text=True,
                         timeout=120)
    assert run.returncode == 0, run.stderr[-2000:]
    assert run.stdout.split("\n")[:3] == [f"stopped {signal.SIGHUP}", f"first {signal.SIGHUP}", "node stopped 1"]
