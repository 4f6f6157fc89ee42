"""Replication road: the replication code's road points (one per element, cut at the map edge) and
the spline nodes its car drives (about every 8 m)."""
from __future__ import annotations

import math

import numpy as np

from .config import ANGLE, LEFT, LENGTH, TYPE, VehicleConfig
from .kernels import _DEG, _engine, _kernels
from .road import _local_index, _pad, heading_changes, spline_at, spline_coefficients


def _norm(v: np.ndarray) -> np.ndarray:
    """``numpy.linalg.norm`` of each 2-vector: the builder's per-vector call gives these bits
    (measured on numpy 1.24 and 2.4)."""
    return np.sqrt(v[:, 0] * v[:, 0] + v[:, 1] * v[:, 1])


def _rotate(c: np.ndarray, s: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``R @ v`` with ``R = [[c, s], [-s, c]]`` per row, through numpy's matmul as the builder's
    ``R.dot(v)``: its BLAS fuses a multiply and an add on FMA CPUs (a quarter of the results then
    differ from ``c * x + s * y``), and a stacked matmul calls the same kernel (measured equal bit
    for bit on numpy 1.24 and 2.4)."""
    R = np.stack([np.stack([c, s], axis=-1), np.stack([-s, c], axis=-1)], axis=-2)
    return np.matmul(R, v[:, :, None])[:, :, 0]


def replication_sections(G: np.ndarray, cfg: VehicleConfig) -> tuple[np.ndarray, np.ndarray]:
    """Both ends of the road builder's cross-section after every element ``(P, m, 2, 2)`` and the
    heading after it ``(P, m)`` [rad], in the replication code's order of operations.

    The builder carries a cross-section of width 2 ``section_half_width`` (ends a, b) and takes
    its midpoint as the road point. Each element orders the ends (a = the end with the larger y,
    or larger x on a tie), then a straight moves both ends along the unit normal of the section;
    a turn rotates both ends about a pivot ``turn_radius - section_half_width`` beyond one end:
    pivot, the ends' unit vectors from it and their lengths, ``R @ unit * length``, pivot + that.
    Which normal, and which end the pivot lies beyond, follow from the heading (the builder decides
    them with a 1 m / 3 degree probe, never near a tie); the arithmetic is the builder's, so road
    points, the strict map cut on them and the road length come out in its bits.
    """
    G = np.asarray(G, dtype=float)
    P, m = G.shape[:2]
    first_left = np.rint(G[:, 0, TYPE]) == LEFT if m else np.zeros(P, bool)
    heading0 = math.radians(cfg.start_heading_deg) + np.where(first_left, math.pi, 0.0)
    turn, dtheta = heading_changes(G)
    heading = heading0[:, None] + np.cumsum(dtheta, axis=1)  # after each element
    before = np.concatenate([heading0[:, None], heading[:, :-1]], axis=1)
    h0 = math.radians(cfg.start_heading_deg)
    normal = np.array([-math.sin(h0), math.cos(h0)])
    normal[np.abs(normal) < 1e-12] = 0.0  # -90 deg: exactly (1, 0), as the builder's first section
    hw = cfg.section_half_width
    a = np.broadcast_to(np.asarray(cfg.start, dtype=float) - hw * normal, (P, 2)).copy()
    b = np.broadcast_to(np.asarray(cfg.start, dtype=float) + hw * normal, (P, 2)).copy()
    pivot = cfg.turn_radius - hw
    ends = np.empty((P, m, 2, 2))
    last = np.full(P, m - 1)  # last element computed per road: after its section left the map, none is built
    rows = np.arange(P)  # roads still on the map
    for i in range(m):
        Gi, ti, hi = G[rows, i], turn[rows, i][:, None], before[rows, i]
        dx, dy = b[:, 0] - a[:, 0], b[:, 1] - a[:, 1]
        swap = ((dy > 0) | ((dy == 0) & (dx > 0)))[:, None]
        pa, pb = np.where(swap, b, a), np.where(swap, a, b)
        u = (pa - pb) / _norm(pb - pa)[:, None]
        fwd = np.stack([np.cos(hi), np.sin(hi)], axis=1)
        # straight: the normal (-u_y, u_x) or (u_y, -u_x) that points forward, times the length
        n = np.stack([-u[:, 1], u[:, 0]], axis=1)
        n = np.where(((n * fwd).sum(axis=1) > 0)[:, None], n, -n)
        sa, sb = pa + n * Gi[:, LENGTH, None], pb + n * Gi[:, LENGTH, None]
        # turn: pivot beyond a ("top": rotate by angle + 180) when a is on the turn's side, else beyond b
        side = ti * np.stack([-fwd[:, 1], fwd[:, 0]], axis=1)  # left normal * (+1 left, -1 right)
        top = ((u * side).sum(axis=1) > 0)[:, None]
        o = np.where(top, pa + u * pivot, pb - u * pivot)
        ob_n, oa_n = _norm(o - pb), _norm(o - pa)
        ob = np.where(top, o - pb, pb - o) / ob_n[:, None]
        oa = np.where(top, o - pa, pa - o) / oa_n[:, None]
        ang = (Gi[:, ANGLE] + np.where(top[:, 0], 180.0, 0.0)) * _DEG
        c, s = np.cos(ang), np.sin(ang)
        s = np.where(ti[:, 0] > 0, -s, s)  # anticlockwise: R = [[c, -s], [s, c]]
        ta = o + _rotate(c, s, oa) * oa_n[:, None]
        tb = o + _rotate(c, s, ob) * ob_n[:, None]
        a, b = np.where(ti != 0, ta, sa), np.where(ti != 0, tb, sb)
        ends[rows, i, 0], ends[rows, i, 1] = a, b
        on_map = _cross_section_inside(ends[rows, i], cfg)
        last[rows[~on_map]] = i
        rows, a, b = rows[on_map], a[on_map], b[on_map]
        if not len(rows):
            break
    ends = ends[np.arange(P)[:, None], np.minimum(np.arange(m)[None, :], last[:, None])]
    return ends, heading


def replication_poses(G: np.ndarray, cfg: VehicleConfig) -> tuple[np.ndarray, np.ndarray]:
    """Road point (midpoint of the builder's cross-section) and heading after every element:
    ``(P, m, 2)``, ``(P, m)`` [rad] (see ``replication_sections``).

    A straight moves the point, a turn rotates it about a pivot ``turn_radius`` to the side. The
    first element sets the direction: the road heads ``start_heading_deg``, except after a first
    left turn, which heads the opposite way (the replication code turns about the same pivot for
    both first turns).
    """
    ends, heading = replication_sections(G, cfg)
    return (ends[:, :, 0] + ends[:, :, 1]) / 2, heading


def _cross_section_inside(ends: np.ndarray, cfg: VehicleConfig) -> np.ndarray:
    """Both ends of the road builder's cross-section inside [0, size - margin) (its move rule)."""
    hi = cfg.map_size - cfg.margin
    return np.all((ends >= 0) & (ends < hi), axis=(-2, -1))


def replication_points(G: np.ndarray, lengths: np.ndarray, cfg: VehicleConfig):
    """Road points of a batch, cut where the road leaves the map: flat ``(sum N, 2)``, ``N``, and
    the number of elements kept per road.

    An element is built only while the cross-section before it is inside the map; its point is
    kept only while it lies in (margin, size - margin); the first element broken ends the road
    (the rest of the scenario is ignored and the road is still scored).
    """
    lengths = np.asarray(lengths)
    G = np.asarray(G, dtype=float)[:, : int(lengths.max(initial=0))]  # no work for the padding
    P, m = G.shape[:2]
    ends, _ = replication_sections(G, cfg)
    points = (ends[:, :, 0] + ends[:, :, 1]) / 2
    lo, hi = cfg.margin, cfg.map_size - cfg.margin
    built = np.concatenate([np.ones((P, 1), bool), _cross_section_inside(ends, cfg)[:, :-1]], axis=1)
    inside = np.all((points > lo) & (points < hi), axis=-1)
    keep = built & inside & (np.arange(m)[None, :] < lengths[:, None])
    used = np.where(keep.all(axis=1), m, np.argmin(keep, axis=1))
    start = np.broadcast_to(np.asarray(cfg.start, dtype=float), (P, 1, 2))
    mask = np.concatenate([np.ones((P, 1), bool), np.arange(m)[None, :] < used[:, None]], axis=1)
    return np.concatenate([start, points], axis=1)[mask], used + 1, used


def _polyline_lengths_numpy(points: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """Length of each polyline, summed segment after segment as GEOS does (the same bits)."""
    counts = np.asarray(counts, dtype=np.int64)
    P = len(counts)
    if P == 0:
        return np.zeros(0)
    Y = _pad(points, counts)
    d = np.diff(Y, axis=1)
    seg = np.sqrt(d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1])
    live = np.arange(Y.shape[1] - 1)[None, :] < (counts - 1)[:, None]
    total = np.zeros(P)
    for j in range(seg.shape[1]):
        total = np.where(live[:, j], total + seg[:, j], total)
    return total


def polyline_lengths(points: np.ndarray, counts: np.ndarray, cfg: VehicleConfig) -> np.ndarray:
    counts = np.asarray(counts, dtype=np.int64)
    if _engine(cfg) == "numba":
        out = np.empty(len(counts))
        _kernels()["lengths"](points, counts, out)
        return out
    return _polyline_lengths_numpy(points, counts)


def _arange_parameters(step: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``numpy.arange(0, 1 + step, step)`` for every road at once: counts and flat parameters."""
    count = np.ceil((1.0 + step) / step).astype(np.int64)
    road, local = _local_index(count)
    return count, local * step[road]


def splprep_nodes(points: np.ndarray, counts: np.ndarray, step: np.ndarray, cfg: VehicleConfig):
    """``splev(arange(0, 1 + step, step), splprep(points, s=0, k=min(3, n-1)))`` per road (flat)."""
    counts = np.asarray(counts, dtype=np.int64)
    X, coef, _ = spline_coefficients(points, counts, cfg)
    n_nodes, t = _arange_parameters(step)
    return spline_at(X, coef, counts, n_nodes, t, cfg), n_nodes


def replication_nodes(points: np.ndarray, counts: np.ndarray, cfg: VehicleConfig):
    """The road the replication car drives: each road's spline sampled with the parameter step
    ``node_step / length of the road points' polyline`` (about every 8 m; the last node may lie
    a little past the last road point). A road of one point keeps it as its only node."""
    counts = np.asarray(counts, dtype=np.int64)
    line = counts >= 2
    if line.all():
        step = (1.0 / polyline_lengths(points, counts, cfg)) * cfg.node_step
        return splprep_nodes(points, counts, step, cfg)
    n_nodes = np.ones(len(counts), dtype=np.int64)
    if not line.any():
        return points.copy(), n_nodes
    road = np.repeat(np.arange(len(counts)), counts)
    nodes_line, n_nodes[line] = replication_nodes(points[line[road]], counts[line], cfg)
    node_road = np.repeat(np.arange(len(counts)), n_nodes)
    nodes = np.empty((int(n_nodes.sum()), 2))
    nodes[line[node_road]] = nodes_line
    nodes[~line[node_road]] = points[~line[road]]
    return nodes, n_nodes
