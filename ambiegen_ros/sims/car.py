"""Full-model car: a kinematic bicycle keeping the right lane of a two-lane road.

The paper executed its roads in BeamNG (SBST 2021 pipeline, BeamNG.AI in the right lane at up to
70 km/h). This is a ROS-free stand-in, time-stepped and independent of the surrogate car:

* *Road*: the problem's interpolated centre line (``VehicleProblem.roads``); two lanes of
  ``lane_width`` (the problem's, 4 m); the right lane's centre is the centre line offset half a
  lane to the right, its polygon (shapely) the union of the quads between the centre line and the
  right edge.
* *Car*: kinematic bicycle (rear-axle reference, ``wheelbase``), a ``length`` x ``width`` bounding
  box, steering angle and steering-rate limits, and a grip limit: a turn asking for more lateral
  acceleration than ``grip`` is cut to it, so a car entering a bend too fast runs wide.
* *Driver*: a speed controller up to the speed limit that slows for curvature ahead: every lane
  node within its preview (``preview_time`` x speed, at least ``preview_min``) caps the speed at
  ``sqrt(corner_lat_accel / curvature)`` plus what braking at ``brake`` can shed before the node;
  the car accelerates at most ``accel`` and brakes at most ``brake``. A curve seen too late is
  entered too fast and the grip limit carries the car wide. Steering by pure pursuit on the right
  lane's centre (lookahead ``lookahead_time`` x speed, at least ``lookahead_min``) or Stanley.

Calibration: a truly cautious driver (``corner_lat_accel`` 4, ``preview_time`` 1.5 s) never
leaves the lane on a valid road (every turn is an arc of >= 14 m radius), so the full model
would confirm no failure at all. The defaults describe a brisk driver in the spirit of BeamNG.AI
at the SBST risk level (corners near the grip limit, reacts to a bend about 0.5 s ahead): about
1 % of Markov-sampled valid roads fail, and a tight right-hand hairpin after a long straight
does; gentle roads pass.

Reference (``sims.reference.vehicle``, on unless ``reference=False``): a road is driven only if
it keeps the competition rules on the road driven (both lanes inside the map with its margin, no
overlap of the road with itself, minimum radius; never a road the replication builder cut at the
map edge), else INVALID_TEST; a failure counts only when the cautious driver above
(``reference_corner_lat_accel``, ``reference_preview_time``, the rest of the config unchanged)
completes the same road, else INVALID_TEST.

Oracle: out of lane when more than ``oob_tolerance`` of the bounding box's area lies outside the
right-lane polygon (checked every step, vectorised over chunks of steps); stall when the car moves
less than ``stall_distance`` in ``stall_time``; success within ``goal_distance`` of the last road
point; timeout after ``timeout_base + road length / timeout_speed`` simulated seconds.
Metrics: outcome, max OOB fraction, max lateral offset from the right lane's centre, and the arc
length along the road where the car first left the lane beyond the tolerance (and first touched
its edge).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import shapely

from ..core.attributes import ScenarioError
from .outcome import Outcome

CONTROLLERS = ("pure_pursuit", "stanley")


@dataclass(frozen=True)
class CarSimConfig:
    """Every number of the full-model car (defaults: a mid-size car, the SBST oracle)."""

    # vehicle
    wheelbase: float = 2.7  # [m]
    length: float = 4.5  # bounding box [m]
    width: float = 1.8  # bounding box [m]
    rear_overhang: float = 0.9  # rear bumper to rear axle [m]
    max_steer_deg: float = 35.0  # road-wheel angle limit
    max_steer_rate_deg: float = 60.0  # road-wheel angle rate limit [deg/s]
    grip: float = 7.0  # most lateral acceleration the tyres give [m/s^2]
    # driver
    speed_limit_kmh: float = 70.0
    start_speed: float = 0.0  # [m/s]
    accel: float = 2.5  # [m/s^2]
    brake: float = 4.0  # [m/s^2]
    corner_lat_accel: float = 6.5  # the driver's cornering target (a brisk ~0.9 of grip) [m/s^2]
    preview_time: float = 0.5  # how far ahead it looks for curves [s] (late: see the module notes)
    preview_min: float = 5.0  # [m]
    speed_gain: float = 2.0  # acceleration per m/s of speed error [1/s]
    controller: str = "pure_pursuit"  # pure_pursuit | stanley
    lookahead_time: float = 0.5  # pure pursuit lookahead per m/s [s]
    lookahead_min: float = 4.0  # [m]
    stanley_gain: float = 1.5  # [1/s]
    dt: float = 0.05  # [s]
    # road and oracle
    lane_width: float = 0.0  # 0 = the problem's lane width
    oob_tolerance: float = 0.85  # failure when more than this fraction of the box is out of the lane
    stall_distance: float = 1.0  # [m]
    stall_time: float = 10.0  # [s]
    goal_distance: float = 8.0  # success this close to the last road point [m]
    timeout_base: float = 30.0  # [s]
    timeout_speed: float = 3.0  # time limit adds road length / this [s]
    check_every: int = 20  # steps per vectorised out-of-lane check
    run_invalid: bool = False  # also simulate roads the problem calls invalid
    # reference check (``sims.reference.vehicle``): the competition rules before, a cautious driver after
    reference: bool = True  # check each scenario with the problem's reference; false = the old, unchecked verdicts
    reference_corner_lat_accel: float = 4.0  # the cautious driver's cornering target [m/s^2]
    reference_preview_time: float = 1.5  # how far ahead the cautious driver looks for curves [s]

    def __post_init__(self):
        if self.controller not in CONTROLLERS:
            raise ScenarioError("option.controller", f"unknown controller {self.controller!r}", "|".join(CONTROLLERS))
        for name in ("wheelbase", "length", "width", "max_steer_deg", "max_steer_rate_deg", "grip",
                     "speed_limit_kmh", "accel", "brake", "corner_lat_accel", "dt", "stall_distance",
                     "stall_time", "goal_distance", "timeout_speed", "lookahead_min", "speed_gain",
                     "reference_corner_lat_accel"):
            if not getattr(self, name) > 0:
                raise ScenarioError(f"option.{name}", "must be > 0")
        if not 0.0 <= self.oob_tolerance <= 1.0:
            raise ScenarioError("option.oob_tolerance", "must be a fraction", "[0, 1]")
        if self.check_every < 1:
            raise ScenarioError("option.check_every", "must be >= 1")
        if self.lane_width < 0:
            raise ScenarioError("option.lane_width", "must be >= 0 (0 = the problem's)")
        for name in ("preview_time", "reference_preview_time"):
            if not getattr(self, name) >= 0:
                raise ScenarioError(f"option.{name}", "must be >= 0")


# --- road geometry -------------------------------------------------------------------------------
@dataclass
class Lane:
    """The right lane of a road: centre polyline, arc lengths, curvature, polygon."""

    road: np.ndarray  # (M, 2) road centre line
    centre: np.ndarray  # (M, 2) right-lane centre
    s: np.ndarray  # (M,) arc length along the lane centre [m]
    road_s: np.ndarray  # (M,) arc length along the road centre line [m]
    curvature: np.ndarray  # (M,) |curvature| of the lane centre [1/m]
    polygon: Any  # shapely geometry of the lane
    width: float


def right_lane(road: np.ndarray, lane_width: float) -> Lane:
    """Offset the road centre line half a lane (and a lane) to the right; build the lane polygon."""
    # here, not at the top: the robot's and room's runs skip the vehicle package
    from ..problems.vehicle.validity import left_normals, right_lane_lines

    road = np.asarray(road, dtype=float)
    centre, s, road_s, curvature = right_lane_lines(road, lane_width)
    edge = road - left_normals(road) * lane_width
    quads = np.stack([road[:-1], road[1:], edge[1:], edge[:-1]], axis=1)
    polygon = shapely.union_all(shapely.polygons(quads))
    shapely.prepare(polygon)
    return Lane(road, centre, s, road_s, curvature, polygon, lane_width)


def box_corners(x, y, yaw, length: float, width: float) -> np.ndarray:
    """(N, 4, 2) corners of boxes centred at (x, y) with heading yaw."""
    x, y, yaw = (np.atleast_1d(np.asarray(v, dtype=float)) for v in (x, y, yaw))
    c, s = np.cos(yaw), np.sin(yaw)
    hl, hw = length / 2, width / 2
    local = np.array([[hl, hw], [-hl, hw], [-hl, -hw], [hl, -hw]])
    cx = x[:, None] + local[None, :, 0] * c[:, None] - local[None, :, 1] * s[:, None]
    cy = y[:, None] + local[None, :, 0] * s[:, None] + local[None, :, 1] * c[:, None]
    return np.stack([cx, cy], axis=-1)


def oob_fraction(lane: Lane, x, y, yaw, length: float, width: float) -> np.ndarray:
    """Fraction of each box's area outside the lane polygon (vectorised; boxes fully inside skip the area)."""
    boxes = shapely.polygons(box_corners(x, y, yaw, length, width))
    out = np.zeros(len(boxes))
    inside = shapely.contains_properly(lane.polygon, boxes)
    todo = ~inside
    if todo.any():
        area_in = shapely.area(shapely.intersection(boxes[todo], lane.polygon))
        out[todo] = np.clip(1.0 - area_in / (length * width), 0.0, 1.0)
    return out


