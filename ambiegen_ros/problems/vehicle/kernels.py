"""The per-road loops as plain Python, compiled by numba on first use (``_kernels``), and the engine
choice. Each kernel does the same operations in the same order as its numpy twin, so the same bits."""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from .config import VehicleConfig

_DEG = math.pi / 180.0  # as math.radians / math.degrees compute them
_RAD = 180.0 / math.pi

_UFUNCS: dict = {}  # (math function, arity) -> numpy ufunc calling it


def libm(fn, *arrays) -> np.ndarray:
    """``fn`` (a ``math`` function) element by element: the C library's result, the one the numba
    kernels get (their ``math.cos`` is LLVM's ``llvm.cos`` = the C library's ``cos``).

    The numpy twins of the kernels call this, not ``np.cos`` & co: on AVX-512 CPUs numpy runs float64
    sin, cos, arccos, arctan, arctan2 through Intel SVML (numpy 2.4's binary carries ``__svml_cos8``
    etc. for its X86_V4 targets), which differs from the C library in the last bit for some
    arguments (numpy issue 23523), and a car that steers from those bits drives another path (issue 18). Slower than
    ``np.cos``; the numpy engine is only the fallback when numba is missing.
    """
    key = (fn, len(arrays))
    if key not in _UFUNCS:
        def call(*args, _fn=fn):
            try:
                return _fn(*args)
            except ValueError:  # math.cos(inf) raises; C's cos returns nan
                return math.nan
        _UFUNCS[key] = np.frompyfunc(call, len(arrays), 1)
    return np.asarray(_UFUNCS[key](*arrays), dtype=float)


def _spline_coef_kernel(spine, counts, offs, total, X, coef):
    """``spline_coefficients`` one road after another (compiled by numba): the same operations in
    the same order as the padded numpy sweep, so the same bits."""
    for r in range(len(counts)):
        n = counts[r]
        o = offs[r]
        if n < 2:
            continue
        h = np.empty(n - 1)
        delta = np.empty((n - 1, 2))
        tot = total[r] if total[r] > 0 else 1.0
        X[r, 0] = 0.0
        for i in range(n - 1):
            h[i] = math.hypot(spine[o + i + 1, 0] - spine[o + i, 0], spine[o + i + 1, 1] - spine[o + i, 1]) / tot
            X[r, i + 1] = X[r, i] + h[i]
        X[r, n - 1] = 1.0
        for i in range(n - 1):
            for dim in range(2):
                delta[i, dim] = (spine[o + i + 1, dim] - spine[o + i, dim]) / h[i]
        M = np.zeros((n, 2))
        if n >= 4:
            m = n - 2  # unknowns M_1..M_{n-2}
            a = np.empty(m)
            b = np.empty(m)
            c = np.empty(m)
            rhs = np.empty((m, 2))
            for i in range(m):
                a[i] = h[i]
                c[i] = h[i + 1]
                b[i] = 2.0 * (a[i] + c[i])
                for dim in range(2):
                    rhs[i, dim] = 6.0 * (delta[i + 1, dim] - delta[i, dim])
            h0, h1 = h[0], h[1]
            b[0] = (h0 + h1) * (h0 + 2.0 * h1) / h1
            c[0] = (h1 * h1 - h0 * h0) / h1
            a[0] = 0.0
            A_, B_ = h[n - 3], h[n - 2]
            a[m - 1] = (A_ * A_ - B_ * B_) / A_
            b[m - 1] = (A_ + B_) * (2.0 * A_ + B_) / A_
            c[m - 1] = 0.0
            cp = np.empty(m)
            rp = np.empty((m, 2))
            cp[0] = c[0] / b[0]
            for dim in range(2):
                rp[0, dim] = rhs[0, dim] / b[0]
            for i in range(1, m):
                den = b[i] - a[i] * cp[i - 1]
                cp[i] = c[i] / den
                for dim in range(2):
                    rp[i, dim] = (rhs[i, dim] - a[i] * rp[i - 1, dim]) / den
            for dim in range(2):
                M[m, dim] = rp[m - 1, dim]
            for i in range(m - 2, -1, -1):
                for dim in range(2):
                    M[i + 1, dim] = rp[i, dim] - cp[i] * M[i + 2, dim]
            for dim in range(2):
                M[0, dim] = ((h0 + h1) * M[1, dim] - h0 * M[2, dim]) / h1
                M[n - 1, dim] = ((A_ + B_) * M[n - 2, dim] - B_ * M[n - 3, dim]) / A_
        elif n == 3:
            for dim in range(2):
                curv = 2.0 * (delta[1, dim] - delta[0, dim]) / (h[0] + h[1])
                M[0, dim] = curv
                M[1, dim] = curv
                M[2, dim] = curv
        for i in range(n - 1):
            for dim in range(2):
                coef[r, i, dim] = spine[o + i, dim]
                coef[r, i, 2 + dim] = delta[i, dim] - h[i] * (2.0 * M[i, dim] + M[i + 1, dim]) / 6.0
                coef[r, i, 4 + dim] = M[i, dim] / 2.0
                coef[r, i, 6 + dim] = (M[i + 1, dim] - M[i, dim]) / (6.0 * h[i])


