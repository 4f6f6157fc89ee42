"""`ambiegen campaign`: the launch file's node set as subprocesses, for machines without ROS.

Starts a recorder, K sim workers and the generator on one DDS domain, waits for the generator to
finish, stops the others with SIGINT (so the MCAP is finalised), then summarises the run from the
MCAP log alone, prints it as a table (``--json``: as JSON) and writes ``DIR/summary.json`` (with
the fidelity profile the run used). The log is ``DIR/<run id>_<UTC time>.mcap``; an existing
non-empty ``DIR`` is refused unless ``--overwrite``. The generator writes the final suite to
``DIR/suite.json``; the same seed gives the same bytes there and the same scenarios and F1 values
in the log, with any number of workers. Node logs go to ``DIR/logs/``.

``stack="nd"`` (robot only) puts a ROS navigation stack behind ``sut_adapter`` in place of the
sim workers: ``robot_world`` hosts each map and ``nd_driver`` (the full model's route and
Nearness Diagram, on Nav2's topics) drives in it, in lockstep, so every verdict is the in-process
full model's for the world's seed (the campaign's). The recorder also logs the robot's topics
(``STACK_TOPICS``): the log replays as a robot bag in Foxglove or RViz.
"""
from __future__ import annotations

import json
import os
import secrets
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .launch_logic import SIM_EXECUTABLES, NodeSpec, log_summary, nd_stack, new_run_id

DISCOVERY_RANGE_VAR = "ROS_AUTOMATIC_DISCOVERY_RANGE"
CAMPAIGN_RANGES = ("LOCALHOST", "SUBNET", "SYSTEM_DEFAULT")  # OFF would keep the campaign's own nodes apart


def discovery_scope(requested: str | None, env: dict[str, str]) -> str:
    """The discovery range of a campaign's nodes: the flag's, else the environment's, else LOCALHOST.

    LOCALHOST by default so that a campaign started on a laptop in the lab's network never
    discovers (nor sends scenarios to) the lab's robots on the same domain id.
    """
    from .ros.transport.discovery import options_from_env

    env = dict(env)
    if requested:  # an explicit flag also beats the deprecated ROS_LOCALHOST_ONLY
        env.pop("ROS_LOCALHOST_ONLY", None)
    scope = requested.upper() if requested else (env.get(DISCOVERY_RANGE_VAR, "").strip() or "LOCALHOST")
    return options_from_env({**env, DISCOVERY_RANGE_VAR: scope}).range


# the sim node of each problem, run as a module (the launch file runs the same one as an executable)
SIM_MODULES = {problem: f"sim_nodes.{executable}" for problem, executable in SIM_EXECUTABLES.items()}
STACKS = ("nd",)
STACK_TOPICS = ("/map", "/initialpose", "/goal_pose", "/scan", "/odom", "/tf", "/tf_static", "/cmd_vel", "/plan",
                "/collision", "/nd_driver/stall", "/ambiegen/world/obstacles", "/ambiegen/world/markers")
"""What a robot stack campaign records besides the AmbieGen topics (types and QoS: the publishers')."""


@dataclass
class CampaignSpec:
    problem: str
    algorithm: str = "nsga2"
    evaluations: int | None = None
    time_budget: float | None = None
    population: int | None = None
    offspring: int | None = None
    seed: int | None = None
    workers: int = 1
    mode: str = "surrogate"
    out: Path = Path("campaign")
    config: str | None = None
    domain_id: int | None = None
    result_timeout: float = 30.0
    timeout: float = 3600.0
    extra_env: dict[str, str] = field(default_factory=dict)
    generator_params: dict[str, Any] = field(default_factory=dict)  # further ROS parameters of the generator
    sim_model: str = "full"  # the workers' executor: full-model simulator + oracle, or the surrogate
    profile: str | None = None  # fidelity profile of every node (None: the config file's, else the default)
    overwrite: bool = False  # write into an `out` that already holds files (a log is still never replaced)
    remote_workers: int = 0  # sim workers started on other machines: the generator waits for them too
    discovery_range: str | None = None  # ROS_AUTOMATIC_DISCOVERY_RANGE of every node (None: see discovery_scope)
    stack: str | None = None  # robot: "nd" = robot_world + nd_driver behind sut_adapter instead of sim workers

    def __post_init__(self):
        if self.stack is not None:
            if self.stack not in STACKS:
                raise ValueError(f"stack: unknown {self.stack!r} (allowed: {'|'.join(STACKS)})")
            if self.problem != "robot":
                raise ValueError(f"stack: a navigation stack runs robot scenarios, not {self.problem}")
            if self.workers != 1 or self.remote_workers:
                raise ValueError("stack: one world and one stack per campaign (--workers 1, no remote workers)")


