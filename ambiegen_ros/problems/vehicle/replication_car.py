"""Replication car: the replication code's discrete car on every road (numba kernel ``_repl_drive``
or all cars stepping together in numpy), and whether its path crosses itself."""
from __future__ import annotations

import math

import numpy as np

from .config import VehicleConfig
from .kernels import _DEG, _RAD, _engine, _heading_deg, _kernels, libm
from .road import _offsets
from .validity import _first_half


def _repl_params(cfg: VehicleConfig) -> np.ndarray:
    return np.array([cfg.v0, cfg.band, cfg.steer_gain, cfg.probe_deg, cfg.accel_per_step, cfg.decel_per_step,
                     cfg.straight_step_div, cfg.turn_step_div, cfg.max_steps], dtype=float)


def _repl_drive_numpy(NX, NY, offs, counts, x0, y0, prm, tot, n_tot, meas, dist, n_dist, maxd):
    """Same as ``_repl_drive_all`` with all cars stepping together (numpy)."""
    v0, band, gain, probe, acc, dec, div_s, div_t = (float(v) for v in prm[:8])
    max_steps = int(prm[8])
    P = len(counts)
    h = _first_half(counts)
    bounds = np.stack([np.stack([offs, offs + h], 1), np.stack([offs + h, offs + counts], 1)], 1)  # (P, part, a|b)
    S = int(max(1, (bounds[:, :, 1] - bounds[:, :, 0]).max() - 1))
    k = bounds[:, :, :1] + np.arange(S)[None, None, :]  # segment starts (P, 2, S)
    live = k + 1 < bounds[:, :, 1:]
    kk = np.where(live, k, 0)
    AX, AY, BX, BY = NX[kk], NY[kk], NX[np.where(live, kk + 1, 0)], NY[np.where(live, kk + 1, 0)]
    seg = np.sqrt((BX - AX) * (BX - AX) + (BY - AY) * (BY - AY))
    half_len = np.zeros((P, 2))
    for j in range(S):
        half_len = np.where(live[:, :, j], half_len + seg[:, :, j], half_len)

    def distance(ids, part, px, py):
        ax, ay, bx, by, ok = AX[ids, part], AY[ids, part], BX[ids, part], BY[ids, part], live[ids, part]
        px, py = px[:, None], py[:, None]
        same = (ax == bx) & (ay == by)
        len2 = (bx - ax) * (bx - ax) + (by - ay) * (by - ay)
        safe = np.where(same | ~ok, 1.0, len2)
        r = ((px - ax) * (bx - ax) + (py - ay) * (by - ay)) / safe
        s = ((ay - py) * (bx - ax) - (ax - px) * (by - ay)) / safe
        d_a = np.sqrt((px - ax) * (px - ax) + (py - ay) * (py - ay))
        d_b = np.sqrt((px - bx) * (px - bx) + (py - by) * (py - by))
        d = np.where(same | (r <= 0.0), d_a, np.where(r >= 1.0, d_b, np.abs(s) * np.sqrt(safe)))
        return np.where(ok, d, np.inf).min(axis=1)

    def heading(ax, ay, bx, by):
        vx, vy = bx - ax, by - ay
        angle = libm(math.acos, np.clip(vx / np.sqrt(vx * vx + vy * vy), -1.0, 1.0)) * _RAD
        return np.where(ay > by, -angle, angle)

    ids = np.arange(P)
    x, y = np.asarray(x0, dtype=float).copy(), np.asarray(y0, dtype=float).copy()
    angle = heading(NX[offs], NY[offs], NX[offs + 1], NY[offs + 1])
    speed = np.full(P, v0)
    part = np.zeros(P, dtype=np.int64)
    steps = np.zeros(P, dtype=np.int64)
    driven = np.zeros(P)
    px, py = x.copy(), y.copy()
    tot[:, 0, 0], tot[:, 0, 1] = x, y
    n_tot[:] = 1
    n_dist[:] = 0
    maxd[:] = -np.inf
    while len(ids):
        go = (driven < half_len[ids, part]) & (steps < max_steps)
        switch = ~go & (part == 0)
        if switch.any():  # restart at the second half's first node, along the road
            a = bounds[ids[switch], 1, 0]
            x[switch], y[switch] = NX[a], NY[a]
            angle[switch] = heading(NX[a - 1], NY[a - 1], NX[a], NY[a])
            part[switch] = 1
            driven[switch] = 0.0
            px[switch], py[switch] = x[switch], y[switch]
            go[switch] = steps[switch] < max_steps
        if not go.all():
            keep = go
            ids, x, y, angle, speed, part, steps, driven, px, py = (
                v[keep] for v in (ids, x, y, angle, speed, part, steps, driven, px, py))
            if not len(ids):
                break
        d = distance(ids, part, x, y)
        meas[ids, n_dist[ids], 0], meas[ids, n_dist[ids], 1] = x, y
        dist[ids, n_dist[ids]] = d
        n_dist[ids] += 1
        maxd[ids] = np.maximum(maxd[ids], d)
        near = d <= band
        with np.errstate(divide="ignore", invalid="ignore"):
            right, left = -probe + angle, probe + angle
            d_right = distance(ids, part, speed * libm(math.cos, right * _DEG) + x,
                               speed * libm(math.sin, right * _DEG) + y)
            d_left = distance(ids, part, speed * libm(math.cos, left * _DEG) + x,
                              speed * libm(math.sin, left * _DEG) + y)
            steer = libm(math.atan, 1 / speed * gain * d) * _RAD
        turned = np.where(d_right < d_left, -steer + angle, steer + angle)
        angle = np.where(near, angle, turned)
        div = np.where(near, div_s, div_t)
        x = speed * libm(math.cos, angle * _DEG) / div + x
        y = speed * libm(math.sin, angle * _DEG) / div + y
        speed = np.where(near, speed + acc, speed - dec)
        tot[ids, n_tot[ids], 0], tot[ids, n_tot[ids], 1] = x, y
        n_tot[ids] += 1
        driven = driven + np.sqrt((x - px) * (x - px) + (y - py) * (y - py))
        px, py = x, y
        steps += 1