def _spline_kernel(X, coef, counts, n_nodes, t, out):
    """Same as ``_spline_numpy``, one road after another (compiled by numba)."""
    q0 = 0
    for r in range(len(counts)):
        seg = 0
        for q in range(q0, q0 + n_nodes[r]):
            while seg < counts[r] - 2 and X[r, seg + 1] <= t[q]:
                seg += 1
            s = t[q] - X[r, seg]
            for dim in range(2):
                out[q, dim] = coef[r, seg, dim] + s * (
                    coef[r, seg, 2 + dim] + s * (coef[r, seg, 4 + dim] + s * coef[r, seg, 6 + dim])
                )
        q0 += n_nodes[r]


def _metrics_kernel(nodes, counts, lo, hi, length, outside, min_radius):
    """Same as ``_metrics_numpy``, one road after another (compiled by numba)."""
    i0 = 0
    for r in range(len(counts)):
        n = counts[r]
        total = 0.0
        out = False
        rmin = np.inf
        for i in range(i0, i0 + n):
            x, y = nodes[i, 0], nodes[i, 1]
            if x < lo or x > hi or y < lo or y > hi:
                out = True
            if i > i0:
                total += math.hypot(x - nodes[i - 1, 0], y - nodes[i - 1, 1])
            if i + 4 < i0 + n:
                px, py = x, y
                qx, qy = nodes[i + 2, 0], nodes[i + 2, 1]
                sx, sy = nodes[i + 4, 0], nodes[i + 4, 1]
                cross = abs((qx - px) * (sy - py) - (qy - py) * (sx - px))
                if cross > 0:
                    a = math.hypot(qx - px, qy - py)
                    b = math.hypot(sx - qx, sy - qy)
                    c = math.hypot(sx - px, sy - py)
                    rad = a * b * c / (2.0 * cross)
                    if rad < rmin:
                        rmin = rad
        length[r] = total
        outside[r] = out
        min_radius[r] = rmin
        i0 += n


def _drive(AX, AY, DX, DY, IL2, so, ns, x, y, th, limit, prm, wb, wa, out):
    """One car, step by step (compiled by numba); same model and search as ``simulate_numpy``.

    ``prm`` = (v0, k, alpha_v, beta_v, band, v_min, dt); writes (x, y, d) rows into ``out`` when
    it has room; returns (max |d|, number of steps recorded).
    """
    v0, k, alpha_v, beta_v, band, v_min, dt = prm[0], prm[1], prm[2], prm[3], prm[4], prm[5], prm[6]
    v = v0
    j = 0
    maxd = 0.0
    step = 0
    while True:
        while True:  # windowed nearest segment, sliding while the best is on the window's edge
            lo = j - wb
            hi = j + wa
            lo_c = lo if lo > 0 else 0
            hi_c = hi if hi < ns - 1 else ns - 1
            best = -1
            bd2 = 0.0
            bt = 0.0
            bcross = 0.0
            for kk in range(lo_c, hi_c + 1):
                g = so + kk
                rx = x - AX[g]
                ry = y - AY[g]
                t = (rx * DX[g] + ry * DY[g]) * IL2[g]
                if t < 0.0:
                    t = 0.0
                elif t > 1.0:
                    t = 1.0
                ex = rx - t * DX[g]
                ey = ry - t * DY[g]
                d2 = ex * ex + ey * ey
                if best < 0 or d2 < bd2:
                    best = kk
                    bd2 = d2
                    bt = t
                    bcross = DX[g] * ry - DY[g] * rx
            j = best
            if (best == hi and best < ns - 1) or (best == lo and best > 0):
                continue
            break
        if j == ns - 1 and bt >= 1.0:  # past the last road point (d would be longitudinal)
            return maxd, step
        dist = math.sqrt(bd2)
        d = dist if bcross > 0 else -dist
        if dist > maxd:
            maxd = dist
        if step < out.shape[0]:
            out[step, 0] = x
            out[step, 1] = y
            out[step, 2] = d
        if step >= limit:
            return maxd, step + 1
        rate = math.atan2(k, v)
        if d < -band:
            dth = rate
        elif d > band:
            dth = -rate
        else:
            dth = 0.0
        dv = -alpha_v if abs(d) > band else beta_v
        x = x + v * math.cos(th) * dt
        y = y + v * math.sin(th) * dt
        th = th + dth * dt
        v = v + dv * dt
        if v < v_min:
            v = v_min
        step += 1


