"""Start-up of the command line: `ambiegen --help` and `ambiegen evaluate` of a one-line scenario,
each against `python -c "import numpy"` timed in the same run.

Usage: python bench/startup.py [--repeats 21]
Runs the installed console script (``.venv/bin/ambiegen``, else ``python -m ambiegen_ros``) as a
subprocess, as a user does, and prints the median and best wall time of each command, its ratio to
`import numpy` (median over median) and the heavy libraries it imported (read from ``python -X
importtime``). The commands are interleaved, one round of all of them per repeat, so a busy
machine slows every command alike; each round runs them with bytecode cached (as installed) and
without (PYTHONDONTWRITEBYTECODE=1, as this machine's shells: our modules compiled at every start).
Targets: issue 15, under 0.4 s; issue 47, `evaluate` of one line at most 2x `import numpy` (with
and without the problem's run config: `--config` once pulled in the whole search). Results:
bench/results/startup.json.
"""
from __future__ import annotations

import argparse
import json
import os
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


def run_once(argv: list[str], env: dict[str, str]) -> float:
    start = time.perf_counter()
    subprocess.run(argv, capture_output=True, check=True, env=env)
    return time.perf_counter() - start


def environments(tmp: str) -> dict[str, dict[str, str]]:
    """How each round runs the commands. "cached": as an installed package, every module's bytecode
    written once and read after (kept in a temporary PYTHONPYCACHEPREFIX, so the source tree stays
    clean; the baseline's numpy too). "not cached": PYTHONDONTWRITEBYTECODE=1, as this machine's
    shells set it: our modules (the repo has no __pycache__) are compiled at every start, numpy's
    are read from site-packages."""
    cached = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    cached["PYTHONPYCACHEPREFIX"] = str(Path(tmp) / "pycache")
    source = {k: v for k, v in os.environ.items() if k != "PYTHONPYCACHEPREFIX"}
    source["PYTHONDONTWRITEBYTECODE"] = "1"
    return {"cached": cached, "not cached": source}


def summary(walls: list[float], numpy_s: float | None, repeats: int) -> dict:
    median = statistics.median(walls)
    entry = {"median_s": round(median, 3), "best_s": round(min(walls), 3), "repeats": repeats}
    if numpy_s is not None:
        entry["ratio_to_import_numpy"] = round(median / numpy_s, 2)
    return entry


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=21)
    args = parser.parse_args()
    figures: dict = {"command": " ".join(Path(c).name for c in command()), "target_s": 0.4, "target_ratio": 2.0,
                     "baseline": "python -c 'import numpy'", "bytecode": "cached (the figures below); "
                     "'without_bytecode_cache': PYTHONDONTWRITEBYTECODE=1, our modules compiled at every start",
                     "load_average_before": [round(x, 2) for x in os.getloadavg()]}
    configs = Path(__file__).resolve().parents[1] / "config"
    with tempfile.TemporaryDirectory() as tmp:
        cases = {"import numpy": [sys.executable, "-c", "import numpy"], "--help": [*command(), "--help"]}
        for name in PROBLEM_NAMES:  # one sampled scenario per problem, as a one-line file
            problem = get_problem(name)
            scenario = problem.codec.from_rows(problem.sample_rows(1, np.random.default_rng(0)))[0]
            path = Path(tmp) / f"{name}.json"
            path.write_text(json.dumps(scenario.to_dict()) + "\n")
            cases[f"evaluate {name}"] = [*command(), "evaluate", str(path)]
            if (configs / f"{name}.yaml").exists():
                cases[f"evaluate {name} --config"] = [*command(), "evaluate", str(path), "--config",
                                                      str(configs / f"{name}.yaml")]
        envs = environments(tmp)
        for env in envs.values():  # warm the file cache, the bytecode cache and numba's cache of compiled kernels
            for argv in cases.values():
                run_once(argv, env)
        walls = {(mode, label): [] for mode in envs for label in cases}
        for _ in range(args.repeats):  # interleaved: one round of every command, both ways, per repeat
            for mode, env in envs.items():
                for label, argv in cases.items():
                    walls[mode, label].append(run_once(argv, env))
        for mode in envs:
            numpy_s = statistics.median(walls[mode, "import numpy"])
            block = figures if mode == "cached" else figures.setdefault("without_bytecode_cache", {})
            print(f"bytecode {mode}:")
            for label, argv in cases.items():
                entry = summary(walls[mode, label], None if label == "import numpy" else numpy_s, args.repeats)
                if mode == "cached" and label != "import numpy":
                    entry["heavy_imports"] = heavy_imports(argv[len(command()):])
                block[label] = entry
                ratio = f"  {entry['ratio_to_import_numpy']:.2f}x import numpy" if label != "import numpy" else ""
                heavy = f"  heavy imports: {', '.join(entry['heavy_imports']) or 'none'}" \
                    if "heavy_imports" in entry else ""
                print(f"  {label:<28} median {entry['median_s']:.3f} s, best {entry['best_s']:.3f} s{ratio}{heavy}")
    figures["load_average_after"] = [round(x, 2) for x in os.getloadavg()]
    print("->", write_result("startup", figures))


if __name__ == "__main__":
    main()
