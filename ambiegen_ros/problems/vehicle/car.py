"""Refined surrogate car (paper eqs. 10-13) on the interpolated road: numpy (all cars stepping
together) or the numba kernel ``_drive`` (one car after another)."""
from __future__ import annotations

import math

import numpy as np

from .config import VehicleConfig
from .kernels import _engine, _kernels, libm
from .road import _offsets


def _segments(nodes: np.ndarray, counts: np.ndarray):
    """Flat segment arrays (start x, y, direction x, y, 1/|dir|^2) and per-road offsets/counts."""
    counts = np.asarray(counts, dtype=int)
    P = len(counts)
    road = np.repeat(np.arange(P), counts)
    keep = road[1:] == road[:-1]
    a = nodes[:-1][keep]
    d = np.diff(nodes, axis=0)[keep]
    l2 = (d * d).sum(axis=1)
    il2 = np.where(l2 > 0, 1.0 / np.where(l2 > 0, l2, 1.0), 0.0)
    nseg = counts - 1
    return (
        np.ascontiguousarray(a[:, 0]),
        np.ascontiguousarray(a[:, 1]),
        np.ascontiguousarray(d[:, 0]),
        np.ascontiguousarray(d[:, 1]),
        il2,
        _offsets(nseg),
        nseg,
    )


def _car_params(cfg: VehicleConfig) -> np.ndarray:
    return np.array([cfg.v0, cfg.k, cfg.alpha_v, cfg.beta_v, cfg.band, cfg.v_min, cfg.dt], dtype=float)


def _start_states(nodes, counts, lengths, cfg, offsets):
    offs = _offsets(counts)
    p0, p1 = nodes[offs], nodes[offs + 1]
    th = np.arctan2(p1[:, 1] - p0[:, 1], p1[:, 0] - p0[:, 0])
    lateral = np.zeros(len(counts)) if offsets is None else np.broadcast_to(np.asarray(offsets, float), (len(counts),))
    x = p0[:, 0] - np.sin(th) * lateral  # left normal of heading th is (-sin, cos)
    y = p0[:, 1] + np.cos(th) * lateral
    limit = np.ceil(cfg.time_factor * lengths / cfg.v0 / cfg.dt - 1e-9).astype(np.int64)
    return x, y, th, limit


def _window_search(x, y, j, soff, nseg, W, seg):
    """Nearest point of each car's road in a window of segments around ``j``.

    Returns the best segment, the signed distance d (> 0 left) and whether the car is past the
    road's end (nearest point = end of the last segment). While the best segment is on the
    window's edge and the road continues beyond it, that car's window slides and is searched again.
    """
    AX, AY, DX, DY, IL2 = seg
    n = len(x)
    best = j.copy()
    d = np.zeros(n)
    past = np.zeros(n, bool)
    todo = np.arange(n)
    while len(todo):
        jj, so, ns = best[todo], soff[todo], nseg[todo]
        k = np.clip(jj[:, None] + W[None, :], 0, (ns - 1)[:, None])
        g = so[:, None] + k
        dx, dy = DX[g], DY[g]
        rx, ry = x[todo, None] - AX[g], y[todo, None] - AY[g]
        t = np.clip((rx * dx + ry * dy) * IL2[g], 0.0, 1.0)
        ex, ey = rx - t * dx, ry - t * dy
        dist2 = ex * ex + ey * ey
        am = np.argmin(dist2, axis=1)
        rows = np.arange(len(todo))
        jn = k[rows, am]
        dist = np.sqrt(dist2[rows, am])
        cross = dx[rows, am] * ry[rows, am] - dy[rows, am] * rx[rows, am]
        best[todo] = jn
        d[todo] = np.where(cross > 0, dist, -dist)
        past[todo] = (jn == ns - 1) & (t[rows, am] >= 1.0)
        slide = ((am == len(W) - 1) & (jn < ns - 1)) | ((am == 0) & (jn > 0))
        todo = todo[slide]
    return best, d, past


