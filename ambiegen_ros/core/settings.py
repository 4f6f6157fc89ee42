"""What defines a search run (``SearchSettings``, recorded in ``config.json``): a plain dataclass.

Apart from the search itself (``core.search``, which imports pymoo and, through it, scipy) so that
reading a run config and building a problem from it (``core.config``, ``run_config``: ``ambiegen
evaluate --config``) start without the search. ``core.search`` re-exports both names.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING

from .names import ALGORITHMS, REFERENCES

if TYPE_CHECKING:
    from .problem import Problem

SUITES = ("best", "population")  # what a search hands on to be executed (``SearchSettings.suite``)


@dataclass
class SearchSettings:
    """Everything that defines a run (recorded in ``config.json``). ``None`` = problem default."""

    algorithm: str = "nsga2"
    evaluations: int | None = None
    time_budget: float | None = None
    population: int | None = None
    offspring: int | None = None
    seed: int = 0
    reference: str = "parent"
    mutation_rate: float = 0.4
    crossover_rate: float = 1.0
    suite_size: int = 10
    suite: str = "best"  # "best": the paper's (SO: the suite_size best; MO: the feasible front) | "population"
    restarts: int = 1  # independent searches sharing the budget; their suites interleave (not random search's)

    def resolved(self, problem: Problem) -> "SearchSettings":
        """Fill unset values from the problem's paper budget and check them."""
        if self.algorithm not in ALGORITHMS:
            raise ValueError(f"algorithm: unknown {self.algorithm!r} (allowed: {'|'.join(ALGORITHMS)})")
        if self.reference not in REFERENCES:
            raise ValueError(f"reference: unknown {self.reference!r} (allowed: {'|'.join(REFERENCES)})")
        if self.suite not in SUITES:
            raise ValueError(f"suite: unknown {self.suite!r} (allowed: {'|'.join(SUITES)})")
        budget = problem.paper_budget
        out = SearchSettings(**asdict(self))
        if out.evaluations is None and out.time_budget is None:
            out.evaluations = budget.evaluations
        out.population = out.population or budget.population
        out.offspring = out.offspring or budget.offspring
        for name in ("population", "offspring"):
            if getattr(out, name) < 2:
                raise ValueError(f"{name}: must be >= 2")
        if out.evaluations is not None and out.evaluations < 1:
            raise ValueError("evaluations: must be >= 1")
        if out.restarts < 1:
            raise ValueError("restarts: must be >= 1")
        if out.restarts > 1 and out.evaluations is not None and out.evaluations < out.restarts * out.population:
            raise ValueError(f"restarts: {out.restarts} searches need at least {out.restarts * out.population} "
                             f"evaluations (a population each), not {out.evaluations}")
        if out.time_budget is not None and out.time_budget <= 0:
            raise ValueError("time_budget: must be > 0 seconds")
        return out


__all__ = ["SUITES", "SearchSettings"]
