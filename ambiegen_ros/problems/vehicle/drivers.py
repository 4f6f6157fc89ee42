"""The two-driver surrogate (issue 26): the full model's brisk driver and the reference's cautious one,
coarse and fast, so that the search climbs towards *certified* failures.

The paper's surrogate car (``car.py``, constant 7 m/s, bang-bang steering) cannot tell which roads
make the full model's brisk driver run wide while a cautious driver keeps its lane: on 500 sampled
refined roads its F1 ranks certified failures no better than chance (``docs/search_for_certified.md``).
This surrogate drives each road twice with the full model's *driver law* (``sims.car``: a speed
target from the curvature ahead, pure pursuit on the right lane, steering-rate and grip limits), once
per driver, but coarsely:

* a 0.1 s step (the full model: 0.05 s) and no stall or goal oracle (the road's end stops the run);
* the lane test is the offset of the car box's centre from the right lane's centre, not the
  box's area outside the lane polygon (shapely): out of lane when ``|offset| > OUT_OFFSET``, the
  offset at which 85 % of an aligned 1.8 m box has left a 4 m lane.

F1 ("certified" objective) = the brisk driver's largest offset, capped ``CAP`` past the
out-of-lane offset (deeper is not more certain), minus how far the cautious driver comes within
``CAP`` of it (a road the reference fails is an invalid test, never a failure):

    F1 = min(o_brisk, OUT + CAP) - max(0, o_cautious - (OUT - CAP))

so F1 > OUT means "the surrogate predicts a certified failure". The arc length along the road where
the brisk driver first left the lane (else where it came closest) says where it failed: the
executor uses it to prefer failures unlike the ones found (``sims.signature``).

The lane is the full model's own (``validity.right_lane_lines``, built once per road for both
drivers); ``_project`` and ``_point_at`` are scalar twins of ``sims.car``'s, for the compiled loop.
The car's numbers are the full model's defaults (``sims.car.CarSimConfig``; a test keeps them
equal). The loop runs compiled by numba when it loads, else as plain Python (same results).
"""
from __future__ import annotations

import math
from dataclasses import astuple, dataclass

import numpy as np

from .validity import right_lane_lines

OUT_OFFSET = 2.0 + (0.85 - 0.5) * 1.8  # lane half-width + 35 % of the box's width [m]
CAP = 0.5  # [m]


@dataclass(frozen=True)
class Driver:
    """One driver on the full model's car (the numbers of ``sims.car.CarSimConfig``)."""

    corner_lat_accel: float = 6.5  # brisk; the reference: 4.0
    preview_time: float = 0.5  # brisk; the reference: 1.5
    wheelbase: float = 2.7
    car_length: float = 4.5
    rear_overhang: float = 0.9
    max_steer_deg: float = 35.0
    max_steer_rate_deg: float = 60.0
    grip: float = 7.0
    speed_limit_kmh: float = 70.0
    accel: float = 2.5
    brake: float = 4.0
    preview_min: float = 5.0
    speed_gain: float = 2.0
    lookahead_time: float = 0.5
    lookahead_min: float = 4.0
    timeout_base: float = 30.0
    timeout_speed: float = 3.0
    dt: float = 0.05


BRISK = Driver()
CAUTIOUS = Driver(corner_lat_accel=4.0, preview_time=1.5)


def _project(cx, cy, s, x, y, i):
    """Nearest lane segment to (x, y) around segment i: (segment, lane arc, signed offset > 0 left)."""
    n = len(cx)
    lo = max(i - 5, 0)
    hi = min(i + 40, n - 1)
    best, best_d2, best_u, best_side = lo, 1e300, 0.0, 0.0
    for j in range(lo, hi):
        dx, dy = cx[j + 1] - cx[j], cy[j + 1] - cy[j]
        l2 = max(dx * dx + dy * dy, 1e-12)
        u = min(max(((x - cx[j]) * dx + (y - cy[j]) * dy) / l2, 0.0), 1.0)
        ex, ey = x - (cx[j] + u * dx), y - (cy[j] + u * dy)
        d2 = ex * ex + ey * ey
        if d2 < best_d2:
            best, best_d2, best_u = j, d2, u
            best_side = dx * (y - cy[j]) - dy * (x - cx[j])
    seg_len = s[best + 1] - s[best] if best + 1 < n else 0.0
    return best, s[best] + best_u * seg_len, math.copysign(math.sqrt(best_d2), best_side)


