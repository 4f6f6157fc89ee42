"""Refined road geometry: the spine by affine transforms and the not-a-knot spline through it, for a
whole batch at once (sections 1-2 of the package notes); the replication road reuses both."""
from __future__ import annotations

import math

import numpy as np

from .config import ANGLE, LEFT, LENGTH, RIGHT, TYPE, VehicleConfig
from .kernels import _engine, _kernels


def heading_changes(G: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Turn direction (+1 left = counter-clockwise, -1 right, 0 straight) and heading change [rad]
    of every element."""
    types = np.rint(G[:, :, TYPE]).astype(int)
    turn = np.where(types == LEFT, 1.0, np.where(types == RIGHT, -1.0, 0.0))
    return turn, turn * np.radians(G[:, :, ANGLE])


def element_points(G: np.ndarray, cfg: VehicleConfig, spacing: float | None = None,
                   heading0: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Spine points of every element of every row: ``(P, m, S, 2)`` and their mask.

    An element of length L (straight) or arc length R * angle (turn) gets ceil(L / spacing)
    equally spaced points after its start, the last one at its end; S is the most any element has
    (``spacing`` = inf: one point per element, at its end). Vectorised affine transforms: each
    element's start pose is the cumulative effect of the previous ones (headings by a cumulative
    sum, positions by summing end displacements). ``heading0`` (P,) overrides the start heading.
    """
    P, m = G.shape[:2]
    spacing = cfg.spine_spacing if spacing is None else spacing
    turn, dtheta = heading_changes(G)
    is_turn = turn != 0
    R = cfg.turn_radius
    seg_len = np.where(is_turn, R * np.abs(dtheta), G[:, :, LENGTH])
    n = np.maximum(1, np.ceil(seg_len / spacing - 1e-9)).astype(int)
    n_sub = int(n.max()) if n.size else 1
    h0 = math.radians(cfg.start_heading_deg) if heading0 is None else np.asarray(heading0, dtype=float)[:, None]
    heading = h0 + np.cumsum(dtheta, axis=1) - dtheta  # at element start

    j = np.arange(1, n_sub + 1)
    mask = j[None, None, :] <= n[:, :, None]
    frac = np.minimum(j[None, None, :], n[:, :, None]) / n[:, :, None]  # (P, m, S), 1 at the end

    def displacement(f):
        h = heading[..., None]
        phi = h + f * dtheta[..., None]
        s = (R * turn)[..., None]
        dx_turn = s * (np.sin(phi) - np.sin(h))
        dy_turn = s * (np.cos(h) - np.cos(phi))
        L = (f * G[:, :, LENGTH][..., None])
        dx = np.where(is_turn[..., None], dx_turn, L * np.cos(h))
        dy = np.where(is_turn[..., None], dy_turn, L * np.sin(h))
        return np.stack([dx, dy], axis=-1)

    end = displacement(np.ones((P, m, 1)))[:, :, 0, :]  # (P, m, 2)
    origin = np.asarray(cfg.start, dtype=float) + np.cumsum(end, axis=1) - end  # element start positions
    if n_sub == 1 and np.all(frac == 1.0):  # one point per element: its end (the same numbers)
        return (origin + end)[:, :, None, :], mask
    pts = origin[:, :, None, :] + displacement(frac)
    return pts, mask


def build_spines(G: np.ndarray, lengths: np.ndarray, cfg: VehicleConfig) -> tuple[np.ndarray, np.ndarray]:
    """Flat spine points ``(sum N, 2)`` of a batch and the count ``N`` per road."""
    G = np.asarray(G, dtype=float)
    P, m = G.shape[:2]
    pts, mask = element_points(G, cfg)
    mask &= (np.arange(m)[None, :] < np.asarray(lengths)[:, None])[:, :, None]
    pts = pts.reshape(P, -1, 2)
    mask = mask.reshape(P, -1)
    start = np.broadcast_to(np.asarray(cfg.start, dtype=float), (P, 1, 2))
    pts = np.concatenate([start, pts], axis=1)
    mask = np.concatenate([np.ones((P, 1), bool), mask], axis=1)
    return pts[mask], mask.sum(axis=1)


# --- 2. interpolation ------------------------------------------------------------------------------
def _offsets(counts: np.ndarray) -> np.ndarray:
    return np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int64)


def _pad(flat: np.ndarray, counts: np.ndarray, fill: float = 0.0) -> np.ndarray:
    """Flat ragged rows -> padded ``(P, max count, ...)`` array."""
    P, N = len(counts), int(counts.max()) if len(counts) else 0
    out = np.full((P, N) + flat.shape[1:], fill, dtype=float)
    out[np.arange(N)[None, :] < counts[:, None]] = flat
    return out


