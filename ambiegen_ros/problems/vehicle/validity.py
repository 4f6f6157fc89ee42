"""Validity rules of both profiles: the competition rules (refined) and the replication code's rules
(enough nodes per half, a simple road, its sharpness check); and ``competition_rules``, the same
rules with the road's width on the road a full-model car drives (its reference check)."""
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
        radius[:-4] = np.where(road[4:] == road[:-4], circumradii(nodes), np.inf)
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


# --- the competition rules on the road the car drives (the full model's reference check) ----------
RULES_STEP = 1.0  # the road is checked on its polyline resampled at most this far apart [m]


def _densify(road: np.ndarray, step: float) -> tuple[np.ndarray, np.ndarray]:
    """The polyline ``road`` with points added along each segment at most ``step`` apart (it keeps
    its corners: this is the road the car's lane is built on), and the arc length of every point."""
    seg = np.diff(road, axis=0)
    seg_len = np.hypot(seg[:, 0], seg[:, 1])
    parts = np.maximum(1, np.ceil(seg_len / step - 1e-9)).astype(np.int64)
    start = np.repeat(np.arange(len(seg)), parts)
    frac = (np.arange(int(parts.sum())) - np.repeat(np.cumsum(parts) - parts, parts)) / np.repeat(parts, parts)
    dense = np.concatenate([road[start] + frac[:, None] * seg[start], road[-1:]])
    arc = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(dense, axis=0).T))])
    return dense, arc


def left_normals(road: np.ndarray) -> np.ndarray:
    """Unit normal pointing left of the direction of travel at each point of a polyline (central
    differences): how the road's lanes are offset from its centre line (also ``sims.car.right_lane``)."""
    tangent = np.gradient(road, axis=0)
    tangent /= np.maximum(np.hypot(tangent[:, 0], tangent[:, 1]), 1e-12)[:, None]
    return np.column_stack([-tangent[:, 1], tangent[:, 0]])


def abs_curvature(points: np.ndarray, stride: int = 2) -> np.ndarray:
    """|curvature| at each node from the circle through (p_i-k, p_i, p_i+k) (ends copy the nearest)."""
    n = len(points)
    out = np.zeros(n)
    if n < 2 * stride + 1:
        return out
    a, b, c = points[:-2 * stride], points[stride:-stride], points[2 * stride:]
    cross = np.abs((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))
    prod = np.hypot(*(b - a).T) * np.hypot(*(c - b).T) * np.hypot(*(c - a).T)
    out[stride:-stride] = 2 * cross / np.maximum(prod, 1e-12)
    out[:stride] = out[stride]
    out[-stride:] = out[-stride - 1]
    return out