def _point_at(cx, cy, s, q, j):
    """The lane centre at arc q, searching forward from node j."""
    n = len(s)
    q = min(max(q, 0.0), s[n - 1])
    while j < n - 2 and s[j + 1] < q:
        j += 1
    seg = s[j + 1] - s[j]
    f = 0.0 if seg <= 0 else (q - s[j]) / seg
    f = min(max(f, 0.0), 1.0)
    return cx[j] + f * (cx[j + 1] - cx[j]), cy[j] + f * (cy[j + 1] - cy[j])


def _drive_one(cx, cy, s, road_s, kappa, prm, out_offset):
    """One drive: (largest |offset| of the box centre, road arc of the first out-of-lane step, or of
    the largest offset when the car never left the lane)."""
    corner, preview_time, L, car_length, rear_overhang = prm[0], prm[1], prm[2], prm[3], prm[4]
    max_steer_deg, max_steer_rate_deg, grip, speed_kmh, accel = prm[5], prm[6], prm[7], prm[8], prm[9]
    brake, preview_min, speed_gain, la_time, la_min = prm[10], prm[11], prm[12], prm[13], prm[14]
    t_base, t_speed, dt = prm[15], prm[16], prm[17]
    n = len(cx)
    v_limit = speed_kmh / 3.6
    max_steer = max_steer_deg * math.pi / 180.0
    steer_step = max_steer_rate_deg * math.pi / 180.0 * dt
    ahead_c = car_length / 2 - rear_overhang
    total = s[n - 1]
    n_max = int(math.ceil((t_base + road_s[n - 1] / t_speed) / dt))
    x, y = _point_at(cx, cy, s, rear_overhang, 0)
    yaw = math.atan2(cy[1] - cy[0], cx[1] - cx[0])
    v, steer, seg = 0.0, 0.0, 0
    seg, s_now, _ = _project(cx, cy, s, x, y, 0)
    cseg = seg
    worst, worst_arc, fail_arc = 0.0, 0.0, -1.0
    for _k in range(n_max):
        # driver: the slowest speed any node in the preview asks for, less what braking sheds
        reach = s_now + max(preview_min, preview_time * v)
        v2 = v_limit * v_limit
        j = seg
        while j < n and (j == seg or s[j - 1] <= reach):
            c = max(kappa[j], 1e-9)
            v2 = min(v2, min(v_limit * v_limit, corner / c) + 2 * brake * max(s[j] - s_now, 0.0))
            j += 1
        a = min(max(speed_gain * (math.sqrt(v2) - v), -brake), accel)
        tx, ty = _point_at(cx, cy, s, s_now + max(la_min, la_time * v), seg)
        alpha = math.atan2(ty - y, tx - x) - yaw
        dist = max(math.hypot(tx - x, ty - y), 1e-6)
        want = min(max(math.atan2(2 * L * math.sin(alpha), dist), -max_steer), max_steer)
        steer += min(max(want - steer, -steer_step), steer_step)
        # vehicle: kinematic bicycle with a grip limit
        yaw_rate = v * math.tan(steer) / L
        if abs(v * yaw_rate) > grip:
            yaw_rate = math.copysign(grip / max(v, 1e-6), yaw_rate)
        v_new = max(v + a * dt, 0.0)
        mid = yaw + 0.5 * yaw_rate * dt
        x += 0.5 * (v + v_new) * math.cos(mid) * dt
        y += 0.5 * (v + v_new) * math.sin(mid) * dt
        yaw += yaw_rate * dt
        v = v_new
        seg, s_now, _ = _project(cx, cy, s, x, y, seg)
        cseg, cs, off = _project(cx, cy, s, x + ahead_c * math.cos(yaw), y + ahead_c * math.sin(yaw), max(cseg, seg - 2))
        off = abs(off)
        arc = road_s[cseg] + (cs - s[cseg]) / max(s[cseg + 1] - s[cseg], 1e-12) * (road_s[cseg + 1] - road_s[cseg]) \
            if cseg + 1 < n else road_s[n - 1]
        if off > worst:
            worst, worst_arc = off, arc
        if off > out_offset and fail_arc < 0:
            fail_arc = arc
        if off > out_offset + 1.0 or s_now >= total - 1e-6:
            break
    return worst, (fail_arc if fail_arc >= 0 else worst_arc)


