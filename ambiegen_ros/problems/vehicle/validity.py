"""Validity rules of both profiles: the competition rules (refined) and the replication code's rules
(enough nodes per half, a simple road, its sharpness check)."""
from __future__ import annotations

import numpy as np

from .config import FEET_PER_METRE, VehicleConfig
from .kernels import _engine, _kernels
from .replication_road import polyline_lengths, splprep_nodes
from .road import _offsets

_COLLINEAR_DET = 1e-6  # the sharpness check's "three points on a line" (radius infinite)


def _metrics_numpy(nodes, counts, lo, hi):
    """Per road: polyline length, whether a node is outside [lo, hi]^2, min circumradius of
    (p_i, p_i+2, p_i+4) (numpy)."""
    P = len(counts)
    road = np.repeat(np.arange(P), counts)
    step = np.hypot(*np.diff(nodes, axis=0).T)
    same_road = road[1:] == road[:-1]
    length = np.bincount(road[1:][same_road], weights=step[same_road], minlength=P)
    out = np.any((nodes < lo) | (nodes > hi), axis=1)
    outside = np.bincount(road, weights=out, minlength=P) > 0
    radius = np.full(len(nodes), np.inf)
    if len(nodes) > 4:
        p, q, s = nodes[:-4], nodes[2:-2], nodes[4:]
        a = np.hypot(*(q - p).T)
        b = np.hypot(*(s - q).T)
        c = np.hypot(*(s - p).T)
        cross = np.abs((q[:, 0] - p[:, 0]) * (s[:, 1] - p[:, 1]) - (q[:, 1] - p[:, 1]) * (s[:, 0] - p[:, 0]))
        with np.errstate(divide="ignore", invalid="ignore"):
            r = np.where(cross > 0, a * b * c / (2.0 * cross), np.inf)
        radius[:-4] = np.where(road[4:] == road[:-4], r, np.inf)
    min_radius = np.minimum.reduceat(radius, _offsets(counts)) if P else np.zeros(0)
    return length, outside, min_radius


def check_roads(nodes: np.ndarray, counts: np.ndarray, cfg: VehicleConfig):
    """Competition rules per road: valid, reason (first broken rule), length [m], min radius [m].

    Rules in reason order: length >= min_road_length; every node inside the map with the margin;
    a simple line (shapely); min circumradius of (p_i, p_i+2, p_i+4) >= min_radius.
    The replication profile has its own rules (``check_replication_roads``).
    """
    if cfg.profile == "replication":
        return check_replication_roads(nodes, counts, cfg)
    import shapely  # imported where used: one road's evaluation should start fast

    counts = np.asarray(counts, dtype=np.int64)
    P = len(counts)
    lo, hi = cfg.margin, cfg.map_size - cfg.margin
    if _engine(cfg) == "numba":
        length, outside, min_radius = np.empty(P), np.empty(P, bool), np.empty(P)
        _kernels()["metrics"](nodes, counts, lo, hi, length, outside, min_radius)
    else:
        length, outside, min_radius = _metrics_numpy(nodes, counts, lo, hi)
    simple = shapely.is_simple(shapely.linestrings(nodes, indices=np.repeat(np.arange(P), counts)))
    offs = _offsets(counts)
    valid = np.ones(P, bool)
    reasons: list[str | None] = [None] * P
    for i in range(P):
        if length[i] < cfg.min_road_length:
            reasons[i] = f"too short: {length[i]:.1f} m < {cfg.min_road_length:g} m"
        elif outside[i]:
            pts = nodes[offs[i]: offs[i] + counts[i]]
            bad = pts[np.any((pts < lo) | (pts > hi), axis=1)][0]
            reasons[i] = f"leaves the map: node ({bad[0]:.1f}, {bad[1]:.1f}) outside [{lo:g}, {hi:g}]"
        elif not simple[i]:
            reasons[i] = "self-intersecting"
        elif min_radius[i] < cfg.min_radius:
            reasons[i] = f"too sharp: min radius {min_radius[i]:.1f} m < {cfg.min_radius:g} m"
        else:
            continue
        valid[i] = False
    return valid, reasons, length, min_radius


