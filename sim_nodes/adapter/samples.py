"""Sample times and frames: how a stream of stamped samples becomes the oracle's series (pure).

The first sample after the scenario started is t = 0; ``stamp_clock`` says how later times are
read (``sample_times``); times that do not go up are dropped (duplicates, reordering).
"""
from __future__ import annotations

import math

import numpy as np


def sample_times(stamp_ns: np.ndarray, recv_ns: np.ndarray, first: tuple[int, int], clock: str,
                 time_scale: float) -> np.ndarray:
    """Simulated seconds since the first sample, from header stamps or arrival times (``stamp_clock``:
    ``sim`` stamps count simulated seconds; ``wall`` stamps are wall time of a system running
    ``time_scale`` times faster; ``receive`` ignores stamps and reads arrival x time_scale)."""
    if clock == "sim":
        return (np.asarray(stamp_ns, dtype=np.int64) - first[0]) / 1e9
    if clock == "wall":
        return (np.asarray(stamp_ns, dtype=np.int64) - first[0]) / 1e9 * time_scale
    return (np.asarray(recv_ns, dtype=np.int64) - first[1]) / 1e9 * time_scale


def increasing(t: np.ndarray, t_prev: float) -> tuple[np.ndarray, float]:
    """Which times go strictly up from ``t_prev`` (duplicates and reordered samples are dropped), and the last kept."""
    keep = np.zeros(len(t), dtype=bool)
    last = t_prev
    for i, ti in enumerate(t):
        if ti > last:
            keep[i], last = True, ti
    return keep, last


def timed(released: list, first: tuple[int, int], clock: str, time_scale: float, t_prev: float):
    """Rows released by the stamp order (``StampOrder.release``: stamp, row, events) as the judge's
    input: (simulated times, value columns as floats, each one's events, the last time), strictly
    increasing from ``t_prev``; None when no time goes up."""
    rows = np.array([row for _, row, _ in released], dtype=object)
    t = sample_times(rows[:, 0].astype(np.int64), rows[:, 1].astype(np.int64), first, clock, time_scale)
    keep, last = increasing(t, t_prev)
    if not keep.any():
        return None, last
    events = [what for (_, _, what), k in zip(released, keep) if k]
    return (t[keep], rows[keep, 2:].astype(float), events), last


def to_map_frame(x: np.ndarray, y: np.ndarray, yaw: np.ndarray, start: tuple[float, float, float]):
    """Poses relative to the start pose (an odometry frame that begins where the robot was
    spawned, ``odom_frame:=start``) -> map frame."""
    sx, sy, syaw = start
    c, s = math.cos(syaw), math.sin(syaw)
    return sx + c * x - s * y, sy + s * x + c * y, (yaw + syaw + math.pi) % (2 * math.pi) - math.pi