def _project(lane: Lane, x: float, y: float, i: int, back: int = 5, ahead: int = 40) -> tuple[int, float, float]:
    """Nearest lane segment to (x, y) searched around segment ``i``: (segment, arc length, signed offset)."""
    P = lane.centre
    lo, hi = max(i - back, 0), min(i + ahead, len(P) - 1)
    a, b = P[lo:hi], P[lo + 1:hi + 1]
    d = b - a
    L2 = np.maximum((d * d).sum(axis=1), 1e-12)
    u = np.clip(((x - a[:, 0]) * d[:, 0] + (y - a[:, 1]) * d[:, 1]) / L2, 0.0, 1.0)
    qx, qy = a[:, 0] + u * d[:, 0], a[:, 1] + u * d[:, 1]
    dist2 = (x - qx) ** 2 + (y - qy) ** 2
    k = int(np.argmin(dist2))
    seg = lo + k
    side = d[k, 0] * (y - a[k, 1]) - d[k, 1] * (x - a[k, 0])  # > 0: left of the lane centre
    return seg, float(lane.s[seg] + u[k] * math.sqrt(L2[k])), math.copysign(math.sqrt(dist2[k]), side)


def _point_at(lane: Lane, s: float) -> tuple[float, float]:
    s = min(max(s, 0.0), float(lane.s[-1]))
    j = int(np.searchsorted(lane.s, s, side="right")) - 1
    j = min(max(j, 0), len(lane.s) - 2)
    seg = lane.s[j + 1] - lane.s[j]
    f = 0.0 if seg <= 0 else (s - lane.s[j]) / seg
    p = lane.centre[j] + f * (lane.centre[j + 1] - lane.centre[j])
    return float(p[0]), float(p[1])