def _drive_all(cx, cy, s, road_s, kappa, offsets, counts, prm, out_offset, worst, arc):
    """Every road's right lane of flat arrays (``offsets``/``counts`` per road), one after another."""
    for r in range(len(counts)):
        o, m = offsets[r], counts[r]
        if m < 5:
            worst[r], arc[r] = 0.0, 0.0
            continue
        worst[r], arc[r] = _drive_one(cx[o:o + m], cy[o:o + m], s[o:o + m], road_s[o:o + m], kappa[o:o + m], prm,
                                      out_offset)


_COMPILED: list = []


def _kernel():
    """``_drive_all`` compiled by numba (with its helpers), or the plain Python one."""
    if not _COMPILED:
        from ...core.accel import numba_module

        numba = numba_module()
        if not numba:
            _COMPILED.append(_drive_all)
        else:
            jit = numba.njit(cache=True, error_model="numpy")
            g = globals()
            for name in ("_project", "_point_at", "_drive_one"):
                g[name] = jit(g[name])
            _COMPILED.append(jit(_drive_all))
    return _COMPILED[0]


def right_lanes(nodes: np.ndarray, counts: np.ndarray, lane_width: float) -> tuple[np.ndarray, ...]:
    """Every road's right lane as the full model builds it (``validity.right_lane_lines``), as flat
    arrays (centre x, centre y, lane arc, road arc, |curvature|) beside per-road offsets and counts."""
    counts = np.asarray(counts, dtype=np.int64)
    offsets = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int64)
    lanes = [right_lane_lines(nodes[o:o + m], lane_width) for o, m in zip(offsets, counts)]
    centre = np.concatenate([lane[0] for lane in lanes]) if lanes else np.zeros((0, 2))
    s, road_s, kappa = (np.concatenate([lane[k] for lane in lanes]) if lanes else np.zeros(0) for k in (1, 2, 3))
    return (np.ascontiguousarray(centre[:, 0]), np.ascontiguousarray(centre[:, 1]), s, road_s, kappa,
            offsets, counts)


def drive_margins(nodes: np.ndarray, counts: np.ndarray, lane_width: float, driver: Driver = BRISK,
                  lanes: tuple[np.ndarray, ...] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Per road of a flat ``nodes`` array (``counts`` nodes each): the largest offset of the car box's
    centre from the right lane's centre [m] and where along the road the car first left the lane [m].
    ``lanes``: ``right_lanes`` of the same roads, when the caller drives them more than once."""
    lanes = right_lanes(nodes, counts, lane_width) if lanes is None else lanes
    worst, arc = np.zeros(len(lanes[-1])), np.zeros(len(lanes[-1]))
    _kernel()(*lanes, np.array(astuple(driver), dtype=float), OUT_OFFSET, worst, arc)
    return worst, arc


def certified_score(brisk: np.ndarray, cautious: np.ndarray) -> np.ndarray:
    """F1 of the "certified" objective (module docstring): > OUT_OFFSET predicts a certified failure."""
    return np.minimum(brisk, OUT_OFFSET + CAP) - np.maximum(0.0, cautious - (OUT_OFFSET - CAP))


__all__ = ["BRISK", "CAP", "CAUTIOUS", "Driver", "OUT_OFFSET", "certified_score", "drive_margins", "right_lanes"]
