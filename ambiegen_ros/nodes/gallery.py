"""Pictures of a logged run's distinct certified failures: what a tester looks at first.

Read from the MCAP alone (``replay.recorded_scenarios``), so a campaign, a launch and a copied log
all give the same pictures. The problem is rebuilt from the run config the log records; failures
are grouped by what failed (``sims.signature``, greedy in scenario order, as RQ3 counts them); each
distinct one is executed again in process with the scenario's recorded seed, so that the picture
has the full run (a thermostat's curves), and drawn from the logged trajectory when the run is not
the logged one (another model, another machine's numbers). A system under test's result (one that
came through ``sut_adapter``: Nav2, the ND stack) is always drawn as logged, and its picture's title
names that system (``system_of``), never our full model. The first failure counted as the same
as an earlier one is drawn beside it (``same_failure_<a>_<b>.png``), so a reader can judge the
grouping. Files are never overwritten.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from ..problems import get_problem
from ..ros.runlog import read_metadata
from ..sims.known_failures import is_known
from ..sims.signature import DistinctFailures, same_failure, signature
from .replay import recorded_scenarios

PICTURES_KEPT = 12


def draw_failures(mcap: str | Path, out_dir: str | Path, limit: int = PICTURES_KEPT) -> dict[str, Any]:
    """One PNG per distinct certified failure (up to ``limit``) in ``out_dir``; what was drawn."""
    from ..sims.full_model import full_model_executor, scenario_seed
    from ..viz.execution import save_execution_plot, save_side_by_side

    rec = recorded_scenarios(mcap)
    config = json.loads(read_metadata(mcap).get("ambiegen_run", {}).get("config_json", "{}") or "{}")
    problem_config = dict(config.get("problem_config") or {})
    problem = get_problem(rec.problem, problem_config)
    full = full_model_executor(problem) if config.get("sim_model", "full") == "full" else None
    workers = "full model" if full is not None else "surrogate"  # what the sim workers ran
    distinct = DistinctFailures()
    pictures: list[dict[str, Any]] = []
    pair: dict[str, Any] | None = None  # what was drawn of it (None: nothing new)
    paired = False
    first_of: list[tuple[Any, int]] = []  # (distinct signature, its scenario id)
    out_dir = Path(out_dir)

    runs: dict[int, Any] = {}

    def shown(sid: int):  # the full run when it is the logged one, else the logged trajectory (each run once)
        if sid not in runs:
            logged = runs[sid] = rec.outcomes[sid]
            if full is not None and not from_system_under_test(logged):
                again = full.execute(rec.scenarios[sid], seed=scenario_seed(rec.seed, sid))
                if again.failure_kind == logged.failure_kind:
                    runs[sid] = again
        return runs[sid]

    known = 0
    for sid in sorted(rec.outcomes):
        logged, scenario = rec.outcomes[sid], rec.scenarios.get(sid)
        sig = None if scenario is None else signature(problem, scenario, logged)
        if sig is None:
            continue
        if is_known(logged):  # a limit its engineers know (sims.known_failures): recorded, not counted as new
            known += 1
            continue
        if not distinct.add(sig):
            if not paired:  # the first failure counted as an earlier one, and only that one
                paired = True
                a = next(first for s, first in first_of if same_failure(sig, s))
                path = out_dir / f"same_failure_{a:05d}_{sid:05d}.png"
                if not path.exists():
                    first, second = shown(a), shown(sid)
                    save_side_by_side(problem, [(rec.scenarios[a], first), (scenario, second)], path,
                                      f"counted as one failure: {sig.describe()}",
                                      [system_of(first, workers), system_of(second, workers)])
                    pair = {"scenario_ids": [a, sid], "signature": sig.describe(), "path": str(path)}
            continue
        first_of.append((sig, sid))
        path = out_dir / f"failure_{sid:05d}_{sig.kind}.png"
        if len(pictures) >= limit or path.exists():  # never drawn over: an earlier picture stays
            continue
        drawn = shown(sid)
        save_execution_plot(problem, scenario, drawn, path, system=system_of(drawn, workers))
        pictures.append({"scenario_id": sid, "signature": sig.describe(), "path": str(path)})
    return {"certified_failures": len(distinct.seen) + known, "known_failures": known,
            "distinct_failures": len(distinct),
            "failure_pictures": pictures, "same_failure_pair": pair}


def from_system_under_test(outcome: Any) -> bool:
    """A result ``sim_nodes/sut_adapter`` published (it adds the stamps' clock to every result, and
    Nav2's own status to Nav2's); a sim worker's full model or surrogate adds neither."""
    metrics = outcome.metrics or {}
    return "stamp_clock" in metrics or "nav2_status" in metrics


def system_of(outcome: Any, workers: str = "full model") -> str:
    """Who drove a run, for its picture's title: Nav2 or another system under test, with the time
    scale it ran at; else ``workers``, what the run's sim workers ran (our full model)."""
    metrics = outcome.metrics or {}
    if not from_system_under_test(outcome):
        return workers
    name = "Nav2" if "nav2_status" in metrics else "system under test"
    try:
        scale = float(metrics.get("time_scale") or 0.0)
    except (TypeError, ValueError):
        scale = 0.0
    return f"{name} (time scale {scale:g})" if scale > 0 else name