# --- the simulation ------------------------------------------------------------------------------
def drive(road: np.ndarray, lane_width: float = 4.0, config: CarSimConfig | None = None,
          seed: int = 0) -> dict[str, Any]:
    """Drive the right lane of the road centre line ``road`` (M, 2); returns the record.

    Deterministic: the car model has no noise, ``seed`` is accepted for a uniform interface.
    """
    cfg = config or CarSimConfig()
    lane = right_lane(road, cfg.lane_width or lane_width)
    dt, L = cfg.dt, cfg.wheelbase
    v_limit = cfg.speed_limit_kmh / 3.6
    v_curve = np.minimum(v_limit, np.sqrt(cfg.corner_lat_accel / np.maximum(lane.curvature, 1e-9)))
    v_curve_sq = v_curve ** 2
    max_steer = math.radians(cfg.max_steer_deg)
    steer_step = math.radians(cfg.max_steer_rate_deg) * dt
    centre_ahead = cfg.length / 2 - cfg.rear_overhang  # rear axle -> box centre
    total = float(lane.s[-1])
    goal = lane.road[-1]
    time_limit = cfg.timeout_base + float(lane.road_s[-1]) / cfg.timeout_speed
    n_max = int(math.ceil(time_limit / dt))

    # The rear bumper starts on the lane's first point (nothing sticks out behind the road).
    x, y = _point_at(lane, cfg.rear_overhang)
    d0 = lane.centre[min(1, len(lane.centre) - 1)] - lane.centre[0]
    yaw = math.atan2(d0[1], d0[0])
    v, steer = cfg.start_speed, 0.0
    seg = 0
    rec = np.zeros((n_max + 1, 8))  # t, cx, cy, yaw, v, steer, arc length, offset
    seg, s_now, offset = _project(lane, x, y, seg)
    rec[0] = (0.0, x + centre_ahead * math.cos(yaw), y + centre_ahead * math.sin(yaw), yaw, v, 0.0, s_now, offset)
    anchor = (x, y, 0.0)
    outcome, kind, detail, end = "timeout", "timeout", f"last road point not reached within {time_limit:.0f} s", n_max
    checked = 0
    oob = np.zeros(n_max + 1)
    fail_at = None
    for k in range(1, n_max + 1):
        # --- driver ---
        hi = min(int(np.searchsorted(lane.s, s_now + max(cfg.preview_min, cfg.preview_time * v))) + 1, len(lane.s))
        lo = max(seg, 0)
        ahead = np.maximum(lane.s[lo:hi] - s_now, 0.0)
        v_target = v_limit
        if hi > lo:
            v_target = min(v_limit, math.sqrt(float(np.min(v_curve_sq[lo:hi] + 2 * cfg.brake * ahead))))
        a = min(max(cfg.speed_gain * (v_target - v), -cfg.brake), cfg.accel)
        if cfg.controller == "pure_pursuit":
            ld = max(cfg.lookahead_min, cfg.lookahead_time * v)
            tx, ty = _point_at(lane, s_now + ld)
            alpha = math.atan2(ty - y, tx - x) - yaw
            dist = max(math.hypot(tx - x, ty - y), 1e-6)
            want = math.atan2(2 * L * math.sin(alpha), dist)
        else:  # Stanley on the front axle
            fx, fy = x + L * math.cos(yaw), y + L * math.sin(yaw)
            fseg, fs, foff = _project(lane, fx, fy, seg)
            p, q = lane.centre[fseg], lane.centre[min(fseg + 1, len(lane.centre) - 1)]
            path_yaw = math.atan2(q[1] - p[1], q[0] - p[0])
            heading_err = (path_yaw - yaw + math.pi) % (2 * math.pi) - math.pi
            want = heading_err + math.atan2(-cfg.stanley_gain * foff, v + 1.0)
        want = min(max(want, -max_steer), max_steer)
        steer += min(max(want - steer, -steer_step), steer_step)
        # --- vehicle: kinematic bicycle with a grip limit ---
        yaw_rate = v * math.tan(steer) / L
        if abs(v * yaw_rate) > cfg.grip:
            yaw_rate = math.copysign(cfg.grip / max(v, 1e-6), yaw_rate)
        v_new = max(v + a * dt, 0.0)
        v_mid = 0.5 * (v + v_new)
        mid = yaw + 0.5 * yaw_rate * dt
        x += v_mid * math.cos(mid) * dt
        y += v_mid * math.sin(mid) * dt
        yaw = (yaw + yaw_rate * dt + math.pi) % (2 * math.pi) - math.pi
        v = v_new
        seg, s_now, offset = _project(lane, x, y, seg)
        t = k * dt
        cx, cy = x + centre_ahead * math.cos(yaw), y + centre_ahead * math.sin(yaw)
        rec[k] = (t, cx, cy, yaw, v, steer, s_now, offset)
        # --- oracle (out of lane in vectorised chunks, the rest every step) ---
        stop = None
        if math.hypot(cx - goal[0], cy - goal[1]) <= cfg.goal_distance and s_now >= total - 2 * cfg.goal_distance:
            stop = ("success", "none", f"last road point reached in {t:.1f} s")
        elif math.hypot(x - anchor[0], y - anchor[1]) >= cfg.stall_distance:
            anchor = (x, y, t)
        elif t - anchor[2] >= cfg.stall_time - 1e-9:
            stop = ("stall", "stall", f"moved less than {cfg.stall_distance:g} m in {cfg.stall_time:g} s")
        if stop is not None or k - checked >= cfg.check_every or k == n_max:
            part = rec[checked + 1:k + 1]
            oob[checked + 1:k + 1] = oob_fraction(lane, part[:, 1], part[:, 2], part[:, 3], cfg.length, cfg.width)
            over = np.flatnonzero(oob[checked + 1:k + 1] > cfg.oob_tolerance)
            if len(over):
                fail_at = checked + 1 + int(over[0])
                break
            checked = k
        if stop is not None:
            outcome, kind, detail = stop
            end = k
            break
    if fail_at is not None:
        end = fail_at
        road_arc = _road_arc(lane, rec[end, 6])
        outcome, kind = "out_of_lane", "out_of_lane"
        detail = (f"{oob[end]:.0%} of the car outside the right lane (tolerance {cfg.oob_tolerance:.0%}) "
                  f"at {road_arc:.1f} m along the road")
    rec, oob = rec[:end + 1], oob[:end + 1]
    touched = np.flatnonzero(oob > 0)
    failure_point = (float(rec[-1, 1]), float(rec[-1, 2])) if kind != "none" else None
    return {
        "outcome": outcome,
        "failure_kind": kind,
        "detail": detail,
        "time": float(rec[-1, 0]),
        "max_oob": float(oob.max()) if len(oob) else 0.0,
        "max_lateral_offset": float(np.abs(rec[:, 7]).max()),
        "oob_arc_length": _road_arc(lane, rec[-1, 6]) if fail_at is not None else None,
        "departure_arc_length": _road_arc(lane, rec[touched[0], 6]) if len(touched) else None,
        "distance_driven": float(np.hypot(*np.diff(rec[:, 1:3], axis=0).T).sum()),
        "max_speed": float(rec[:, 4].max()),
        "road_length": float(lane.road_s[-1]),
        "failure_point": failure_point,
        "lane": lane,
        "timeline": {"t": rec[:, 0], "x": rec[:, 1], "y": rec[:, 2], "yaw": rec[:, 3], "v": rec[:, 4],
                     "steer": rec[:, 5], "offset": rec[:, 7], "oob": oob},
    }