def simulate_numpy(nodes, counts, lengths, cfg: VehicleConfig, offsets=None, record: bool = False):
    """All cars step together (numpy); returns max |d| per road (and per-road traces if ``record``).

    Each step: d from the windowed nearest-point search, then an Euler step of paper eqs. 10-13.
    A car stops once past the road's last point or at its time limit; finished cars are dropped
    from the arrays so the remaining ones step faster.
    """
    counts = np.asarray(counts, dtype=int)
    P = len(counts)
    seg = _segments(nodes, counts)
    soff, nseg = seg[5], seg[6]
    x, y, th, limit = _start_states(nodes, counts, np.asarray(lengths, float), cfg, offsets)
    v = np.full(P, cfg.v0)
    j = np.zeros(P, dtype=np.int64)
    step = np.zeros(P, dtype=np.int64)
    ids = np.arange(P)
    maxd = np.zeros(P)
    result = np.zeros(P)
    W = np.arange(-cfg.window_back, cfg.window_ahead + 1)
    trace: list[list] = [[] for _ in range(P)] if record else []
    while len(ids):
        j, d, past = _window_search(x, y, j, soff, nseg, W, seg[:5])
        maxd = np.where(past, maxd, np.maximum(maxd, np.abs(d)))  # past the end: d is longitudinal
        if record:
            for r, i in enumerate(ids):
                if not past[r]:
                    trace[i].append((x[r], y[r], d[r]))
        done = past | (step >= limit)
        rate = libm(math.atan2, cfg.k, v)
        dth = np.where(d < -cfg.band, rate, np.where(d > cfg.band, -rate, 0.0))
        dv = np.where(np.abs(d) > cfg.band, -cfg.alpha_v, cfg.beta_v)
        x = x + v * libm(math.cos, th) * cfg.dt
        y = y + v * libm(math.sin, th) * cfg.dt
        th = th + dth * cfg.dt
        v = np.maximum(v + dv * cfg.dt, cfg.v_min)
        step = step + 1
        if done.any():
            result[ids[done]] = maxd[done]
            keep = ~done
            ids, x, y, th, v, j, step, maxd = (a[keep] for a in (ids, x, y, th, v, j, step, maxd))
            soff, nseg, limit = soff[keep], nseg[keep], limit[keep]
    if record:
        return result, [np.array(tr, dtype=float).reshape(-1, 3) for tr in trace]
    return result


def simulate_numba(nodes, counts, lengths, cfg: VehicleConfig, offsets=None, record: bool = False):
    """Same results as ``simulate_numpy`` (compiled loop per car); raises if numba is missing."""
    kernels = _kernels()
    if not kernels:
        raise ImportError("numba is not installed; use engine='numpy'")
    drive, drive_all = kernels["drive"], kernels["drive_all"]
    counts = np.asarray(counts, dtype=int)
    AX, AY, DX, DY, IL2, soff, nseg = _segments(nodes, counts)
    x, y, th, limit = _start_states(nodes, counts, np.asarray(lengths, float), cfg, offsets)
    prm = _car_params(cfg)
    soff, nseg = soff.astype(np.int64), nseg.astype(np.int64)
    if not record:
        return drive_all(AX, AY, DX, DY, IL2, soff, nseg, x, y, th, limit, prm, cfg.window_back, cfg.window_ahead)
    result = np.zeros(len(counts))
    traces = []
    for i in range(len(counts)):
        buf = np.empty((int(limit[i]) + 1, 3))
        result[i], n = drive(AX, AY, DX, DY, IL2, soff[i], nseg[i], x[i], y[i], th[i], limit[i], prm,
                             cfg.window_back, cfg.window_ahead, buf)
        traces.append(buf[:n].copy())
    return result, traces


def simulate(nodes, counts, lengths, cfg: VehicleConfig, offsets=None, record: bool = False):
    """Surrogate car on every road: max |d| per road (plus (x, y, d) traces if ``record``)."""
    fn = simulate_numba if _engine(cfg) == "numba" else simulate_numpy
    return fn(nodes, counts, lengths, cfg, offsets=offsets, record=record)
