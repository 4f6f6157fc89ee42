"""AmbieGen's variation operators as pymoo operators (pinned pymoo 0.6.1.6 signatures).

They work on genome rows (see ``core.scenario``) of the pymoo problem ``problem.case`` and never
leave an attribute's domain or the length limits; the case study's own restrictions (24 h
schedules, valid roads, ...) are judged by its ``evaluate`` (invalid = F1 0), as in the paper.

Each offspring remembers the row of the parent whose head it kept (``"ref"``): the paper measures
F2 as the Jaccard distance between a child and its parent.
"""
from __future__ import annotations

import numpy as np
from pymoo.core.crossover import Crossover
from pymoo.core.duplicate import DuplicateElimination
from pymoo.core.mutation import Mutation
from pymoo.core.problem import Problem as PymooProblem
from pymoo.core.sampling import Sampling

from .problem import Problem


class CaseStudyProblem(PymooProblem):
    """The pymoo view of a case study: genome rows as variables; evaluation happens in ``search``."""

    def __init__(self, case: Problem, n_obj: int, n_ieq_constr: int):
        codec = case.codec
        xl = [float(codec.m_min)] + [a.low for a in codec.attributes] * codec.m_max
        xu = [float(codec.m_max)] + [a.high for a in codec.attributes] * codec.m_max
        super().__init__(n_var=codec.n_var, n_obj=n_obj, n_ieq_constr=n_ieq_constr, xl=xl, xu=xu)
        self.case = case


class ScenarioSampling(Sampling):
    """Initial population from the case study's sampler (uniform or Markov chain, per its config)."""

    def _do(self, problem, n_samples, *args, random_state=None, **kwargs):
        return problem.case.sample_rows(n_samples, random_state)


class OnePointCrossover(Crossover):
    """Variable-length one-point crossover: cut k in 1..min(m1, m2) - 1, tails swapped.

    Child 1 = head of parent 1 + tail of parent 2 (length m2), child 2 the converse (length m1), so
    children inherit legal lengths. Parents shorter than 2 elements are copied unchanged.
    """

    def __init__(self, prob: float = 1.0):
        super().__init__(n_parents=2, n_offsprings=2, prob=prob)

    def _do(self, problem, X, *args, random_state=None, **kwargs):
        codec = problem.case.codec
        A, len_a = codec.split(X[0])
        B, len_b = codec.split(X[1])
        shortest = np.minimum(len_a, len_b)
        # k uniform in [1, shortest - 1]; k = m_max (no swap) where shortest < 2
        k = np.where(shortest >= 2, 1 + np.floor(random_state.random(len(A)) * np.maximum(shortest - 1, 1)), codec.m_max)
        head = (np.arange(codec.m_max)[None, :] < k[:, None])[:, :, None]
        child1 = np.where(head, A, B)
        child2 = np.where(head, B, A)
        len1 = np.where(shortest >= 2, len_b, len_a)
        len2 = np.where(shortest >= 2, len_a, len_b)
        return np.stack([codec.join(child1, len1), codec.join(child2, len2)])

    def do(self, problem, pop, parents=None, *args, random_state=None, **kwargs):
        off = super().do(problem, pop, parents, *args, random_state=random_state, **kwargs)
        # pymoo lays offspring out as (n_offsprings, n_matings) flattened: child o of mating j
        # is off[o * n_matings + j]; its reference parent is parent o of that mating.
        matings = [pop[m] for m in parents] if parents is not None else pop
        n_matings = len(matings)
        for index, child in enumerate(off):
            o, j = divmod(index, n_matings)
            child.set("ref", matings[j][o].get("X"))
        return off


class ScenarioMutation(Mutation):
    """With probability ``prob`` per offspring, one of: exchange, change-of-variable, scramble."""

    OPERATORS = ("exchange", "change", "scramble")

    def __init__(self, prob: float = 0.4):
        super().__init__(prob=prob)

    def _do(self, problem, X, *args, random_state=None, **kwargs):
        codec = problem.case.codec
        G, lengths = codec.split(X)
        G = G.copy()
        rng = random_state
        choice = rng.integers(0, 3, size=len(G))
        for i in range(len(G)):
            m = lengths[i]
            if choice[i] == 1 or m < 2:
                self._change(G[i], m, codec.attributes, rng)
            elif choice[i] == 0:
                a, b = rng.choice(m, size=2, replace=False)
                G[i, [a, b]] = G[i, [b, a]]
            else:
                size = rng.integers(2, m + 1)
                picked = np.sort(rng.choice(m, size=size, replace=False))
                G[i, picked] = G[i, rng.permutation(picked)]
        return codec.join(G, lengths)

    @staticmethod
    def _change(cells: np.ndarray, m: int, attributes, rng: np.random.Generator) -> None:
        """Re-draw one attribute of one element within its domain (a different value if any)."""
        if m < 1:
            return
        element = rng.integers(0, m)
        j = rng.integers(0, len(attributes))
        attr = attributes[j]
        old = cells[element, j]
        for _ in range(20):
            new = float(attr.sample(rng, 1)[0])
            if new != old:
                break
        cells[element, j] = new


class ScenarioDuplicateElimination(DuplicateElimination):
    """Duplicates of the same environment: equal canonical genomes (``Problem.canonical``: padding
    zeroed, cells the environment ignores set to one value), compared by their row bytes.

    Without the canonical form a population can fill with clones that differ only in ignored
    cells (a straight's angle), which the replication code's encoding cannot even express.
    """

    def __init__(self, case: Problem | None = None):
        super().__init__()
        self.case = case

    def _keys(self, pop) -> list[bytes]:
        X = np.asarray(pop.get("X"), dtype=float)
        if self.case is not None and len(X):
            codec = self.case.codec
            X = codec.join(*self.case.canonical(*codec.split(X)))
        return [row.tobytes() for row in X]

    def _do(self, pop, other, is_duplicate):
        seen = set() if other is None else set(self._keys(other))
        for i, k in enumerate(self._keys(pop)):
            if k in seen:
                is_duplicate[i] = True
            elif other is None:
                seen.add(k)
        return is_duplicate
