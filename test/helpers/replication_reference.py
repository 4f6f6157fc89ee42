"""The replication code's verdicts on our scenario format (a copy of part of the shared reference).

Each line of ``test/data/replication/<problem>.jsonl`` holds a scenario and the verdict (validity, F1)
of the authors' replication code, which produced the paper's tables. ``agreement`` scores a
problem against them the way the fidelity requirement is stated: validity agreement over all
scenarios, F1 equality (to ``tol``) over the scenarios valid in both.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

DATA = Path(__file__).resolve().parents[1] / "data" / "replication"


def load(problem: str) -> list[dict]:
    with open(DATA / f"{problem}.jsonl") as fh:
        return [json.loads(line) for line in fh if line.strip()]


@dataclass
class Agreement:
    total: int = 0
    valid_agree: int = 0
    both_valid: int = 0
    f1_equal: int = 0
    mismatches: list = field(default_factory=list)  # (index, sampler, ours, theirs)

    @property
    def validity_rate(self) -> float:
        return self.valid_agree / max(self.total, 1)

    @property
    def f1_rate(self) -> float:
        return self.f1_equal / max(self.both_valid, 1)


def agreement(problem, rows: list[dict], tol: float = 1e-6) -> Agreement:
    """Evaluate every reference scenario in one batch and compare with the stored verdicts."""
    scenarios = [problem.parse(row["scenario"]) for row in rows]
    ev = problem.evaluate_scenarios(scenarios)
    out = Agreement(total=len(rows))
    for i, row in enumerate(rows):
        ref = row["replication"]
        ours_valid, ours_f1 = bool(ev.valid[i]), float(ev.f1[i])
        out.valid_agree += ours_valid == ref["valid"]
        if ours_valid and ref["valid"]:
            out.both_valid += 1
            if abs(ours_f1 - ref["f1"]) <= tol:
                out.f1_equal += 1
                continue
        if ours_valid != ref["valid"] or (ours_valid and ref["valid"]):
            out.mismatches.append((i, row["sampler"], (ours_valid, ours_f1), (ref["valid"], ref["f1"])))
    return out
