"""What defines an experiment: the request (ExperimentSpec), its checks, and its identity.

The identity is everything that changes a run's result; ``--resume`` refuses a directory whose
identity differs, so a resumed experiment never mixes runs made under different settings.
"""
from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass, field
from typing import Any

from .. import __version__
from ..core.problem import Budget

# The paper's RQ3 search (population, offspring, evaluations). The pipeline's search carries one
# population on for the whole run and always uses at least these evaluations (see .pipeline).
RQ3_ROUNDS = {
    "robot": Budget(100, 10, 4100),  # NSGA-II, 10 offspring, at most 400 generations
    "vehicle": Budget(100, 25, 5100),  # "5,100 evaluations (population 100, 200 generations, 25 offspring)"
    "thermostat": Budget(100, 25, 5100),  # no paper RQ3: as the vehicle
}
PAPER_RQ3_BUDGET_S = 7200.0


class ExperimentError(ValueError):
    """A bad experiment request (refused before anything is written or overwritten)."""


EXECUTOR_IDLE = ("random", "wait")
SEARCH_FOR = ("certified", "paper")  # --full-model: the problem's ``certified_search`` setting, or the paper's  # an idle executor runs a valid random sample, or waits for the search


@dataclass
class ExperimentSpec:
    problem: str
    algorithms: tuple[str, ...] = ("ga", "nsga2", "random")
    runs: int = 30
    seed: int = 0
    profile: str | None = None
    evaluations: int | None = None
    time_budget: float | None = None
    full_model: bool = False
    config_file: str | None = None
    sim_options: dict[str, Any] = field(default_factory=dict)
    distinct_distance: float = 0.0
    clock: str = "wall"
    executors: int = 1
    execution_cost: float = 0.0
    signature_radius: float | None = None
    executor_idle: str = "random"  # --full-model: what an executor without a candidate does
    search_for: str = "certified"  # --full-model: "certified" (``Problem.certified_search``) | "paper"
    novelty: bool = True  # --full-model: a search's executor skips predicted repeats of found failures

    def check(self) -> None:
        from ..core.search import ALGORITHMS

        if not self.algorithms:
            raise ExperimentError("--algorithms: give at least one")
        for alg in self.algorithms:
            if alg not in ALGORITHMS:
                raise ExperimentError(f"--algorithms: unknown {alg!r} (allowed: {','.join(ALGORITHMS)})")
        if len(set(self.algorithms)) != len(self.algorithms):
            raise ExperimentError("--algorithms: an algorithm is listed twice")
        if self.runs < 1:
            raise ExperimentError("--runs: must be >= 1")
        if self.evaluations is not None and self.time_budget is not None:
            raise ExperimentError("--evaluations and --time-budget exclude each other")
        if self.full_model and self.evaluations is not None:
            raise ExperimentError("--full-model runs on a clock budget (--time-budget)")
        if self.time_budget is not None and not self.time_budget > 0:
            raise ExperimentError("--time-budget: must be > 0 seconds")
        if self.distinct_distance < 0 or self.distinct_distance >= 1:
            raise ExperimentError("--distinct-distance: must be in [0, 1)")
        if self.clock not in ("wall", "cpu"):
            raise ExperimentError("--clock: wall|cpu")
        if self.executors < 1:
            raise ExperimentError("--executors: must be >= 1")
        if not (self.execution_cost >= 0 and self.execution_cost < float("inf")):
            raise ExperimentError("--execution-cost: must be >= 0 seconds")
        if self.search_for not in SEARCH_FOR:
            raise ExperimentError(f"--search-for: {'|'.join(SEARCH_FOR)}")
        if self.executor_idle not in EXECUTOR_IDLE:
            raise ExperimentError(f"--executor-idle: {'|'.join(EXECUTOR_IDLE)}")
        if self.signature_radius is not None and not self.signature_radius >= 0:
            raise ExperimentError("--signature-radius: must be >= 0")


