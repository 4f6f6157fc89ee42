"""A small test network: hosts as Linux network namespaces joined by one bridge, multicast on.

Every host is a namespace with loopback and one veth link (``eth0``, 10.77.0.<k>/24) into a
switch namespace that holds the bridge, so no interface or route is added to the machine's own
namespace and traffic never leaves these namespaces. Names carry the creating pid and a counter,
so concurrent runs do not meet; ``destroy`` kills what still runs inside and deletes them all.

Used by test/ros/test_multihost.py, test/ros/test_discovery_range.py and bench/multihost.py.
Tests fire faults on events (``Progress``: results seen, workers lost or back), never at a
wall-clock offset; offsets remain for the bench's fixed schedule.
Needs root (CAP_NET_ADMIN + CAP_SYS_ADMIN) and iproute2; ``unavailable_reason`` says why not.
"""
from __future__ import annotations

import itertools
import os
import re
import shlex
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Sequence

from ambiegen_ros.campaign import SIM_MODULES

SUBNET = "10.77.0"
_serial = itertools.count()


def _ip(*args: str, check: bool = True) -> subprocess.CompletedProcess:
    return subprocess.run(["ip", *args], capture_output=True, text=True, check=check, timeout=20)


def unavailable_reason() -> str | None:
    """Why namespaces cannot be made here (None when they can): probed by making one."""
    if os.name != "posix" or not Path("/proc/self/ns/net").exists():
        return "network namespaces need Linux"
    if os.geteuid() != 0:
        return "making network namespaces needs root"
    if shutil.which("ip") is None:
        return "iproute2 ('ip') is not installed"
    probe = f"agprobe{os.getpid()}"
    try:
        _ip("netns", "add", probe)
    except subprocess.CalledProcessError as exc:
        return f"'ip netns add' failed: {exc.stderr.strip()}"
    try:
        _ip("-n", probe, "link", "add", "p0", "type", "veth", "peer", "name", "p1")
        _ip("-n", probe, "link", "add", "br0", "type", "bridge")
    except subprocess.CalledProcessError as exc:
        return f"cannot make veth/bridge links in a namespace: {exc.stderr.strip()}"
    finally:
        _ip("netns", "del", probe, check=False)
    return None


