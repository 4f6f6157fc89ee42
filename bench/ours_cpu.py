"""What our side of a Nav2 run costs without Nav2 (issue 58): our three nodes at Nav2's rates.

    python bench/ours_cpu.py [--count 6] [--transport dds|rclpy] [--tag TAG]

Runs the first ``--count`` scenarios of a hazards suite through ``ambiegen rerun``'s machinery with
the node set of a real-time Nav2 run -- ``robot_world`` free-running at time scale 1 (0.02 s steps:
odometry and TF at 50 Hz, scans, markers and collision reports at 10 Hz, ``/clock`` at 100 Hz),
``sut_adapter`` turning every 20 ms, the recorder on Nav2's topics -- with our ``nd_driver`` in
Nav2's place (a STAND-IN: one command per scan, 10 Hz, where Nav2's controller sends 20). The
CPU time of each process comes from /proc every 2 s; a part's share is its CPU seconds over the
wall seconds the runs took. Writes ``bench/results/ours_cpu[_TAG].json`` with ``ours_cores``
(adapter + world + recorder). ``--transport`` sets ``AMBIEGEN_TRANSPORT`` for the nodes (default:
auto, rclpy where a sourced ROS 2 has it). ``--crowd N`` adds N idle DDS endpoints (half publishers,
half subscribers, from this process) standing in for the size of Nav2's graph: its 25-odd nodes
each offer parameter and lifecycle services, so a graph query meets hundreds of endpoints. The
real-time Nav2 figure is ``bench/nav2_cpu.py``'s.
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import threading
import time
from collections import defaultdict
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))
from _common import report  # noqa: E402
from nav2_cpu import core_shares, cpu_seconds, processes  # noqa: E402

OURS = ("sut_adapter", "robot_world", "recorder")


def nav2_rate_stack(seed: int, tag: str, profile: str | None, config_file: str | None) -> list:
    """``launch_logic.nd_stack``'s nodes at a real-time Nav2 run's rates (see the module docstring)."""
    from ambiegen_ros.launch_logic import NodeSpec

    return [
        NodeSpec("robot_world", "robot_world", {"time_scale": 1.0, "seed": seed, "paired_start": True}),
        NodeSpec("nd_driver", "nd_driver", {"paired_start": True}),
        NodeSpec("sut_adapter", "sut_adapter", {
            "problem": "robot", "worker_id": f"sut_{tag}", "profile": profile, "config_file": config_file,
            "stall_topic": "/nd_driver/stall", "plan_topic": "/plan", "collision_topic": "/collision",
            "min_result_subscribers": 2, "settle_time": 1.0, "tick_period": 0.02, "time_scale": 1.0}),
    ]


def ours(pid: int) -> bool:
    """Is ``pid`` below this process (a node of this bench, not of another session on the machine)?"""
    me = os.getpid()
    while pid > 1:
        try:
            pid = int(Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[1])
        except (OSError, IndexError, ValueError):
            return False
        if pid == me:
            return True
    return False


class Sampler(threading.Thread):
    """CPU seconds of each of this bench's processes, read from /proc every ``every`` seconds."""

    def __init__(self, every: float = 2.0):
        super().__init__(daemon=True)
        self.every, self.stop = every, threading.Event()
        self.first: dict[int, float] = {}
        self.last: dict[int, float] = {}
        self.names: dict[int, str] = {}

    def run(self) -> None:
        while not self.stop.is_set():
            for pid, name in processes().items():
                used = cpu_seconds(pid) if pid in self.names or ours(pid) else None
                if used is not None:
                    self.first.setdefault(pid, used)
                    self.last[pid], self.names[pid] = used, name
            self.stop.wait(self.every)

    def shares(self, wall: float) -> dict[str, float]:
        return core_shares(self.first, self.last, self.names, wall)


def crowd(endpoints: int):
    """A DDS node holding ``endpoints`` idle endpoints, like the services of Nav2's nodes (None: 0)."""
    if endpoints <= 0:
        return None
    from ambiegen_ros.ros.qos import DEFAULT
    from ambiegen_ros.ros.transport.dds_backend import DdsNode

    node = DdsNode("crowd")
    for i in range(endpoints // 2):
        node.create_publisher("std_msgs/msg/String", f"/crowd/reply_{i}", DEFAULT)
        node.create_subscription("std_msgs/msg/String", f"/crowd/request_{i}", lambda msg: None, DEFAULT)
    return node


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--suite", default=str(HERE.parent / "docs/results/nav2/mppi_hazards_passes_suite.json"))
    ap.add_argument("--count", type=int, default=6, help="scenarios of the suite run (default 6)")
    ap.add_argument("--transport", choices=("rclpy", "dds"), default=None)
    ap.add_argument("--crowd", type=int, default=0, metavar="N",
                    help="N idle DDS endpoints standing in for Nav2's graph (default 0; Nav2's is 600-odd)")
    ap.add_argument("--tag", default="")
    args = ap.parse_args(argv)
    if args.transport:
        os.environ["AMBIEGEN_TRANSPORT"] = args.transport
    import ambiegen_ros.launch_logic as launch_logic
    from ambiegen_ros.ros.transport import select_backend
    from ambiegen_ros.trials.configs import StackConfig, prepare
    from ambiegen_ros.trials.rows import TrialLog
    from ambiegen_ros.trials.runner import TrialSettings, run_trials
    from ambiegen_ros.trials.suite import Suite, load_suite

    launch_logic.nd_stack = nav2_rate_stack  # the session builds its node set from this name
    backend = select_backend()
    full = load_suite([args.suite], None, None)
    suite = Suite(full.problem, full.problem_config, full.entries[:args.count], full.sources)
    with tempfile.TemporaryDirectory(prefix="ours_cpu_") as tmp:
        settings = TrialSettings(stack="nd", results=Path(tmp) / "rows.jsonl", bags=Path(tmp) / "bags", repeat=1)
        settings.bags.mkdir()
        prepared = [prepare(StackConfig("nd", ()), "nd", None, 1.0, settings.bags)]
        crowded = crowd(args.crowd)
        sampler = Sampler()
        sampler.start()
        t0 = time.monotonic()
        run_trials(suite, prepared, settings)
        wall = time.monotonic() - t0
        sampler.stop.set()
        sampler.join()
        rows = TrialLog(settings.results).rows()
        if crowded is not None:
            crowded.shutdown()
    shares = sampler.shares(wall)
    ours = sum(shares.get(name, 0.0) for name in OURS)
    verdicts: dict[str, int] = defaultdict(int)
    for row in rows:
        verdicts[row.get("failure_kind") or "pass"] += 1
    figures = {"transport": backend, "scenarios": len(suite.entries), "wall_s": round(wall, 1),
               "ours_cores": round(ours, 3), "shares": shares, "verdicts": dict(verdicts),
               "stand_in": "nd_driver in Nav2's place (10 Hz commands)", "crowd_endpoints": args.crowd,
               "cpus": os.cpu_count()}
    report("ours_cpu", args.tag, figures)
    return 0


if __name__ == "__main__":
    sys.exit(main())
