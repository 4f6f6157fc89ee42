"""The vehicle's reference: the competition rules before the drive, a cautious driver after a failure.

* ``before``: only roads valid by the SBST/SBFT competition rules are driven, checked on the road
  the car would drive (``car.road_check``): inside the map with its margin (the centre line and
  both edges of its two lanes), no overlap of the road's surface with itself, no bend tighter
  than the minimum radius. In the replication profile the road builder cuts a road at the map
  edge and the surrogate still scores the rest; a cut road is a road that leaves the map, so it
  is never driven. Passed: the checked road goes to the simulator (``evidence["road"]``).
* ``after`` (the system under test failed): the same car with a cautious driver
  (``reference_corner_lat_accel``, ``reference_preview_time``; every other number as the system
  under test's) drives the same road. If it fails too, the road asked the impossible of any
  reasonable driver: INVALID_TEST.
"""
from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from ...problems.vehicle.validity import competition_rules
from .. import car
from ..outcome import Outcome
from . import ReferenceVerdict


def before(problem: Any, scenario: Any, config: car.CarSimConfig) -> ReferenceVerdict:
    """The competition rules on the road the car would drive (a road the builder cut breaks them)."""
    check = car.road_check(problem, scenario)
    pc = problem.config
    reasons = []
    if check.cut:  # reason enough: the road the scenario describes leaves the map (most random roads)
        length = float(np.hypot(*np.diff(check.road, axis=0).T).sum())
        reasons.append(f"road leaves the map: the road builder cut it after {check.elements_built} of "
                       f"{check.elements} elements, {length:.0f} m along it")
    else:
        lane_width = config.lane_width or float(pc.lane_width)
        # the replication profile's sharpness check runs on its spline re-sampled every metre, not on
        # the ~8 m nodes the car drives; the refined road's nodes are that 1 m sampling already
        radius = check.min_radius if pc.profile == "replication" else None
        _, reason = competition_rules(check.road, lane_width, pc.map_size, pc.margin, pc.min_radius, radius=radius)
        reasons += [reason] if reason else []
    metrics = {"road_cut": check.cut, "elements_built": check.elements_built}
    if reasons:
        return ReferenceVerdict(False, "competition_rules", "; ".join(reasons), metrics)
    return ReferenceVerdict(True, "competition_rules", "", metrics, evidence={"road": check.road})


def cautious(config: car.CarSimConfig) -> car.CarSimConfig:
    """The reference driver: the system under test's car and oracle, cornering and looking ahead cautiously."""
    return dataclasses.replace(config, corner_lat_accel=config.reference_corner_lat_accel,
                               preview_time=config.reference_preview_time)


def _what_it_did(run: dict[str, Any]) -> str:
    if run["failure_kind"] == "out_of_lane":
        return f"leaves the lane at {run['oob_arc_length']:.0f} m"
    if run["failure_kind"] == "stall":
        return "stalls"
    return f"fails ({run['failure_kind']}: {run['detail']})"


def after(problem: Any, scenario: Any, config: car.CarSimConfig, outcome: Outcome, seed: int) -> ReferenceVerdict:
    """A cautious driver on the road the system under test failed: it must complete it."""
    ref = cautious(config)
    road = car.road_of(problem, scenario)[0]
    run = car.drive(road, float(problem.config.lane_width), ref, seed=seed)
    who = f"a cautious driver ({ref.corner_lat_accel:g} m/s^2 corners, {ref.preview_time:g} s preview)"
    metrics = {"driver_outcome": run["outcome"], "driver_max_oob": run["max_oob"],
               "driver_corner_lat_accel": ref.corner_lat_accel, "driver_preview_time": ref.preview_time}
    if run["failure_kind"] == "none":
        return ReferenceVerdict(True, "reference_driver", "", metrics)
    return ReferenceVerdict(False, "reference_driver", f"{who} also {_what_it_did(run)}", metrics)
