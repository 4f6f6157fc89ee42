"""`ambiegen campaign`: the launch file's node set as subprocesses, for machines without ROS.

Starts a recorder, K sim workers and the generator on one DDS domain, waits for the generator to
finish, stops the others with SIGINT (so the MCAP is finalised), then summarises the run from the
MCAP log alone, prints it as a table (``--json``: as JSON) and writes ``DIR/summary.json`` (with
the fidelity profile the run used). The log is ``DIR/<run id>_<UTC time>.mcap``; an existing
non-empty ``DIR`` is refused unless ``--overwrite``. The generator writes the final suite to
``DIR/suite.json``; the same seed gives the same bytes there and the same scenarios and F1 values
in the log, with any number of workers. Node logs go to ``DIR/logs/``.
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

from .launch_logic import SIM_EXECUTABLES, log_summary, new_run_id, summary_table
from .ros.mcap_log import log_file_name

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


def _ros_params(**params: Any) -> list[str]:
    args = ["--ros-args"]
    for name, value in params.items():
        if value is None:
            continue
        if isinstance(value, bool):
            value = "true" if value else "false"
        args += ["-p", f"{name}:={value}"]
    return args


class ProcessGroup:
    """Node subprocesses with their logs in one folder; stopped with SIGINT, SIGKILL as a last resort."""

    def __init__(self, log_dir: Path, env: dict[str, str]):
        self.log_dir = Path(log_dir)
        self.env = env
        self.procs: dict[str, subprocess.Popen] = {}

    def start(self, name: str, module: str, args: list[str]) -> subprocess.Popen:
        self.log_dir.mkdir(parents=True, exist_ok=True)
        log = open(self.log_dir / f"{name}.log", "wb")
        self.procs[name] = subprocess.Popen(
            [sys.executable, "-m", module, *args], env=self.env, stdout=log, stderr=subprocess.STDOUT
        )
        log.close()
        return self.procs[name]

    def stop(self, order: list[str] | None = None, timeout: float = 15.0) -> None:
        for name in order or list(self.procs):
            proc = self.procs.get(name)
            if proc is None or proc.poll() is not None:
                continue
            proc.send_signal(signal.SIGINT)
            try:
                proc.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()


class Campaign:
    def __init__(self, spec: CampaignSpec):
        self.spec = spec
        spec.seed = secrets.randbelow(2**31) if spec.seed is None else spec.seed
        self.run_id = new_run_id(spec.problem, spec.algorithm, spec.seed)
        self.out = Path(spec.out)
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
        self._start("recorder", "ambiegen_ros.nodes.recorder", _ros_params(output=str(self.mcap.resolve())))
        for k in range(spec.workers):
            name = f"{spec.problem}_sim_{k}"
            self._start(
                name,
                SIM_MODULES[spec.problem],
                ["--ros-args", "-r", f"__node:={name}"]
                + _ros_params(
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
            _ros_params(
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
                subscriber_wait=30.0,
                result_timeout=spec.result_timeout,
                **spec.generator_params,
            ),
        )
        generator = self.procs["generator"]
        interrupted = False
        try:
            while generator.poll() is None:
                if time.monotonic() - start > spec.timeout:
                    generator.send_signal(signal.SIGINT)
                    break
                if self.procs["recorder"].poll() is not None:
                    break  # without a recorder nothing is logged: stop early
                if progress:
                    progress(self, time.monotonic() - start)
                time.sleep(0.2)
        except KeyboardInterrupt:
            interrupted = True
        finally:
            self._stop_all()
        summary = self._summary(time.monotonic() - start)
        summary["interrupted"] = interrupted
        (self.out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
        return summary

    def _stop_all(self) -> None:
        """Generator first (it may still be writing timeouts), then workers, recorder last."""
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
            "domain_id": self.env.get("ROS_DOMAIN_ID", "0"),
            "discovery_range": self.env[DISCOVERY_RANGE_VAR],
            "elapsed_s": round(elapsed, 2),
            "exit_codes": {n: p.returncode for n, p in self.procs.items()},
        }
        summary.update(log_summary(self.mcap, self.run_id, str(self.out / "logs" / "recorder.log")))
        if self.suite.exists():
            summary["suite"] = str(self.suite)
        return summary


def register_cli(sub) -> None:
    """Adds `campaign` and `recover` to the `ambiegen` CLI."""
    from .core.search import ALGORITHMS
    from .problems import PROBLEM_NAMES, PROFILES

    p = sub.add_parser(
        "campaign",
        help="start generator + sim workers + recorder over DDS, write DIR/*.mcap and DIR/summary.json",
        description=__doc__,
    )
    p.add_argument("--problem", required=True, choices=PROBLEM_NAMES)
    p.add_argument("--algorithm", default="nsga2", choices=ALGORITHMS)
    budget = p.add_mutually_exclusive_group()
    budget.add_argument("--evaluations", type=int, help="evaluation budget (default: the paper's)")
    budget.add_argument("--time-budget", type=float, metavar="SECONDS")
    p.add_argument("--population", type=int)
    p.add_argument("--offspring", type=int)
    p.add_argument("--seed", type=int, help="random seed (default: drawn and recorded)")
    p.add_argument("--workers", type=int, default=1, help="sim workers sharing the scenarios (default 1)")
    p.add_argument("--mode", default="surrogate", choices=("surrogate", "in_the_loop"),
                   help="surrogate: search with the surrogate, then execute the suite; in_the_loop: every F1 from the sims")
    p.add_argument("--sim-model", default="full", choices=("full", "surrogate"),
                   help="what the sim workers run: full-model simulator + failure oracle (default) or the surrogate")
    p.add_argument("--config", metavar="FILE.yaml", help="run config (search settings + problem_config)")
    p.add_argument("--profile", choices=PROFILES,
                   help="fidelity profile of the generator and every sim worker (default: the config's, else replication)")
    p.add_argument("--domain-id", type=int, help="ROS_DOMAIN_ID for all nodes (default: inherited, else 0)")
    p.add_argument("--discovery-range", type=str.lower, choices=[r.lower() for r in CAMPAIGN_RANGES],
                   help="which nodes this campaign's nodes may discover (ROS_AUTOMATIC_DISCOVERY_RANGE): localhost "
                   "(default, unless that variable is set: a campaign on a laptop never joins the lab's robots), "
                   "subnet (sim workers on other machines; add ROS_STATIC_PEERS where multicast does not reach), "
                   "system_default (the middleware's own settings)")
    p.add_argument("--remote-workers", type=int, default=0, metavar="N",
                   help="sim workers started on other machines (see README 'Running on several machines'): "
                   "the generator waits for them as well; --workers may then be 0")
    p.add_argument("--result-timeout", type=float, default=30.0, help="seconds to wait for each result")
    p.add_argument(
        "--max-in-flight", type=int, help="scenarios in flight per worker (generator default 8; more suits fast, vectorised sims)"
    )
    p.add_argument("--timeout", type=float, default=3600.0, help="stop the campaign after this many seconds")
    p.add_argument("--out", required=True, metavar="DIR", help="run directory (an existing non-empty one is refused)")
    p.add_argument("--overwrite", action="store_true",
                   help="write into a non-empty --out (replaces summary.json, suite.json and logs/; never an MCAP)")
    p.add_argument("--json", action="store_true", help="print the summary as JSON instead of a table")
    p.set_defaults(func=cmd_campaign)

    p = sub.add_parser(
        "replay",
        help="re-publish a log's scenarios, or re-execute them on running sim/SUT nodes and compare results",
        description=(
            "Without --execute: re-publish the scenario messages byte for byte with their recorded QoS. "
            "With --execute: run them again on the sim/SUT nodes on the graph (or on --workers K spawned "
            "sim workers), record the new results (--record) and write a regression report."
        ),
    )
    p.add_argument("log", metavar="LOG.mcap")
    p.add_argument("--execute", action="store_true", help="re-execute and compare instead of re-publishing")
    p.add_argument("--rate", type=float, default=1.0, help="publish: speed factor of the recorded pace (0 = at once)")
    p.add_argument("--workers", type=int, default=0, help="execute: also start K sim workers for the log's problem")
    p.add_argument("--record", metavar="OUT.mcap",
                   help="execute: also start a recorder writing this file (an existing file is refused)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing --record or --report file")
    p.add_argument("--sim-model", default="full", choices=("full", "surrogate"), help="execute: what spawned workers run")
    p.add_argument("--report", metavar="FILE.json", help="execute: regression report (default LOG.replay.json)")
    p.add_argument("--domain-id", type=int, help="ROS_DOMAIN_ID (default: inherited, else 0)")
    p.add_argument("--result-timeout", type=float, default=30.0, help="seconds to wait for each result")
    p.set_defaults(func=cmd_replay)

    p = sub.add_parser("recover", help="rebuild a valid MCAP from one cut short by SIGKILL")
    p.add_argument("mcap", metavar="FILE.mcap")
    p.add_argument("-o", "--output", metavar="OUT.mcap",
                   help="default: FILE.recovered.mcap; an existing file is refused, the input always")
    p.add_argument("--overwrite", action="store_true", help="replace an existing --output (never the input)")
    p.set_defaults(func=cmd_recover)


def cmd_campaign(args) -> int:
    from .cli import BadInput

    if args.workers < 0 or args.remote_workers < 0 or args.workers + args.remote_workers < 1:
        raise BadInput("--workers and --remote-workers: at least one sim worker in all (neither below 0)")
    from .ros.transport.base import TransportError

    try:
        scope = discovery_scope(args.discovery_range, dict(os.environ))
    except TransportError as exc:
        raise BadInput(str(exc))
    if args.remote_workers and scope == "LOCALHOST":
        raise BadInput("--remote-workers: workers on other machines are not discovered with the default "
                       "localhost discovery range; add --discovery-range subnet")
    if args.domain_id is not None and not 0 <= args.domain_id <= 232:
        raise BadInput(f"--domain-id {args.domain_id}: allowed 0..232 (ROS 2 on Linux: 0..101)")
    if args.domain_id is not None and args.domain_id > 101:
        print(f"warning: --domain-id {args.domain_id} > 101 maps to UDP ports in Linux's ephemeral range; "
              "participants may fail to bind", file=sys.stderr)
    spec = CampaignSpec(
        problem=args.problem,
        algorithm=args.algorithm,
        evaluations=args.evaluations,
        time_budget=args.time_budget,
        population=args.population,
        offspring=args.offspring,
        seed=args.seed,
        workers=args.workers,
        mode=args.mode,
        out=Path(args.out),
        config=args.config,
        domain_id=args.domain_id,
        result_timeout=args.result_timeout,
        timeout=args.timeout,
        generator_params={} if args.max_in_flight is None else {"max_in_flight": args.max_in_flight},
        sim_model=args.sim_model,
        profile=args.profile,
        overwrite=args.overwrite,
        remote_workers=args.remote_workers,
        discovery_range=args.discovery_range,
    )
    campaign = Campaign(spec)
    tty = sys.stderr.isatty()

    def progress(c: Campaign, elapsed: float) -> None:
        if tty:
            sys.stderr.write(f"\rcampaign {c.run_id}: running {elapsed:5.0f} s (logs in {c.out / 'logs'})")
            sys.stderr.flush()

    try:
        summary = campaign.run(progress)
    except FileExistsError as exc:
        raise BadInput(str(exc)) from None
    if tty:
        sys.stderr.write("\n")
    print(json.dumps(summary, indent=2) if args.json else summary_table(summary))
    ok = summary.get("exit_codes", {}).get("generator") == 0 and not summary.get("unresolved") and "log_error" not in summary
    return 0 if ok else 1


def cmd_replay(args) -> int:
    from .cli import BadInput
    from .nodes.replay import Replay, recorded_scenarios
    from .ros.transport import create_node

    if not Path(args.log).exists():
        raise BadInput(f"{args.log}: no such file")
    if args.record and Path(args.record).exists() and not args.overwrite:
        raise BadInput(f"--record {args.record} already exists; refusing to overwrite it (another name, or --overwrite)")
    if args.execute and args.report and Path(args.report).exists() and not args.overwrite:
        raise BadInput(f"--report {args.report} already exists; refusing to overwrite it (another name, or --overwrite)")
    if args.domain_id is not None:
        os.environ["ROS_DOMAIN_ID"] = str(args.domain_id)
    group = ProcessGroup(Path(args.report or args.log).parent / "replay_logs", dict(os.environ))
    expected = 1
    if args.execute and (args.workers or args.record):
        problem = recorded_scenarios(args.log)[0]
        if args.record:
            group.start("recorder", "ambiegen_ros.nodes.recorder",
                        _ros_params(output=str(Path(args.record).resolve()), overwrite=args.overwrite))
        for k in range(args.workers):
            name = f"{problem}_sim_{k}"
            group.start(name, SIM_MODULES[problem], ["--ros-args", "-r", f"__node:={name}"] + _ros_params(worker_id=name, model=args.sim_model, min_result_subscribers=1 + bool(args.record))[1:])
        expected = max(args.workers, 1) + bool(args.record)
    params = {"mode": "execute" if args.execute else "publish", "rate": args.rate, "min_subscribers": expected,
              "result_timeout": args.result_timeout, "report": args.report or "", "overwrite": args.overwrite}
    node = create_node("replay", argv=["replay"], parameter_overrides=params)
    try:
        replay = Replay(node=node, log=args.log)
        code = replay.run()
    finally:
        group.stop()
    if replay.report:
        print(json.dumps({k: v for k, v in replay.report.items() if k != "entries"}, indent=2))
    return code


def cmd_recover(args) -> int:
    from mcap.exceptions import McapError

    from .cli import BadInput
    from .ros.mcap_log import recover

    src = Path(args.mcap)
    dst = Path(args.output) if args.output else src.with_suffix(".recovered.mcap")
    if not src.is_file():
        raise BadInput(f"{src}: no such file")
    try:
        stats = recover(src, dst, overwrite=args.overwrite)
    except FileExistsError as exc:
        raise BadInput(f"{exc} (another -o, or --overwrite)") from None
    except (ValueError, McapError, OSError) as exc:
        raise BadInput(str(exc)) from None
    print(json.dumps({"recovered": str(dst), **stats}, indent=2))
    return 0
