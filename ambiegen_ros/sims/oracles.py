"""Failure oracles applied to observed trajectories (ROS-free).

The full-model simulators judge their own runs step by step. A system under test from outside
(``sim_nodes/sut_adapter.py``) only shows its odometry or temperature readings, so the same
oracles are restated here over time-stamped samples, with the thresholds taken from the same
config dataclasses (``RobotSimConfig``, ``CarSimConfig``, ``RoomSimConfig``) and the geometry from
the simulators' own helpers (the robot's monitors ``robot.RobotMonitors`` and body clearance
``robot.WallGeometry``, ``car.right_lane``, ``car.oob_fraction``, ``car._project``). Fed with a
full-model timeline they give the full model's verdict (tested), which is what makes adapter results comparable with in-process ones.

Judges are incremental: ``add(...)`` takes a batch of samples (numpy arrays; times in simulated
seconds since the run started, increasing), works on the whole batch at once where the check
allows (wall clearance, out-of-lane fraction, squared errors) and stops at the first event; the
``judge_*`` functions wrap them for a complete series. Sample 0 is the start: like the
simulators, only the robot's stall check applies to it. A series that ends without a verdict
gives an ``error`` outcome naming why (``finish(reason)``), never a pass.
"""
from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np

from . import car, robot
from .car import CarSimConfig
from .outcome import Outcome
from .robot import RobotSimConfig, clearances
from .room import RoomSimConfig

EPS_T = 1e-6  # time comparisons tolerate stamp rounding (nanosecond stamps of float seconds)


class _Judge:
    """Shared bookkeeping: the verdict, the time of the last sample, errors and external reports."""

    def __init__(self) -> None:
        self.kind: str | None = None  # failure kind once decided ("none" = passed)
        self.detail = ""
        self.failure_point: tuple[float, float] | None = None
        self.samples = 0
        self.t_last = -math.inf

    @property
    def decided(self) -> bool:
        return self.kind is not None

    def _decide(self, kind: str, detail: str, point: tuple[float, float] | None = None) -> None:
        self.kind, self.detail, self.failure_point = kind, detail, point

    def fail(self, kind: str, detail: str) -> None:
        """A verdict from outside the samples (a bumper report, an error); the first verdict stays."""
        if not self.decided:
            self._decide(kind, detail, self._last_point())

    def finish(self, reason: str) -> None:
        """The series ended (or was abandoned) without a verdict: an ``error`` naming ``reason``."""
        if not self.decided:
            self._decide("error", reason)

    def _last_point(self) -> tuple[float, float] | None:
        return None

    def _outcome(self, objectives: dict[str, float], metrics: dict[str, Any], trajectory, timeline) -> Outcome:
        if not self.decided:
            self.finish(f"no verdict after {self.samples} samples")
        return Outcome(
            objectives=objectives if self.kind != "error" else {},
            failed=self.kind not in ("none", "error"),
            failure_kind=self.kind,
            detail=self.detail,
            metrics=metrics,
            trajectory=trajectory,
            timeline=timeline,
            failure_point=self.failure_point,
        )


