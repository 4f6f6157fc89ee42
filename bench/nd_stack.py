"""The ND stack over ROS against the in-process full model: same verdicts? how much slower?

Draws robot maps of a profile (seeded), keeps those the problem calls valid and whose reference
(a clearance route) passes, and runs each twice: in process (``full_model_executor``, laser seed
0) and through ``robot_world`` (lockstep, dt 0.1 s) + ``nd_driver`` + ``sut_adapter`` as separate
processes over DDS. ``--safety-dist`` > 0 gives the ND robot failures to compare (0 = the paper's).

    python bench/nd_stack.py --maps 20 --profile refined --safety-dist 0.3

Prints one line per map and writes ``bench/results/nd_stack_<profile>.json``: verdicts equal,
time differences, the largest trajectory gap, and wall seconds per map both ways.

Where the two differ, the wire is why: a LaserScan carries float32 ranges and float32 end
angles, and the heading crosses as a quaternion. ND amplifies differences of 1e-7 m on marginal
maps. So each map also runs in process with exactly those roundings (``wire_emulation``): the
ROS run must match that one to the step (``gap_to_wire_m``).
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
for extra in (REPO, REPO / "test", REPO / "bench"):
    sys.path.insert(0, str(extra))

import numpy as np  # noqa: E402

from _common import write_result  # noqa: E402
from helpers.wire import wire_emulation  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--maps", type=int, default=20)
    ap.add_argument("--profile", default="refined", choices=("replication", "refined"))
    ap.add_argument("--safety-dist", type=float, default=0.0, help="the ND robot's safety distance [m]")
    ap.add_argument("--seed", type=int, default=11, help="seed of the map draw")
    ap.add_argument("--busy", type=int, default=0, help="processes spinning beside the ROS runs (a loaded machine)")
    ap.add_argument("--domain-id", type=int, default=int(os.environ.get("ROS_DOMAIN_ID", "77")))
    args = ap.parse_args(argv)
    os.environ["ROS_DOMAIN_ID"] = str(args.domain_id)
    os.environ.pop("AMBIEGEN_TRANSPORT", None)

    from helpers.nd_maps import busy_loops, certified_maps
    from helpers.sut_graph import Driver, Procs
    from ambiegen_ros.problems import get_problem
    from ambiegen_ros.ros.transport import create_node
    from ambiegen_ros.sims.full_model import full_model_executor

    p = get_problem("robot", {"profile": args.profile})
    full = full_model_executor(p, safety_dist=args.safety_dist)
    maps, refs, inproc_s = certified_maps(p, full, args.maps, args.seed), [], []
    for sc in maps:
        t0 = time.perf_counter()
        refs.append(full.execute(sc, seed=0))
        inproc_s.append(time.perf_counter() - t0)
    procs = Procs(args.domain_id, Path(tempfile.mkdtemp(prefix="nd_stack_")))
    procs.start("world", "sim_nodes.robot_world", lockstep=True, time_scale=0.0, scan_rate=10.0, cmd_vel_stamped=True,
                paired_start=True, **{"sim.dt": 0.1})
    procs.start("nd", "sim_nodes.nd_driver", cmd_vel_stamped=True, paired_start=True, **{"sim.safety_dist": args.safety_dist})
    procs.start("adapter", "sim_nodes.sut_adapter", problem="robot", worker_id="sut", profile=args.profile,
                stall_topic="/nd_driver/stall", settle_time=0.1)
    node = create_node("nd_stack_bench", argv=[])
    rows, ros_trajectories = [], {}
    try:
        with busy_loops(args.busy):  # --busy N: a loaded machine, on purpose
            driver = Driver(node, p)
            driver.wait_matched()
            for i, (sc, ref, t_in) in enumerate(zip(maps, refs, inproc_s)):
                t0 = time.perf_counter()
                driver.send(f"m{i}", [sc])
                (res,) = driver.wait(f"m{i}", 1, 900)
                wall = time.perf_counter() - t0
                if res is None:
                    print(f"map {i}: no answer\n{procs.logs()}")
                    return 1
                n = min(len(res.trajectory), len(ref.trajectory)) if res.trajectory is not None else 0
                gap = float(np.abs(np.asarray(res.trajectory[:n]) - ref.trajectory[:n]).max()) if n else None
                row = {"map": i, "in_process": ref.failure_kind, "ros": res.failure_kind,
                       "same": res.failure_kind == ref.failure_kind, "time_in_process": ref.metrics.get("time"),
                       "time_ros": float(res.metrics["time"]) if "time" in res.metrics else None, "max_gap_m": gap,
                       "wall_s_ros": round(wall, 2), "wall_s_in_process": round(t_in, 2)}
                rows.append(row)
                ros_trajectories[i] = res.trajectory
                print(f"map {i}: in process {ref.failure_kind:8s} ros {res.failure_kind:8s} time {row['time_in_process']:.1f}"
                      f" / {row['time_ros']:.1f} s, gap {gap:.3f} m, wall {t_in:.1f} / {wall:.1f} s", flush=True)
    finally:
        node.shutdown()
        procs.stop_all()
    for row, sc in zip(rows, maps):  # the in-process run with the wire's number formats
        with wire_emulation():
            wire = full.execute(sc, seed=0)
        row["wire_emulation"] = wire.failure_kind
        row["ros_equals_wire"] = row["ros"] == wire.failure_kind
        res_traj = ros_trajectories[row["map"]]
        n = min(len(res_traj), len(wire.trajectory)) if res_traj is not None else 0
        row["gap_to_wire_m"] = float(np.abs(np.asarray(res_traj[:n]) - wire.trajectory[:n]).max()) if n else None
    same = sum(r["same"] for r in rows)
    dt = [abs(r["time_ros"] - r["time_in_process"]) for r in rows if r["time_ros"] is not None]
    figures = {
        "profile": args.profile, "safety_dist": args.safety_dist, "maps": len(rows), "seed": args.seed,
        "busy_loops": args.busy,
        "verdicts_equal": same, "kinds_in_process": sorted({r["in_process"] for r in rows}),
        "failures_in_process": sum(r["in_process"] != "none" for r in rows),
        "max_time_difference_s": max(dt) if dt else None,
        "max_trajectory_gap_m": max(r["max_gap_m"] or 0.0 for r in rows),
        "ros_equals_wire_emulation": sum(r["ros_equals_wire"] for r in rows),
        "max_gap_to_wire_emulation_m": max(r["gap_to_wire_m"] or 0.0 for r in rows),
        "median_wall_s_ros": float(np.median([r["wall_s_ros"] for r in rows])),
        "median_wall_s_in_process": float(np.median([r["wall_s_in_process"] for r in rows])),
        "rows": rows,
    }
    path = write_result(f"nd_stack_{args.profile}" + (f"_busy{args.busy}" if args.busy else ""), figures)
    print(f"over ROS = in process with the wire's roundings: {figures['ros_equals_wire_emulation']}/{len(rows)} "
          f"verdicts, largest gap {figures['max_gap_to_wire_emulation_m']:.2e} m")
    print(f"{same}/{len(rows)} verdicts equal; max time difference {figures['max_time_difference_s']} s; largest "
          f"trajectory gap {figures['max_trajectory_gap_m']:.3f} m; median wall {figures['median_wall_s_in_process']:.1f} s "
          f"in process, {figures['median_wall_s_ros']:.1f} s over ROS -> {path}")
    return 0 if same == len(rows) else 1


if __name__ == "__main__":
    sys.exit(main())