def _drive_all(AX, AY, DX, DY, IL2, soff, nseg, x, y, th, limit, prm, wb, wa):
    """Every car of a batch (compiled by numba; calls the compiled ``_drive``)."""
    out = np.empty(len(x))
    empty = np.empty((0, 3))
    for i in range(len(x)):
        out[i] = _drive_jit(AX, AY, DX, DY, IL2, soff[i], nseg[i], x[i], y[i], th[i], limit[i], prm, wb, wa, empty)[0]
    return out


_drive_jit: Any = None  # numba-compiled ``_drive``, referenced by ``_drive_all``; set by ``_kernels``
_distance_jit: Any = None  # compiled ``_geos_distance`` / ``_heading_deg`` / ``_repl_drive`` (same)
_heading_jit: Any = None
_repl_drive_jit: Any = None
_KERNELS: Any = None  # dict of compiled kernels, or False when numba is unavailable


def _kernels():
    """Compile the per-road loops on first use (cached on disk by numba); False when numba does not load.

    ``core.accel`` imports numba (a broken install falls back with one warning, like any import error).
    """
    global _KERNELS, _drive_jit, _distance_jit, _heading_jit, _repl_drive_jit
    if _KERNELS is None:
        from ...core.accel import numba_module

        numba = numba_module()
        if not numba:
            _KERNELS = False
        else:
            jit = numba.njit(cache=True)
            exact = numba.njit(cache=True, error_model="numpy")  # IEEE results, no Python exceptions
            _drive_jit = jit(_drive)
            _distance_jit = exact(_geos_distance)
            _heading_jit = exact(_heading_deg)
            _repl_drive_jit = exact(_repl_drive)
            _KERNELS = {
                "drive": _drive_jit,
                "drive_all": jit(_drive_all),
                "spline": jit(_spline_kernel),
                "spline_coef": exact(_spline_coef_kernel),
                "metrics": jit(_metrics_kernel),
                "lengths": exact(_polyline_lengths_kernel),
                "min_radius": exact(_min_radius_kernel),
                "repl_drive": _repl_drive_jit,
                "repl_drive_all": exact(_repl_drive_all),
            }
    return _KERNELS


def kernels_loaded() -> bool:
    """Whether the numba kernels are compiled already (then even one road uses them)."""
    return bool(_KERNELS)


def _engine(cfg: VehicleConfig) -> str:
    """"numba" or "numpy" for this config; "numba" without numba installed is an error."""
    if cfg.engine == "numpy":
        return "numpy"
    if _kernels():
        return "numba"
    if cfg.engine == "numba":
        raise ImportError("numba is not installed; use engine='numpy'")
    return "numpy"


def _polyline_lengths_kernel(points, counts, out):
    """Same as ``_polyline_lengths_numpy`` (compiled by numba)."""
    i0 = 0
    for r in range(len(counts)):
        total = 0.0
        for i in range(i0 + 1, i0 + counts[r]):
            dx = points[i, 0] - points[i - 1, 0]
            dy = points[i, 1] - points[i - 1, 1]
            total += math.sqrt(dx * dx + dy * dy)
        out[r] = total
        i0 += counts[r]


def _min_radius_kernel(fine, counts, scale, out):
    """Same as ``_min_radius_numpy`` (compiled by numba)."""
    i0 = 0
    for r in range(len(counts)):
        best = np.inf
        for i in range(i0, i0 + counts[r] - 5):
            p1x = np.rint(fine[i, 0] * scale) / scale
            p1y = np.rint(fine[i, 1] * scale) / scale
            p2x = np.rint(fine[i + 2, 0] * scale) / scale
            p2y = np.rint(fine[i + 2, 1] * scale) / scale
            p3x = np.rint(fine[i + 4, 0] * scale) / scale
            p3y = np.rint(fine[i + 4, 1] * scale) / scale
            temp = p2x * p2x + p2y * p2y
            bc = (p1x * p1x + p1y * p1y - temp) / 2
            cd = (temp - p3x * p3x - p3y * p3y) / 2
            det = (p1x - p2x) * (p2y - p3y) - (p2x - p3x) * (p1y - p2y)
            if abs(det) < 1e-6:  # _COLLINEAR_DET
                continue
            cx = (bc * (p2y - p3y) - cd * (p1y - p2y)) / det
            cy = ((p1x - p2x) * cd - (p2x - p3x) * bc) / det
            rad = math.sqrt((cx - p1x) ** 2 + (cy - p1y) ** 2)
            if rad < best:
                best = rad
        out[r] = best
        i0 += counts[r]


