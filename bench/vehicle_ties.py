"""How often the replication profile's road disagrees with the replication code's own arithmetic (issue 18).

Usage: python bench/vehicle_ties.py --authors DIR [--sampled 100000] [--candidates 100000] [--seed 2024]

DIR is a checkout of the replication code's vehicle folder (github.com/dgumenyuk/Environment_generation,
RQ1_RQ2/Vehicle_case_study/Random: car_road.py, vehicle.py); it is imported from there, never copied.
Compared per road, against its ``Map`` builder + ``remove_invalid_cases`` + shapely length:
the road points (bit for bit), the length of their polyline (bit for bit) and the node count
``len(arange(0, 1 + 8 / L, 8 / L))``; on the tie-prone set also F1 (its ``Car``, |difference| > 1e-6).

Two sets: roads from our replication sampler, and tie-prone roads (angles multiples of 15, lengths
from a short list) whose road length lies within 1e-9 of a multiple of 8 m or whose road point lies
within 1e-9 of the 4 / 196 m cut. Writes bench/results/vehicle_ties.json.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import write_result  # noqa: E402

from ambiegen_ros.problems.vehicle import (  # noqa: E402
    VehicleProblem,
    polyline_lengths,
    replication_points,
    replication_poses,
)
from ambiegen_ros.problems.vehicle.replication_road import _arange_parameters  # noqa: E402

NAMES = ("straight", "left", "right")


def segments(G, n):
    return [(NAMES[int(e[0])], int(e[1] if e[0] == 0 else e[2])) for e in G[:n]]


def theirs(segs, with_car: bool):
    """Their road points, polyline length, node count and (``with_car``) F1."""
    from car_road import Map
    from shapely.geometry import LineString
    from vehicle import Car

    states = {f"st{i}": {"state": k, "value": v} for i, (k, v) in enumerate(segs)}
    builder = Map(200)
    pts = builder.get_points_from_states(states)
    _, pts = builder.remove_invalid_cases(pts, states)
    pts = np.array([[float(q[0]), float(q[1])] for q in pts])
    if len(pts) < 2:
        return pts, 0.0, 0, 0.0
    length = LineString(pts).length
    n = len(np.arange(0, 1 + 8 / length, 8 / length))
    f1 = 0.0
    if with_car:
        car = Car(9, 12, 200)
        fitness, _ = car.execute_road(car.interpolate_road(pts))
        f1 = -fitness if fitness else 0.0
    return pts, length, n, f1


def compare(problem, G, L, with_car: bool) -> dict:
    pts, counts, _ = replication_points(G, L, problem.config)
    lengths = polyline_lengths(pts, counts, problem.config)
    offs = np.concatenate([[0], np.cumsum(counts)])
    f1 = problem.evaluate(G, L).f1 if with_car else None
    road = length = nodes = car = 0
    for r in range(len(L)):
        tp, tl, tn, tf = theirs(segments(G[r], L[r]), with_car)
        ours = pts[offs[r]: offs[r + 1]]
        road += len(ours) != len(tp) or not np.array_equal(ours, tp)
        length += len(ours) >= 2 and lengths[r] != tl
        n = int(_arange_parameters(np.array([8 / lengths[r]]))[0][0]) if len(ours) >= 2 else 0
        nodes += n != tn
        car += bool(with_car and abs(f1[r] - tf) > 1e-6)
    return {"roads": int(len(L)), "points_differ": int(road), "length_differs": int(length),
            "node_count_differs": int(nodes), **({"f1_differs": int(car)} if with_car else {})}


def tie_prone(problem, n: int, rng) -> tuple[np.ndarray, np.ndarray]:
    m = problem.m_max
    G = np.zeros((n, m, 3))
    L = rng.integers(2, 9, n)
    G[:, :, 0] = rng.choice(3, (n, m), p=[0.45, 0.275, 0.275])
    G[:, :, 1] = rng.choice([5, 6, 7, 8, 10, 12, 14, 16, 20, 24, 26, 29, 30, 32, 36, 40, 42, 45, 46, 48, 50], (n, m))
    G[:, :, 2] = rng.choice([15, 30, 45, 60, 75], (n, m))
    G[np.arange(m)[None, :] >= L[:, None]] = 0
    G, L = problem.canonical(G, L)
    pts, counts, _ = replication_points(G, L, problem.config)
    lengths = polyline_lengths(pts, counts, problem.config)
    poses, _ = replication_poses(G, problem.config)
    near = np.abs(lengths / 8 - np.rint(lengths / 8)) < 1e-9
    for limit in (problem.config.margin, problem.config.map_size - problem.config.margin):
        near |= (np.abs(poses - limit) < 1e-9).any(axis=(1, 2))
    return G[near], L[near]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--authors", required=True, help="folder with the replication code's car_road.py and vehicle.py")
    ap.add_argument("--sampled", type=int, default=100_000)
    ap.add_argument("--candidates", type=int, default=100_000, help="random roads screened for ties")
    ap.add_argument("--seed", type=int, default=2024)
    args = ap.parse_args()
    sys.path.insert(0, str(Path(args.authors).resolve()))
    problem = VehicleProblem()
    rng = np.random.default_rng(args.seed)
    figures = {}
    t = time.perf_counter()
    G, L = problem.sample(args.sampled, rng)
    figures["sampled"] = compare(problem, G, L, with_car=False)
    G, L = tie_prone(problem, args.candidates, rng)
    figures["tie_prone"] = {"candidates": args.candidates, **compare(problem, G, L, with_car=True)}
    figures["seconds"] = round(time.perf_counter() - t, 1)
    for name, row in figures.items():
        print(f"{name}: {row}")
    print(write_result("vehicle_ties", figures))


if __name__ == "__main__":
    main()
