"""The tables of trials, from rows alone (no ROS, no bag): how often each failure reproduces, and
what a configuration fixes, keeps, breaks and costs against a baseline.

A scenario's runs on one configuration are ``k of N``: N runs of the stack (errors of ours left
out, ``rows.counted``), k of them failures (known failures included: Nav2 failed all the same),
by kind (a starved run, the stack without its computer, ``reruns.starved``: in a column of its own,
apart from the other errors, never a failure nor a run of the stack). Its status: **fails** when
k >= N / 2, **passes** when k = 0, **flaky** in between. Against the baseline (the first
configuration) a configuration **fixes** a scenario the baseline fails and it passes, **improves**
one it only makes flaky, **keeps** one both fail, and **breaks** one the baseline passes and it
fails at least once. Fisher's exact test (two-sided) compares the failure counts of the two, per
scenario and pooled. The cost of a configuration is measured on the
scenarios the baseline passes every time: time to the goal (simulated seconds) and Nav2's
recoveries on its passes, median and 90th percentile, and the median of its time over the
baseline's per scenario.
"""
from __future__ import annotations

from collections import Counter, defaultdict
from typing import Any, Iterable

import numpy as np

from ..sims.obstacles import contact_speeds
from .reruns import starved
from .rows import counted

DEFAULT_CHARGE_SPEEDS = (0.05, 0.1, 0.2)  # m/s: what-ifs of the contact table


def fisher_p(k_a: int, n_a: int, k_b: int, n_b: int) -> float:
    """Two-sided Fisher exact p of k_a / n_a against k_b / n_b failures (1.0 when either has no runs)."""
    if n_a == 0 or n_b == 0:
        return 1.0
    from scipy.stats import fisher_exact

    return float(fisher_exact([[k_a, n_a - k_a], [k_b, n_b - k_b]])[1])


def kind_of(row: dict) -> str:
    """What a run says, in one word: pass, near_miss, invalid_test, starved, or the failure's kind
    (``known:`` in front of a known one)."""
    if starved(row):
        return "starved"
    kind = row.get("failure_kind", "error")
    if kind == "none":
        return "near_miss" if int(row.get("recoveries") or 0) > 0 else "pass"
    if row.get("failed"):
        return f"known:{kind}" if row.get("known_failure") else kind
    return kind


class Cell:
    """One scenario's counted runs on one configuration."""

    def __init__(self, rows: Iterable[dict]):
        self.rows = [r for r in rows if counted(r)]
        self.errors = 0  # errors of ours, starved runs apart
        self.starved = 0
        self.kinds = Counter(kind_of(r) for r in self.rows)

    @property
    def n(self) -> int:
        return len(self.rows)

    @property
    def k(self) -> int:
        return sum(bool(r.get("failed")) for r in self.rows)

    @property
    def status(self) -> str:
        if self.n == 0:
            return "not run"
        if self.k == 0:
            return "passes"
        return "fails" if 2 * self.k >= self.n else "flaky"

    def failures(self) -> str:
        """'2 of 3: collision 2' (or '0 of 3')."""
        kinds = ", ".join(f"{kind} {c}" for kind, c in sorted(self.kinds.items(), key=lambda kc: (-kc[1], kc[0]))
                          if kind not in ("pass", "near_miss", "invalid_test"))
        return f"{self.k} of {self.n}" + (f": {kinds}" if kinds else "")

    def passes(self) -> list[dict]:
        return [r for r in self.rows if r.get("failure_kind") == "none"]


def cells(rows: list[dict], labels: list[str], keys: list[str]) -> dict[tuple[str, str], Cell]:
    by: dict[tuple[str, str], list[dict]] = defaultdict(list)
    for r in rows:
        by[(r["label"], r["key"])].append(r)
    out = {}
    for label in labels:
        for key in keys:
            cell = Cell(by.get((label, key), []))
            cell.errors = sum(not counted(r) and not starved(r) for r in by.get((label, key), []))
            cell.starved = sum(starved(r) for r in by.get((label, key), []))
            out[(label, key)] = cell
    return out


def _md(header: list[str], lines: list[list[Any]]) -> list[str]:
    return ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)] + \
        ["| " + " | ".join(str(c) for c in line) + " |" for line in lines]


def _stat(values: list[float], q: float) -> str:
    return f"{np.percentile(values, q):.1f}" if values else "-"