def _geos_distance(NX, NY, a, b, px, py):
    """Distance from (px, py) to the polyline of nodes a..b-1, by GEOS's point-to-segment formula
    (the same bits as shapely's ``distance``)."""
    best = np.inf
    for k in range(a, b - 1):
        ax, ay, bx, by = NX[k], NY[k], NX[k + 1], NY[k + 1]
        if ax == bx and ay == by:
            dx, dy = px - ax, py - ay
            d = math.sqrt(dx * dx + dy * dy)
        else:
            len2 = (bx - ax) * (bx - ax) + (by - ay) * (by - ay)
            r = ((px - ax) * (bx - ax) + (py - ay) * (by - ay)) / len2
            if r <= 0.0:
                dx, dy = px - ax, py - ay
                d = math.sqrt(dx * dx + dy * dy)
            elif r >= 1.0:
                dx, dy = px - bx, py - by
                d = math.sqrt(dx * dx + dy * dy)
            else:
                s = ((ay - py) * (bx - ax) - (ax - px) * (by - ay)) / len2
                d = abs(s) * math.sqrt(len2)
        if d < best:
            best = d
    return best


def _heading_deg(ax, ay, bx, by):
    """Direction a -> b in degrees, as the replication code computes it (acos, sign from y)."""
    vx, vy = bx - ax, by - ay
    c = vx / math.sqrt(vx * vx + vy * vy)
    angle = math.acos(min(1.0, max(-1.0, c))) * _RAD
    return -angle if ay > by else angle


def _repl_drive(NX, NY, o, n, x, y, prm, tot, meas, dist):
    """The replication car on one road (nodes o..o+n-1), from a fresh state; compiled by numba.

    Writes the car's path (start + one point per step) to ``tot``, the measuring positions and
    distances to ``meas`` / ``dist``; returns (points in tot, distances).
    """
    v0, band, gain, probe, acc, dec, div_s, div_t = prm[0], prm[1], prm[2], prm[3], prm[4], prm[5], prm[6], prm[7]
    max_steps = int(prm[8])
    h = n // 2 + (n % 2) * ((n // 2) % 2)
    speed = v0
    angle = _heading_jit(NX[o], NY[o], NX[o + 1], NY[o + 1])
    tot[0, 0] = x
    tot[0, 1] = y
    nt = 1
    nd = 0
    i = 0
    for part in range(2):
        a = o if part == 0 else o + h
        b = o + h if part == 0 else o + n
        if part == 1:  # the car restarts at the second half's first node, along the road
            x = NX[a]
            y = NY[a]
            angle = _heading_jit(NX[a - 1], NY[a - 1], NX[a], NY[a])
        half_len = 0.0
        for k in range(a + 1, b):
            dx = NX[k] - NX[k - 1]
            dy = NY[k] - NY[k - 1]
            half_len += math.sqrt(dx * dx + dy * dy)
        driven = 0.0
        px = x
        py = y
        while driven < half_len and i < max_steps:
            d = _distance_jit(NX, NY, a, b, x, y)
            meas[nd, 0] = x
            meas[nd, 1] = y
            dist[nd] = d
            nd += 1
            if d <= band:
                x = speed * math.cos(angle * _DEG) / div_s + x
                y = speed * math.sin(angle * _DEG) / div_s + y
                speed += acc
            else:
                probe_right = -probe + angle
                d_right = _distance_jit(NX, NY, a, b, speed * math.cos(probe_right * _DEG) + x,
                                     speed * math.sin(probe_right * _DEG) + y)
                probe_left = probe + angle
                d_left = _distance_jit(NX, NY, a, b, speed * math.cos(probe_left * _DEG) + x,
                                    speed * math.sin(probe_left * _DEG) + y)
                steer = math.atan(1 / speed * gain * d) * _RAD
                angle = -steer + angle if d_right < d_left else steer + angle
                x = speed * math.cos(angle * _DEG) / div_t + x
                y = speed * math.sin(angle * _DEG) / div_t + y
                speed -= dec
            tot[nt, 0] = x
            tot[nt, 1] = y
            nt += 1
            dx = x - px
            dy = y - py
            driven += math.sqrt(dx * dx + dy * dy)
            px = x
            py = y
            i += 1
    return nt, nd


def _repl_drive_all(NX, NY, offs, counts, x0, y0, prm, tot, n_tot, meas, dist, n_dist, maxd):
    """Every car of a chunk (compiled by numba; calls the compiled ``_repl_drive``)."""
    for r in range(len(counts)):
        n_tot[r], n_dist[r] = _repl_drive_jit(NX, NY, offs[r], counts[r], x0[r], y0[r], prm,
                                              tot[r], meas[r], dist[r])
        best = -np.inf
        for k in range(n_dist[r]):
            if dist[r, k] > best:
                best = dist[r, k]
        maxd[r] = best
