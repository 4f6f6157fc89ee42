"""`ambiegen execute SCENARIO.json [--json] [--seed S] [--config FILE.yaml] [--profile P] [--set OPTION=VALUE ...]`.

Runs one scenario on its full-model simulator (no ROS) and prints the verdict; with ``--json``
exactly one object ``{"problem", "valid", "failed", "failure_kind", "verdict", "reference",
"metrics", "profile"}`` (failure_kind null when the run passed; verdict PASS, FAIL(kind) or
INVALID_TEST(reason): a failure counts only when the problem's reference passes the scenario). ``--config``: the
problem_config of a run config (e.g. ``config/robot_small.yaml``'s nearer goal), as the run that made the scenario
used. Bad input (unreadable or malformed scenario or config, unknown or out-of-domain option) is one line and
exit status 2.
"""
from __future__ import annotations

import argparse
import json

from .common import add_config_option, add_profile_option, load_scenario


def cmd_execute(args: argparse.Namespace) -> int:
    from ..sims.full_model import full_model_executor
    from ..sims.options import parse_options, result_json

    problem, scenario = load_scenario(args, args.scenario)
    executor = full_model_executor(problem, **parse_options(args.set))
    outcome = executor.execute(scenario, seed=args.seed)
    out = result_json(problem.name, outcome)
    out["profile"] = problem.profile
    if args.json:
        print(json.dumps(out))
        return 0
    if outcome.failure_kind == "invalid_test":
        verdict = "INVALID_TEST (not a failure: no reference passes it either)"
    else:
        verdict = "FAILED" if out["failed"] else ("not run (invalid)" if not out["valid"] else "passed")
        verdict += f" [{out['failure_kind']}]" if out["failure_kind"] else ""
    print(f"{problem.name} [{problem.profile}]: {verdict}: {outcome.detail}")
    for key, value in out["metrics"].items():
        if key not in ("detail",):
            print(f"  {key}: {value:.4g}" if isinstance(value, float) else f"  {key}: {value}")
    print(f"  wall time: {outcome.elapsed_sec:.3f} s")
    return 0


def register(sub) -> None:
    p = sub.add_parser("execute", help="run one scenario on its full-model simulator (no ROS) and judge it")
    p.add_argument("scenario", metavar="SCENARIO.json")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--seed", type=int, default=0, help="simulator seed (sensor noise); default 0")
    p.add_argument("--set", action="append", default=[], metavar="OPTION=VALUE",
                   help="simulator option, e.g. oob_tolerance=0.95, controller=pid, or reference=false "
                        "(no reference check: the old verdicts) (repeatable)")
    add_config_option(p)
    add_profile_option(p)
    p.set_defaults(func=cmd_execute)
