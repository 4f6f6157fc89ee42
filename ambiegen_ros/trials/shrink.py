"""Shrinking a failing scenario on a supervised stack: the fewest walls and cells that keep its failure.

A finding is reported on a minimal map, as a fuzzer reports a minimal input: what is left is what
the bug needs. ``ShrinkFeed`` feeds ``runner._run_configuration`` one scenario at a time, as a
search's batches are fed (``trials.search``), so every try is a real run on the stack with its row
in the results file and a crash restarts the stack. It runs in three steps:

1. the scenario as given, up to ``tries`` times: its first failure is the **signature** to keep (the
   failure kind and, on the planner stack, the oracle that flagged it: ``plan_oracle``);
2. ``core.shrink.Ddmin`` over the map's parts (``RobotProblem.map_parts``: each wall, each side of
   the border);
3. ``Ddmin`` over the cells those parts left.

A try keeps the failure when one of its up to ``tries`` runs fails with the signature (a failure
that comes and goes, as a memory error does, needs ``tries`` above 1). The scenario's genome never
changes: the cells taken away are listed in its metadata (``problems.robot.problem.CLEARED``).
"""
from __future__ import annotations

from typing import Any, Callable

from ..core.shrink import Ddmin
from ..problems.robot.problem import CLEARED, cleared_cells
from .configs import Prepared
from .runner import Feed, TrialSettings, run_feed
from .suite import Entry, Suite, scenario_key


def signature(outcome: Any) -> tuple[str, str] | None:
    """What makes two failures the same for a shrink: the kind, and the planner oracle's name."""
    if not outcome.failed:
        return None
    return str(outcome.failure_kind), str((outcome.metrics or {}).get("plan_oracle") or "")


class ShrinkFeed(Feed):
    """The shrink's tries as entries (``<name>~0`` the scenario itself, ``<name>~<k>`` the k-th
    smaller map); ``minimal`` is the smallest failing scenario (dict) once ``done``."""

    def __init__(self, problem: Any, entry: Entry, problem_config: dict, tries: int, say: Callable[[str], None]):
        self.problem, self.entry, self.problem_config, self.tries, self.say = problem, entry, problem_config, tries, say
        scenario = problem.parse(entry.scenario)
        self.parts = problem.map_parts(scenario)
        before = cleared_cells(scenario.metadata, problem.config.map_size)
        self.already = {tuple(c) for c in (before.tolist() if before is not None else [])}
        self.occupied = {tuple(c) for _, cells in self.parts for c in cells.tolist()}
        self.signature: tuple[str, str] | None = None
        self.minimal: dict | None = None
        self.step = "original"
        self.ddmin: Ddmin | None = None
        self.count = 0  # the tries made so far
        self.current: Entry | None = None
        self.answers: list[Any] = []
        self.history: list[str] = []
        self.answered: dict[str, bool] = {}  # scenario key -> kept the failure

    def cells_of(self, kept: list[int]) -> set:
        """The cells of the parts ``kept`` (indices into ``parts``)."""
        return {tuple(c) for i in kept for c in self.parts[i][1].tolist()}

    def scenario_keeping(self, cells: set) -> dict:
        """The scenario with every occupied cell not in ``cells`` cleared."""
        if not self.occupied - cells:
            return self.entry.scenario  # nothing taken away: the scenario as given (and as it ran)
        cleared = sorted((self.occupied - cells) | self.already)
        metadata = {**(self.entry.scenario.get("metadata") or {}), CLEARED: [list(c) for c in cleared]}
        return {**self.entry.scenario, "metadata": metadata}

    def _try(self, scenario: dict) -> list[Entry]:
        self.count += 1
        self.current = Entry(name=f"{self.entry.name}~{self.count - 1}", scenario=scenario,
                             key=scenario_key(scenario, self.problem_config))
        self.answers = []
        return [self.current]

    def _next_step(self) -> list[Entry]:
        """The next try of the current ddmin, moving on to the next step when it is minimal."""
        while True:
            assert self.ddmin is not None
            kept = self.ddmin.ask()
            if kept is not None:
                cells = self.cells_of(kept) if self.step == "parts" else set(kept)
                scenario = self.scenario_keeping(cells)
                known = self.answered.get(scenario_key(scenario, self.problem_config))
                if known is not None:  # the same map again (another chunking gave it): its answer stands
                    self.ddmin.tell(known)
                    continue
                return self._try(scenario)
            if self.step == "parts":
                names = [self.parts[i][0] for i in self.ddmin.current]
                self._say(f"parts: {len(self.parts)} -> {len(names)} ({', '.join(names) or 'none'})")
                cells = sorted(self.cells_of(self.ddmin.current))
                self.step, self.ddmin = "cells", Ddmin(cells)
                self.minimal = self.scenario_keeping(set(cells))
                continue
            cells = set(self.ddmin.current)
            self._say(f"cells: {len(self.occupied)} occupied -> {len(cells)}")
            self.minimal, self.step = self.scenario_keeping(cells), "done"
            return []

    def _say(self, line: str) -> None:
        self.history.append(line)
        self.say(f"shrink {self.entry.name}: {line} after {self.count} tries")

    def more(self) -> list[Entry]:
        if self.step == "done":
            return []
        if self.current is None:
            return self._try(self.entry.scenario)
        if not self.answers:  # the runner stopped before the try was told
            return []
        kept = any(self._keeps(o) for o in self.answers)
        if not kept and len(self.answers) < self.tries:
            return [self.current]  # the same try once more
        if self.step == "original":
            if self.signature is None:
                self._say(f"it did not fail in {len(self.answers)} runs: nothing to shrink")
                self.step = "done"
                return []
            self._say(f"it fails as {'/'.join(s for s in self.signature if s)}")
            self.step, self.ddmin, self.minimal = "parts", Ddmin(list(range(len(self.parts)))), self.entry.scenario
            return self._next_step()
        assert self.ddmin is not None
        self.answered[self.current.key] = kept
        self.ddmin.tell(kept)
        return self._next_step()

    def _keeps(self, outcome: Any) -> bool:
        sig = signature(outcome)
        if self.step == "original" and self.signature is None and sig is not None:
            self.signature = sig
        return sig is not None and sig == self.signature

    def took(self, entry: Entry, outcome: Any) -> None:
        if self.current is not None and entry.key == self.current.key:
            self.answers.append(outcome)


def run_shrink(problem: Any, entry: Entry, suite: Suite, prepared: Prepared, settings: TrialSettings, tries: int = 1,
               say: Callable[[str], None] = print) -> ShrinkFeed:
    """Shrink ``entry`` on one supervised stack; every try is a row of ``settings.results``. Returns
    the feed: ``minimal`` (None when the scenario did not fail), ``signature``, ``history``."""
    feed = ShrinkFeed(problem, entry, suite.problem_config, tries, say)
    run_feed(suite, prepared, settings, feed, say)
    return feed


__all__ = ["ShrinkFeed", "run_shrink", "signature"]