# --- robot -----------------------------------------------------------------------------------------
class RobotJudge(_Judge):
    """The paper's monitors (``robot.RobotMonitors``: stall, route completion, loitering, time
    limit; unsafe proximity and waypoint arrivals recorded) on observed poses.

    The body is the pioneer2dx footprint (a ``robot_profile.ProfiledConfig``'s robot's) at each pose's
    heading: pass ``yaw``; without it the
    heading of the motion between samples stands in. ``stall`` (optional, per sample): the robot's
    own stall flag (the ND driver gave up), as Player's position2d data carries it; without it a
    robot that gave up and stands still is caught by the loitering monitor instead. The route
    (waypoint arrivals, the time limit) is planned from the first sample's cell by the simulator's
    ``robot.plan_route``: the clearance route (``sims.reference.robot``) unless the config says
    ``reference=false`` (then the old A* with the problem's ``diagonal`` rule); ``route_length``
    overrides its length for the time limit, ``speed`` the top speed it divides by (a stack's own,
    e.g. Nav2's controller's; default the config's ``cruise_speed``).

    ``early_verdicts=False`` judges a stack with its own recoveries: stall, route completion and
    loitering are recorded, not decided (``RobotMonitors``), and the stack's own result decides
    (``stack_result``), unless a collision or the time limit came first.
    """

    def __init__(self, grid: np.ndarray, resolution: float, goal_xy: tuple[float, float],
                 config: RobotSimConfig | None = None, origin: tuple[float, float] = (0.0, 0.0),
                 diagonal: str = "both_free", route_length: float | None = None, speed: float | None = None,
                 early_verdicts: bool = True):
        super().__init__()
        self.speed = speed
        self.early_verdicts = early_verdicts
        self.cfg = config or RobotSimConfig()
        self.grid = np.asarray(grid, dtype=bool)
        self.resolution = float(resolution)
        self.goal = (float(goal_xy[0]), float(goal_xy[1]))
        self.origin = (float(origin[0]), float(origin[1]))
        self.diagonal = diagonal
        self.route_length = route_length
        profile = getattr(self.cfg, "robot_profile", None)  # issue 69: a ProfiledConfig's robot, else the Pioneer
        self.walls = robot.WallGeometry(self.grid, self.resolution, self.cfg.clearance_cells, self.origin,
                                        **({"footprint": profile.footprint()} if profile is not None else {}),
                                        engine=self.cfg.engine)
        self.monitors: robot.RobotMonitors | None = None
        self.route_m: float | None = None
        self._t: list[np.ndarray] = []
        self._xy: list[np.ndarray] = []
        self._heading = 0.0
        self._prev: tuple[float, float] | None = None

    @property
    def time_limit(self) -> float:
        """Simulated seconds the oracle needs at most (known once the first sample gave the start)."""
        if self.monitors is not None:
            return self.monitors.time_limit
        return self.cfg.time_limit(self.route_length, self.speed) if self.route_length is not None else math.inf

    def start(self, x0: float, y0: float) -> np.ndarray:
        """Plan the route from the start (map frame) before the first sample; returns its waypoints
        ((K, 2), map frame; none without a route). Else the first sample starts it."""
        res, (ox, oy) = self.resolution, self.origin
        cell = lambda px, py: (int(math.floor((px - ox) / res)), int(math.floor((py - oy) / res)))  # noqa: E731
        waypoints, length = robot.plan_route(self.grid, res, cell(x0, y0), cell(*self.goal), self.cfg,
                                             self.cfg.route_diagonal or self.diagonal)
        self.route_m = float(length) if len(waypoints) else None  # the route itself, whatever the limit uses
        if self.route_length is not None:
            length = self.route_length
        self.monitors = robot.RobotMonitors(self.cfg, self.goal, self.cfg.time_limit(length, self.speed),
                                            waypoints[1:] + self.origin if len(waypoints) else None,
                                            no_route=not len(waypoints), early_verdicts=self.early_verdicts)
        return waypoints + self.origin if len(waypoints) else waypoints

    def _headings(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Heading of the motion into each sample (the previous one where it did not move)."""
        px = np.concatenate([[self._prev[0]], x[:-1]]) if self._prev else np.concatenate([[x[0]], x[:-1]])
        py = np.concatenate([[self._prev[1]], y[:-1]]) if self._prev else np.concatenate([[y[0]], y[:-1]])
        dx, dy = x - px, y - py
        if self._prev is None and len(x) > 1:  # the first sample faces the second
            dx[0], dy[0] = x[1] - x[0], y[1] - y[0]
        out = np.empty(len(x))
        heading = self._heading
        for i in range(len(x)):
            if dx[i] * dx[i] + dy[i] * dy[i] > 1e-12:
                heading = math.atan2(dy[i], dx[i])
            out[i] = heading
        self._heading = heading
        return out

    def add(self, t, x, y, yaw=None, stall=None, collision=None) -> bool:
        """Judge a batch of samples; returns True once decided (later samples are ignored).

        ``stall`` (per sample): the robot's stall flag, a cause (``"emergency_stop"``) or a bool
        (``"reported"``); ``collision`` (per sample): a collision reported by the world, as a text
        naming the report, or None. One sample's priority: the world's collision, then the
        monitors' own order (contact, the stall flag, goal, loitering, time limit), so that events
        sharing a stamp always resolve the same way."""
        if self.decided:
            return True
        t, x, y = (np.atleast_1d(np.asarray(a, dtype=float)) for a in (t, x, y))
        if not len(t):
            return False
        yaw = self._headings(x, y) if yaw is None else np.atleast_1d(np.asarray(yaw, dtype=float))
        causes = [None] * len(t) if stall is None else [_cause(f) for f in np.atleast_1d(np.asarray(stall, dtype=object))]
        reports = [None] * len(t) if collision is None else list(collision)
        clear = self.walls.clearance(x, y, yaw)
        if self.monitors is None:
            self.start(float(x[0]), float(y[0]))
        mon = self.monitors
        assert mon is not None
        used = len(t)
        for i in range(len(t)):
            if mon.update(float(t[i]), float(x[i]), float(y[i]), float(clear[i]), causes[i], reports[i]):
                used = i + 1
                break
        self._prev = (float(x[used - 1]), float(y[used - 1]))
        if mon.kind is not None:
            self._decide(mon.kind, mon.detail, mon.failure_point)
        self._t.append(t[:used])
        self._xy.append(np.column_stack([x[:used], y[:used]]))
        self.samples += used
        self.t_last = float(t[used - 1])
        return self.decided

    def _last_point(self):
        return self._prev

    @property
    def elapsed(self) -> float:
        """Simulated seconds covered so far."""
        return 0.0 if self.monitors is None else self.monitors.t

    def stack_result(self, succeeded: bool, kind: str, detail: str) -> None:
        """The stack's own verdict (Nav2's action result) at the last judged sample: a pass, or a
        failure of ``kind``. A verdict reached before (a collision, the time limit) stands."""
        if succeeded and not self.decided:
            self._decide("none", detail)
        else:
            self.fail(kind, detail)

    def outcome(self) -> Outcome:
        t = np.concatenate(self._t) if self._t else np.zeros(0)
        xy = np.concatenate(self._xy) if self._xy else np.zeros((0, 2))
        t_rel = t - t[0] if len(t) else t
        mon = self.monitors
        metrics: dict[str, Any] = (mon.metrics() if mon is not None
                                   else {"time": 0.0, "path_length": 0.0, "min_clearance": None})
        metrics.update({
            "outcome": {"none": "success"}.get(self.kind or "error", self.kind or "error"),
            "radius": self.cfg.radius,
            "distance_to_goal": (float(math.hypot(xy[-1, 0] - self.goal[0], xy[-1, 1] - self.goal[1]))
                                 if len(xy) else None),
            "samples": self.samples,
            "route_length_m": self.route_m,  # the route planned from the start (known failures read it)
            "map_side_m": float(max(self.grid.shape) * self.resolution),
            # our monitors, the stack's own result, or nothing (an error)
            "decided_by": ("monitors" if mon is not None and mon.decided
                           else "stack" if self.kind not in (None, "error") else "none"),
        })
        if mon is not None and self.kind == "stall" and mon.outcome == "no_route":
            metrics["outcome"] = "no_route"
        success = self.kind == "none"
        return self._outcome(
            {"robot_time": float(metrics["time"]) if success else self.time_limit}, metrics,
            xy if len(xy) else None, {"t": t_rel, "x": xy[:, 0], "y": xy[:, 1]},
        )


def _cause(flag: Any) -> str | None:
    """A stall flag as the monitors take it: a cause, or "reported" for a bare true."""
    if isinstance(flag, str):
        return flag or None
    return "reported" if flag else None


def judge_robot(t, x, y, grid: np.ndarray, resolution: float, goal_xy: tuple[float, float],
                config: RobotSimConfig | None = None, origin: tuple[float, float] = (0.0, 0.0), *,
                yaw=None, stall=None, diagonal: str = "both_free") -> Outcome:
    """Judge a complete robot trajectory (times in simulated seconds, positions in the map frame)."""
    judge = RobotJudge(grid, resolution, goal_xy, config, origin, diagonal)
    if not judge.add(t, x, y, yaw, stall):
        judge.finish(f"trajectory ends after {judge.elapsed:.1f} s without a verdict")
    return judge.outcome()


# --- car -------------------------------------------------------------------------------------------
class CarJudge(_Judge):
    """Out of lane (more than ``oob_tolerance`` of the box outside the right lane), stall (less than
    ``stall_distance`` in ``stall_time``, measured at the rear axle), success within
    ``goal_distance`` of the last road point near the road's end, timeout
    (``timeout_base + road length / timeout_speed``). Samples are box centres with headings."""

    def __init__(self, road: np.ndarray, lane_width: float, config: CarSimConfig | None = None):
        super().__init__()
        self.cfg = config or CarSimConfig()
        self.lane = car.right_lane(np.asarray(road, dtype=float), self.cfg.lane_width or float(lane_width))
        self.time_limit = self.cfg.timeout_base + float(self.lane.road_s[-1]) / self.cfg.timeout_speed
        self.centre_ahead = self.cfg.length / 2 - self.cfg.rear_overhang
        self._rows: list[np.ndarray] = []  # t, cx, cy, yaw, v, oob, offset, lane s
        self._seg = 0
        self._anchor: tuple[float, float, float] | None = None
        self._t0 = 0.0
        self._prev: tuple[float, float] | None = None

    def add(self, t, x, y, yaw, v=None) -> bool:
        if self.decided:
            return True
        t, x, y, yaw = (np.atleast_1d(np.asarray(a, dtype=float)) for a in (t, x, y, yaw))
        if not len(t):
            return False
        v = np.full(len(t), np.nan) if v is None else np.atleast_1d(np.asarray(v, dtype=float))
        cfg, lane = self.cfg, self.lane
        oob = car.oob_fraction(lane, x, y, yaw, cfg.length, cfg.width)
        rx = x - self.centre_ahead * np.cos(yaw)  # rear axle: where the simulator measures stall
        ry = y - self.centre_ahead * np.sin(yaw)
        goal = lane.road[-1]
        total = float(lane.s[-1])
        rows = np.zeros((len(t), 8))
        used = len(t)
        for i in range(len(t)):
            ti = float(t[i])
            self._seg, s_now, offset = car._project(lane, float(rx[i]), float(ry[i]), self._seg)
            if self._anchor is None:  # the start
                self._t0 = ti
                self._anchor = (float(rx[i]), float(ry[i]), ti)
                rows[i] = (ti, x[i], y[i], yaw[i], v[i], 0.0, offset, s_now)
                self._prev = (float(x[i]), float(y[i]))
                continue
            rows[i] = (ti, x[i], y[i], yaw[i], v[i], oob[i], offset, s_now)
            self._prev = (float(x[i]), float(y[i]))
            rel = ti - self._t0
            if oob[i] > cfg.oob_tolerance:  # wins ties with the other events, as in the simulator
                arc = float(np.interp(s_now, lane.s, lane.road_s))
                self._decide("out_of_lane", f"{oob[i]:.0%} of the car outside the right lane (tolerance "
                                            f"{cfg.oob_tolerance:.0%}) at {arc:.1f} m along the road", self._prev)
            elif math.hypot(x[i] - goal[0], y[i] - goal[1]) <= cfg.goal_distance and s_now >= total - 2 * cfg.goal_distance:
                self._decide("none", f"last road point reached in {rel:.1f} s")
            else:
                ax, ay, at = self._anchor
                if math.hypot(rx[i] - ax, ry[i] - ay) >= cfg.stall_distance:
                    self._anchor = (float(rx[i]), float(ry[i]), ti)
                elif ti - at >= cfg.stall_time - EPS_T:
                    self._decide("stall", f"moved less than {cfg.stall_distance:g} m in {cfg.stall_time:g} s", self._prev)
                if not self.decided and rel >= self.time_limit - EPS_T:
                    self._decide("timeout", f"last road point not reached within {self.time_limit:.0f} s", self._prev)
            if self.decided:
                used = i + 1
                break
        self._rows.append(rows[:used])
        self.samples += used
        self.t_last = float(t[used - 1])
        return self.decided

    def _last_point(self):
        return self._prev

    @property
    def elapsed(self) -> float:
        return 0.0 if self._anchor is None else self.t_last - self._t0

    def outcome(self) -> Outcome:
        rows = np.concatenate(self._rows) if self._rows else np.zeros((0, 8))
        lane = self.lane
        oob = rows[:, 5]
        touched = np.flatnonzero(oob > 0)
        arc = lambda s: float(np.interp(s, lane.s, lane.road_s))  # noqa: E731
        speeds = rows[:, 4]
        metrics = {
            "outcome": {"none": "success"}.get(self.kind or "error", self.kind or "error"),
            "time": float(rows[-1, 0] - rows[0, 0]) if len(rows) else 0.0,
            "max_oob": float(oob.max()) if len(oob) else 0.0,
            "max_lateral_offset": float(np.abs(rows[:, 6]).max()) if len(rows) else 0.0,
            "oob_arc_length": arc(rows[-1, 7]) if self.kind == "out_of_lane" else None,
            "departure_arc_length": arc(rows[touched[0], 7]) if len(touched) else None,
            "distance_driven": float(np.hypot(*np.diff(rows[:, 1:3], axis=0).T).sum()) if len(rows) > 1 else 0.0,
            "max_speed": float(np.nanmax(speeds)) if len(speeds) and np.isfinite(speeds).any() else None,
            "road_length": float(lane.road_s[-1]),
            "oob_tolerance": self.cfg.oob_tolerance,
            "lane_width": lane.width,
            "samples": self.samples,
        }
        t_rel = rows[:, 0] - rows[0, 0] if len(rows) else rows[:, 0]
        timeline = {"t": t_rel, "x": rows[:, 1], "y": rows[:, 2], "yaw": rows[:, 3], "v": rows[:, 4], "oob": oob}
        return self._outcome({"vehicle_max_oob": metrics["max_oob"]}, metrics,
                             rows[:, 1:3].copy() if len(rows) else None, timeline)


def judge_car(t, x, y, yaw, road: np.ndarray, lane_width: float = 4.0, config: CarSimConfig | None = None,
              v=None) -> Outcome:
    """Judge a complete car trajectory: box centres and headings against the road's right lane."""
    judge = CarJudge(road, lane_width, config)
    if not judge.add(t, x, y, yaw, v):
        judge.finish(f"trajectory ends after {judge.elapsed:.1f} s without a verdict")
    return judge.outcome()


