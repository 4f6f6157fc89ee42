"""``--rerank learned``: executed outcomes correct the surrogate's ranking (issue 16, section 3).

The surrogate ranks; the full model decides. A logistic regression (numpy, L2-regularised, fitted
by Newton's method) predicts the probability that a candidate is a certified failure from its
genome row and the surrogate's numbers (F1 and the numeric metrics of its evaluation). It is
refitted every ``refit_every`` executions once both outcomes have been seen; the waiting candidates
are then re-ordered by that probability. Until then (and for random search, which executes in the
order sampled) the surrogate's F1 orders them. Invalid tests and passes are both "not a failure".
"""
from __future__ import annotations

import numpy as np


class FailureModel:
    """P(certified failure | candidate), learned from this run's executions."""

    def __init__(self, problem, refit_every: int = 10, l2: float = 1.0, iterations: int = 25):
        self.problem = problem
        self.refit_every, self.l2, self.iterations = max(1, int(refit_every)), float(l2), int(iterations)
        self._keys: list[str] | None = None  # the surrogate metrics used, fixed by the first candidate
        self._X: list[np.ndarray] = []
        self._y: list[float] = []
        self.weights: np.ndarray | None = None
        self._mean = self._scale = None
        self.fits = 0

    def features(self, candidates) -> np.ndarray:
        if self._keys is None:
            self._keys = sorted(candidates[0].metrics) if candidates else []
        return np.array([np.concatenate([np.nan_to_num(c.row, nan=0.0), [c.f1],
                                         [c.metrics.get(k, 0.0) for k in self._keys]]) for c in candidates], dtype=float)

    def learn(self, candidate, outcome) -> bool:
        """Add one executed candidate; True when the model was refitted (re-order the queue)."""
        self._X.append(self.features([candidate])[0])
        self._y.append(1.0 if outcome.failed else 0.0)
        if len(self._y) % self.refit_every or len(set(self._y)) < 2:
            return False
        self.fit(np.array(self._X), np.array(self._y))
        return True

    def fit(self, X: np.ndarray, y: np.ndarray) -> None:
        """Newton's method on the L2-regularised log-likelihood (standardised features, free intercept)."""
        self._mean = X.mean(axis=0)
        self._scale = np.where(X.std(axis=0) > 1e-12, X.std(axis=0), 1.0)
        Z = np.column_stack([np.ones(len(X)), (X - self._mean) / self._scale])
        w = np.zeros(Z.shape[1])
        penalty = np.full(Z.shape[1], self.l2)
        penalty[0] = 0.0
        for _ in range(self.iterations):
            p = 1.0 / (1.0 + np.exp(-np.clip(Z @ w, -30, 30)))
            grad = Z.T @ (p - y) + penalty * w
            H = (Z * (p * (1 - p))[:, None]).T @ Z + np.diag(penalty + 1e-9)
            step = np.linalg.solve(H, grad)
            w -= step
            if np.max(np.abs(step)) < 1e-6:
                break
        self.weights = w
        self.fits += 1

    def probability(self, X: np.ndarray) -> np.ndarray:
        Z = np.column_stack([np.ones(len(X)), (X - self._mean) / self._scale])
        return 1.0 / (1.0 + np.exp(-np.clip(Z @ self.weights, -30, 30)))

    def score(self, candidates) -> np.ndarray:
        """Higher = executed sooner: the failure probability once fitted, the surrogate F1 before."""
        if self.weights is None:
            return np.array([c.f1 for c in candidates], dtype=float)
        return self.probability(self.features(candidates))


__all__ = ["FailureModel"]
