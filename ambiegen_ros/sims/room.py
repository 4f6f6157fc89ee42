"""Full-model thermostat: a physical room with a heater, a noisy quantised sensor and a controller.

* *Room* (``problems.thermostat_room``, issue 46): two thermal masses, the air with its contents
  and the envelope, losing heat to an ambient temperature; the 1.5 kW heater warms the air. The
  room and heater are the same in every room model; a model (the environmental condition) sets
  the ambient and the losses, fitted to the paper's seven pairs of ON / OFF curves. Integrated
  exactly over each ``dt`` with the heater constant over the step. Heating never lowers the
  temperature, at any later time, in any model.
* *Sensor*: the air temperature plus Gaussian noise (``sensor_noise``, from the run's seeded
  generator), rounded to ``sensor_resolution`` (0.1 degC).
* *Controller*, run every ``control_period`` seconds on the sensor reading:
  ``onoff`` - hysteresis (heater starts ON; OFF once reading >= goal + h, ON once reading <
  goal - h); ``pid`` - a PID on the error (goal - reading) whose output in [0, 1] is a duty cycle
  over ``pwm_period``, realised in whole control ticks; ``anti_windup``: ``clamp`` limits the
  integral term to the output range (it can still hold full output after a long saturation),
  ``conditional`` stops integrating while the output is saturated in the error's direction.
  ``ideal`` - the reference (``sims.reference.thermostat``): full power while the true
  temperature is below the goal, off at or above it, decided every ``dt``; no noise, no
  quantisation, no hysteresis (``ideal_config``: the on/off rule with those settings).

The room starts at rest: the air at the first goal, the envelope in balance with it.

Oracle: the RMSE between the true air temperature and the scheduled goal, sampled after every
``dt`` over the whole schedule, must not exceed ``requirement_rmse`` (1 degC, the paper's
requirement); above it the run fails with kind ``requirement``. Metrics: rmse, max error, time
above/below the goal band, heater duty, switch count.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any, Sequence

import numpy as np

from ..core.attributes import ScenarioError
from ..problems import thermostat_room as physics
from .outcome import Outcome

CONTROLLERS = ("onoff", "pid", "ideal")
ANTI_WINDUP = ("clamp", "conditional")


@dataclass(frozen=True)
class RoomSimConfig:
    """Every number of the full-model thermostat (defaults: the paper's requirement and hysteresis)."""

    dt: float = 10.0  # integration step [s]
    sensor_noise: float = 0.05  # standard deviation [degC]; 0 = exact
    sensor_resolution: float = 0.1  # quantisation [degC]; 0 = none
    controller: str = "onoff"  # onoff | pid | ideal (the reference controller)
    control_period: float = 60.0  # controller runs this often [s] (a multiple of dt)
    hysteresis: float = 0.1  # on/off band half-width [degC]
    kp: float = 1.0  # PID gains on degC error -> duty (a PI in the range SIMC tuning gives this room)
    ki: float = 0.0005  # [1/s]
    kd: float = 0.0  # [s]
    pwm_period: float = 180.0  # PID duty-cycle period [s]; the relay acts on control ticks
    anti_windup: str = "clamp"  # PID: clamp (integral term within the output range) | conditional
    requirement_rmse: float = 1.0  # [degC]
    reference_margin: float = 0.1  # a failure counts when the ideal controller passes by at least this [degC]
    band: float = 0.5  # metrics: time spent more than this above / below the goal [degC]
    run_invalid: bool = False  # also simulate schedules the problem calls invalid
    reference: bool = True  # check each scenario with the problem's reference; false = the old, unchecked verdicts

    def __post_init__(self):
        if self.controller not in CONTROLLERS:
            raise ScenarioError("option.controller", f"unknown controller {self.controller!r}", "|".join(CONTROLLERS))
        if self.anti_windup not in ANTI_WINDUP:
            raise ScenarioError("option.anti_windup", f"unknown {self.anti_windup!r}", "|".join(ANTI_WINDUP))
        for name in ("dt", "control_period", "pwm_period", "requirement_rmse"):
            if not getattr(self, name) > 0:
                raise ScenarioError(f"option.{name}", "must be > 0")
        for name in ("sensor_noise", "sensor_resolution", "hysteresis", "band", "kp", "ki", "kd", "reference_margin"):
            if getattr(self, name) < 0:
                raise ScenarioError(f"option.{name}", "must be >= 0")
        ratio = self.control_period / self.dt
        if abs(ratio - round(ratio)) > 1e-9:
            raise ScenarioError("option.control_period", "must be a multiple of dt", f"k * {self.dt:g} s")
        if not isinstance(self.reference, bool):
            raise ScenarioError("option.reference", f"expected true or false, got {self.reference!r}", "true|false")
        if self.reference_margin >= self.requirement_rmse:
            raise ScenarioError("option.reference_margin", "must be below requirement_rmse", f"< {self.requirement_rmse:g}")

    def controller_args(self) -> tuple:
        """The controller as ``thermostat_room.run_rows`` takes it (the ideal one as on/off settings)."""
        cfg = ideal_config(self) if self.controller == "ideal" else self
        kind = physics.PID if cfg.controller == "pid" else physics.ONOFF
        every = int(round(cfg.control_period / cfg.dt))
        windup = physics.CONDITIONAL if cfg.anti_windup == "conditional" else physics.CLAMP
        return (kind, every, cfg.hysteresis, cfg.kp, cfg.ki, cfg.kd, int(round(cfg.pwm_period / cfg.dt)), windup,
                cfg.control_period)


def ideal_config(config: RoomSimConfig) -> RoomSimConfig:
    """The ideal controller as settings of the on/off rule: with no hysteresis it is ON while the
    temperature is below the goal and OFF at or above it; reading the true temperature every ``dt``."""
    return replace(config, controller="onoff", hysteresis=0.0, sensor_noise=0.0, sensor_resolution=0.0,
                   control_period=config.dt)


def room_of(problem: Any) -> tuple[tuple, tuple]:
    """The physical room a thermostat problem's config describes: (construction, conditions)."""
    return problem.config.room_construction, problem.config.room_conditions


def heat(setpoints: Sequence[float], durations_min: Sequence[float], models: Sequence[int],
         room: tuple[Sequence[float], Sequence[Sequence[float]]], config: RoomSimConfig | None = None, seed: int = 0,
         initial_temperature: float | None = None) -> dict[str, Any]:
    """Run one schedule (goal, minutes, 1-based room model per element) in ``room`` (construction,
    conditions: ``room_of(problem)``); returns the record."""
    cfg = config or RoomSimConfig()
    if cfg.controller == "ideal":
        cfg = ideal_config(cfg)
    construction, conditions = physics.check_room(*room)
    rng = np.random.default_rng(seed)
    dt = cfg.dt
    steps = np.rint(np.asarray(durations_min, dtype=float) * 60.0 / dt).astype(np.int64)
    n = int(steps.sum())
    times = dt * np.arange(n + 1)
    ends = np.cumsum(np.asarray(durations_min, dtype=float) * 60.0)
    total = float(ends[-1]) if len(ends) else 0.0
    element = np.minimum(np.searchsorted(ends, times, side="right"), max(len(ends) - 1, 0))
    goal_at = np.asarray(setpoints, dtype=float)[element] if len(ends) else np.zeros(n + 1)
    noise = rng.normal(0.0, cfg.sensor_noise, n + 1) if cfg.sensor_noise > 0 else np.zeros(n + 1)
    models0 = np.asarray(models, dtype=np.int64) - 1
    T = float(setpoints[0] if initial_temperature is None else initial_temperature)
    envelope = physics.envelope_at_rest(construction, conditions[models0[0]], T) if len(models0) else T
    state = physics.new_state(1, np.array([T]), np.array([envelope]))
    rec = (np.empty((1, max(n, 2))), np.empty((1, max(n, 2))), np.empty((1, max(n, 2))))
    elements = np.zeros((1, max(len(steps), 2)))
    physics.run_rows(state, steps[None, :], np.asarray(setpoints, dtype=float)[None, :], models0[None, :],
                     physics.step_tables(construction, conditions, float(dt)), cfg.controller_args(),
                     noise=noise[None, :n] if n > 1 else noise[None, :1], q=cfg.sensor_resolution, record=rec,
                     elements=elements, compiled=physics.compiled_loaded())
    st = state[0]
    temp = np.concatenate([[T], rec[0][0, :n]])
    meas = np.concatenate([rec[1][0, :n], [st[physics.READING]]]) if n else np.array([T])
    heater = np.concatenate([rec[2][0, :n], [st[physics.ON]]]) if n else np.array([1.0])
    err = temp[1:] - goal_at[:-1]  # sample k (k >= 1): after step k, against that step's goal
    rmse = math.sqrt(st[physics.SUMSQ] / n) if n else 0.0
    worst = int(st[physics.WORST]) if n else 0
    return {
        "rmse": float(rmse),
        "max_error": float(st[physics.MAXABS]) if n else 0.0,
        "above_band_min": float((err > cfg.band).sum() * dt / 60.0),
        "below_band_min": float((err < -cfg.band).sum() * dt / 60.0),
        "heater_duty": float(st[physics.HEATED] / n) if n else 0.0,
        "switches": int(st[physics.SWITCHES]),
        "duration_min": total / 60.0,
        "worst_time_s": float(times[worst + 1]) if n else 0.0,
        "worst_temperature": float(temp[worst + 1]) if n else T,
        "element_sumsq": elements[0, :len(steps)],
        "timeline": {"t": times, "temperature": temp, "measured": meas, "setpoint": goal_at, "heater": heater},
    }


def schedule_of(problem: Any, scenario: Any) -> tuple[list[float], list[float], list[int]]:
    """(setpoints, durations in minutes, room models) of the schedule the surrogate scores (in the
    replication profile, elements past the 24th hour are not part of the day)."""
    G, lengths = problem.codec.split(problem.codec.to_row(scenario))
    m = int(problem.scored_lengths(G, lengths)[0])
    return ([float(v) for v in G[0, :m, 0]], [float(v) for v in G[0, :m, 1]], [int(round(v)) for v in G[0, :m, 2]])


def simulate(problem: Any, scenario: Any, config: RoomSimConfig | None = None, seed: int = 0) -> Outcome:
    """Execute one day schedule on the full-model room and judge it against the RMSE requirement.

    A failure is placed where the thermostat loses most to the ideal controller (the element with
    the largest excess of squared error, and in it the moment of the largest excess error): the
    largest error itself mostly sits on a set-point jump that no controller follows."""
    cfg = config or RoomSimConfig()
    setpoints, durations, models = schedule_of(problem, scenario)
    run = heat(setpoints, durations, models, room_of(problem), cfg, seed=seed)
    failed = run["rmse"] > cfg.requirement_rmse
    outcome = "requirement" if failed else "success"
    metrics = {k: run[k] for k in ("rmse", "max_error", "above_band_min", "below_band_min", "heater_duty",
                                   "switches", "duration_min")}
    metrics = {"outcome": outcome, "time": run["duration_min"] * 60.0, **metrics,
               "controller": cfg.controller, "seed": int(seed)}
    detail = f"RMSE {run['rmse']:.2f} degC {'>' if failed else '<='} {cfg.requirement_rmse:g} degC"
    point = None
    if failed:
        point, where = _worst_excess(setpoints, durations, models, room_of(problem), cfg, run)
        detail += f" ({where})"
    else:
        detail += f" (worst {run['max_error']:.2f} degC at {run['worst_time_s'] / 3600:.2f} h)"
    return Outcome(
        objectives={"thermostat_rmse": run["rmse"]},
        failed=failed,
        failure_kind="requirement" if failed else "none",
        detail=detail,
        metrics=metrics,
        trajectory=None,
        timeline=run["timeline"],
        failure_point=point,
    )


def _worst_excess(setpoints, durations, models, room: tuple, cfg: RoomSimConfig, run: dict) -> tuple[tuple, str]:
    """(failure point (hour, temperature), words) where the thermostat loses most to the ideal controller."""
    ideal = heat(setpoints, durations, models, room, ideal_config(cfg))
    dur = np.asarray(durations, dtype=float)
    j = int(physics.worst_excess(run["element_sumsq"][None, :], ideal["element_sumsq"][None, :], dur[None, :])[0][0])
    tl, ti = run["timeline"], ideal["timeline"]
    start, end = float(dur[:j].sum() * 60.0), float(dur[:j + 1].sum() * 60.0)
    inside = np.flatnonzero((tl["t"] > start) & (tl["t"] <= end + 1e-9))
    goal = tl["setpoint"][inside - 1]
    excess = np.abs(tl["temperature"][inside] - goal) - np.abs(ti["temperature"][inside] - goal)
    k = int(inside[np.argmax(excess)]) if len(inside) else 0
    steps = max(len(inside), 1)
    rms = lambda e: math.sqrt(float(e) / steps)  # noqa: E731
    words = (f"the ideal controller {ideal['rmse']:.2f} degC; the thermostat loses most in "
             f"{start / 3600:.1f}-{end / 3600:.1f} h, goal {setpoints[j]:g} degC in room model {models[j]}: "
             f"RMSE {rms(run['element_sumsq'][j]):.2f} against {rms(ideal['element_sumsq'][j]):.2f} degC")
    return (float(tl["t"][k]) / 3600.0, float(tl["temperature"][k])), words


class SteppedRoom:
    """``heat`` advanced one ``dt`` at a time, the set point and room model read at each step (so
    they can change live); the same loop, noise stream and integration."""

    def __init__(self, config: RoomSimConfig, room: tuple, initial_temperature: float, seed: int = 0):
        self.cfg = ideal_config(config) if config.controller == "ideal" else config
        self.construction, self.conditions = physics.check_room(*room)
        self.tables = physics.step_tables(self.construction, self.conditions, float(self.cfg.dt))
        self.controller = self.cfg.controller_args()
        self.rng = np.random.default_rng(seed)
        self.state: np.ndarray | None = None
        self.T = float(initial_temperature)
        self._noise = np.zeros((1, 1))

    @property
    def t(self) -> float:
        return self.k * self.cfg.dt

    @property
    def k(self) -> int:
        return 0 if self.state is None else int(self.state[0, physics.STEP])

    def step(self, goal: float, model: int) -> float:
        """Sense and decide at t_k with ``goal`` and ``model`` in effect, integrate to t_k+1."""
        m = int(model) - 1
        if self.state is None:  # at rest in the first model in effect
            env = physics.envelope_at_rest(self.construction, self.conditions[m], self.T)
            self.state = physics.new_state(1, np.array([self.T]), np.array([env]))
        self._noise[0, 0] = self.rng.normal(0.0, self.cfg.sensor_noise) if self.cfg.sensor_noise > 0 else 0.0
        physics.run_rows(self.state, np.ones((1, 1), dtype=np.int64), np.array([[float(goal)]]),
                         np.array([[m]], dtype=np.int64), self.tables, self.controller, noise=self._noise,
                         q=self.cfg.sensor_resolution, compiled=physics.compiled_loaded())
        self.T = float(self.state[0, physics.TA])
        return self.T


__all__ = ["RoomSimConfig", "SteppedRoom", "heat", "ideal_config", "room_of", "schedule_of", "simulate"]