# --- one configuration: does it reproduce? ---------------------------------------------------------
def rerun_table(rows: list[dict], label: str, names: dict[str, str]) -> tuple[list[str], dict]:
    """Per scenario: runs, passes (near misses), failures by kind (k of N), invalid tests, errors, starved runs."""
    keys = list(names)
    table = cells(rows, [label], keys)
    lines, out = [], {}
    for key in keys:
        c = table[(label, key)]
        near = c.kinds.get("near_miss", 0)
        passed = c.kinds.get("pass", 0) + near
        lines.append([names[key], c.n, f"{passed}" + (f" ({near})" if near else ""), c.failures(),
                      c.kinds.get("invalid_test", 0), c.errors, c.starved, c.status])
        out[names[key]] = {"key": key, "runs": c.n, "failures": c.k, "kinds": dict(c.kinds), "errors": c.errors,
                           "starved": c.starved, "status": c.status}
    total_k = sum(table[(label, k)].k for k in keys)
    total_n = sum(table[(label, k)].n for k in keys)
    total_starved = sum(table[(label, k)].starved for k in keys)
    md = [f"Configuration `{label}`: {total_k} failures in {total_n} runs of {len(keys)} scenarios"
          + (f" ({total_starved} starved runs not counted: the stack did not get its computer)" if total_starved
             else ""), ""]
    md += _md(["scenario", "runs", "passed (near misses)", "failed (k of N, by kind)", "invalid tests", "errors",
               "starved", "status"], lines)
    return md, {"label": label, "runs": total_n, "failures": total_k, "starved": total_starved, "scenarios": out}


def reproduction(rows: list[dict], label: str, names: dict[str, str], at_least: float = 2 / 3) -> dict:
    """How many scenarios fail at least ``at_least`` of their runs (the bar for "it reproduces")."""
    table = cells(rows, [label], list(names))
    run = [c for c in table.values() if c.n]
    return {"scenarios_run": len(run), "reproduce": sum(c.k >= at_least * c.n for c in run),
            "ever_fail": sum(c.k > 0 for c in run), "never_fail": sum(c.k == 0 for c in run), "bar": at_least}


# --- several configurations: what does a fix do? ----------------------------------------------------
def compare_tables(rows: list[dict], labels: list[str], names: dict[str, str]) -> tuple[list[str], dict]:
    """Per scenario x configuration: k of N and Fisher's p against the baseline (``labels[0]``); per
    configuration: fixed, improved, kept, broken (scenario names), pooled counts; and the cost."""
    keys = list(names)
    base = labels[0]
    table = cells(rows, labels, keys)
    header = ["scenario"] + [f"`{label}`" for label in labels] + [f"p ({label} vs {base})" for label in labels[1:]]
    lines = []
    for key in keys:
        b = table[(base, key)]
        line: list[Any] = [names[key]] + [table[(label, key)].failures() for label in labels]
        line += [f"{fisher_p(b.k, b.n, table[(label, key)].k, table[(label, key)].n):.2g}" for label in labels[1:]]
        lines.append(line)
    md = ["Failures per scenario (k of N runs, by kind), and Fisher's exact p against "
          f"`{base}`:", ""] + _md(header, lines)
    summary: dict[str, Any] = {}
    md += ["", f"What each configuration does against `{base}` (fails: k >= N/2; passes: k = 0; flaky: between):", ""]
    lines = []
    for label in labels:
        groups: dict[str, list[str]] = {"fixed": [], "improved": [], "kept": [], "broken": []}
        for key in keys:
            b, c = table[(base, key)].status, table[(label, key)].status
            if "not run" in (b, c):
                continue
            if b == "fails":
                groups["fixed" if c == "passes" else "improved" if c == "flaky" else "kept"].append(names[key])
            elif b == "passes" and c != "passes":
                groups["broken"].append(names[key])
        k = sum(table[(label, key)].k for key in keys)
        n = sum(table[(label, key)].n for key in keys)
        kb = sum(table[(base, key)].k for key in keys)
        nb = sum(table[(base, key)].n for key in keys)
        p = fisher_p(kb, nb, k, n)
        hungry = sum(table[(label, key)].starved for key in keys)
        summary[label] = {**{g: v for g, v in groups.items()}, "failures": k, "runs": n, "p_pooled": p,
                          "starved": hungry}
        if label == base:
            lines.append([f"`{label}` (baseline)", f"{k} of {n}", "-", "-", "-", "-", "-", hungry])
            continue
        lines.append([f"`{label}`", f"{k} of {n}", f"{p:.2g}"] + [", ".join(v) or "none" for v in groups.values()]
                     + [hungry])
    md += _md(["configuration", "failures (pooled)", "p (pooled)", "fixed", "improved (flaky)", "kept (still fails)",
               "broken (new failures)", "starved (not counted)"], lines)
    cost_md, cost = cost_table(rows, labels, names)
    md += ["", *cost_md]
    return md, {"baseline": base, "configurations": summary, "cost": cost,
                "cells": {names[key]: {label: {"runs": table[(label, key)].n, "failures": table[(label, key)].k,
                                               "kinds": dict(table[(label, key)].kinds),
                                               "starved": table[(label, key)].starved,
                                               "status": table[(label, key)].status} for label in labels}
                          for key in keys}}