def _road_arc(lane: Lane, lane_s: float) -> float:
    """Lane-centre arc length -> road centre-line arc length (through the node index)."""
    return float(np.interp(lane_s, lane.s, lane.road_s))


@dataclass
class RoadCheck:
    """One scenario's road as the car drives it, with what the problem's rules say about it."""

    road: np.ndarray  # (M, 2) interpolated centre line (replication: the spline nodes about 8 m apart)
    valid: bool
    reason: str | None
    min_radius: float  # the profile's sharpness measure [m]
    elements: int  # elements of the scenario
    elements_built: int  # elements the road builder kept (replication: it cuts a road at the map edge)

    @property
    def cut(self) -> bool:
        return self.elements_built < self.elements


_LAST_CHECK: list[Any] = [None, None, None]  # problem, genome bytes, RoadCheck: the executor asks twice in a row


def road_check(problem: Any, scenario: Any) -> RoadCheck:
    """Build a vehicle scenario's road and check it with the problem's rules (no surrogate drive).

    The last answer is kept: an execution asks for it twice (the problem's restrictions, then the
    reference's competition rules), and building a replication road is most of a screening's time.
    """
    row = problem.codec.to_row(scenario)
    key = row.tobytes()
    if _LAST_CHECK[0] is problem and _LAST_CHECK[1] == key:
        return _LAST_CHECK[2]
    check = _road_check(problem, row)
    _LAST_CHECK[:] = [problem, key, check]
    return check


