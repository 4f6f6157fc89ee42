"""`ambiegen campaign`, `ambiegen replay` and `ambiegen recover`: the ROS side of the command line.

The work is the library's (``ambiegen_ros.campaign``, ``nodes.replay``, ``ros.mcap_log``); this
module turns flags into its calls and its errors into one-line ``BadInput``.
"""
from __future__ import annotations

import json
import os
import sys
from pathlib import Path

from .common import BadInput, add_config_option


def register(sub) -> None:
    """Adds `campaign`, `replay` and `recover` to the `ambiegen` CLI."""
    from .. import campaign as library
    from ..core.names import ALGORITHMS
    from ..problems import PROBLEM_NAMES, PROFILES

    p = sub.add_parser(
        "campaign",
        help="start generator + sim workers + recorder over DDS, write DIR/*.mcap and DIR/summary.json",
        description=library.__doc__,
    )
    p.add_argument("--problem", required=True, choices=PROBLEM_NAMES)
    p.add_argument("--algorithm", default="nsga2", choices=ALGORITHMS)
    budget = p.add_mutually_exclusive_group()
    budget.add_argument("--evaluations", type=int, help="evaluation budget (default: the paper's)")
    budget.add_argument("--time-budget", type=float, metavar="SECONDS")
    p.add_argument("--execution-budget", type=float, metavar="SECONDS",
                   help="stop sending scenarios this many seconds after the first; the ones sent finish and are "
                        "logged (a real-time stack gets a fixed time; either mode)")
    p.add_argument("--population", type=int)
    p.add_argument("--offspring", type=int)
    p.add_argument("--seed", type=int, help="random seed (default: drawn and recorded)")
    p.add_argument("--workers", type=int, default=1, help="sim workers sharing the scenarios (default 1)")
    p.add_argument("--stack", choices=library.STACKS,
                   help="robot: run a ROS navigation stack as the system under test instead of sim workers: "
                        "'nd' = robot_world + nd_driver (our Nearness Diagram robot on Nav2's topics) behind "
                        "sut_adapter; the log also holds /scan, /odom, /tf, /cmd_vel, /plan")
    p.add_argument("--mode", default="surrogate", choices=("surrogate", "in_the_loop"),
                   help="surrogate: search with the surrogate, then execute the suite; in_the_loop: every F1 from the sims")
    p.add_argument("--sim-model", default="full", choices=("full", "surrogate"),
                   help="what the sim workers run: full-model simulator + failure oracle (default) or the surrogate")
    add_config_option(p)
    p.add_argument("--profile", choices=PROFILES,
                   help="fidelity profile of the generator and every sim worker (default: the config's, else replication)")
    p.add_argument("--domain-id", type=int, help="ROS_DOMAIN_ID for all nodes (default: inherited, else 0)")
    p.add_argument("--discovery-range", type=str.lower, choices=[r.lower() for r in library.CAMPAIGN_RANGES],
                   help="which nodes this campaign's nodes may discover (ROS_AUTOMATIC_DISCOVERY_RANGE): localhost "
                   "(default, unless that variable is set: a campaign on a laptop never joins the lab's robots), "
                   "subnet (sim workers on other machines; add ROS_STATIC_PEERS where multicast does not reach), "
                   "system_default (the middleware's own settings)")
    p.add_argument("--remote-workers", type=int, default=0, metavar="N",
                   help="sim workers started on other machines (see docs/multihost_security.md#running-on-several-machines): "
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
    from ..campaign import Campaign, CampaignSpec, discovery_scope
    from ..launch_logic import summary_table

    if args.workers < 0 or args.remote_workers < 0 or args.workers + args.remote_workers < 1:
        raise BadInput("--workers and --remote-workers: at least one sim worker in all (neither below 0)")
    from ..ros.transport.base import TransportError

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
    if args.stack and (args.problem != "robot" or args.workers != 1 or args.remote_workers):
        raise BadInput(f"--stack {args.stack}: runs robot scenarios on one world and one stack "
                       "(--problem robot, --workers 1, no --remote-workers)")
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
        generator_params={key: value for key, value in (("max_in_flight", args.max_in_flight),
                                                        ("execution_budget", args.execution_budget)) if value is not None},
        sim_model=args.sim_model,
        profile=args.profile,
        overwrite=args.overwrite,
        remote_workers=args.remote_workers,
        discovery_range=args.discovery_range,
        stack=args.stack,
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
    from ..campaign import SIM_MODULES, ProcessGroup, ros_params
    from ..nodes import unusable_messages
    from ..nodes.replay import Replay, recorded_scenarios
    from ..ros.transport import TransportError, create_node

    if not Path(args.log).exists():
        raise BadInput(f"{args.log}: no such file")
    if args.record and Path(args.record).exists() and not args.overwrite:
        raise BadInput(f"--record {args.record} already exists; refusing to overwrite it (another name, or --overwrite)")
    if args.execute and args.report and Path(args.report).exists() and not args.overwrite:
        raise BadInput(f"--report {args.report} already exists; refusing to overwrite it (another name, or --overwrite)")
    missing = unusable_messages()  # the replay node's own check, before any process starts
    if missing:
        raise BadInput(missing)
    if args.domain_id is not None:
        os.environ["ROS_DOMAIN_ID"] = str(args.domain_id)
    group = ProcessGroup(Path(args.report or args.log).parent / "replay_logs", dict(os.environ))
    expected = 1
    if args.execute and (args.workers or args.record):
        problem = recorded_scenarios(args.log)[0]
        if args.record:
            group.start("recorder", "ambiegen_ros.nodes.recorder",
                        ros_params(output=str(Path(args.record).resolve()), overwrite=args.overwrite))
        for k in range(args.workers):
            name = f"{problem}_sim_{k}"
            group.start(name, SIM_MODULES[problem], ["--ros-args", "-r", f"__node:={name}"] + ros_params(
                worker_id=name, model=args.sim_model, min_result_subscribers=1 + bool(args.record))[1:])
        expected = max(args.workers, 1) + bool(args.record)
    params = {"mode": "execute" if args.execute else "publish", "rate": args.rate, "min_subscribers": expected,
              "result_timeout": args.result_timeout, "report": args.report or "", "overwrite": args.overwrite}
    try:  # the node inside: a backend that cannot start (e.g. rclpy without ambiegen_msgs) stops the group too
        try:
            node = create_node("replay", argv=["replay"], parameter_overrides=params)
        except TransportError as exc:
            raise BadInput(str(exc)) from None
        replay = Replay(node=node, log=args.log)
        code = replay.run()
    finally:
        group.stop()
    if replay.report:
        print(json.dumps({k: v for k, v in replay.report.items() if k != "entries"}, indent=2))
    return code


def cmd_recover(args) -> int:
    from mcap.exceptions import McapError

    from ..ros.mcap_log import recover

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
