"""A tiny case study for testing the engine without the real surrogates.

F1 = sum of `size` over elements of kind "a" (+ 0.1 * weight); invalid when more than 6 elements.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ambiegen_ros.core.attributes import Categorical, FloatInterval, IntRange
from ambiegen_ros.core.problem import Budget, Evaluation, Problem


@dataclass(frozen=True)
class ToyConfig:
    alpha: float = 20.0
    max_valid_length: int = 6


class ToyProblem(Problem):
    name = "toy"
    attributes = (
        Categorical("kind", ("a", "b", "c")),
        IntRange("size", 2, 10, 2, tolerance=2),
        FloatInterval("weight", -1.0, 1.0, tolerance=0.25),
    )
    m_min = 1
    m_max = 8
    f1_label = "toy"
    paper_budget = Budget(20, 10, 200)
    Config = ToyConfig

    def sample(self, n, rng):
        lengths = rng.integers(self.m_min, self.m_max + 1, size=n)
        G = np.stack([a.sample(rng, (n, self.m_max)) for a in self.attributes], axis=-1)
        return G, lengths

    def evaluate(self, G, lengths):
        used = np.arange(self.m_max)[None, :] < lengths[:, None]
        score = np.sum(np.where(used & (G[:, :, 0] == 0), G[:, :, 1], 0.0), axis=1)
        score += 0.1 * np.sum(np.where(used, G[:, :, 2], 0.0), axis=1)
        valid = lengths <= self.config.max_valid_length
        reasons = [None if v else f"too long: {m} > {self.config.max_valid_length}" for v, m in zip(valid, lengths)]
        return Evaluation(np.where(valid, score, 0.0), valid, reasons, {"length": lengths.astype(float)})

    def environment(self, scenario):
        return scenario.elements
