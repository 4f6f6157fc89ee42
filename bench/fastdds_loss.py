"""Does the log of a campaign on Fast DDS hold every scenario and result? (issue 19, part 0)

    python bench/fastdds_loss.py --setup ~/jazzy-verify/install/setup.bash --runs 20 [--rev HEAD]

Builds the repository at ``--rev`` (a git revision; default the working tree) with colcon into a
temporary workspace, then runs ``ros2 launch ambiegen_ros campaign.launch.py`` ``--runs`` times on
``rmw_fastrtps_cpp``: a thermostat GA campaign of ``--evaluations`` (2,000) in-the-loop
evaluations with 2 workers. Each finished log is counted: the run's scenarios and the results
of them (by run id and scenario id, so a run on the same domain cannot count). Prints one line per run and writes
``bench/results/fastdds_loss_<rev>.json``.
"""
from __future__ import annotations

import argparse
import os
import shlex
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
for extra in (REPO, REPO / "bench", REPO / "test" / "real_ros"):
    sys.path.insert(0, str(extra))

from _common import write_result  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--setup", default=os.path.expanduser("~/jazzy-verify/install/setup.bash"))
    ap.add_argument("--runs", type=int, default=20)
    ap.add_argument("--evaluations", type=int, default=2000)
    ap.add_argument("--rev", default="", help="git revision to build ('' = the working tree)")
    ap.add_argument("--rmw", default="rmw_fastrtps_cpp")
    ap.add_argument("--domain-id", type=int, default=5, help="outside the test suite's pool (10-101)")
    args = ap.parse_args(argv)
    os.environ["AMBIEGEN_ROS_SETUP"] = args.setup
    import jazzy_env as je
    from ambiegen_ros.nodes.replay import recorded_scenarios

    info = je.probe()
    if "skip" in info:
        raise SystemExit(info["skip"])
    root = Path(tempfile.mkdtemp(prefix="fastdds_loss_"))
    if args.rev:
        src = root / "src" / "ambiegen"
        src.mkdir(parents=True)
        subprocess.run(f"git -C {shlex.quote(str(REPO))} archive {shlex.quote(args.rev)} | tar -x -C {shlex.quote(str(src))}",
                       shell=True, check=True)
        install, run, took = je.colcon_build(src, root)
        if run.returncode != 0:
            raise SystemExit(run.stdout[-3000:] + run.stderr[-3000:])
    else:
        install = je.working_tree_install(root)
    label = args.rev or "worktree"
    rows = []
    for k in range(args.runs):
        out = root / f"run{k}"
        out.mkdir()
        launch = dict(problem="thermostat", algorithm="ga", evaluations=args.evaluations, workers=2, seed=100 + k,
                      mode="in_the_loop", output_dir=str(out))
        cmd = "ros2 launch ambiegen_ros campaign.launch.py " + " ".join(shlex.quote(f"{a}:={v}") for a, v in launch.items())
        t0 = time.monotonic()
        run = subprocess.run(je.ros_command(cmd, install), env=je.ros_env(args.domain_id, args.rmw), cwd=out,
                             capture_output=True, text=True, timeout=1800)
        wall = time.monotonic() - t0
        mcaps = list(out.glob("*.mcap"))
        counts = {"scenarios": 0, "results": 0}
        if mcaps:  # this run's own scenarios and results (another run on the domain must not count)
            rec = recorded_scenarios(mcaps[0])
            counts = {"scenarios": len(rec.scenarios), "results": len(rec.outcomes)}
        lost = (args.evaluations - counts["scenarios"]) + (args.evaluations - counts["results"])
        rows.append({"run": k, "exit": run.returncode, **counts, "lost": lost, "wall_s": round(wall, 1)})
        print(f"run {k}: exit {run.returncode}, {counts['scenarios']} scenarios / {counts['results']} results logged, "
              f"{lost} lost, {wall:.0f} s", flush=True)
    complete = sum(r["lost"] == 0 and r["exit"] == 0 for r in rows)
    path = write_result(f"fastdds_loss_{label}", {"rmw": args.rmw, "evaluations": args.evaluations, "rev": label,
                                                  "runs": len(rows), "complete": complete, "rows": rows})
    print(f"{label}: {complete} of {len(rows)} runs complete -> {path}")
    return 0 if complete == len(rows) else 1


if __name__ == "__main__":
    sys.exit(main())
