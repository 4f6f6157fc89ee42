"""Vehicle search operators, replication profile (issue 17; figures in ``docs/vehicle_search.md``).

The replication code (RQ1_RQ2/Vehicle_case_study, Pymoo_GA / Pymoo_MO) rebuilds a road after every
operator and drops the elements from the first one whose road point leaves the map; its
``MyDuplicateElimination`` compares those cut roads. Our genomes keep such a tail (the car never
drives it), and comparing genomes let clones of one road, differing only past the map edge, fill
a GA population: the runs that got stuck. ``RoadDuplicateElimination`` compares roads as theirs
does, and is what the replication profile's search uses (``VehicleProblem.search_operators``),
with our sampling, crossover and mutation.

Their sampling, crossover and mutation are written here too (``authors_operators``), for the
measurement only: with every road scored from a fresh car they get less far than ours (theirs may
owe part of their figures to their car keeping its speed between two scorings of one object: their
GA scores mutated copies of uncrossed parents again, pymoo 0.4.2 crossing with probability 0.9):

* every child is cut to the road it builds (``cut_to_road``);
* mutation, per child with the mutation rate, a draw w in 1..101 (``randint(1, 101)``): w < 20
  exchange two elements (positions drawn with replacement, so sometimes none moves);
  20 <= w <= 40 flip one element's kind (a straight becomes a left or right turn with a new
  angle, a turn a straight with a new length); else swap ``m // 2`` positions (drawn with
  replacement) pair by pair and re-draw the value of an odd one left over. New values come from
  the sampler's domains (theirs stop one step short of the top: lengths to 49, angles to 80);
* crossover: one-point as ours, only when both parents have more than two elements (else copies).
"""
from __future__ import annotations

import copy

import numpy as np
from pymoo.core.mutation import Mutation
from pymoo.core.variable import get

from ...core.attributes import IntRange
from ...core.operators import OnePointCrossover, ScenarioDuplicateElimination, ScenarioSampling
from .config import ANGLE, LEFT, LENGTH, RIGHT, STRAIGHT, TYPE
from .replication_road import replication_points

DRAW_HIGH, EXCHANGE_BELOW, FLIP_UP_TO = 101, 20, 40  # w in 1..101: w < 20 exchange, w <= 40 flip, else pairs


def cut_to_road(case, X: np.ndarray) -> np.ndarray:
    """Genome rows cut to the elements their road keeps (replication profile), in canonical form."""
    G, lengths = case.codec.split(X)
    G, lengths = case.canonical(G, lengths)
    if len(lengths):
        lengths = np.maximum(np.minimum(lengths, replication_points(G, lengths, case.config)[2]), case.m_min)
    return case.codec.join(G, lengths)


class RoadDuplicateElimination(ScenarioDuplicateElimination):
    """Duplicates of the same road: canonical genomes cut to the elements the road keeps (the
    replication code compares its cut ``states``), whatever the genomes hold past the map edge."""

    def _keys(self, pop) -> list[bytes]:
        X = np.asarray(pop.get("X"), dtype=float)
        return [row.tobytes() for row in (cut_to_road(self.case, X) if len(X) else X)]


class RoadSampling(ScenarioSampling):
    """The replication sampler's roads, cut to what they build."""

    def _do(self, problem, n_samples, *args, random_state=None, **kwargs):
        return cut_to_road(problem.case, super()._do(problem, n_samples, *args, random_state=random_state, **kwargs))


class RoadCrossover(OnePointCrossover):
    """One-point crossover when both parents have more than two elements (else copies); children cut."""

    def _do(self, problem, X, *args, random_state=None, **kwargs):
        Y = super()._do(problem, X, *args, random_state=random_state, **kwargs)
        codec = problem.case.codec
        too_short = (codec.split(X[0])[1] <= 2) | (codec.split(X[1])[1] <= 2)
        Y[:, too_short] = X[:, too_short]
        return cut_to_road(problem.case, Y.reshape(-1, Y.shape[-1])).reshape(Y.shape)