def _find_circle_radius(p1x, p1y, p2x, p2y, p3x, p3y):
    """Radius of the circle through three points, by the replication code's formula (inf when
    collinear); numpy arrays or floats."""
    temp = p2x * p2x + p2y * p2y
    bc = (p1x * p1x + p1y * p1y - temp) / 2
    cd = (temp - p3x * p3x - p3y * p3y) / 2
    det = (p1x - p2x) * (p2y - p3y) - (p2x - p3x) * (p1y - p2y)
    flat = np.abs(det) < _COLLINEAR_DET
    safe = np.where(flat, 1.0, det)
    cx = (bc * (p2y - p3y) - cd * (p1y - p2y)) / safe
    cy = ((p1x - p2x) * cd - (p2x - p3x) * bc) / safe
    return np.where(flat, np.inf, np.sqrt((cx - p1x) ** 2 + (cy - p1y) ** 2))


def _min_radius_numpy(fine: np.ndarray, counts: np.ndarray, scale: float) -> np.ndarray:
    """Smallest radius over the windows (i, i+2, i+4), i < count - 5, of the rounded nodes."""
    counts = np.asarray(counts, dtype=np.int64)
    P = len(counts)
    pts = np.rint(fine * scale) / scale
    out = np.full(P, np.inf)
    if len(pts) <= 5:
        return out
    road = np.repeat(np.arange(P), counts)
    local = np.arange(len(pts)) - np.repeat(_offsets(counts), counts)
    first = np.flatnonzero(local[:-4] < (counts[road[:-4]] - 5))  # window starts (same road by construction)
    p1, p2, p3 = pts[first], pts[first + 2], pts[first + 4]
    r = _find_circle_radius(p1[:, 0], p1[:, 1], p2[:, 0], p2[:, 1], p3[:, 0], p3[:, 1])
    np.minimum.at(out, road[first], r)
    return out


def sharpness_radius(nodes: np.ndarray, counts: np.ndarray, length: np.ndarray, cfg: VehicleConfig) -> np.ndarray:
    """The replication code's sharpness measure per road: its nodes interpolated again (splprep,
    ``max(interp_min_nodes, int(length / interp_step))`` steps), rounded to ``radius_decimals``,
    smallest circle through (p_i, p_i+2, p_i+4) [m] (inf: none). Roads need >= 2 nodes."""
    step = 1.0 / np.maximum(cfg.interp_min_nodes, (length / cfg.interp_step).astype(np.int64))
    fine, n_fine = splprep_nodes(nodes, counts, step, cfg)
    scale = 10.0 ** cfg.radius_decimals
    if _engine(cfg) == "numba":
        out = np.empty(len(counts))
        _kernels()["min_radius"](fine, n_fine, scale, out)
        return out
    return _min_radius_numpy(fine, n_fine, scale)


def _first_half(counts):
    """Nodes in the first half of a road: Python's round(n / 2) (half to even)."""
    counts = np.asarray(counts, dtype=np.int64)
    return counts // 2 + (counts % 2) * ((counts // 2) % 2)


def check_replication_roads(nodes: np.ndarray, counts: np.ndarray, cfg: VehicleConfig):
    """The replication code's rules per road: valid, reason, length [m], sharpness radius [m].

    In reason order: the car needs >= 2 nodes in each half of the road ("too short"); the node
    polyline must be simple ("road not simple"); the radius of ``sharpness_radius`` must not be
    below ``min_radius`` (47 ft, "too sharp").
    """
    counts = np.asarray(counts, dtype=np.int64)
    P = len(counts)
    length = polyline_lengths(nodes, counts, cfg)
    min_radius = np.full(P, np.inf)
    simple = np.ones(P, bool)
    line = counts >= 2
    if line.any():
        import shapely

        road = np.repeat(np.arange(P), counts)
        sub = nodes[line[road]]
        lines = shapely.linestrings(sub, indices=np.repeat(np.arange(int(line.sum())), counts[line]))
        simple[line] = shapely.is_simple(lines)
        min_radius[line] = sharpness_radius(sub, counts[line], length[line], cfg)
    half = _first_half(counts)
    valid = np.ones(P, bool)
    reasons: list[str | None] = [None] * P
    for i in range(P):
        if half[i] < 2 or counts[i] - half[i] < 2:
            reasons[i] = f"too short: {counts[i]} road nodes, the car needs 2 in each half"
        elif not simple[i]:
            reasons[i] = "road not simple"
        elif min_radius[i] < cfg.min_radius:
            reasons[i] = (f"too sharp: min radius {min_radius[i]:.2f} m < {cfg.min_radius:.2f} m "
                          f"({cfg.min_radius * FEET_PER_METRE:g} ft)")
        else:
            continue
        valid[i] = False
    return valid, reasons, length, min_radius