def cost_table(rows: list[dict], labels: list[str], names: dict[str, str]) -> tuple[list[str], dict]:
    """The cost of each configuration on the scenarios the baseline passes every time."""
    keys = list(names)
    base = labels[0]
    table = cells(rows, labels, keys)
    easy = [key for key in keys if table[(base, key)].status == "passes"]
    lines, out = [], {}
    for label in labels:
        passes = [r for key in easy for r in table[(label, key)].passes()]
        times = [float(r["time_s"]) for r in passes if r.get("time_s") is not None]
        recov = [float(r.get("recoveries") or 0) for r in passes]
        ratios = []
        for key in easy:
            mine = [float(r["time_s"]) for r in table[(label, key)].passes() if r.get("time_s") is not None]
            theirs = [float(r["time_s"]) for r in table[(base, key)].passes() if r.get("time_s") is not None]
            if mine and theirs:
                ratios.append(float(np.median(mine) / np.median(theirs)))
        broke = sum(table[(label, key)].k > 0 for key in easy)
        runs = sum(table[(label, key)].n for key in easy)
        fails = sum(table[(label, key)].k for key in easy)
        out[label] = {"scenarios": len(easy), "runs": runs, "failures": fails, "scenarios_broken": broke,
                      "time_median_s": float(np.median(times)) if times else None,
                      "time_p90_s": float(np.percentile(times, 90)) if times else None,
                      "recoveries_median": float(np.median(recov)) if recov else None,
                      "recoveries_p90": float(np.percentile(recov, 90)) if recov else None,
                      "time_vs_baseline_median": float(np.median(ratios)) if ratios else None}
        lines.append([f"`{label}`", f"{fails} of {runs} ({broke} scenarios)", _stat(times, 50), _stat(times, 90),
                      _stat(recov, 50), _stat(recov, 90),
                      f"{np.median(ratios):.2f}" if ratios and label != base else "-"])
    md = [f"Cost, on the {len(easy)} scenarios `{base}` passes every time (passes only; time in simulated s):", ""]
    md += _md(["configuration", "failures there", "time median", "time p90", "recoveries median", "recoveries p90",
               "time / baseline's (median per scenario)"], lines)
    return md, out


# --- contacts: who ran into whom, and how fast --------------------------------------------------------
def contact_table(rows: list[dict], names: dict[str, str], speeds: tuple[float, ...] = DEFAULT_CHARGE_SPEEDS
                  ) -> tuple[list[str], dict]:
    """Every collision with a person: the robot's speed, both speeds along the line of contact, and
    how many collisions each threshold on the robot's speed (below it, not charged) would drop."""
    hits = []
    for r in rows:
        found = contact_speeds(r.get("detail")) if r.get("failed") else None
        if found:
            hits.append((r, found))
    if not hits:
        return [], {"collisions_with_people": 0}
    lines = [[names.get(r["key"], r["key"]), r["label"], r.get("repeat", "-"), f"{abs(s['robot_mps']):.2f}",
              f"{s['robot_along_mps']:.2f}", f"{s['person_along_mps']:+.2f}"] for r, s in hits]
    drop = {f"{t:g}": sum(abs(s["robot_mps"]) <= t for _, s in hits) for t in speeds}
    md = [f"Collisions with people ({len(hits)}): speeds in m/s; along the line of contact, each positive towards "
          "the other", ""]
    md += _md(["scenario", "configuration", "run", "robot", "robot along", "person along"], lines)
    md += ["", "Not charged if the robot was slower than: " + ", ".join(f"{t} m/s drops {n}" for t, n in drop.items())]
    return md, {"collisions_with_people": len(hits), "dropped_by_threshold": drop,
                "speeds": [dict(s, scenario=names.get(r["key"], r["key"]), label=r["label"]) for r, s in hits]}


__all__ = ["Cell", "compare_tables", "contact_table", "cost_table", "fisher_p", "kind_of", "rerun_table",
           "reproduction"]