class RoadMutation(Mutation):
    """Exchange / flip / pairs, as the replication code's ``MyTcMutation``; children cut."""

    def __init__(self, prob: float = 0.4):
        super().__init__(prob=prob)

    def do(self, problem, pop, inplace=True, *args, random_state=None, **kwargs):
        """pymoo's ``Mutation.do`` (each child mutated with probability ``prob``), but the operators
        and the cut run on the children drawn only: building roads is the costly part."""
        if not inplace:
            pop = copy.deepcopy(pop)
        rng = random_state if random_state is not None else np.random.default_rng()
        chosen = np.flatnonzero(rng.random(len(pop)) <= float(get(self.prob)))
        if len(chosen):
            pop[chosen].set("X", self._do(problem, pop[chosen].get("X"), *args, random_state=rng, **kwargs))
        return pop

    def _do(self, problem, X, *args, random_state=None, **kwargs):
        case = problem.case
        G, lengths = case.codec.split(X)
        G = G.copy()
        rng = random_state
        length_attr, angle_attr = self.value_domains(case)
        for i in range(len(G)):
            m = int(lengths[i])
            if m < 1:
                continue
            draw = int(rng.integers(1, DRAW_HIGH + 1))
            if draw < EXCHANGE_BELOW:
                a, b = rng.integers(0, m, size=2)
                G[i, [a, b]] = G[i, [b, a]]
            elif draw <= FLIP_UP_TO:
                self._flip(G[i, int(rng.integers(0, m))], length_attr, angle_attr, rng)
            else:
                self._swap_pairs(G[i], m, length_attr, angle_attr, rng)
        return cut_to_road(case, case.codec.join(G, lengths))

    @staticmethod
    def value_domains(case) -> tuple[IntRange, IntRange]:
        """Lengths and angles a mutation draws: the sampler's (angles from ``sample_angle_min``)."""
        _, length_attr, angle_attr = case.attributes
        low = max(int(case.config.sample_angle_min), int(angle_attr.low))
        return length_attr, IntRange(angle_attr.name, low, angle_attr.high, angle_attr.step)

    @staticmethod
    def _redraw_value(cell: np.ndarray, length_attr, angle_attr, rng) -> None:
        if cell[TYPE] == STRAIGHT:
            cell[LENGTH] = float(length_attr.sample(rng, 1)[0])
        else:
            cell[ANGLE] = float(angle_attr.sample(rng, 1)[0])

    @classmethod
    def _flip(cls, cell: np.ndarray, length_attr, angle_attr, rng) -> None:
        """A straight becomes a left or right turn, a turn a straight; its value is drawn anew."""
        cell[TYPE] = float(rng.choice([LEFT, RIGHT])) if cell[TYPE] == STRAIGHT else float(STRAIGHT)
        cls._redraw_value(cell, length_attr, angle_attr, rng)

    @classmethod
    def _swap_pairs(cls, cells: np.ndarray, m: int, length_attr, angle_attr, rng) -> None:
        """``m // 2`` positions drawn with replacement, swapped two by two in random order; an odd
        one left over gets a new value."""
        picked = list(rng.integers(0, m, size=m // 2))
        while picked:
            first = picked.pop(int(rng.integers(0, len(picked))))
            if not picked:
                cls._redraw_value(cells[first], length_attr, angle_attr, rng)
                break
            second = picked.pop(int(rng.integers(0, len(picked))))
            cells[[first, second]] = cells[[second, first]]


def authors_operators(mutation_rate: float, crossover_rate: float) -> dict:
    """The replication code's sampling, crossover and mutation (with the cut). Not the replication
    profile's search: scored honestly they are weaker than ours (``docs/vehicle_search.md``);
    ``bench/vehicle_search_diagnosis.py --operators authors`` measures them."""
    return dict(
        sampling=RoadSampling(),
        crossover=RoadCrossover(prob=crossover_rate),
        mutation=RoadMutation(prob=mutation_rate),
    )