def _road_check(problem: Any, row: np.ndarray) -> RoadCheck:
    from ..problems.vehicle import check_roads

    G, lengths = problem.codec.split(row)
    _, n_spine, nodes, n_nodes = problem.roads(G, lengths)
    valid, reasons, _, min_radius = check_roads(nodes, n_nodes, problem.config)
    elements = int(lengths[0])
    # replication: the builder's points are the start and one per element kept; refined never cuts
    built = int(n_spine[0]) - 1 if problem.config.profile == "replication" else elements
    return RoadCheck(np.asarray(nodes, dtype=float)[: int(n_nodes[0])], bool(valid[0]), reasons[0],
                     float(min_radius[0]), elements, built)


def road_of(problem: Any, scenario: Any) -> tuple[np.ndarray, bool, str | None]:
    """The interpolated centre line of a vehicle scenario, its validity and the broken rule."""
    check = road_check(problem, scenario)
    return check.road, check.valid, check.reason


def simulate(problem: Any, scenario: Any, config: CarSimConfig | None = None, seed: int = 0,
             road: np.ndarray | None = None) -> Outcome:
    """Execute one road on the full-model car and judge it with the SBST out-of-lane oracle.

    ``road``: the scenario's centre line when the caller built it already (the reference check did).
    """
    cfg = config or CarSimConfig()
    if road is None:
        road = road_of(problem, scenario)[0]
    run = drive(road, float(problem.config.lane_width), cfg, seed=seed)
    tl = run["timeline"]
    metrics = {k: run[k] for k in ("outcome", "time", "max_oob", "max_lateral_offset", "oob_arc_length",
                                   "departure_arc_length", "distance_driven", "max_speed", "road_length")}
    metrics["oob_tolerance"] = cfg.oob_tolerance
    metrics["lane_width"] = cfg.lane_width or float(problem.config.lane_width)
    metrics["seed"] = int(seed)
    return Outcome(
        objectives={"vehicle_max_oob": run["max_oob"]},
        failed=run["failure_kind"] != "none",
        failure_kind=run["failure_kind"],
        detail=run["detail"],
        metrics=metrics,
        trajectory=np.column_stack([tl["x"], tl["y"]]),
        timeline={k: tl[k] for k in ("t", "x", "y", "yaw", "v", "steer", "oob")},
        failure_point=run["failure_point"],
    )


__all__ = ["CarSimConfig", "Lane", "RoadCheck", "box_corners", "drive", "oob_fraction", "right_lane", "road_check",
           "road_of", "simulate"]