class TestNetwork:
    """Hosts ``names`` (e.g. a, b, c) on one bridged subnet; ``address(name)`` is each one's IP."""

    __test__ = False  # not a pytest class

    def __init__(self, names: Sequence[str] = ("a", "b", "c"), multicast: bool = True):
        self.tag = f"ag{os.getpid()}n{next(_serial)}"
        self.names = list(names)
        self.switch = f"{self.tag}sw"
        self.multicast = multicast
        self.created: list[str] = []
        self.procs: list[subprocess.Popen] = []

    # --- layout ------------------------------------------------------------------------------
    def ns(self, name: str) -> str:
        return f"{self.tag}{name}"

    def address(self, name: str) -> str:
        return f"{SUBNET}.{self.names.index(name) + 1}"

    def port(self, name: str) -> str:
        """The switch-side end of a host's link (in the switch namespace)."""
        return f"p{name}"

    def create(self) -> "TestNetwork":
        try:
            for ns in [self.switch] + [self.ns(n) for n in self.names]:
                _ip("netns", "add", ns)
                self.created.append(ns)
                _ip("-n", ns, "link", "set", "lo", "up")
            _ip("-n", self.switch, "link", "add", "br0", "type", "bridge", "mcast_snooping", "0")
            _ip("-n", self.switch, "link", "set", "br0", "up")
            for name in self.names:
                ns, port = self.ns(name), self.port(name)
                _ip("-n", self.switch, "link", "add", port, "type", "veth", "peer", "name", "eth0", "netns", ns)
                _ip("-n", self.switch, "link", "set", port, "master", "br0")
                _ip("-n", self.switch, "link", "set", port, "up")
                _ip("-n", ns, "addr", "add", f"{self.address(name)}/24", "dev", "eth0")
                _ip("-n", ns, "link", "set", "eth0", "up")
            self.set_multicast(self.multicast)
        except BaseException:
            self.destroy()
            raise
        return self

    def set_multicast(self, on: bool) -> None:
        """Multicast on every host link (with a 224.0.0.0/4 route) and the bridge, or off."""
        self.multicast = on
        flag = "on" if on else "off"
        _ip("-n", self.switch, "link", "set", "br0", "multicast", flag)
        for name in self.names:
            ns = self.ns(name)
            _ip("-n", ns, "link", "set", "eth0", "multicast", flag)
            if on:
                _ip("-n", ns, "route", "replace", "224.0.0.0/4", "dev", "eth0")
            else:
                _ip("-n", ns, "route", "del", "224.0.0.0/4", check=False)

    def set_link(self, name: str, up: bool) -> None:
        """Pull (or plug back) a host's cable: the switch-side end of its link goes down (up).

        The host keeps its interface, address and routes, as a machine whose cable is unplugged.
        """
        _ip("-n", self.switch, "link", "set", self.port(name), "up" if up else "down")

    # --- processes ---------------------------------------------------------------------------
    def popen(self, name: str, args: Sequence[str], **kwargs) -> subprocess.Popen:
        """Start ``args`` inside host ``name``; stopped by ``destroy`` if still running."""
        proc = subprocess.Popen(["ip", "netns", "exec", self.ns(name), *args], **kwargs)
        self.procs.append(proc)
        return proc

    def run(self, name: str, args: Sequence[str], timeout: float = 30) -> subprocess.CompletedProcess:
        return subprocess.run(["ip", "netns", "exec", self.ns(name), *args], capture_output=True, text=True,
                              timeout=timeout)

    def pids(self, name: str) -> list[int]:
        return self.pids_of(self.ns(name))

    def destroy(self) -> None:
        """Stop every process still inside a host, then delete the namespaces (safe to repeat)."""
        for proc in self.procs:
            if proc.poll() is None:
                proc.send_signal(signal.SIGINT)
        deadline = time.monotonic() + 5
        for proc in self.procs:
            try:
                proc.wait(max(0.1, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
        for ns in list(self.created):
            for pid in self.pids_of(ns):  # started in there by our processes
                try:
                    os.kill(pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass
            _ip("netns", "del", ns, check=False)
            self.created.remove(ns)

    @staticmethod
    def pids_of(ns: str) -> list[int]:
        out = _ip("netns", "pids", ns, check=False).stdout.split()
        return [int(p) for p in out if p.isdigit()]

    def __enter__(self) -> "TestNetwork":
        return self.create()

    def __exit__(self, *exc) -> None:
        self.destroy()


# --- a campaign across hosts (shared by test/ros/test_multihost.py and bench/multihost.py) ----------
REPO = Path(__file__).resolve().parents[2]


def node_env(domain: int, **extra: str) -> dict[str, str]:
    """Environment of a node process: this repo importable, one domain, the rest inherited."""
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain), PYTHONUNBUFFERED="1", PYTHONPATH=str(REPO), **extra)
    for var in ("ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_STATIC_PEERS", "ROS_LOCALHOST_ONLY"):
        if var not in extra:
            env.pop(var, None)
    return env


def rclpy_unavailable_reason() -> str | None:
    """Why node processes cannot run on rclpy here (None when they can): the real-ROS suite's
    condition, a Jazzy install whose ``import rclpy`` works (test/real_ros/jazzy_env.py)."""
    return _jazzy_env().probe().get("skip")


def _jazzy_env():
    real_ros = str(REPO / "test" / "real_ros")
    if real_ros not in sys.path:
        sys.path.insert(0, real_ros)
    import jazzy_env

    return jazzy_env


def node_process(args: Sequence[str], domain: int, backend: str = "dds", install: Path | None = None,
                 **extra_env: str) -> tuple[list[str], dict[str, str]]:
    """Command and environment of ``python ARGS`` as a node process on ``backend``: the venv's
    python on the DDS backend; on rclpy the ROS python under the sourced Jazzy install (and the
    colcon workspace ``install``, which brings ambiegen_msgs), as the real-ROS suite runs them.
    The caller runs it in REPO, so this working tree's modules come first."""
    if backend != "rclpy":
        return [sys.executable, *args], node_env(domain, AMBIEGEN_TRANSPORT=backend, **extra_env)
    jazzy = _jazzy_env()
    command = " ".join(shlex.quote(a) for a in (jazzy.probe()["executable"], *args))
    return jazzy.ros_command(command, install), jazzy.ros_env(domain, **extra_env)


def start_worker(net: TestNetwork, host: str, domain: int, worker_id: str, log_dir: Path,
                 problem: str = "thermostat", backend: str = "dds", install: Path | None = None,
                 result_subscribers: int = 2, **extra_env: str) -> subprocess.Popen:
    """A surrogate sim worker on ``host`` (the issue's ``thermostat_sim -p model:=surrogate``).

    It announces itself (so the generator starts) only once ``result_subscribers`` readers of
    its results are matched: generator and recorder, plus the result probe when one listens."""
    log_dir.mkdir(parents=True, exist_ok=True)
    module = SIM_MODULES[problem]
    args, env = node_process(["-m", module, "--ros-args", "-r", f"__node:={worker_id}", "-p", f"worker_id:={worker_id}",
                              "-p", "model:=surrogate", "-p", f"min_result_subscribers:={result_subscribers}"],
                             domain, backend, install, **extra_env)
    with open(log_dir / f"{worker_id}.log", "wb") as log:
        return net.popen(host, args, cwd=REPO, env=env, stdout=log, stderr=subprocess.STDOUT)


def start_campaign(net: TestNetwork, host: str, domain: int, out: Path, evaluations: int, remote_workers: int,
                   seed: int = 1, extra_args: Sequence[str] = (), backend: str = "dds", install: Path | None = None,
                   **extra_env: str) -> subprocess.Popen:
    """``ambiegen campaign`` (generator + recorder, no local worker) in the loop on ``host``."""
    args, env = node_process(
        ["-m", "ambiegen_ros", "campaign", "--problem", "thermostat", "--algorithm", "ga",
         "--mode", "in_the_loop", "--evaluations", str(evaluations), "--seed", str(seed),
         "--workers", "0", "--remote-workers", str(remote_workers), "--discovery-range", "subnet",
         "--domain-id", str(domain), "--out", str(out), "--json", *extra_args], domain, backend, install, **extra_env)
    return net.popen(host, args, cwd=REPO, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def read_dispatch(mcap: Path, run_id: str) -> dict:
    """What the log says of each scenario: sends (s, worker, attempt) and results (log time s,
    worker, failure kind). A send's time is its header stamp, the generator's clock when it
    published, so it compares exactly with the generator's log lines (no delivery lag)."""
    from ambiegen_ros.ros import topics
    from ambiegen_ros.ros.runlog import iter_messages

    scenario_topics = {topics.scenarios(p) for p in topics.SCENARIO_TYPES}
    sends: dict[int, list[tuple[float, str, int]]] = {}
    results: dict[int, list[tuple[float, str, int]]] = {}
    for topic, _, stamp, msg in iter_messages(mcap, scenario_topics | {topics.RESULTS}):
        if topic in scenario_topics and msg.meta.run_id == run_id:
            sent = msg.meta.header.stamp
            sends.setdefault(int(msg.meta.scenario_id), []).append(
                (sent.sec + sent.nanosec / 1e9, msg.meta.assigned_worker, int(msg.meta.attempt)))
        elif topic == topics.RESULTS and msg.run_id == run_id:
            results.setdefault(int(msg.scenario_id), []).append((stamp / 1e9, msg.worker, int(msg.failure_kind)))
    return {"sends": sends, "results": results}


def fault_timings(dispatch: dict, worker: str, fault_at: float, horizon: float = 15.0) -> dict:
    """What became of the scenarios a fault stranded on ``worker``: those sent to it from just
    before the fault until ``horizon`` s after, whose first result did not come from it.

    Seconds from the fault to their first and last re-send to another worker (reassignment) and
    to the last of their results (recovered); how many got no result, or a timeout record."""
    moved = []
    for sid, sends in dispatch["sends"].items():
        mine = [s for s in sends if s[1] == worker and fault_at - 2 <= s[0] <= fault_at + horizon]
        results = dispatch["results"].get(sid, [])
        if not mine or (results and (results[0][1] == worker or results[0][0] <= fault_at)):
            continue
        if results and results[0][1] in {s[1] for s in sends if s[0] < mine[0][0]}:
            continue  # answered by a worker that had it before this one (e.g. a late answer from a cut host)
        elsewhere = [s for s in sends if s[0] > mine[0][0] and s[1] != worker]
        moved.append((elsewhere[0] if elsewhere else None, results[0] if results else None))
    resent = [m[0][0] for m in moved if m[0] is not None]
    finished = [m[1][0] for m in moved if m[1] is not None]
    return {
        "stranded": len(moved),
        "resent": len(resent),
        "resent_to": sorted({m[0][1] for m in moved if m[0] is not None}),
        "unanswered": sum(1 for m in moved if m[1] is None),
        "first_resend_s": round(min(resent) - fault_at, 2) if resent else None,
        "last_resend_s": round(max(resent) - fault_at, 2) if resent else None,
        "last_result_s": round(max(finished) - fault_at, 2) if finished else None,
    }


def wait_for_line(path: Path, text: str, proc: subprocess.Popen, timeout: float) -> float:
    """Wall time when ``text`` first shows in the log at ``path`` (fails if ``proc`` ends first).

    ``timeout`` is a safety net for a hung process, not a measure: the wait ends on the line."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if path.exists() and text in path.read_text(errors="replace"):
            return time.time()
        if proc.poll() is not None:
            raise RuntimeError(f"{path.name}: process ended before '{text}'")
        time.sleep(0.05)
    raise TimeoutError(f"no '{text}' in {path} after {timeout:g} s")


WORKER_EVENT = re.compile(r"\[(?:WARN|INFO)\] \[(\d+\.\d+)\] \[generator\]: worker (\S+) (lost|is back|joined)")


class Progress:
    """What a running campaign has done so far, for fault triggers: results seen by the result
    probe (test/helpers/result_probe.py, on host a) and the generator's worker events.

    "Since" means since the last fault was applied (``mark``), so a trigger asks about what
    followed the previous fault: ``answered("c1")`` after the cable is back, ``event("b2",
    "lost")`` after the kill."""

    def __init__(self, probe: subprocess.Popen, generator_log: Path):
        self.generator_log = generator_log
        self.results = 0
        self.by_worker: dict[str, int] = {}
        self._marked: dict[str, int] = {}
        self._since = 0.0
        self._lock = threading.Lock()
        self._reader = threading.Thread(target=self._read, args=(probe,), daemon=True)
        self._reader.start()

    def _read(self, probe: subprocess.Popen) -> None:
        for line in probe.stdout:
            parts = line.split()
            if len(parts) == 2:
                with self._lock:
                    self.results += 1
                    self.by_worker[parts[0]] = self.by_worker.get(parts[0], 0) + 1

    def mark(self, at: float) -> None:
        with self._lock:
            self._marked = dict(self.by_worker)
            self._since = at

    def answered(self, worker: str) -> int:
        """Results from ``worker`` seen since the last fault."""
        with self._lock:
            return self.by_worker.get(worker, 0) - self._marked.get(worker, 0)

    def event(self, worker: str, kind: str) -> bool:
        """Did the generator log ``worker <worker> <kind>`` (lost | is back | joined) since the last fault?"""
        text = self.generator_log.read_text(errors="replace") if self.generator_log.exists() else ""
        return any(w == worker and k == kind and float(t) > self._since for t, w, k in WORKER_EVENT.findall(text))


def start_probe(net: TestNetwork, host: str, domain: int, backend: str = "dds",
                install: Path | None = None) -> subprocess.Popen:
    """The result probe on ``host`` (its stdout: one ``worker scenario_id`` line per result)."""
    args, env = node_process([str(REPO / "test" / "helpers" / "result_probe.py")], domain, backend, install,
                             ROS_AUTOMATIC_DISCOVERY_RANGE="SUBNET")
    return net.popen(host, args, cwd=REPO, env=env, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)


def _wait_for_trigger(when, progress: Progress, began: float, campaign: subprocess.Popen, deadline: float,
                      what: str) -> None:
    """Wait until a fault is due: ``when`` is an offset in s after the start (a bench's fixed
    schedule) or a predicate on ``progress`` (an event). Fails if the campaign ends first."""
    while True:
        if callable(when):
            if when(progress):
                return
        elif time.time() >= began + when:
            return
        if campaign.poll() is not None:
            raise RuntimeError(f"the campaign ended before the trigger of '{what}' "
                               f"({progress.results} results seen, by worker {progress.by_worker})")
        if time.monotonic() > deadline:  # a safety net for a hung run, not a measure
            raise TimeoutError(f"'{what}' never became due ({progress.results} results seen, by worker "
                               f"{progress.by_worker})")
        time.sleep(0.02)


def campaign_across_hosts(net: TestNetwork, out: Path, domain: int, evaluations: int, workers: dict[str, str],
                          faults: Sequence[tuple] = (), backend: str = "dds",
                          timeout: float = 240, wait_for: int | None = None, install: Path | None = None) -> dict:
    """Generator + recorder on host ``a``, ``workers`` (id -> host) elsewhere, and ``faults``
    applied in order: (when, "down" | "up" | "kill", host or worker id), where ``when`` is a
    predicate on a ``Progress`` (fires on an event: tests) or an offset in s after the generator
    starts (bench/multihost.py's fixed schedule). A result probe on host ``a`` feeds the
    ``Progress``; every worker waits until it is matched, so it misses no result.

    Returns the summary, what the log says of each scenario, the faults as (wall time, action,
    target), results seen when each fault fired, the generator's log and each worker's process.
    The generator waits for ``wait_for`` workers (default: all) before it starts. On rclpy every
    process needs the workspace ``install`` (node_process)."""
    import json

    probe = start_probe(net, "a", domain, backend, install)
    procs = {w: start_worker(net, host, domain, w, out / "workers", backend=backend, install=install,
                             result_subscribers=3)
             for w, host in workers.items()}
    campaign = start_campaign(net, "a", domain, out / "run", evaluations,
                              len(workers) if wait_for is None else wait_for,
                              backend=backend, install=install)
    generator_log = out / "run" / "logs" / "generator.log"
    began = wait_for_line(generator_log, "workers: starting", campaign, timeout)
    progress = Progress(probe, generator_log)
    progress.mark(began)
    deadline = time.monotonic() + timeout
    if faults and not any(callable(f[0]) for f in faults):
        faults = sorted(faults)
    applied, seen = [], []
    try:
        for when, action, target in faults:
            _wait_for_trigger(when, progress, began, campaign, deadline, f"{action} {target}")
            if action == "kill":
                procs[target].kill()
            else:
                net.set_link(target, action == "up")
            applied.append((time.time(), action, target))
            seen.append(progress.results)
            progress.mark(applied[-1][0])
        stdout, stderr = campaign.communicate(timeout=max(1.0, deadline - time.monotonic()))
    except subprocess.TimeoutExpired:
        campaign.kill()
        stdout, stderr = campaign.communicate()
    except BaseException:
        campaign.kill()
        campaign.communicate()
        raise
    summary = json.loads(stdout[stdout.index("{"):stdout.rindex("}") + 1]) if "{" in stdout else {}
    result = {"summary": summary, "returncode": campaign.returncode, "stderr": stderr, "began": began,
              "faults": applied, "results_seen_at_faults": seen, "results_seen": progress.results,
              "generator_log": generator_log.read_text(errors="replace"), "workers": procs}
    if summary.get("mcap"):
        result["dispatch"] = read_dispatch(Path(summary["mcap"]), summary["run_id"])
    return result