def _plain_json(value: Any) -> Any:
    """The value as JSON would give it back (tuples -> lists, numpy -> Python), for comparisons."""
    return json.loads(json.dumps(value, default=lambda v: v.item() if hasattr(v, "item") else str(v)))


def resolve(spec: ExperimentSpec) -> dict[str, Any]:
    """The experiment's identity: everything that changes a run's result (checked on --resume)."""
    from ..core.config import load_config_file
    from ..problems import problem_class
    from ..run_config import make_run

    spec.check()
    certified = spec.full_model and spec.search_for == "certified"
    defaults = None
    if certified:  # the search hunts the failures of the system the executors run (--set options)
        from ..sims.full_model import sim_config

        case = problem_class(spec.problem)
        defaults = {**case.certified_search, **case.certified_settings(sim_config(spec.problem, spec.sim_options))}
    settings: dict[str, Any] = {}
    problem = None
    file_cfg = load_config_file(spec.config_file)
    for alg in spec.algorithms:
        overrides: dict[str, Any] = {"algorithm": alg, "seed": spec.seed}
        if spec.full_model:
            rnd = RQ3_ROUNDS.get(spec.problem)
            if rnd is None:
                raise ExperimentError(f"--full-model: no RQ3 setting for {spec.problem!r}")
            overrides["evaluations"] = rnd.evaluations  # the search's guaranteed evaluations
            for name in ("population", "offspring"):
                if name not in file_cfg:
                    overrides[name] = getattr(rnd, name)
        else:
            overrides["evaluations"] = spec.evaluations
            overrides["time_budget"] = spec.time_budget
        problem, s = make_run(spec.problem, spec.config_file, profile=spec.profile, problem_defaults=defaults,
                              **overrides)
        entry = dataclasses.asdict(s)
        entry.pop("seed")
        settings[alg] = entry
    assert problem is not None
    identity: dict[str, Any] = {
        "problem": problem.name,
        "profile": problem.profile,
        "problem_config": problem.config_dict(),
        "seed": spec.seed,
        "mode": "rq3_full_model" if spec.full_model else "rq1_rq2_surrogate",
        "settings": settings,
        "ambiegen_ros": __version__,
    }
    if spec.full_model:
        from ..sims.full_model import full_model_executor
        from ..sims.signature import DEFAULT_RADIUS

        executor = full_model_executor(problem, **spec.sim_options)
        identity["full_model"] = {
            "time_budget_s": spec.time_budget or PAPER_RQ3_BUDGET_S,
            "clock": spec.clock,
            "executors": spec.executors,
            "execution_cost_s": spec.execution_cost,
            "distinct_distance": spec.distinct_distance,
            "executor_idle": spec.executor_idle,
            "search_for": spec.search_for,
            "novelty": spec.novelty,
            "signature_radius": (DEFAULT_RADIUS[problem.name] if spec.signature_radius is None
                                 else spec.signature_radius),
            "simulator": executor.config_dict(),
        }
    return _plain_json(identity)


def run_identity(identity: dict[str, Any], algorithm: str) -> dict[str, Any]:
    """What a run file records of the experiment: the shared part plus its algorithm's settings."""
    out = {k: v for k, v in identity.items() if k != "settings"}
    out["algorithm"] = algorithm
    out["settings"] = identity["settings"][algorithm]
    return out


def differences(a: Any, b: Any, prefix: str = "") -> list[str]:
    """Keys (dotted) whose values differ between two JSON-like documents."""
    if isinstance(a, dict) and isinstance(b, dict):
        out = []
        for key in sorted(set(a) | set(b)):
            out += differences(a.get(key), b.get(key), f"{prefix}.{key}" if prefix else str(key))
        return out
    return [] if a == b else [prefix or "(root)"]


__all__ = ["PAPER_RQ3_BUDGET_S", "RQ3_ROUNDS", "SEARCH_FOR", "ExperimentError", "ExperimentSpec",
           "differences", "resolve", "run_identity"]
