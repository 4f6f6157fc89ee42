"""A search on a supervised stack: AmbieGen's ask and tell, each scenario run by a ``StackSession``.

The campaign launch (``nav2_campaign.launch.py``) runs a search too, but nothing there watches the
stack: a Nav2 server that dies turns the rest of the night into aborted goals. Here each batch the
search asks is a queue of runs of ``runner._run_configuration``, so a search gets what ``rerun``
has: a stack process that dies or hangs is FAIL(sut_crashed) for its scenario (and the stack is
restarted, the scenario run once more on the fresh stack), a part of ours that dies is an error
record and the same scenario runs again, and every run is a row of the results file. The search
is told each scenario's first verdict of the stack (``loop_evaluation``, as the generator tells
it); what the problem calls invalid is never run (the generator's rule), and told as such.
"""
from __future__ import annotations

from typing import Any, Callable

from ..nodes.generator import loop_evaluation
from ..sims.outcome import Outcome
from .configs import Prepared
from .runner import Feed, TrialSettings, run_feed
from .suite import Entry, Suite, scenario_key


class SearchFeed(Feed):
    """The search's batches as entries (``g<generation>-<index>``), told back once all are run; with
    ``in_the_loop`` False the search runs on the surrogate alone first and its suite is one batch
    (``s-<rank>``, best first), as a campaign's surrogate mode executes it."""

    def __init__(self, problem: Any, search: Any, problem_config: dict, say: Callable[[str], None],
                 in_the_loop: bool = True):
        self.problem, self.search, self.problem_config, self.say = problem, search, problem_config, say
        self.in_the_loop = in_the_loop
        self.generation = 0
        self.batch: list[Entry] = []
        self.outcomes: dict[str, Any] = {}
        self.entries: list[Entry] = []  # every one run, for the report

    def _entry(self, name: str, scenario: dict) -> Entry:
        return Entry(name=name, scenario=scenario, key=scenario_key(scenario, self.problem_config))

    def _suite(self) -> list[Entry]:
        """The surrogate search's suite, once: what the problem allows of it, best first."""
        if self.generation:
            return []
        self.generation = 1
        result = self.search.run()
        runs = [self._entry(f"s-{rank}", item["scenario"]) for rank, item in enumerate(result.suite) if item["valid"]]
        self.say(f"surrogate search done: {result.evaluations} evaluations, best F1 {result.best_f1:.3f}; "
                 f"running {len(runs)} of its {len(result.suite)} suite scenarios")
        self.entries += runs
        return runs

    def more(self) -> list[Entry]:
        if not self.in_the_loop:
            return self._suite()
        if self.batch:
            missing = [e.name for e in self.batch if e.name not in self.outcomes]
            if missing:  # the runner stopped inside the batch: nothing is told of half a batch
                return []
            self.search.tell(loop_evaluation([self.outcomes[e.name] for e in self.batch], self.problem.loop_f1))
            failed = sum(bool(self.outcomes[e.name].failed) for e in self.batch)
            self.say(f"generation {self.generation} told: {failed} of {len(self.batch)} failed")
        X = self.search.ask()
        self.batch = []
        if X is None:
            return []
        self.generation += 1
        valid = self.problem.evaluate_rows(X).valid
        runs = []
        for i, row in enumerate(X):
            entry = self._entry(f"g{self.generation}-{i}", self.problem.codec.from_row(row).to_dict())
            self.batch.append(entry)
            if valid[i]:
                runs.append(entry)
            else:  # never sent, as the generator never sends what the problem forbids
                self.outcomes[entry.name] = Outcome.rejected("restriction broken: the problem calls it invalid")
        self.entries += runs
        return runs

    def took(self, entry: Entry, outcome: Any) -> None:
        self.outcomes[entry.name] = outcome


def run_search(problem: Any, search: Any, suite: Suite, prepared: Prepared, settings: TrialSettings,
               say: Callable[[str], None] = print, in_the_loop: bool = True) -> SearchFeed:
    """Run the search on one supervised stack until it ends or ``settings.budget_s`` (wall seconds of
    sending) is spent; rows go to ``settings.results``. Returns the feed (its entries: what ran)."""
    feed = SearchFeed(problem, search, suite.problem_config, say, in_the_loop)
    run_feed(suite, prepared, settings, feed, say)
    return feed


__all__ = ["SearchFeed", "run_search"]
