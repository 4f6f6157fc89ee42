"""Reading a run back from its MCAP log: decoded messages, metadata and the campaign summary.

The summary is computed from the log alone (not from what the generator believes), so it is the
proof that every published scenario ended with a result or an explicit timeout record. It counts
executions: the scenarios the generator did not send because the problem calls them invalid
(``topics.not_sent``) are counted apart, as ``not_sent``, never among the outcomes.
"""
from __future__ import annotations

from collections import Counter
from pathlib import Path
from typing import Any, Iterator

from mcap.reader import make_reader

from ..sims.outcome import FAILURE_NAMES, NAV2_RECOVERIES, near_miss
from . import topics
from .types import get_registry


def iter_messages(path: str | Path, only: set[str] | None = None, start_ns: int | None = None,
                  end_ns: int | None = None) -> Iterator[tuple[str, str, int, Any]]:
    """(topic, type, log time ns, decoded message) for every message, in log-time order.

    ``start_ns``/``end_ns`` (log time, end excluded) read one stretch of a long bag: only the
    chunks that overlap it are decompressed and only its messages decoded."""
    for topic, typename, log_ns, _, msg in iter_timed(path, only, start_ns, end_ns):
        yield topic, typename, log_ns, msg


def iter_timed(path: str | Path, only: set[str] | None = None, start_ns: int | None = None,
               end_ns: int | None = None) -> Iterator[tuple[str, str, int, int, Any]]:
    """``iter_messages`` with each message's publish time after its log time (when its writer sent
    it; the log time in a bag that kept none)."""
    registry = get_registry()
    with open(path, "rb") as fh:
        reader = make_reader(fh)
        for schema, channel, message in reader.iter_messages(topics=list(only) if only else None, starting_at=start_ns,
                                                             ending_before=end_ns, log_time_order=True):
            typename = schema.name if schema else ""
            yield (channel.topic, typename, message.log_time, message.publish_time or message.log_time,
                   registry.deserialize(message.data, typename))


def read_metadata(path: str | Path) -> dict[str, dict[str, str]]:
    with open(path, "rb") as fh:
        return {m.name: dict(m.metadata) for m in make_reader(fh).iter_metadata()}


def summarize(path: str | Path, run_id: str | None = None) -> dict[str, Any]:
    """Counts per run from the log: scenarios, results, failures, timeouts, errors, unresolved ids,
    scenarios not sent (the problem calls them invalid); for a run against Nav2 (results with
    ``nav2_recoveries``), its near misses: passes that needed Nav2's recovery branch."""
    scenario_topics = {topics.scenarios(p) for p in topics.SCENARIO_TYPES}
    not_sent_topics = {topics.not_sent(p) for p in topics.SCENARIO_TYPES}
    scenarios: dict[int, int] = {}
    not_sent: dict[int, str] = {}  # scenario id -> the rule it breaks (its reason up to the first ':')
    results: dict[int, Any] = {}
    duplicates = 0
    kinds: dict[str, int] = {}
    nav2_results, near_misses = 0, 0
    last_status = None
    for topic, _, _, msg in iter_messages(path, scenario_topics | not_sent_topics | {topics.RESULTS, topics.STATUS}):
        if topic in scenario_topics or topic in not_sent_topics:
            if run_id is None:
                run_id = msg.meta.run_id
            if msg.meta.run_id != run_id:
                continue
            sid = int(msg.meta.scenario_id)
            if topic in not_sent_topics:
                not_sent[sid] = msg.meta.invalid_reason.split(":", 1)[0].strip() or "?"
            else:
                scenarios[sid] = scenarios.get(sid, 0) + 1
        elif topic == topics.RESULTS:
            if run_id is not None and msg.run_id != run_id:
                continue
            sid = int(msg.scenario_id)
            if sid in results:
                duplicates += 1
                continue
            results[sid] = msg
            kind = FAILURE_NAMES.get(int(msg.failure_kind), str(msg.failure_kind))
            kinds[kind] = kinds.get(kind, 0) + 1
            recoveries = next((kv.value for kv in msg.metrics if kv.key == NAV2_RECOVERIES), None)
            if recoveries is not None:
                nav2_results += 1
                near_misses += near_miss(kind, recoveries)
        elif topic == topics.STATUS and (run_id is None or msg.run_id == run_id):
            last_status = msg
    unresolved = sorted(set(scenarios) - set(results))
    summary = {
        "run_id": run_id,
        "mcap": str(path),
        "scenarios_published": len(scenarios),
        "not_sent": len(not_sent),
        "not_sent_rules": dict(Counter(not_sent.values()).most_common()),
        "scenario_messages": sum(scenarios.values()),
        "results_received": sum(1 for sid in results if sid in scenarios),
        "failures": sum(1 for m in results.values() if m.failed),
        "timeouts": kinds.get("sim_timeout", 0),
        "errors": kinds.get("error", 0),
        "invalid": kinds.get("invalid_scenario", 0),
        "invalid_tests": kinds.get("invalid_test", 0),
        "outcomes": dict(sorted(kinds.items())),
        "duplicate_results": duplicates,
        "unresolved": unresolved,
    }
    if nav2_results:
        summary["near_misses"] = near_misses
    if last_status is not None:
        summary.update(
            evaluations=int(last_status.evaluations),
            best_f1=float(last_status.best_f1),
            final_state=str(last_status.state),
        )
    return summary