def right_lane_lines(road: np.ndarray, lane_width: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The right lane a car drives on a road centre line: its centre (offset half a lane to the
    right), arc length along it, arc length along the road, |curvature| of its centre. The full
    model (``sims.car.right_lane``) and the two-driver surrogate (``drivers``) share it."""
    road = np.asarray(road, dtype=float)
    centre = road - left_normals(road) * (lane_width / 2)
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(centre, axis=0).T))])
    road_s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(road, axis=0).T))])
    return centre, s, road_s, abs_curvature(centre)


def lane_edges(road: np.ndarray, lane_width: float) -> tuple[np.ndarray, np.ndarray]:
    """Left and right edges of a two-lane road: the centre line offset ``lane_width`` either side."""
    left = left_normals(road)
    return road + left * lane_width, road - left * lane_width


def circumradii(road: np.ndarray) -> np.ndarray:
    """Radius of the circle through (p_i, p_i+2, p_i+4) for every i (inf on a line): the competition's
    sharpness measure on nodes about a metre apart."""
    if len(road) < 5:
        return np.full(0, np.inf)
    p, q, s = road[:-4], road[2:-2], road[4:]
    a, b, c = np.hypot(*(q - p).T), np.hypot(*(s - q).T), np.hypot(*(s - p).T)
    cross = np.abs((q[:, 0] - p[:, 0]) * (s[:, 1] - p[:, 1]) - (q[:, 1] - p[:, 1]) * (s[:, 0] - p[:, 0]))
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(cross > 0, a * b * c / (2.0 * cross), np.inf)


def _outside_map(points: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """How far each point lies outside the square [lo, hi]^2 [m] (0 inside)."""
    return np.maximum(np.maximum(lo - points, points - hi), 0.0).max(axis=1)


def _edges_clear(left: np.ndarray, right: np.ndarray) -> bool:
    """Neither edge crosses itself and the two never meet (shapely predicates: fast when true)."""
    import shapely

    lines = shapely.linestrings([left, right])
    return bool(shapely.is_simple(lines).all() and not shapely.intersects(lines[0], lines[1]))


def _crossings(line: np.ndarray, other: np.ndarray | None = None) -> np.ndarray:
    """Index pairs (i, j) of segments of ``line`` that cross segments of ``other`` (None: of
    ``line`` itself, neighbours sharing a point left out), by an STR tree (shapely)."""
    import shapely

    segs = shapely.linestrings(np.stack([line[:-1], line[1:]], axis=1))
    others = segs if other is None else shapely.linestrings(np.stack([other[:-1], other[1:]], axis=1))
    i, j = shapely.STRtree(others).query(segs, predicate="intersects")
    keep = (j > i + 1) if other is None else np.ones(len(i), bool)
    return np.column_stack([i[keep], j[keep]])


def _point_segment_distance(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distance from each point to the segment a-b of its row, and where on it (0..1)."""
    d = b - a
    u = np.clip(((points - a) * d).sum(axis=1) / np.maximum((d * d).sum(axis=1), 1e-12), 0.0, 1.0)
    return np.hypot(*(a + u[:, None] * d - points).T), u


def _overlaps(line: np.ndarray, gap: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points and segments of ``line`` closer than ``gap`` that are not neighbours along the arc:
    (point index, segment index, distance) of each such pair.

    The closest approach of two stretches of a polyline is a point of one to a segment of the
    other. Going forward from point i, its neighbours are the unbroken run of segments i, i+1, ...
    within ``gap`` of it (backward: i-1, i-2, ...); a segment within ``gap`` beyond the first one
    farther away is the road coming back onto itself. Candidates come from a k-d tree (scipy),
    the distances are exact; segments are about a metre long.
    """
    from scipy.spatial import cKDTree

    seg_max = float(np.hypot(*np.diff(line, axis=0).T).max())
    pairs = cKDTree(line).query_pairs(gap + seg_max, output_type="ndarray")
    pt = np.concatenate([pairs[:, 0], pairs[:, 1], pairs[:, 0], pairs[:, 1]])
    other = np.concatenate([pairs[:, 1], pairs[:, 0], pairs[:, 1] - 1, pairs[:, 0] - 1])  # segments at the other point
    ok = (other >= 0) & (other < len(line) - 1)
    pt, seg = pt[ok], other[ok]
    key = np.sort(pt * len(line) + seg)
    key = key[np.r_[True, key[1:] != key[:-1]]]
    pt, seg = key // len(line), key % len(line)
    dist, _ = _point_segment_distance(line[pt], line[seg], line[seg + 1])
    close = dist < gap
    pt, seg, dist = pt[close], seg[close], dist[close]
    if not len(pt):
        return pt, seg, dist
    ahead = seg >= pt
    step = np.where(ahead, seg - pt, pt - 1 - seg)  # segments apart along the arc (0 = touching)
    order = np.lexsort((step, ahead, pt))  # runs per (point, direction), nearest first
    p_s, a_s = pt[order], ahead[order]
    first = np.r_[True, (p_s[1:] != p_s[:-1]) | (a_s[1:] != a_s[:-1])]
    rank = np.arange(len(order)) - np.maximum.accumulate(np.where(first, np.arange(len(order)), 0))
    bad = np.zeros(len(pt), bool)
    bad[order[step[order] != rank]] = True  # not in the unbroken run of neighbours
    return pt[bad], seg[bad], dist[bad]


def competition_rules(road: np.ndarray, lane_width: float, map_size: float, margin: float, min_radius: float,
                      radius: float | None = None, gap: float | None = None) -> tuple[bool, str | None]:
    """The SBST/SBFT competition rules on the road a car drives: ``(ok, reason of each broken rule)``.

    ``road`` (M, 2) is the centre line as driven (a polyline; its corners stay corners); the road
    has two lanes of ``lane_width``, so its surface reaches ``lane_width`` either side.

    1. Inside the map: every point of the centre line and of both edges at least ``margin`` inside
       the ``map_size`` square ("road leaves the map by 3.2 m at 140 m along it").
    2. No overlap: neither edge crosses itself or the other, and no part of the centre line comes
       within ``gap`` (default 2 ``lane_width``: the two surfaces would overlap) of a part that is
       not its neighbour along the arc ("road overlaps itself at 85 m and 230 m ...").
    3. Not too sharp: the smallest radius is at least ``min_radius``; ``radius`` is the road's
       smallest radius when the caller measured it (the replication profile's sharpness check on
       its spline), else the circumradius of (p_i, p_i+2, p_i+4) of ``road`` (nodes about 1 m apart).
    Reasons are joined with "; " in that order. The edges are offset at the nodes, as the car's
    lane is; the overlap is measured on the centre line resampled every ``RULES_STEP`` metres.
    """
    road = np.asarray(road, dtype=float)
    if len(road) < 2:
        return False, "road has fewer than 2 points"
    gap = 2.0 * lane_width if gap is None else gap
    node_arc = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(road, axis=0).T))])
    # the edges as the car's lane is built: offset at the nodes, straight between them (so the
    # nodes decide whether they stay in the map, and an 8 m polyline's corners do not fold them)
    left, right = lane_edges(road, lane_width)
    reasons = []
    lo, hi = margin, map_size - margin
    out = np.maximum.reduce([_outside_map(p, lo, hi) for p in (road, left, right)])
    if out.max() > 1e-9:
        k = int(np.argmax(out))
        reasons.append(f"road leaves the map by {out[k]:.1f} m at {node_arc[k]:.0f} m along it "
                       f"(its {2 * lane_width:g} m surface must stay {margin:g} m inside the {map_size:g} m map)")
    dense, arc = _densify(road, RULES_STEP)
    pt, seg, dist = _overlaps(dense, gap)
    if len(pt):
        k = int(np.argmin(dist))
        _, u = _point_segment_distance(dense[pt[k]][None], dense[seg[k]][None], dense[seg[k] + 1][None])
        there = arc[seg[k]] + u[0] * (arc[seg[k] + 1] - arc[seg[k]])
        first, second = sorted((arc[pt[k]], there))
        reasons.append(f"road overlaps itself at {first:.0f} m and {second:.0f} m along it "
                       f"(centre lines {dist[k]:.1f} m apart, less than {gap:g} m)")
    elif not _edges_clear(left, right):  # the centre lines apart: an inner edge folding in a bend tighter than a lane
        for name, pairs in (("left edge", _crossings(left)), ("right edge", _crossings(right)),
                            ("two edges", _crossings(left, right))):
            if len(pairs):
                where = " and ".join(f"{node_arc[k]:.0f} m" for k in sorted(set(pairs[0].tolist())))
                reasons.append(f"road's {name} cross{' each other' if name == 'two edges' else 'es itself'} "
                               f"at {where} along it")
                break
    radii = circumradii(road)
    smallest = float(radii.min(initial=np.inf)) if radius is None else float(radius)
    if smallest < min_radius:
        where = f" at {node_arc[int(np.argmin(radii)) + 2]:.0f} m along it" if radius is None else ""
        reasons.append(f"road too sharp: radius {smallest:.1f} m < {min_radius:g} m{where}")
    return not reasons, "; ".join(reasons) or None