# --- thermostat ------------------------------------------------------------------------------------
class ThermostatJudge(_Judge):
    """RMSE of the room temperature against the schedule, each sample weighted by the time since the
    previous one and judged against the set point in effect just before it (for samples every
    ``dt`` exactly the simulator's mean over steps); decided once the schedule's end is covered."""

    def __init__(self, setpoints: Sequence[float], durations_min: Sequence[float],
                 config: RoomSimConfig | None = None):
        super().__init__()
        self.cfg = config or RoomSimConfig()
        self.setpoints = np.asarray(setpoints, dtype=float)
        self.ends = np.cumsum(np.asarray(durations_min, dtype=float) * 60.0)
        self.total = float(self.ends[-1]) if len(self.ends) else 0.0
        self._t0: float | None = None
        self._t_prev = 0.0
        self._t: list[np.ndarray] = []
        self._temp: list[np.ndarray] = []
        self._err: list[np.ndarray] = []
        self._w: list[np.ndarray] = []

    def goal_before(self, t_rel: np.ndarray) -> np.ndarray:
        """The set point in effect just before each time (seconds since the schedule started)."""
        idx = np.minimum(np.searchsorted(self.ends, np.asarray(t_rel, dtype=float) - EPS_T, side="right"),
                         len(self.ends) - 1)
        return self.setpoints[idx]

    def add(self, t, temperature) -> bool:
        if self.decided:
            return True
        t = np.atleast_1d(np.asarray(t, dtype=float))
        temp = np.atleast_1d(np.asarray(temperature, dtype=float))
        if not len(t):
            return False
        if self._t0 is None:
            self._t0 = float(t[0])
        rel = t - self._t0
        prev = np.concatenate([[self._t_prev], rel[:-1]])
        keep = (prev < self.total - EPS_T) | (rel <= 0)  # samples whose interval starts inside the schedule
        rel, prev, temp_k, t_k = rel[keep], prev[keep], temp[keep], t[keep]
        if len(rel):
            # a sample past the end counts only for the part of its interval inside the schedule
            weight = np.maximum(np.minimum(rel, self.total) - prev, 0.0)
            self._err.append(temp_k - self.goal_before(np.minimum(rel, self.total)))
            self._w.append(weight)  # sample 0 (rel = 0) weighs nothing: it is the start
            self._t.append(rel)
            self._temp.append(temp_k)
            self._t_prev = float(rel[-1])
            self.samples += len(rel)
            self.t_last = float(t_k[-1])
        if self._t_prev >= self.total - EPS_T:
            self._judge()
        return self.decided

    @property
    def elapsed(self) -> float:
        return self._t_prev

    def _judge(self) -> None:
        err, w = np.concatenate(self._err), np.concatenate(self._w)
        covered = w.sum()
        if covered <= 0:
            self.finish("no temperature samples inside the schedule")
            return
        rmse = float(math.sqrt(float((w * err * err).sum()) / covered))
        self.rmse = rmse
        failed = rmse > self.cfg.requirement_rmse
        worst = int(np.argmax(np.where(w > 0, np.abs(err), -1.0)))
        t_rel, temp = np.concatenate(self._t), np.concatenate(self._temp)
        self._worst = (float(t_rel[worst]), float(temp[worst]), float(abs(err[worst])))
        detail = (f"RMSE {rmse:.2f} degC {'>' if failed else '<='} {self.cfg.requirement_rmse:g} degC "
                  f"(worst {abs(err[worst]):.2f} degC at {t_rel[worst] / 3600:.2f} h)")
        point = (t_rel[worst] / 3600.0, float(temp[worst])) if failed else None
        self._decide("requirement" if failed else "none", detail, point)

    def outcome(self) -> Outcome:
        t = np.concatenate(self._t) if self._t else np.zeros(0)
        temp = np.concatenate(self._temp) if self._temp else np.zeros(0)
        err = np.concatenate(self._err) if self._err else np.zeros(0)
        w = np.concatenate(self._w) if self._w else np.zeros(0)
        band = self.cfg.band
        rmse = getattr(self, "rmse", None)
        metrics = {
            "outcome": {"none": "success"}.get(self.kind or "error", self.kind or "error"),
            "time": float(min(self._t_prev, self.total)),
            "rmse": rmse,
            "max_error": float(np.abs(err[w > 0]).max()) if (w > 0).any() else None,
            "above_band_min": float(w[err > band].sum() / 60.0),
            "below_band_min": float(w[err < -band].sum() / 60.0),
            "duration_min": self.total / 60.0,
            "samples": self.samples,
        }
        timeline = {"t": t, "temperature": temp, "setpoint": self.goal_before(t) if len(t) else t}
        return self._outcome({"thermostat_rmse": rmse if rmse is not None else 0.0}, metrics, None, timeline)