def spline_coefficients(spine: np.ndarray, counts: np.ndarray, cfg: VehicleConfig | None = None):
    """Not-a-knot cubic spline through each spine, for the whole batch at once.

    Parameter: normalised chord length (as splprep). Second derivatives M come from one padded
    tridiagonal (Thomas) sweep vectorised across roads (the not-a-knot end conditions are
    substituted into the first and last rows); 2 points give a line and 3 a parabola (splprep's
    k = 1, 2). Returns knots ``X (P, N)``, per-interval polynomial coefficients
    ``(P, N-1, 8)`` = (y, b, c, d) for x and y with ``S = y + b s + c s^2 + d s^3``, s = u - X_i,
    and the spine polyline length per road. With ``cfg`` on the numba engine, one road after
    another (the same operations in the same order, so the same bits; entries past a road's
    length are left 0).
    """
    counts = np.asarray(counts, dtype=np.int64)
    P = len(counts)
    Y = _pad(spine, counts)  # (P, N, 2)
    N = Y.shape[1]
    valid_h = np.arange(N - 1)[None, :] < (counts - 1)[:, None]
    chord = np.where(valid_h, np.hypot(*np.moveaxis(np.diff(Y, axis=1), -1, 0)), 0.0)
    # a running sum, not chord.sum(axis=1): numpy's pairwise sum regroups with the padded width, so
    # a road's length (and F1) would change in the last bits with the longest road of its batch
    total = np.cumsum(chord, axis=1)[:, -1] if chord.shape[1] else np.zeros(P)
    if cfg is not None and _engine(cfg) == "numba":
        X, coef = np.zeros((P, N)), np.zeros((P, max(N - 1, 0), 8))
        _kernels()["spline_coef"](np.ascontiguousarray(spine, dtype=float), counts, _offsets(counts), total, X, coef)
        return X, coef, total
    h = np.where(valid_h, chord / np.where(total > 0, total, 1.0)[:, None], 1.0)  # padding: harmless 1
    X = np.concatenate([np.zeros((P, 1)), np.cumsum(np.where(valid_h, h, 0.0), axis=1)], axis=1)
    X[np.arange(P), counts - 1] = 1.0
    delta = np.diff(Y, axis=1) / h[:, :, None]  # divided differences (P, N-1, 2)

    M = np.zeros((P, N, 2))
    rows = np.arange(P)
    cubic = counts >= 4
    if N >= 4 and cubic.any():
        # unknowns M_1..M_{N-2}; rows past a road's own M_{n-2} become identity rows with rhs 0
        live = (np.arange(1, N - 1)[None, :] <= (counts - 2)[:, None]) & cubic[:, None]
        a = h[:, :-1].copy()  # coefficient of M_{i-1}: h_{i-1}
        c = h[:, 1:].copy()  # coefficient of M_{i+1}: h_i
        b = 2.0 * (a + c)
        r = 6.0 * (delta[:, 1:] - delta[:, :-1])
        h0, h1 = h[:, 0], h[:, 1]
        # not-a-knot at x_1: M_0 = ((h0 + h1) M_1 - h0 M_2) / h1, substituted into the row of M_1
        b[:, 0] = (h0 + h1) * (h0 + 2.0 * h1) / h1
        c[:, 0] = (h1 * h1 - h0 * h0) / h1
        a[:, 0] = 0.0
        # not-a-knot at x_{n-2}: M_{n-1} = ((A + B) M_{n-2} - B M_{n-3}) / A, A = h_{n-3}, B = h_{n-2}
        last = np.clip(counts - 3, 0, N - 3)  # row of M_{n-2}
        A_, B_ = h[rows, np.clip(counts - 3, 0, N - 2)], h[rows, np.clip(counts - 2, 0, N - 2)]
        a[rows, last] = (A_ * A_ - B_ * B_) / A_
        b[rows, last] = (A_ + B_) * (2.0 * A_ + B_) / A_
        c[rows, last] = 0.0
        a = np.where(live, a, 0.0)
        b = np.where(live, b, 1.0)
        c = np.where(live, c, 0.0)
        r = np.where(live[:, :, None], r, 0.0)
        n_unk = N - 2
        cp = np.empty_like(c)
        rp = np.empty_like(r)
        cp[:, 0] = c[:, 0] / b[:, 0]
        rp[:, 0] = r[:, 0] / b[:, 0, None]
        for i in range(1, n_unk):
            den = b[:, i] - a[:, i] * cp[:, i - 1]
            cp[:, i] = c[:, i] / den
            rp[:, i] = (r[:, i] - a[:, i, None] * rp[:, i - 1]) / den[:, None]
        sol = np.empty_like(r)
        sol[:, -1] = rp[:, -1]
        for i in range(n_unk - 2, -1, -1):
            sol[:, i] = rp[:, i] - cp[:, i, None] * sol[:, i + 1]
        M[:, 1:-1] = np.where(live[:, :, None], sol, 0.0)
        M0 = ((h0 + h1)[:, None] * M[:, 1] - h0[:, None] * M[:, 2]) / h1[:, None]
        Mn2, Mn3 = M[rows, np.clip(counts - 2, 0, N - 1)], M[rows, np.clip(counts - 3, 0, N - 1)]
        Mn1 = ((A_ + B_)[:, None] * Mn2 - B_[:, None] * Mn3) / A_[:, None]
        M[cubic, 0] = M0[cubic]
        M[rows[cubic], counts[cubic] - 1] = Mn1[cubic]
    parabola = counts == 3
    if parabola.any():
        curv = 2.0 * (delta[parabola, 1] - delta[parabola, 0]) / (h[parabola, 0] + h[parabola, 1])[:, None]
        M[parabola, :3] = curv[:, None, :]
    M0, M1, hb = M[:, :-1], M[:, 1:], h[:, :, None]
    coef = np.concatenate([Y[:, :-1], delta - hb * (2.0 * M0 + M1) / 6.0, M0 / 2.0, (M1 - M0) / (6.0 * hb)], axis=2)
    return X, np.ascontiguousarray(coef), total


