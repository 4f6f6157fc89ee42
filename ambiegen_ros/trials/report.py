"""What ``ambiegen rerun`` and ``compare`` print and write, from the results file alone.

``report`` takes the rows of the suite's scenarios and the configurations asked for, and returns
the markdown (printed) and a JSON document; ``write`` puts both in a folder under names of their
own (``<what>_<UTC time>.md`` / ``.json``) with pictures (``viz.trials``): for a comparison, one per
scenario whose status changed between configurations; for a rerun, one per scenario that failed in a
run (a crash of the stack included). Nothing is written over another file.
"""
from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

from .rows import rows_of
from .suite import Suite, problem_of
from .tables import cells, compare_tables, contact_table, rerun_table, reproduction


def report(suite: Suite, results: str | Path, labels: list[str]) -> tuple[list[str], dict[str, Any]]:
    """The tables of ``labels`` over the suite's scenarios (one label: the rerun tables)."""
    names = suite.names()
    rows = rows_of(results, labels, set(names))
    md: list[str] = []
    doc: dict[str, Any] = {"results": str(results), "suite": suite.sources, "labels": labels,
                           "problem_config": suite.problem_config}
    for label in labels:
        table, data = rerun_table(rows, label, names)
        md += table + [""]
        doc.setdefault("rerun", {})[label] = {**data, "reproduction": reproduction(rows, label, names)}
    if len(labels) > 1:
        table, data = compare_tables(rows, labels, names)
        md += table + [""]
        doc["compare"] = data
    contacts, data = contact_table(rows, names)
    if contacts:
        md += contacts + [""]
    doc["contacts"] = data
    return md, doc


def changed(suite: Suite, results: str | Path, labels: list[str]) -> list[str]:
    """Keys of the scenarios whose status (fails / flaky / passes) differs between configurations."""
    names = suite.names()
    table = cells(rows_of(results, labels, set(names)), labels, list(names))
    out = []
    for key in names:
        statuses = {table[(label, key)].status for label in labels} - {"not run"}
        if len(statuses) > 1:
            out.append(key)
    return out


def _safe(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name)[:80]


def failure_kind_of(row: dict) -> tuple[str, str, str]:
    """What a failing row is, coarsely enough that one bug is one kind: the verdict's kind, the
    planner oracle that flagged it and the known failure it matches (each '' where it has none)."""
    metrics = row.get("metrics") or {}
    return (str(row.get("failure_kind", "")), str(metrics.get("plan_oracle", "")), str(row.get("known_failure") or ""))


def first_of_each_kind(keys: list[str], rows: list[dict], per_kind: int) -> list[str]:
    """The first ``per_kind`` of ``keys`` (failing scenarios, in order) of each failure kind: a search
    may fail hundreds of times on one bug, and a picture of each would cost minutes, not tell more."""
    kind_of: dict[str, tuple] = {}
    for r in rows:
        if r.get("failed"):
            kind_of.setdefault(r["key"], failure_kind_of(r))
    seen: dict[tuple, int] = {}
    kept = []
    for key in keys:
        kind = kind_of.get(key, ("",))
        if seen.get(kind, 0) < per_kind:
            seen[kind] = seen.get(kind, 0) + 1
            kept.append(key)
    return kept


def write(suite: Suite, results: str | Path, labels: list[str], out_dir: str | Path, stamp: str,
          what: str, pictures_per_kind: int | None = None) -> dict[str, Any]:
    """Write ``<what>_<stamp>.md`` and ``.json`` in ``out_dir``, and the pictures (``pictures_<stamp>/``)
    of the scenarios whose verdicts changed (a comparison) or that failed (a rerun); with
    ``pictures_per_kind`` only the first that many failing scenarios of each kind (``failure_kind_of``).
    Returns the paths written, and ``pictures_left_out``: how many failing scenarios got no picture."""
    from ..viz.trials import save_runs_side_by_side
    from .tables import Cell

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    md, doc = report(suite, results, labels)
    written: dict[str, Any] = {}
    for suffix, text in (("md", "\n".join(md) + "\n"), ("json", json.dumps(doc, indent=2) + "\n")):
        path = out / f"{what}_{stamp}.{suffix}"
        with open(path, "x") as fh:  # a new name every time: never over an earlier report
            fh.write(text)
        written[suffix] = str(path)
    problem = problem_of(suite)
    names = suite.names()
    rows = rows_of(results, labels, set(names))
    drawn = changed(suite, results, labels) if len(labels) > 1 else \
        [key for key in names if any(r["key"] == key and r.get("failed") for r in rows)]
    if pictures_per_kind is not None:
        kept = first_of_each_kind(drawn, rows, pictures_per_kind)
        written["pictures_left_out"] = len(drawn) - len(kept)
        drawn = kept
    if drawn:
        pictures = []
        for key in drawn:
            entry = next(e for e in suite.entries if e.key == key)
            panels = []
            for label in labels:
                mine = [r for r in rows if r["label"] == label and r["key"] == key]
                panels.append((f"{label}: failed {Cell(mine).failures()}", [r for r in Cell(mine).rows]))
            path = out / f"pictures_{stamp}" / f"{_safe(entry.name)}.png"
            pictures.append(str(save_runs_side_by_side(problem, problem.parse(entry.scenario), panels, path,
                                                       f"{entry.name}: {', '.join(labels)}")))
        written["pictures"] = pictures
    return written


__all__ = ["changed", "report", "write"]