def judge_thermostat(t, temperature, setpoints: Sequence[float], durations_min: Sequence[float],
                     config: RoomSimConfig | None = None) -> Outcome:
    """Judge a complete temperature series (simulated seconds since the schedule started)."""
    judge = ThermostatJudge(setpoints, durations_min, config)
    if not judge.add(t, temperature):
        judge.finish(f"temperature series ends after {judge.elapsed:.0f} s of a {judge.total:.0f} s schedule")
    return judge.outcome()


def warm_up_judge(problem_name: str, config: Any) -> None:
    """Judge a tiny made-up run once, so that a judge's one-time costs are paid now.

    The robot judge's first ``add`` loads its compiled clearance kernel (0.5-1.7 s on a busy
    machine). A node that judges samples as they stream in (``sut_adapter``) calls this at
    start-up: paid in the middle of a run, that pause blocks its only thread while the SUT keeps
    sending, and a sample queue that overflows reads as a robot standing still.
    """
    if problem_name == "robot":
        RobotJudge(np.zeros((4, 4), dtype=bool), 1.0, (3.5, 3.5), config).add(
            np.array([0.0, 0.1]), np.array([0.5, 0.6]), np.array([0.5, 0.5]), np.zeros(2))
    elif problem_name == "vehicle":
        CarJudge(np.array([[0.0, 0.0], [50.0, 0.0]]), 4.0, config).add(
            np.array([0.0, 0.1]), np.array([0.0, 0.5]), np.array([-2.0, -2.0]), np.zeros(2), np.ones(2))
    else:
        ThermostatJudge([20.0], [1.0], config).add(np.array([0.0, 60.0]), np.array([20.0, 20.0]))


__all__ = ["CarJudge", "RobotJudge", "ThermostatJudge", "clearances", "judge_car", "judge_robot",
           "judge_thermostat", "warm_up_judge"]