def _spline_numpy(X, coef, counts, n_nodes, t):
    """Evaluate every road's spline at its parameters ``t`` (flat, ``n_nodes`` per road; numpy).

    A parameter past the last knot extrapolates the last piece (as ``splev``)."""
    P, N = X.shape
    road, _ = _local_index(n_nodes)
    # interval = number of inner knots x_1..x_{n-2} at or below t (searched road by road: exact,
    # and independent of the other roads of the batch)
    seg = np.empty(len(t), dtype=np.int64)
    for r, q0 in enumerate(_offsets(n_nodes)):
        q = slice(q0, q0 + n_nodes[r])
        seg[q] = np.searchsorted(X[r, 1: max(counts[r] - 1, 1)], t[q], side="right")
    cf = coef.reshape(P * (N - 1), 8)[road * (N - 1) + seg]
    s = (t - X.reshape(-1)[road * N + seg])[:, None]
    return cf[:, 0:2] + s * (cf[:, 2:4] + s * (cf[:, 4:6] + s * cf[:, 6:8]))


def spline_at(X, coef, counts, n_nodes, t, cfg: VehicleConfig) -> np.ndarray:
    """Points ``(sum n_nodes, 2)`` of the splines of ``spline_coefficients`` at the flat parameters ``t``."""
    if _engine(cfg) == "numba":
        out = np.empty((len(t), 2))
        _kernels()["spline"](X, coef, np.asarray(counts, dtype=np.int64), np.asarray(n_nodes, dtype=np.int64), t, out)
        return out
    return _spline_numpy(X, coef, counts, n_nodes, t)


def _local_index(n_nodes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Road of every flat node and the node's index within its road."""
    road = np.repeat(np.arange(len(n_nodes)), n_nodes)
    return road, np.arange(int(n_nodes.sum())) - np.repeat(_offsets(n_nodes), n_nodes)


def interpolate(spine: np.ndarray, counts: np.ndarray, cfg: VehicleConfig) -> tuple[np.ndarray, np.ndarray]:
    """Interpolated centre lines of a batch: flat nodes ``(sum M, 2)`` and ``M`` per road.

    The curve of ``splprep(s=0, k=min(3, n-1))`` through the spine (see ``spline_coefficients``),
    sampled at ``M = max(interp_min_nodes, floor(spine length / interp_step) + 1)`` equally
    spaced parameter values (about one node per metre).
    """
    counts = np.asarray(counts, dtype=np.int64)
    X, coef, total = spline_coefficients(spine, counts, cfg)
    n_nodes = np.maximum(cfg.interp_min_nodes, np.floor(total / cfg.interp_step + 1e-9).astype(np.int64) + 1)
    road, local = _local_index(n_nodes)
    return spline_at(X, coef, counts, n_nodes, local / (n_nodes[road] - 1.0), cfg), n_nodes


def interpolate_splprep(spine: np.ndarray, cfg: VehicleConfig) -> np.ndarray:
    """Reference: one road through scipy's splprep/splev (slow; used by tests)."""
    from scipy.interpolate import splev, splprep

    spine = np.asarray(spine, dtype=float)
    total = float(np.hypot(*np.diff(spine, axis=0).T).sum())
    n_nodes = max(cfg.interp_min_nodes, int(math.floor(total / cfg.interp_step + 1e-9)) + 1)
    tck, _ = splprep([spine[:, 0], spine[:, 1]], s=0, k=min(3, len(spine) - 1))
    x, y = splev(np.linspace(0.0, 1.0, n_nodes), tck)
    return np.column_stack([x, y])
