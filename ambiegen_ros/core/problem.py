"""The one small interface every case study implements (the paper's extension point).

It lives in ``core`` because the search engine, the run records and the operators work on it;
the case studies themselves live in ``ambiegen_ros.problems``.

A problem supplies: its attributes and length limits, a sampler for the initial population, the
"TC to environment" step (``environment``), and the surrogate fitness (``evaluate``). Everything
works on whole batches: ``G`` is a ``(P, m_max, n_attr)`` float array of attribute codes (see
``core.attributes``) and ``lengths`` a ``(P,)`` int array; cells past a row's length are 0.

Every number of a case study is a field of its ``Config`` dataclass, so it can be overridden from a
YAML file or a ROS parameter and is recorded in each run's ``config.json``.

Fidelity profiles: every Config has a ``profile`` field. ``replication`` (the default) reproduces
the authors' replication code, which produced the paper's tables (its domains, sampler, validity
rules and surrogate); ``refined`` keeps the models as the paper's equations and the project spec
write them. A profile may change the attribute domains and length limits, so a problem instance
takes them from ``layout()`` rather than from the class.
"""
from __future__ import annotations

import dataclasses
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import Any, ClassVar, Sequence

import numpy as np

from .attributes import Attribute, ScenarioError
from .scenario import GenomeCodec, Scenario
from .names import DEFAULT_PROFILE, PROFILES


def check_profile(value: Any) -> str:
    """Validate a Config's ``profile`` field (called from each Config's ``__post_init__``)."""
    if value not in PROFILES:
        raise ScenarioError("config.profile", f"unknown profile {value!r}", "|".join(PROFILES))
    return value


@dataclass(frozen=True)
class Budget:
    """Population size, offspring per generation and total evaluations (paper defaults)."""

    population: int
    offspring: int
    evaluations: int


@dataclass
class Evaluation:
    """Surrogate results for a batch: F1 (0 where invalid), validity, the broken rule, metrics."""

    f1: np.ndarray
    valid: np.ndarray
    reasons: list[str | None]
    metrics: dict[str, np.ndarray] = field(default_factory=dict)

    def row(self, i: int) -> dict[str, Any]:
        """One scenario's result as plain JSON-ready values."""
        out: dict[str, Any] = {
            "valid": bool(self.valid[i]),
            "reason": self.reasons[i],
            "f1": float(self.f1[i]),
        }
        for key, values in self.metrics.items():
            value = values[i]
            out[key] = value.item() if hasattr(value, "item") else value
        return out


class Problem(ABC):
    """Base class of a case study. Subclasses set the class variables and implement three methods."""

    name: ClassVar[str]
    attributes: ClassVar[tuple[Attribute, ...]]
    m_min: ClassVar[int]
    m_max: ClassVar[int]
    f1_label: ClassVar[str]  # e.g. "RMSE [degC]" for plots and summaries
    paper_budget: ClassVar[Budget]
    Config: ClassVar[type]  # a dataclass with every tunable number; must have an ``alpha`` field
    # problem_config a search for *certified* failures runs with by default (``experiment --full-model``,
    # issue 26): the surrogate's validity is the reference's static check, its F1 relative to the
    # reference. Empty: the paper's own setting is that search.
    certified_search: ClassVar[dict[str, Any]] = {}

    @classmethod
    def certified_settings(cls, sim_config: Any) -> dict[str, Any]:
        """problem_config that makes the certified surrogate model the system the full model runs
        with ``sim_config`` (its controller, say); added to ``certified_search``. Empty: nothing to copy."""
        return {}

    def __init__(self, config: Any = None, **overrides: Any):
        # Config fields may default per profile (None resolved in __post_init__): build the config
        # from the values given, so that e.g. profile="refined" gets the refined defaults.
        if config is None:
            config = self.config_from_dict(overrides)
        elif isinstance(config, dict):
            config = self.config_from_dict({**config, **overrides})
        elif overrides:
            config = dataclasses.replace(config, **overrides)
        self.config = config
        self.attributes, self.m_min, self.m_max = self.layout()
        self.codec = GenomeCodec(self.name, self.attributes, self.m_min, self.m_max)

    def layout(self) -> tuple[tuple[Attribute, ...], int, int]:
        """Attribute domains and length limits of this instance's profile (default: the class's)."""
        cls = type(self)
        return cls.attributes, cls.m_min, cls.m_max

    @property
    def profile(self) -> str:
        """The fidelity profile of this instance (``replication`` or ``refined``)."""
        return str(getattr(self.config, "profile", DEFAULT_PROFILE))

    # --- configuration ---------------------------------------------------------------------
    @classmethod
    def config_from_dict(cls, data: dict[str, Any]) -> Any:
        """Build a Config from a dict, naming any unknown key (bad input never passes silently)."""
        known = {f.name: f for f in dataclasses.fields(cls.Config)}
        unknown = set(data) - set(known)
        if unknown:
            raise ScenarioError(
                f"config.{sorted(unknown)[0]}", f"unknown {cls.name} parameter", ", ".join(sorted(known))
            )
        return cls.Config(**data)

    def config_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self.config)

    @property
    def alpha(self) -> float:
        """MO constraint threshold: a scenario is 'risky' when F1 > alpha."""
        return float(self.config.alpha)

    # --- the three parts a case study supplies -----------------------------------------------
    @abstractmethod
    def sample(self, n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """Draw ``n`` initial scenarios as ``(G, lengths)``; every cell inside its domain."""

    @abstractmethod
    def evaluate(self, G: np.ndarray, lengths: np.ndarray) -> Evaluation:
        """Check the problem's restrictions and compute the surrogate F1 for a whole batch."""

    @abstractmethod
    def environment(self, scenario: Scenario) -> Any:
        """'TC to environment': the concrete environment (schedule, map, road) of one scenario."""

    def canonical(self, G: np.ndarray, lengths: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The canonical genomes of a batch: two genomes of the same environment become equal.

        Default: as they are. A problem whose environment ignores some cells (a straight's angle,
        a schedule's elements past 24 h) sets them to one value; the search's duplicate
        elimination compares canonical genomes.
        """
        return G, lengths

    def loop_f1(self, outcome: Any) -> float:
        """F1 of an executed scenario (a ``sims.outcome.Outcome``) for a search in the loop.
        Default: the execution's first objective; a problem may offer others in its config."""
        return outcome.f1

    def search_operators(self, settings: Any) -> dict[str, Any]:
        """pymoo operators this problem replaces for its profile (keys of pymoo's GA/NSGA2
        arguments: ``eliminate_duplicates``, ``mutation``, ...). Default: none, the generic ones."""
        return {}

    # --- conveniences built on the three parts ---------------------------------------------------
    def parse(self, data: dict[str, Any]) -> Scenario:
        return self.codec.validate(data)

    def evaluate_rows(self, X: np.ndarray) -> Evaluation:
        return self.evaluate(*self.codec.split(X))

    def evaluate_scenarios(self, scenarios: Sequence[Scenario]) -> Evaluation:
        X = np.stack([self.codec.to_row(s) for s in scenarios])
        return self.evaluate_rows(X)

    def sample_rows(self, n: int, rng: np.random.Generator) -> np.ndarray:
        return self.codec.join(*self.sample(n, rng))
