"""`ambiegen evaluate SUITE.jsonl --json` on large suites: wall time of the whole command.

Usage: python bench/evaluate_suite.py [--lines 10000] [--problems thermostat robot vehicle] [--profile P]
Writes 10,000 sampled scenarios per problem to a temporary JSON Lines file, runs the real CLI
as a subprocess (parse + validation + one batched evaluation + JSON out) and prints the time.
Target (issue 7): a 10,000-line file takes seconds, not minutes. Results: bench/results/evaluate_suite.json.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import write_result  # noqa: E402

from ambiegen_ros.problems import PROBLEM_NAMES, PROFILES, get_problem  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--lines", type=int, default=10_000)
    parser.add_argument("--problems", nargs="+", default=list(PROBLEM_NAMES), choices=PROBLEM_NAMES)
    parser.add_argument("--profile", default="replication", choices=PROFILES)
    args = parser.parse_args()
    figures = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.problems:
            problem = get_problem(name, {"profile": args.profile})
            rows = problem.sample_rows(args.lines, np.random.default_rng(1))
            path = Path(tmp) / f"{name}.jsonl"
            path.write_text("".join(json.dumps(s.to_dict()) + "\n" for s in problem.codec.from_rows(rows)))
            start = time.perf_counter()
            out = subprocess.run(
                [sys.executable, "-m", "ambiegen_ros", "evaluate", str(path), "--json", "--profile", args.profile],
                capture_output=True, text=True, check=True,
            )
            wall = time.perf_counter() - start
            answered = len(out.stdout.splitlines())
            assert answered == args.lines, (answered, out.stderr[-500:])
            figures[name] = {"lines": args.lines, "profile": args.profile, "wall_s": round(wall, 2),
                             "lines_per_s": round(args.lines / wall)}
            print(f"{name:<11} {args.lines} lines [{args.profile}]: {wall:6.2f} s ({args.lines / wall:,.0f} lines/s)")
    print("->", write_result("evaluate_suite", figures))


if __name__ == "__main__":
    main()
