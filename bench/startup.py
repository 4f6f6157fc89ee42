"""Start-up of the command line: `ambiegen --help` and `ambiegen evaluate` of a one-line scenario.

Usage: python bench/startup.py [--repeats 7]
Runs the installed console script (``.venv/bin/ambiegen``, else ``python -m ambiegen_ros``) as a
subprocess, as a user does, and prints the median and best wall time of each command, plus the
heavy libraries each one imported (read from ``python -X importtime``). Target (issue 15): both
under 0.4 s. Results: bench/results/startup.json.
"""
from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import write_result  # noqa: E402

import numpy as np  # noqa: E402

from ambiegen_ros.problems import PROBLEM_NAMES, get_problem  # noqa: E402

HEAVY = ("numba", "pymoo", "matplotlib", "scipy", "shapely", "cyclonedds", "mcap", "rclpy")


def command() -> list[str]:
    script = Path(sys.executable).with_name("ambiegen")
    return [str(script)] if script.exists() else [sys.executable, "-m", "ambiegen_ros"]


def heavy_imports(args: list[str]) -> list[str]:
    """Top-level packages among HEAVY that the command imported."""
    run = subprocess.run([sys.executable, "-X", "importtime", "-m", "ambiegen_ros", *args], capture_output=True,
                         text=True)
    seen = {line.split("|")[-1].strip().split(".")[0] for line in run.stderr.splitlines() if "import time:" in line}
    return sorted(seen & set(HEAVY))


def timed(args: list[str], repeats: int) -> list[float]:
    walls = []
    for _ in range(repeats):
        start = time.perf_counter()
        subprocess.run([*command(), *args], capture_output=True, check=True)
        walls.append(time.perf_counter() - start)
    return walls


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args()
    figures = {"command": " ".join(Path(c).name for c in command()), "target_s": 0.4}
    with tempfile.TemporaryDirectory() as tmp:
        cases = {"--help": ["--help"]}
        for name in PROBLEM_NAMES:  # one sampled scenario per problem, as a one-line file
            problem = get_problem(name)
            scenario = problem.codec.from_rows(problem.sample_rows(1, np.random.default_rng(0)))[0]
            path = Path(tmp) / f"{name}.json"
            path.write_text(json.dumps(scenario.to_dict()) + "\n")
            cases[f"evaluate {name}"] = ["evaluate", str(path)]
        timed(["--help"], 1)  # warm the file cache, and numba's cache of compiled kernels
        for label, argv in cases.items():
            walls = timed(argv, args.repeats)
            heavy = heavy_imports(argv)
            figures[label] = {"median_s": round(statistics.median(walls), 3), "best_s": round(min(walls), 3),
                              "repeats": args.repeats, "heavy_imports": heavy}
            print(f"ambiegen {label:<20} median {statistics.median(walls):.3f} s, best {min(walls):.3f} s"
                  f"  heavy imports: {', '.join(heavy) or 'none'}")
    print("->", write_result("startup", figures))


if __name__ == "__main__":
    main()