def simulate_replication(nodes: np.ndarray, counts: np.ndarray, cfg: VehicleConfig, offsets=None,
                         record: bool = False, chunk: int = 256):
    """The replication car on every road (each from a fresh state; roads need >= 2 nodes per half).

    Returns max distance per road and whether the car's path is simple (F1 = max distance where
    it is, 0 where the path crosses itself); with ``record`` also per-road traces
    (measuring positions and distances, and the car's path).
    """
    import shapely  # imported where used: one road's evaluation should start fast

    counts = np.asarray(counts, dtype=np.int64)
    P = len(counts)
    offs = _offsets(counts)
    NX, NY = np.ascontiguousarray(nodes[:, 0]), np.ascontiguousarray(nodes[:, 1])
    x0, y0 = NX[offs].copy(), NY[offs].copy()
    if offsets is not None and P:
        lateral = np.broadcast_to(np.asarray(offsets, float), (P,))
        th = np.array([_heading_deg(NX[o], NY[o], NX[o + 1], NY[o + 1]) for o in offs]) * _DEG
        x0, y0 = x0 - np.sin(th) * lateral, y0 + np.cos(th) * lateral  # > 0: left of the road
    prm = _repl_params(cfg)
    numba = _engine(cfg) == "numba"
    drive_all = _kernels()["repl_drive_all"] if numba else _repl_drive_numpy
    K = cfg.max_steps
    maxd = np.zeros(P)
    simple = np.ones(P, bool)
    traces = []
    for c0 in range(0, P, chunk):
        c = slice(c0, min(P, c0 + chunk))
        C = c.stop - c.start
        tot, meas, dist = np.empty((C, K + 1, 2)), np.empty((C, K, 2)), np.empty((C, K))
        n_tot, n_dist = np.zeros(C, dtype=np.int64), np.zeros(C, dtype=np.int64)
        drive_all(NX, NY, offs[c], counts[c], x0[c], y0[c], prm, tot, n_tot, meas, dist, n_dist, maxd[c])
        path_used = np.arange(K + 1)[None, :] < n_tot[:, None]
        simple[c] = shapely.is_simple(shapely.linestrings(tot[path_used], indices=np.repeat(np.arange(C), n_tot)))
        if record:
            traces += [(meas[r, :n_dist[r]].copy(), dist[r, :n_dist[r]].copy(), tot[r, :n_tot[r]].copy())
                       for r in range(C)]
    return (maxd, simple, traces) if record else (maxd, simple)
