"""Jaccard distance between scenarios (the paper's F2) and diversity statistics.

Two elements at the same position are "the same" when every categorical attribute is equal and
every numeric attribute differs by at most its tolerance. With ``I`` such positions and lengths
``m_a``, ``m_b``: ``F2 = 1 - I / (m_a + m_b - I)``. Vectorised over pairs of rows.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from .attributes import Attribute


def jaccard_distance(
    G_a: np.ndarray, len_a: np.ndarray, G_b: np.ndarray, len_b: np.ndarray, attributes: Sequence[Attribute]
) -> np.ndarray:
    """Row-wise distance between batches ``a[i]`` and ``b[i]`` (shapes ``(P, m_max, n)``)."""
    same = np.ones(G_a.shape[:2], dtype=bool)
    for j, attr in enumerate(attributes):
        same &= attr.same(G_a[:, :, j], G_b[:, :, j])
    both = np.arange(G_a.shape[1])[None, :] < np.minimum(len_a, len_b)[:, None]
    inter = np.sum(same & both, axis=1)
    union = len_a + len_b - inter
    return np.where(union > 0, 1.0 - inter / np.maximum(union, 1), 0.0)


def pairwise_jaccard(G: np.ndarray, lengths: np.ndarray, attributes: Sequence[Attribute]) -> np.ndarray:
    """Symmetric ``(P, P)`` distance matrix of one batch."""
    n = len(G)
    ii, jj = np.triu_indices(n, k=1)
    out = np.zeros((n, n))
    if len(ii):
        d = jaccard_distance(G[ii], lengths[ii], G[jj], lengths[jj], attributes)
        out[ii, jj] = d
        out[jj, ii] = d
    return out


def mean_pairwise_diversity(G: np.ndarray, lengths: np.ndarray, attributes: Sequence[Attribute]) -> float:
    """The paper's suite diversity: mean F2 over all unordered pairs (0 for fewer than 2)."""
    n = len(G)
    if n < 2:
        return 0.0
    D = pairwise_jaccard(G, lengths, attributes)
    return float(D[np.triu_indices(n, k=1)].mean())


def nearest_distance(
    G: np.ndarray, lengths: np.ndarray, G_ref: np.ndarray, len_ref: np.ndarray, attributes: Sequence[Attribute]
) -> np.ndarray:
    """For each row of ``G``: the distance to its nearest row of the reference set (1 if empty)."""
    if len(G_ref) == 0:
        return np.ones(len(G))
    n, r = len(G), len(G_ref)
    ia = np.repeat(np.arange(n), r)
    ib = np.tile(np.arange(r), n)
    d = jaccard_distance(G[ia], lengths[ia], G_ref[ib], len_ref[ib], attributes)
    return d.reshape(n, r).min(axis=1)
