"""Every number of the lane-keeping case study (``VehicleConfig``) and one road as built, checked
and driven (``Road``)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ...core.attributes import ScenarioError
from ...core.problem import check_profile

TYPE, LENGTH, ANGLE = 0, 1, 2  # attribute columns of G
STRAIGHT, LEFT, RIGHT = 0, 1, 2  # codes of the "type" attribute
FEET_PER_METRE = 3.280839895  # the replication code's sharpness threshold is 47 ft
OBJECTIVES = ("max_deviation", "certified")  # F1: the paper's surrogate car; the two drivers (issue 26)
REPLICATION_M_MAX = 50  # its generator has no limit; 1 road in ~200,000 has more elements (measured)


@dataclass(frozen=True)
class VehicleConfig:
    """Every tunable number of the lane-keeping case study.

    Fields that default to None take their profile's value in ``__post_init__`` (recorded resolved).
    """

    profile: str = "replication"  # replication | refined (see the module notes)
    alpha: float | None = None  # MO constraint: "risky" when F1 > alpha [m]; replication 8, refined 10, certified 2.5
    objective: str = "max_deviation"  # F1: the paper's surrogate car | "certified" (``drivers``: two drivers, the rules)
    # map and road construction
    map_size: float = 200.0  # square map side [m]
    margin: float = 4.0  # refined: nodes this far inside the map; replication: road points in (margin, size - margin) [m]
    start: tuple = (100.0, 100.0)  # first road point [m]
    start_heading_deg: float | None = None  # initial heading: refined 90 (+y); replication -90 (a first left turn: +90)
    turn_radius: float | None = None  # radius of a turn's centre-line arc [m]: refined 20, replication 30
    spine_spacing: float = 5.0  # refined: max distance between spine points along a segment [m]
    # interpolation and validity
    interp_step: float = 1.0  # one interpolated node per this many metres (replication: of the sharpness check)
    interp_min_nodes: int = 20
    min_road_length: float = 20.0  # refined [m]
    min_radius: float | None = None  # smallest circumradius of (p_i, p_i+2, p_i+4) [m]: refined 14.33, replication 47 ft
    # surrogate car, refined (paper eqs. 10-13, table 7)
    v0: float | None = None  # initial speed [m/s]: refined 7, replication 9
    k: float = 3.5  # steering gain: turn rate atan(k / v) [rad/s]
    alpha_v: float = 0.3  # deceleration outside the band [m/s^2]
    beta_v: float = 0.1  # acceleration inside the band [m/s^2]
    band: float = 1.0  # e: no steering while |d| <= band [m] (both profiles)
    v_min: float = 0.0  # speed floor [m/s]
    dt: float = 0.1  # integration step [s]
    time_factor: float = 3.0  # time limit = time_factor * road length / v0
    window_back: int = 2  # nearest-segment search window around the previous one (segments)
    window_ahead: int = 4
    # replication profile: the replication code's road builder and discrete car
    section_half_width: float = 5.0  # the road builder's cross-section: +- this across the centre [m]
    node_step: float = 8.0  # the car's road: spline nodes about this far apart [m]
    radius_decimals: int = 3  # the sharpness check rounds its nodes to this many decimals
    steer_gain: float = 2.0  # a turning step steers by atan(steer_gain * d / v)
    probe_deg: float = 1.0  # it turns towards whichever of +- probe_deg ends closer to the road
    accel_per_step: float = 0.3  # speed gained per step within the band [m/s]
    decel_per_step: float = 0.1  # speed lost per step outside the band [m/s]
    straight_step_div: float = 2.3  # a straight step advances v / straight_step_div [m]
    turn_step_div: float = 3.0  # a turning step advances v / turn_step_div [m]
    max_steps: int = 1000  # steps of one drive (both halves of the road)
    engine: str = "auto"  # car simulation: "auto" (numba if importable) | "numba" | "numpy"
    # drawing / ROS
    lane_width: float = 4.0  # two lanes of this width either side of the centre line [m]
    # sampling
    sampling: str = "markov"  # "markov" | "uniform" (segment types of the initial population)
    first_type: str = "straight"  # type of the first element under Markov sampling
    first_length: int | None = None  # length of a first straight: replication 5 (its generator), refined 0 = drawn
    sample_angle_min: int | None = None  # smallest sampled turn angle [deg]: replication 10, refined 5
    p_from_straight: tuple = (0.1, 0.45, 0.45)  # P(straight, left, right) after a straight
    p_from_turn: tuple = (0.2, 0.4, 0.4)  # P(straight, left, right) after a left or right turn

    def __post_init__(self):
        check_profile(self.profile)
        replication = self.profile == "replication"
        if self.objective not in OBJECTIVES:
            raise ScenarioError("config.objective", f"unknown objective {self.objective!r}", "|".join(OBJECTIVES))
        defaults = {
            "alpha": 2.5 if self.objective == "certified" else 8.0 if replication else 10.0,
            "start_heading_deg": -90.0 if replication else 90.0,
            "turn_radius": 30.0 if replication else 20.0,
            "min_radius": 47.0 / FEET_PER_METRE if replication else 14.33,
            "v0": 9.0 if replication else 7.0,
            "first_length": 5 if replication else 0,
            "sample_angle_min": 10 if replication else 5,
        }
        for name, value in defaults.items():
            if getattr(self, name) is None:
                object.__setattr__(self, name, value)
        # YAML / JSON give lists; keep the config hashable and the chain well-formed.
        for name in ("p_from_straight", "p_from_turn"):
            probs = tuple(float(p) for p in getattr(self, name))
            if len(probs) != 3 or min(probs) < 0 or abs(sum(probs) - 1.0) > 1e-9:
                raise ScenarioError(f"config.{name}", f"bad probabilities {probs}", "3 numbers >= 0 summing to 1")
            object.__setattr__(self, name, probs)
        start = tuple(float(v) for v in self.start)
        if len(start) != 2:
            raise ScenarioError("config.start", f"expected (x, y), got {self.start!r}")
        object.__setattr__(self, "start", start)
        if self.sampling not in ("markov", "uniform"):
            raise ScenarioError("config.sampling", f"unknown sampling {self.sampling!r}", "markov|uniform")
        if self.first_type not in ("straight", "left", "right"):
            raise ScenarioError("config.first_type", f"unknown type {self.first_type!r}", "straight|left|right")
        if self.engine not in ("auto", "numba", "numpy"):
            raise ScenarioError("config.engine", f"unknown engine {self.engine!r}", "auto|numba|numpy")
        for name in ("turn_radius", "spine_spacing", "interp_step", "dt", "v0", "k", "time_factor", "node_step",
                     "straight_step_div", "turn_step_div"):
            if not getattr(self, name) > 0:
                raise ScenarioError(f"config.{name}", "must be > 0")
        if self.max_steps < 1:
            raise ScenarioError("config.max_steps", "must be >= 1")
        if self.window_back < 1 or self.window_ahead < 1:  # the previous best must not sit on an edge
            raise ScenarioError("config.window_back", "window too small", "window_back >= 1, window_ahead >= 1")


@dataclass
class Road:
    """One road as built, checked and driven by the surrogate ("TC to environment").

    ``nodes`` is the road the surrogate scores, and the one plotted, published and driven by the
    full car model: refined, the spline sampled every metre; replication, its spline sampled
    about every ``node_step`` metres (the polyline the replication car measures its distance to).
    """

    spine: np.ndarray  # (N, 2) points from the affine transforms (replication: one per element kept)
    nodes: np.ndarray  # (M, 2) interpolated centre line
    length: float  # of the interpolated centre line [m]
    valid: bool
    reason: str | None
    min_radius: float  # smallest circumradius of (p_i, p_i+2, p_i+4) [m]
    path: np.ndarray  # (K, 2) surrogate car positions where d was measured, one per step
    deviations: np.ndarray  # (K,) d at each path point: refined signed (> 0 = left), replication unsigned
    max_deviation: float  # max |d| of the surrogate run (F1 if the road is valid)
    lane_width: float
    map_size: float
    margin: float
    car_path_simple: bool = True  # replication: F1 = 0 when the car's path crosses itself

    @property
    def f1(self) -> float:
        return self.max_deviation if self.valid and self.car_path_simple else 0.0

    def to_dict(self) -> dict[str, Any]:
        return {
            "valid": self.valid,
            "reason": self.reason,
            "length": self.length,
            "min_radius": self.min_radius,
            "max_deviation": self.max_deviation,
            "car_path_simple": self.car_path_simple,
            "f1": self.f1,
            "lane_width": self.lane_width,
            "spine": self.spine.tolist(),
            "nodes": self.nodes.tolist(),
            "path": self.path.tolist(),
            "deviations": self.deviations.tolist(),
        }
