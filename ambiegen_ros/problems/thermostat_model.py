"""The thermostat's surrogate: the room models, the on/off controller and its simulation.

Split from ``problems.thermostat`` (the case study) so that each reads on its own. Simulation
(all numbers in ``ThermostatConfig``), for steps s = 0, 1, ... of ``step_minutes``:

* the goal and room model of step s are those of the element in effect at minute ``s * step``;
* the room starts at the first goal with the heater ON;
* the curve restarts at every element boundary and at every heater switch: ``T0`` is the
  temperature then and ``n = 1, 2, ...`` counts the steps since; ON ``T = k_on1 (1 - exp(-k_on2 n))
  + T0``, OFF ``T = k_off1 exp(-k_off2 n) + T0 - k_off1``, with the element's room model;
* before each step the controller compares the temperature with the step's goal: ON switches OFF
  once ``T >= goal + hysteresis``, OFF switches ON once ``T < goal - hysteresis``.

Every path (scalar loop for a few schedules, vectorised loop for a batch, the numba loop) reads
the curve values from one precomputed table (``curve_table``) and adds ``T0``, so an F1 value
does not depend on the batch it was computed in (bit for bit), which campaigns need to reproduce
a seed.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from functools import lru_cache
from typing import Any

import numpy as np

from ..core.attributes import IntRange, ScenarioError
from ..core.problem import check_profile
from .thermostat_room import (CLAMP, CONDITIONAL, MAXABS, ONOFF, PID, ROOM_CONDITIONS, ROOM_CONSTRUCTION, SUMSQ, WORST,
                              check_room, envelope_at_rest, new_state, run_rows, step_tables)

# (k_on1, k_on2, k_off1, k_off2) per room model 1..7 (the paper prints three; the rest come from
# the replication data, see the project spec).
ROOM_MODELS: tuple[tuple[float, float, float, float], ...] = (
    (7.7, 0.11887928, 5.6, 0.02929884),
    (7.0, 0.13425024, 3.8, 0.07661568),
    (7.9, 0.11180434, 5.2, 0.04803319),
    (6.0, 0.14704908, 4.8, 0.12038760),
    (8.3, 0.09551135, 4.5, 0.10103580),
    (7.2, 0.11189481, 5.6, 0.04109810),
    (5.7, 0.07745100, 4.8, 0.05723616),
)

TEMP, DUR, MODEL = 0, 1, 2  # attribute columns of G

TEMPERATURE = IntRange("temperature", 16, 25, 1, tolerance=0, unit="degC")
ROOM_MODEL = IntRange("model", 1, 7, 1, tolerance=0)
DURATION = IntRange("duration", 60, 240, 15, tolerance=15, unit="min")  # the paper; sampled in both profiles
# the replication code merges a short remainder of the day into the last element (up to 240 + 45)
# and its mutation draws 60..285: the durations its search can produce
REPLICATION_DURATION = IntRange("duration", 60, 285, 15, tolerance=15, unit="min")


OBJECTIVES = ("rmse", "reference_relative", "certified")


@dataclass(frozen=True)
class ThermostatConfig:
    """Every tunable number of the thermostat case study (defaults: paper / replication code)."""

    profile: str = "replication"  # replication | refined (see the module notes)
    alpha: float | None = None  # MO constraint: "risky" when F1 > alpha; None: 1.5 (rmse), 0.3 (reference_relative)
    requirement_rmse: float = 1.0  # the system requirement (a failure when RMSE exceeds it)
    step_minutes: float = 3.0  # simulation time step
    horizon_minutes: float = 1440.0  # R1: a schedule lasts at most 24 h
    hysteresis: float = 0.1  # on/off band half-width [degC]
    max_jump: float = 5.0  # refined: adjacent |temp(e_i) - temp(e_i+1)| < max_jump; replication: range <= max_jump
    sampling: str = "markov"  # "markov" | "uniform" (temperatures of the initial population)
    p_stay: float = 0.3  # Markov chain: P(keep raising / lowering)
    markov_max_step: int | None = None  # next temperature within t..t+k (raise) / t-k..t; None: 5 replication, 4 refined
    room_models: tuple = ROOM_MODELS  # (k_on1, k_on2, k_off1, k_off2) for models 1..7
    engine: str = "auto"  # "auto": the compiled loop when numba imports, else numpy | "numpy"
    objective: str = "rmse"  # F1: "rmse" (the paper) | "reference_relative" (RMSE minus an ideal controller's)
    reference_step_minutes: float = 0.5  # the ideal controller decides this often (a divisor of step_minutes)
    # objective "certified" only (issue 26): the full model's room, controller period and sampling
    control_seconds: float = 60.0  # the thermostat decides this often (sims.room's control_period)
    sample_seconds: float = 10.0  # integration / error-sampling step; the ideal decides every step (sims.room's dt)
    room_construction: tuple = ROOM_CONSTRUCTION  # the full model's room: heater W, C_air J/K, C_envelope J/K, H_air_envelope W/K
    room_conditions: tuple = ROOM_CONDITIONS  # per room model: ambient degC, H_air_out W/K, H_envelope_out W/K
    controller: str = "onoff"  # certified: the system under test as sims.room runs it: onoff | pid
    kp: float = 1.0  # certified, pid: sims.room's gains, duty-cycle period and anti-windup
    ki: float = 0.0005
    kd: float = 0.0
    pwm_seconds: float = 180.0
    anti_windup: str = "clamp"
    sensor_resolution: float = 0.1  # certified: the thermostat's sensor steps [degC] (sims.room's)
    sensor_noise: float = 0.05  # certified: its noise [degC]; the surrogate reads sims.room's noise stream of seed 0
    certified_cap: float | None = None  # F1 stops rising this far above the requirement [degC]; None: no cap
    reference_margin: float = 0.1  # certified: the ideal controller must pass by this much (sims.room's reference_margin)

    def __post_init__(self):
        check_profile(self.profile)
        # YAML / JSON give lists; keep the config hashable and the table well-formed.
        table = tuple(tuple(float(v) for v in row) for row in self.room_models)
        if not table or any(len(row) != 4 for row in table):
            raise ScenarioError("config.room_models", "each row needs 4 numbers", "(k_on1, k_on2, k_off1, k_off2)")
        object.__setattr__(self, "room_models", table)
        if self.alpha is None:  # relative: about the 99th percentile of sampled valid days (0.28 degC)
            alpha = {"rmse": 1.5, "reference_relative": 0.3, "certified": self.requirement_rmse}
            object.__setattr__(self, "alpha", alpha.get(self.objective, 1.5))
        if self.markov_max_step is None:
            object.__setattr__(self, "markov_max_step", 5 if self.profile == "replication" else 4)
        if self.engine not in ("auto", "numpy"):
            raise ScenarioError("config.engine", f"unknown engine {self.engine!r}", "auto|numpy")
        if self.objective not in OBJECTIVES:
            raise ScenarioError("config.objective", f"unknown objective {self.objective!r}", "|".join(OBJECTIVES))
        if self.sampling not in ("markov", "uniform"):
            raise ScenarioError("config.sampling", f"unknown sampling {self.sampling!r}", "markov|uniform")
        if not self.step_minutes > 0:
            raise ScenarioError("config.step_minutes", "must be positive")
        ratio = self.step_minutes / self.reference_step_minutes if self.reference_step_minutes > 0 else 0.0
        if self.objective == "reference_relative" and (ratio < 1 or abs(ratio - round(ratio)) > 1e-9):
            raise ScenarioError("config.reference_step_minutes", "must divide step_minutes",
                                f"{self.step_minutes:g} / k for k = 1, 2, ...")
        try:
            cons, conds = check_room(self.room_construction, self.room_conditions)
        except ValueError as exc:
            field, _, why = str(exc).partition(": ")
            raise ScenarioError(f"config.{field}", why) from None
        object.__setattr__(self, "room_construction", cons)
        object.__setattr__(self, "room_conditions", conds)
        if self.controller not in ("onoff", "pid"):
            raise ScenarioError("config.controller", f"unknown controller {self.controller!r}", "onoff|pid")
        if self.anti_windup not in ("clamp", "conditional"):
            raise ScenarioError("config.anti_windup", f"unknown {self.anti_windup!r}", "clamp|conditional")
        every = self.control_seconds / self.sample_seconds if self.sample_seconds > 0 else 0.0
        if self.objective == "certified" and (every < 1 or abs(every - round(every)) > 1e-9):
            raise ScenarioError("config.control_seconds", "must be a multiple of sample_seconds (both > 0)",
                                f"k * {self.sample_seconds:g} s for k = 1, 2, ...")
        if not 0.0 <= self.reference_margin < self.requirement_rmse:
            raise ScenarioError("config.reference_margin", "must be >= 0 and below requirement_rmse")
        for name in ("sensor_resolution", "sensor_noise"):
            if getattr(self, name) < 0:
                raise ScenarioError(f"config.{name}", "must be >= 0")
        if self.certified_cap is not None and not self.certified_cap > 0:
            raise ScenarioError("config.certified_cap", "must be > 0 (or null: no cap)")
        if not 0.0 <= self.p_stay <= 1.0:
            raise ScenarioError("config.p_stay", "must be a probability", "0..1")

    @property
    def replication(self) -> bool:
        return self.profile == "replication"


def ideal_config(config: ThermostatConfig) -> ThermostatConfig:
    """The surrogate's ideal controller: the same room curves with no hysteresis (ON while T < goal,
    OFF at or above it; the surrogate has no sensor noise or quantisation to remove), deciding every
    ``reference_step_minutes``. The curves' rates are per step, so a step k times finer divides
    them by k: the same curves in time. On the 3-minute step itself it would not be ideal: each
    switch restarts a curve at its steepest, and with no hysteresis it overshoots the goal by up to
    0.9 degC a step (it followed 77 % of sampled days worse than the hysteresis controller).
    """
    k = int(round(config.step_minutes / config.reference_step_minutes))
    models = tuple((on1, on2 / k, off1, off2 / k) for on1, on2, off1, off2 in config.room_models)
    return replace(config, hysteresis=0.0, step_minutes=config.step_minutes / k, room_models=models,
                   objective="rmse")


SCALAR_BATCH = 16  # up to this many valid schedules, evaluate() uses the scalar simulator


# --- simulation --------------------------------------------------------------------------------
@lru_cache(maxsize=8)
def curve_table(room_models: tuple, n_max: int) -> tuple[np.ndarray, np.ndarray]:
    """Curve values ``T = (A[r, n] + T0) - B[r]`` for row ``r = 2 * (model - 1) + on``, n = 0..n_max.

    ON: ``A = k_on1 (1 - exp(-k_on2 n))``, ``B = 0``; OFF: ``A = k_off1 exp(-k_off2 n)``,
    ``B = k_off1`` (the formulas in the replication code's order of operations). One table for
    every path makes results independent of how scenarios were batched.
    """
    k = np.asarray(room_models, dtype=float)
    n = np.arange(n_max + 1, dtype=float)
    A = np.empty((2 * len(k), n_max + 1))
    A[0::2] = k[:, 2:3] * np.exp(-k[:, 3:4] * n)  # OFF (on = 0)
    A[1::2] = k[:, 0:1] * (1.0 - np.exp(-k[:, 1:2] * n))  # ON (on = 1)
    B = np.zeros(2 * len(k))
    B[0::2] = k[:, 2]
    A.setflags(write=False)
    B.setflags(write=False)
    return A, B


def simulate_schedule(goals_per_step, models_per_step, config: ThermostatConfig | None = None,
                      starts=None, return_heater: bool = False):
    """Plain-Python simulator of one schedule (the reference the vectorised one is tested against).

    ``goals_per_step[s]`` / ``models_per_step[s]`` (1-based model ids) hold during step s and
    ``starts[s]`` says that step s begins an element (default: wherever goal or model changes).
    Returns ``(temperatures after each step, errors)`` and, if asked, the heater state per step;
    ``errors`` are the samples F1 is computed from (lagged in the replication profile).
    """
    config = config or ThermostatConfig()
    h = config.hysteresis
    goals = [float(g) for g in goals_per_step]
    models = [int(m) for m in models_per_step]
    if starts is None:
        starts = [s == 0 or goals[s] != goals[s - 1] or models[s] != models[s - 1] for s in range(len(goals))]
    A, B = curve_table(config.room_models, max(len(goals), 1))
    A_rows, B_rows = A.tolist(), B.tolist()
    reset, lag = config.replication, config.replication
    temps: list[float] = []
    errors: list[float] = []
    heater: list[bool] = []
    T = goals[0] if goals else 0.0
    on, T0, n = True, T, 0
    for goal, model, start in zip(goals, models, starts):
        if start:  # the curve restarts at every element
            T0, n = T, 0
            if reset:
                on = True
        if on and T >= goal + h:
            on, T0, n = False, T, 0
        elif not on and T < goal - h:
            on, T0, n = True, T, 0
        before = T - goal
        n += 1
        r = 2 * (model - 1) + int(on)
        T = (A_rows[r][n] + T0) - B_rows[r]
        temps.append(T)
        errors.append(before if lag else T - goal)
        heater.append(on)
    out = (np.array(temps), np.array(errors))
    return (*out, np.array(heater, dtype=bool)) if return_heater else out


@dataclass
class BatchRun:
    """Result of ``simulate_batch``: per-row RMSE, max |error|, step count (traces if recorded)."""

    rmse: np.ndarray
    max_error: np.ndarray
    n_steps: np.ndarray
    temperature: np.ndarray | None = None  # (P, S) after each step, if recorded
    heater: np.ndarray | None = None  # (P, S) heater ON during each step, if recorded
    goal: np.ndarray | None = None  # (P, S) goal during each step, if recorded
    model: np.ndarray | None = None  # (P, S) room model during each step, if recorded


def _element_steps(G: np.ndarray, lengths: np.ndarray, step: float) -> tuple[np.ndarray, np.ndarray]:
    """First step of each element and its number of steps: step s runs from minute ``s * step``."""
    m_max = G.shape[1]
    used = np.arange(m_max)[None, :] < lengths[:, None]
    dur = np.where(used, G[:, :, DUR], 0.0)
    ends = np.cumsum(dur, axis=1)
    first = np.ceil((ends - dur) / step - 1e-9)
    count = np.maximum(np.ceil(ends / step - 1e-9) - first, 0.0)
    return first.astype(np.int64), count.astype(np.int64)


def simulate_batch(
    G: np.ndarray, lengths: np.ndarray, config: ThermostatConfig | None = None, record: bool = False
) -> BatchRun:
    """Vectorised simulator of a batch of (domain-valid) schedules ``(G, lengths)``.

    One Python iteration per time step, numpy over the individuals; nothing of size (P, S) is
    built unless ``record``. Goals and room models change only at element boundaries, so they are
    applied as sparse "events" (a few rows per step) instead of per-step arrays; the curve comes
    from ``curve_table`` by flat index ``row * (S + 1) + n``.
    """
    config = config or ThermostatConfig()
    G = np.asarray(G, dtype=float)
    lengths = np.asarray(lengths, dtype=int)
    P, m_max = G.shape[0], G.shape[1]
    h = float(config.hysteresis)
    first, count = _element_steps(G, lengths, float(config.step_minutes))
    n_steps = count.sum(axis=1)
    S = int(n_steps.max(initial=0))
    A, B = curve_table(config.room_models, max(S, 1))
    A_flat, width = A.ravel(), A.shape[1]
    reset, lag = config.replication, config.replication

    # events: element (p, j) takes effect at step first[p, j]; a row's end snapshots its errors
    p_idx, j_idx = np.nonzero(count > 0)
    ev_step = first[p_idx, j_idx]
    order = np.argsort(ev_step, kind="stable")
    p_idx, j_idx, ev_step = p_idx[order], j_idx[order], ev_step[order]
    ev_goal = G[p_idx, j_idx, TEMP]
    ev_base = 2 * (G[p_idx, j_idx, MODEL].astype(np.int64) - 1)  # table row of the model's OFF curve
    ev_bounds = np.searchsorted(ev_step, np.arange(S + 1))
    end_rows = np.argsort(n_steps, kind="stable")
    end_bounds = np.searchsorted(n_steps[end_rows], np.arange(S + 1))

    goal, up, lo = np.zeros(P), np.zeros(P), np.zeros(P)
    base = np.zeros(P, dtype=np.int64)
    T = G[:, 0, TEMP].copy() if m_max else np.zeros(P)  # start at the first goal, heater ON
    T0 = T.copy()
    on = np.ones(P, dtype=bool)
    n = np.zeros(P, dtype=np.int64)
    sw, tmp = np.empty(P, dtype=bool), np.empty(P, dtype=bool)
    d, rowB = np.empty(P), np.empty(P)
    idx = np.empty(P, dtype=np.int64)
    sumsq, maxabs = np.zeros(P), np.zeros(P)
    final_sumsq, final_maxabs = np.zeros(P), np.zeros(P)
    if record:
        rec_T, rec_on = np.empty((S, P)), np.empty((S, P), dtype=bool)
        rec_goal, rec_model = np.empty((S, P)), np.empty((S, P))

    for s in range(S):
        a, b = ev_bounds[s], ev_bounds[s + 1]
        if a < b:  # elements starting now: new goal and model; the curve restarts
            rows = p_idx[a:b]
            g = ev_goal[a:b]
            goal[rows], up[rows], lo[rows], base[rows] = g, g + h, g - h, ev_base[a:b]
            T0[rows], n[rows] = T[rows], 0
            if reset:
                on[rows] = True
        a, b = end_bounds[s], end_bounds[s + 1]
        if a < b:  # rows whose schedule ended before this step
            rows = end_rows[a:b]
            final_sumsq[rows], final_maxabs[rows] = sumsq[rows], maxabs[rows]
        # switch: ON -> OFF once T >= goal + h, OFF -> ON once T < goal - h; restart the curve
        np.greater_equal(T, up, out=sw)
        sw &= on
        np.less(T, lo, out=tmp)
        np.greater(tmp, on, out=tmp)  # (T < lo) and not on
        sw |= tmp
        on ^= sw
        np.copyto(T0, T, where=sw)
        np.logical_not(sw, out=tmp)
        np.multiply(n, tmp, out=n)
        if lag:
            np.subtract(T, goal, out=d)
        n += 1
        # T = (A[row, n] + T0) - B[row], row = base + on
        np.add(base, on, out=idx)
        np.take(B, idx, out=rowB)
        idx *= width
        idx += n
        np.take(A_flat, idx, out=T)
        T += T0
        T -= rowB
        if not lag:
            np.subtract(T, goal, out=d)
        np.abs(d, out=d)
        np.maximum(maxabs, d, out=maxabs)
        d *= d
        sumsq += d
        if record:
            rec_T[s], rec_on[s], rec_goal[s], rec_model[s] = T, on, goal, base // 2 + 1

    ended = n_steps < S
    sumsq[ended], maxabs[ended] = final_sumsq[ended], final_maxabs[ended]
    rmse = np.sqrt(sumsq / np.maximum(n_steps, 1))
    run = BatchRun(rmse=rmse, max_error=maxabs, n_steps=n_steps)
    if record:
        run.temperature, run.heater = rec_T.T.copy(), rec_on.T.copy()
        run.goal, run.model = rec_goal.T.copy(), rec_model.T.astype(np.int64)
    return run


def _simulate_rows(first, count, goal, base, T_init, A_flat, width, B, h, reset, lag, sumsq, maxabs):
    """Every schedule of a batch, one after another (compiled by numba when available): the same
    floating-point operations in the same order as ``simulate_schedule`` and ``simulate_batch``."""
    for p in range(first.shape[0]):
        T = T_init[p]
        on = True
        T0 = T
        n = 0
        acc = 0.0
        top = 0.0
        for j in range(first.shape[1]):
            if count[p, j] == 0:
                continue
            g = goal[p, j]
            up = g + h
            lo = g - h
            T0 = T
            n = 0
            if reset:
                on = True
            for _ in range(count[p, j]):
                if on and T >= up:
                    on = False
                    T0 = T
                    n = 0
                elif (not on) and T < lo:
                    on = True
                    T0 = T
                    n = 0
                e = T - g
                n += 1
                r = base[p, j] + (1 if on else 0)
                T = (A_flat[r * width + n] + T0) - B[r]
                if not lag:
                    e = T - g
                e = abs(e)
                if e > top:
                    top = e
                acc += e * e
        sumsq[p] = acc
        maxabs[p] = top


_ROWS_KERNEL: Any = None  # compiled ``_simulate_rows``, or False without numba


def simulate_rows(G: np.ndarray, lengths: np.ndarray, config: ThermostatConfig) -> tuple[np.ndarray, np.ndarray] | None:
    """RMSE and max |error| of a batch with the compiled per-schedule loop; None without numba."""
    global _ROWS_KERNEL
    if _ROWS_KERNEL is None:
        from ..core.accel import jit

        _ROWS_KERNEL = jit(_simulate_rows) or False
    if not _ROWS_KERNEL:
        return None
    G = np.asarray(G, dtype=float)
    lengths = np.asarray(lengths, dtype=int)
    first, count = _element_steps(G, lengths, float(config.step_minutes))
    n_steps = count.sum(axis=1)
    A, B = curve_table(config.room_models, max(int(n_steps.max(initial=0)), 1))
    P = len(G)
    sumsq, maxabs = np.zeros(P), np.zeros(P)
    base = np.where(count > 0, 2 * (G[:, :, MODEL].astype(np.int64) - 1), 0)
    _ROWS_KERNEL(first, count, np.ascontiguousarray(G[:, :, TEMP]), base, G[:, 0, TEMP].copy(), A.ravel(),
                 A.shape[1], B, float(config.hysteresis), config.replication, config.replication, sumsq, maxabs)
    return np.sqrt(sumsq / np.maximum(n_steps, 1)), maxabs


@lru_cache(maxsize=4)
def seed0_noise(sigma: float, steps: int) -> np.ndarray | None:
    """The sensor noise ``sims.room.heat`` draws for noise seed 0 (its first ``steps`` values), as
    one row every schedule reads: the surrogate is then the full model run with seed 0."""
    if sigma <= 0 or steps <= 0:
        return None
    noise = np.random.default_rng(0).normal(0.0, sigma, steps + 1)[None, :steps]
    noise.setflags(write=False)
    return noise


def simulate_room(G: np.ndarray, lengths: np.ndarray, config: ThermostatConfig, ideal: bool = False,
                  engine: str | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """RMSE, max |error|, the hour of the largest error and each element's sum of squared errors of each
    schedule on the full model's room (``sims.room.heat``: the same physical room, loop, controller,
    sensor and sampling, with the noise of seed 0): the ``certified`` objective's surrogate, so
    that its F1 ranks schedules as the full model and its reference do. ``ideal``: the reference
    controller (no hysteresis, deciding every sample step). Elements must last whole sample steps
    (durations are multiples of 15 min)."""
    G = np.asarray(G, dtype=float)
    lengths = np.asarray(lengths, dtype=int)
    dt = float(config.sample_seconds)
    used = np.arange(G.shape[1])[None, :] < lengths[:, None]
    count = np.where(used, np.rint(G[:, :, DUR] * 60.0 / dt), 0).astype(np.int64)
    model = np.where(used, G[:, :, MODEL] - 1, 0).astype(np.int64)
    cons, conds = config.room_construction, config.room_conditions
    air = G[:, 0, TEMP].copy()
    env = np.array([envelope_at_rest(cons, conds[m], a) for m, a in zip(model[:, 0].tolist(), air.tolist())])
    state = new_state(len(G), air, env)
    if ideal:
        controller = (ONOFF, 1, 0.0, 0.0, 0.0, 0.0, 1, CLAMP, dt)
    else:
        kind = PID if config.controller == "pid" else ONOFF
        controller = (kind, int(round(config.control_seconds / dt)), float(config.hysteresis), config.kp, config.ki,
                      config.kd, int(round(config.pwm_seconds / dt)),
                      CONDITIONAL if config.anti_windup == "conditional" else CLAMP, float(config.control_seconds))
    noise = None if ideal else seed0_noise(float(config.sensor_noise), int(count.sum(axis=1).max(initial=0)))
    elements = np.zeros((len(G), max(G.shape[1], 2)))
    run_rows(state, count, np.ascontiguousarray(G[:, :, TEMP]), model, step_tables(cons, conds, dt), controller,
             noise=noise, q=0.0 if ideal else float(config.sensor_resolution), elements=elements,
             compiled=(engine or config.engine) != "numpy")
    return (np.sqrt(state[:, SUMSQ] / np.maximum(count.sum(axis=1), 1)), state[:, MAXABS],
            (state[:, WORST] + 1) * dt / 3600.0, elements[:, :G.shape[1]])


def schedule_steps(
    setpoints, durations, models, config: ThermostatConfig | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-element schedule -> per-step goals, models and element starts (one schedule).

    Step s belongs to the element whose interval ``[start, end)`` holds minute ``s * step``.
    """
    config = config or ThermostatConfig()
    step = float(config.step_minutes)
    goals: list[float] = []
    room: list[int] = []
    starts: list[bool] = []
    start = 0.0
    for temp, dur, model in zip(setpoints, durations, models):
        end = start + float(dur)
        s = len(goals)
        first = True
        while s * step < end - 1e-9:
            goals.append(float(temp))
            room.append(int(model))
            starts.append(first)
            first = False
            s += 1
        start = end
    return np.array(goals), np.array(room, dtype=np.int64), np.array(starts, dtype=bool)


def compiled_loaded() -> bool:
    """Whether the numba loop is compiled already (then even one schedule uses it)."""
    return bool(_ROWS_KERNEL)
