"""What a real-time Nav2 run costs, part by part, in cores (issue 58): read from /proc, nothing added.

    python bench/nav2_cpu.py --seconds 600 [--tag TAG]     # while `ambiegen rerun --stack bringup` runs

Every ``--every`` seconds it reads the CPU time (user + system) of each process of the running
stack session: our three nodes (``sut_adapter``, ``robot_world``, the recorder), the runner, and
each Nav2 server (by its ``__node:=`` name). A part's share of a core is its CPU seconds over the
wall seconds it was watched; a process that ends (a session that moves on to its next
configuration) is replaced by its successor and both are counted. Writes
``bench/results/nav2_cpu[_TAG].json`` with ``ours_cores`` (the three nodes together) and
``nav2_cores`` (every Nav2 server together), and each part's share. Sampling /proc costs nothing the
stack would notice, so it can watch a measurement run.
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from collections import defaultdict
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import report  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from ambiegen_ros.trials.supervise import cpu_seconds  # noqa: E402  (one reading of /proc for both)

OURS = {"sim_nodes.sut_adapter": "sut_adapter", "sim_nodes.robot_world": "robot_world",
        "ambiegen_ros.nodes.recorder": "recorder", "ambiegen_ros rerun": "runner", "ambiegen_ros compare": "runner",
        "ambiegen rerun": "runner", "ambiegen compare": "runner",
        "ambiegen_ros.cli rerun": "runner", "ambiegen_ros.cli compare": "runner"}  # python -m, or the installed command
NAV2_LIB = "/lib/nav2_"


def processes(domain: int | None = None) -> dict[int, str]:
    """pid -> part name, for the session's processes (only those with ``ROS_DOMAIN_ID=domain`` if given:
    one stack of several on the machine)."""
    out = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            args = (entry / "cmdline").read_bytes().split(b"\0")
            # the stack's processes have the domain in their environment; the runner may have it as its
            # --domain-id argument only (it sets it for what it starts)
            if domain is not None and f"ROS_DOMAIN_ID={domain}".encode() not in (entry / "environ").read_bytes().split(b"\0") \
                    and f"--domain-id\0{domain}\0".encode() not in b"\0".join(args) + b"\0":
                continue
        except OSError:
            continue
        line = " ".join(a.decode(errors="replace") for a in args)
        for key, name in OURS.items():
            if key in line:
                out[int(entry.name)] = name
                break
        else:
            if NAV2_LIB in line or "/lib/opennav_" in line:
                node = next((a[8:].decode() for a in args if a.startswith(b"__node:=")), Path(args[0].decode()).name)
                out[int(entry.name)] = f"nav2/{node}"
    return out



def core_shares(first: dict[int, float], last: dict[int, float], names: dict[int, str], wall: float) -> dict[str, float]:
    """Each part's CPU seconds (its processes, successors included) over the wall seconds watched."""
    parts: dict[str, float] = defaultdict(float)
    for pid, name in names.items():
        parts[name] += last[pid] - first[pid]
    return {name: round(cpu / wall, 3) for name, cpu in sorted(parts.items())}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seconds", type=float, default=600.0)
    ap.add_argument("--every", type=float, default=5.0)
    ap.add_argument("--tag", default="")
    ap.add_argument("--domain-id", type=int, default=None,
                    help="watch only the stack run with this ROS_DOMAIN_ID (one of several on the machine)")
    args = ap.parse_args(argv)
    first: dict[int, float] = {}
    last: dict[int, float] = {}
    names: dict[int, str] = {}
    t0 = time.monotonic()
    while time.monotonic() - t0 < args.seconds:
        for pid, name in processes(args.domain_id).items():
            used = cpu_seconds(pid)
            if used is None:
                continue
            first.setdefault(pid, used)
            last[pid] = used
            names[pid] = name
        time.sleep(args.every)
    wall = time.monotonic() - t0
    shares = core_shares(first, last, names, wall)
    ours = sum(v for k, v in shares.items() if k in ("sut_adapter", "robot_world", "recorder"))
    nav2 = sum(v for k, v in shares.items() if k.startswith("nav2/"))
    figures = {"wall_s": round(wall, 1), "ours_cores": round(ours, 3), "nav2_cores": round(nav2, 3),
               "runner_cores": shares.get("runner", 0.0), "shares": shares, "cpus": os.cpu_count()}
    report("nav2_cpu", args.tag, figures)
    return 0


if __name__ == "__main__":
    sys.exit(main())
