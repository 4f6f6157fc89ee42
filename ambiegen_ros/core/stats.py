"""The paper's statistics: two-sided Mann-Whitney U, Cliff's delta and its magnitude, Spearman.

The paper compares algorithms with a two-tailed Mann-Whitney U test and measures the effect
size with Cliff's delta, labelled with the usual thresholds (Romano et al.):
negligible < 0.147 <= small < 0.33 <= medium < 0.474 <= large (on |delta|).
"""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np

MAGNITUDES = ((0.147, "negligible"), (0.33, "small"), (0.474, "medium"))


def _sample(values: Sequence[float]) -> np.ndarray:
    """Finite values only: a missing measurement (NaN/None) is not evidence for either side."""
    a = np.asarray([np.nan if v is None else v for v in values], dtype=float)
    return a[np.isfinite(a)]


def cliffs_delta(a: Sequence[float], b: Sequence[float]) -> float:
    """P(a > b) - P(a < b) over all pairs; NaN when a sample is empty."""
    x, y = _sample(a), _sample(b)
    if len(x) == 0 or len(y) == 0:
        return math.nan
    diff = x[:, None] - y[None, :]
    return float((np.count_nonzero(diff > 0) - np.count_nonzero(diff < 0)) / diff.size)


def magnitude(delta: float) -> str:
    """The paper's label of |delta| ("n/a" for NaN)."""
    if not math.isfinite(delta):
        return "n/a"
    d = abs(delta)
    for limit, label in MAGNITUDES:
        if d < limit:
            return label
    return "large"


def mann_whitney(a: Sequence[float], b: Sequence[float]) -> float:
    """Two-sided Mann-Whitney U p-value (scipy; exact for small samples without ties).

    Two samples made of one and the same value carry no evidence of a difference: p = 1
    (scipy's normal approximation has zero variance there). NaN when a sample is empty.
    """
    from scipy.stats import mannwhitneyu

    x, y = _sample(a), _sample(b)
    if len(x) == 0 or len(y) == 0:
        return math.nan
    if np.ptp(np.concatenate([x, y])) == 0:
        return 1.0
    return float(mannwhitneyu(x, y, alternative="two-sided").pvalue)


def smallest_p(n_a: int, n_b: int) -> float:
    """The smallest two-sided Mann-Whitney p that samples of these sizes can give (exact test, no
    ties, the samples fully apart): 2 / C(n_a + n_b, n_a). 3 runs against 3 can never reach 0.05."""
    if n_a < 1 or n_b < 1:
        return 1.0
    return min(1.0, 2.0 / math.comb(n_a + n_b, n_a))


def greater_exact(a: Sequence[float], b: Sequence[float], limit: int = 200_000) -> tuple[float, float]:
    """(U of a, one-sided p that a is stochastically greater than b), by enumerating every split of
    the pooled values into groups of len(a) and len(b): exact with ties, which count runs of
    distinct failures are full of (0, 0, 0 against 0, 0, 0 gives p = 1, not scipy's 0.65).

    Above ``limit`` splits it falls back to scipy's one-sided test. NaN when a sample is empty."""
    from itertools import combinations

    from scipy.stats import mannwhitneyu, rankdata

    x, y = _sample(a), _sample(b)
    if len(x) == 0 or len(y) == 0:
        return math.nan, math.nan
    if math.comb(len(x) + len(y), len(x)) > limit:
        res = mannwhitneyu(x, y, alternative="greater")
        return float(res.statistic), float(res.pvalue)
    ranks = rankdata(np.concatenate([x, y]))  # midranks: a tie counts half a win each way
    # U of every group a could have been: its rank sum less the least rank sum of that size
    us = ranks[np.array(list(combinations(range(len(ranks)), len(x))))].sum(axis=1) - len(x) * (len(x) + 1) / 2
    u = float(us[0])  # the first group is a itself
    return u, float(np.mean(us >= u - 1e-9))


def compare(metric: str, name_a: str, a: Sequence[float], name_b: str, b: Sequence[float]) -> dict:
    """One row of ``stats.json``: the test and effect size of ``a`` against ``b``."""
    delta = cliffs_delta(a, b)
    p = mann_whitney(a, b)
    return {
        "metric": metric,
        "a": name_a,
        "b": name_b,
        "n_a": int(len(_sample(a))),
        "n_b": int(len(_sample(b))),
        "p_value": None if math.isnan(p) else p,
        "cliffs_delta": None if math.isnan(delta) else delta,
        "magnitude": magnitude(delta),
    }


def roc_auc(score: Sequence[float], label: Sequence[bool]) -> float:
    """P(the score of a random positive > that of a random negative), ties counted half: how well a
    score ranks a 0/1 verdict, (Cliff's delta of positives against negatives + 1) / 2. NaN when a
    class is empty."""
    score, label = np.asarray(score, dtype=float), np.asarray(label, dtype=bool)
    return (cliffs_delta(score[label], score[~label]) + 1.0) / 2.0


def spearman(x: Sequence[float], y: Sequence[float]) -> tuple[float, float, int]:
    """(rho, p-value, n) over the pairs where both are finite; NaN when either side is constant."""
    from scipy.stats import spearmanr

    xa = np.asarray([np.nan if v is None else v for v in x], dtype=float)
    ya = np.asarray([np.nan if v is None else v for v in y], dtype=float)
    keep = np.isfinite(xa) & np.isfinite(ya)
    n = int(keep.sum())
    if n < 3 or np.ptp(xa[keep]) == 0 or np.ptp(ya[keep]) == 0:
        return math.nan, math.nan, n
    res = spearmanr(xa[keep], ya[keep])
    return float(res[0]), float(res[1]), n


__all__ = ["MAGNITUDES", "cliffs_delta", "compare", "greater_exact", "magnitude", "mann_whitney", "roc_auc", "smallest_p", "spearman"]
