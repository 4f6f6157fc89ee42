"""Planning time of the robot's clearance route (``sims.reference.robot``) on 50 m maps.

Usage: python bench/robot_route.py [--maps 20] [--seed 0] [--profile replication] [--save]
Plans the route between the problem's start and goal on sampled maps (500 x 500 fine cells at the
default 0.1 m) and on an empty room, after one warm-up call (scipy's imports), and prints the
median and worst time per map and how many maps have a route. Target (issue 16): well under 1 s.
``--save`` writes bench/results/robot_route.json.
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import write_result  # noqa: E402

import numpy as np  # noqa: E402

from ambiegen_ros.problems import get_problem  # noqa: E402
from ambiegen_ros.problems.robot import build_grids  # noqa: E402
from ambiegen_ros.sims.reference.robot import route_for  # noqa: E402
from ambiegen_ros.sims.robot import RobotSimConfig  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--maps", type=int, default=20)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--profile", default="replication")
    ap.add_argument("--save", action="store_true")
    args = ap.parse_args()
    problem = get_problem("robot", {"profile": args.profile})
    pc, cfg = problem.config, RobotSimConfig()
    G, lengths = problem.sample(args.maps, np.random.default_rng(args.seed))
    grids = list(build_grids(G, lengths, pc))
    empty = np.zeros_like(grids[0])
    empty[0, :] = empty[-1, :] = empty[:, 0] = empty[:, -1] = True
    route_for(empty, pc.resolution, pc.start, pc.goal, cfg)  # warm-up
    times, found = [], 0
    for grid in [empty] + grids:
        t0 = time.perf_counter()
        route = route_for(grid, pc.resolution, pc.start, pc.goal, cfg)
        times.append(time.perf_counter() - t0)
        found += route.found
    figures = {"maps": len(times), "fine_cells": int((pc.map_size * pc.resolution / route.fine) ** 2),
               "median_s": statistics.median(times), "max_s": max(times), "empty_room_s": times[0],
               "with_route": found, "profile": args.profile, "seed": args.seed}
    print(f"{figures['maps']} maps ({figures['fine_cells']} fine cells each): median {figures['median_s']:.3f} s, "
          f"worst {figures['max_s']:.3f} s, empty room {figures['empty_room_s']:.3f} s; {found} with a route")
    if args.save:
        print(write_result("robot_route", figures))


if __name__ == "__main__":
    main()
