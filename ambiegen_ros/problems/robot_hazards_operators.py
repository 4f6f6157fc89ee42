"""The hazards scenario's mutation (issue 48): the generic one exchanges and scrambles elements,
which would turn a wall into the start; this one changes an element within its kind."""
from __future__ import annotations

from pymoo.core.mutation import Mutation

from .robot_hazards import mutate


class HazardMutation(Mutation):
    """With probability ``prob`` per offspring, ``robot_hazards.mutate``: one attribute an element
    uses re-drawn within its kind, or a hazard added or dropped."""

    def __init__(self, prob: float = 0.4):
        super().__init__(prob=prob)

    def _do(self, problem, X, *args, random_state=None, **kwargs):
        case = problem.case
        G, lengths = case.codec.split(X)
        G, lengths = G.copy(), lengths.copy()
        mutate(G, lengths, random_state, case.config)
        return case.codec.join(*case.canonical(G, lengths))