def ros_params(**params: Any) -> list[str]:
    """``--ros-args -p name:=value ...`` of the given parameters (``None`` values are left out)."""
    args = ["--ros-args"]
    for name, value in params.items():
        if value is None:
            continue
        if isinstance(value, bool):
            value = "true" if value else "false"
        args += ["-p", f"{name}:={value}"]
    return args


def ros_value(value: Any) -> str:
    """A parameter value as ``-p name:=VALUE`` takes it (YAML): booleans in lower case, lists as
    flow sequences, a string quoted whenever YAML would read it bare as something else (the empty
    string as null, "107" as an integer, "true" as a boolean: a node declaring a string refuses them)."""
    import yaml

    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(json.dumps(v) for v in value) + "]"
    if isinstance(value, str):
        try:
            bare_ok = yaml.safe_load(value) == value  # "" reads as None
        except yaml.YAMLError:
            bare_ok = False
        return value if bare_ok else "'" + value.replace("'", "''") + "'"
    return str(value)


def node_argv(node: NodeSpec, python: str | None = None) -> list[str]:
    """The command line of one planned node (``launch_logic.NodeSpec``): a script of ours runs as
    ``python -m <its module>`` (the interpreter of this process: under a sourced ROS the nodes get
    rclpy, without it the DDS backend), any other package's through ``ros2 run``. Parameters that
    are None are left out."""
    ros = ["--ros-args", "-r", f"__node:={node.name}"]
    if node.namespace:
        ros += ["-r", f"__ns:=/{node.namespace}"]
    for source, target in node.remappings:
        ros += ["-r", f"{source}:={target}"]
    for path in node.params_files:
        ros += ["--params-file", str(path)]
    for name, value in node.parameters.items():
        if value is not None:
            ros += ["-p", f"{name}:={ros_value(value)}"]
    if node.package == "ambiegen_ros":
        return [python or sys.executable, "-m", node_module(node.executable), *ros]
    return ["ros2", "run", node.package, node.executable, *ros]


def node_module(executable: str) -> str:
    """The module an executable of ours runs (``entry.SCRIPTS`` maps them the same way): a sim-side
    node in ``sim_nodes``, a search-side one in ``ambiegen_ros.nodes``."""
    from importlib.util import find_spec

    for package in ("sim_nodes", "ambiegen_ros.nodes"):
        if find_spec(f"{package}.{executable}") is not None:
            return f"{package}.{executable}"
    raise ValueError(f"no node module for the executable {executable!r}")


class ProcessGroup:
    """Node subprocesses with their logs in one folder; stopped with SIGINT, SIGKILL as a last resort.

    Each process leads a process group of its own, so that a stop reaches what it started too
    (``ros2 launch`` and its servers, ``ros2 run`` and its node), and a terminal's Ctrl-C reaches
    the command alone, which stops them in order. Each is told this process's pid
    (``signals.child_env``): a node whose command is gone, even by SIGKILL, stops on its own."""

    def __init__(self, log_dir: Path, env: dict[str, str], env_of: dict[str, dict[str, str]] | None = None):
        self.log_dir = Path(log_dir)
        self.env = env
        self.env_of = env_of or {}  # a process's own additions to ``env`` (its transport), by name
        self.procs: dict[str, subprocess.Popen] = {}

    def start(self, name: str, module: str, args: list[str]) -> subprocess.Popen:
        return self.start_argv(name, [sys.executable, "-m", module, *args])

    def start_argv(self, name: str, argv: list[str]) -> subprocess.Popen:
        """Any command (a node of ours, ``ros2 launch ...``), its output in ``<log_dir>/<name>.log``."""
        from .ros.transport.signals import child_env

        self.log_dir.mkdir(parents=True, exist_ok=True)
        with open(self.log_dir / f"{name}.log", "ab") as log:
            self.procs[name] = subprocess.Popen(argv, env=child_env({**self.env, **self.env_of.get(name, {})}),
                                                stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
        return self.procs[name]

    def stop(self, order: list[str] | None = None, timeout: float = 15.0) -> None:
        """Each process in ``order`` (default: all), one after the other: SIGINT to its group, up to
        ``timeout`` s for it to finish its work (a recorder finalises its MCAP), then SIGKILL to what
        is left of the group."""
        for name in order or list(self.procs):
            proc = self.procs.get(name)
            if proc is None or proc.poll() is not None:
                continue
            _signal_group(proc, signal.SIGINT)
            _signal_group(proc, signal.SIGCONT)  # a stopped process takes its SIGINT only once it runs
            try:
                proc.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                _signal_group(proc, signal.SIGKILL)
                proc.wait()
            else:  # the leader is gone: what it started and left behind goes too
                _signal_group(proc, signal.SIGKILL)


def _signal_group(proc: subprocess.Popen, sig: int) -> None:
    """``sig`` to the process group ``proc`` leads (its own: ``start_new_session``), if any is left."""
    try:
        os.killpg(proc.pid, sig)
    except (ProcessLookupError, PermissionError):
        pass


class Campaign:
    def __init__(self, spec: CampaignSpec):
        self.spec = spec
        spec.seed = secrets.randbelow(2**31) if spec.seed is None else spec.seed
        self.run_id = new_run_id(spec.problem, spec.algorithm, spec.seed)
        self.out = Path(spec.out)
        from .ros.mcap_log import log_file_name  # mcap and rosbags load when a campaign starts

        self.mcap = self.out / log_file_name(self.run_id)
        self.suite = self.out / "suite.json"
        self.env = dict(os.environ, **spec.extra_env)
        if spec.domain_id is not None:
            self.env["ROS_DOMAIN_ID"] = str(spec.domain_id)
        self.env[DISCOVERY_RANGE_VAR] = discovery_scope(spec.discovery_range, self.env)
        if spec.discovery_range:
            self.env.pop("ROS_LOCALHOST_ONLY", None)
        self.env.setdefault("PYTHONUNBUFFERED", "1")
        self.group = ProcessGroup(self.out / "logs", self.env)
        self.procs = self.group.procs
        self._start = self.group.start

    def run(self, progress=None) -> dict[str, Any]:
        spec = self.spec
        if self.out.exists() and (not self.out.is_dir() or any(self.out.iterdir())) and not spec.overwrite:
            raise FileExistsError(f"{self.out} already exists and is not an empty directory; "
                                  "choose another --out or pass --overwrite")
        self.out.mkdir(parents=True, exist_ok=True)
        self.suite.unlink(missing_ok=True)  # written by this run's generator, not left from another
        start = time.monotonic()
        interrupted = False
        try:  # a stop signal while the nodes start stops the ones started, as one later does
            self._start_nodes()
            generator = self.procs["generator"]
            while generator.poll() is None:
                if time.monotonic() - start > spec.timeout:
                    generator.send_signal(signal.SIGINT)
                    break
                if self.procs["recorder"].poll() is not None:
                    break  # without a recorder nothing is logged: stop early
                if progress:
                    progress(self, time.monotonic() - start)
                time.sleep(0.2)
        except KeyboardInterrupt:  # Ctrl-C, or SIGTERM/SIGHUP/SIGINT as signals.Stopped
            interrupted = True
        finally:
            self._stop_all()
        summary = self._summary(time.monotonic() - start)
        summary["interrupted"] = interrupted
        from .ros.transport.signals import signal_name, stop_signal

        if stop_signal() is not None:
            summary["stopped_by"] = signal_name(stop_signal())
        (self.out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
        return summary

    def _start_nodes(self) -> None:
        """Recorder first (it hears everything), then the stack or the sim workers, the generator last."""
        spec = self.spec
        self._start("recorder", "ambiegen_ros.nodes.recorder", ros_params(
            output=str(self.mcap.resolve()), extra_topics=",".join(STACK_TOPICS) if spec.stack else None))
        if spec.stack:
            self._start_stack()
        for k in range(0 if spec.stack else spec.workers):
            name = f"{spec.problem}_sim_{k}"
            self._start(
                name,
                SIM_MODULES[spec.problem],
                ["--ros-args", "-r", f"__node:={name}"]
                + ros_params(
                    worker_id=f"{name}_{self.run_id[-6:]}",  # unique per run: campaigns may share a domain
                    model=spec.sim_model,
                    profile=spec.profile,
                    # stream Odometry/Temperature for the executed suite; in the loop it would be every evaluation
                    timeline_period=0.0 if spec.mode == "in_the_loop" else None,
                    min_result_subscribers=2,
                    config_file=spec.config,
                )[1:],
            )
        self._start(
            "generator",
            "ambiegen_ros.nodes.generator",
            ros_params(
                problem=spec.problem,
                algorithm=spec.algorithm,
                evaluations=spec.evaluations,
                time_budget=spec.time_budget,
                population=spec.population,
                offspring=spec.offspring,
                seed=spec.seed,
                profile=spec.profile,
                mode=spec.mode,
                run_id=self.run_id,
                suite_file=str(self.suite.resolve()),
                config_file=spec.config,
                min_subscribers=spec.workers + spec.remote_workers + 1,
                min_workers=spec.workers + spec.remote_workers,
                min_recorders=1,  # no scenario before the recorder reads every topic it records (the stack's too)
                subscriber_wait=300.0,  # a bound, not a wait: it ends once every worker matches (busy machines start slowly)
                result_timeout=spec.result_timeout,
                **spec.generator_params,
            ),
        )

    def _start_stack(self) -> None:
        """robot_world + nd_driver + sut_adapter: the full model's loop, step for step, over ROS topics."""
        for node in nd_stack(self.spec.seed, self.run_id[-6:], self.spec.profile, self.spec.config):
            self.group.start_argv(node.name, node_argv(node))

    def _stop_all(self) -> None:
        """Generator first (it may still be writing timeouts), then workers, recorder last."""
        if "generator" in self.procs:
            time.sleep(0.3)  # let the last results reach the recorder
        self.group.stop(["generator"] + [n for n in self.procs if n not in ("generator", "recorder")] + ["recorder"])

    def _summary(self, elapsed: float) -> dict[str, Any]:
        spec = self.spec
        summary: dict[str, Any] = {
            "run_id": self.run_id,
            "problem": spec.problem,
            "algorithm": spec.algorithm,
            "mode": spec.mode,
            "sim_model": spec.sim_model,
            "profile": spec.profile,
            "seed": spec.seed,
            "workers": spec.workers,
            "stack": spec.stack,
            "domain_id": self.env.get("ROS_DOMAIN_ID", "0"),
            "discovery_range": self.env[DISCOVERY_RANGE_VAR],
            "elapsed_s": round(elapsed, 2),
            "exit_codes": {n: p.returncode for n, p in self.procs.items()},
        }
        summary.update(log_summary(self.mcap, self.run_id, str(self.out / "logs" / "recorder.log")))
        if self.suite.exists():
            summary["suite"] = str(self.suite)
        return summary
