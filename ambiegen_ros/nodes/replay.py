"""`replay`: bring a recorded run back onto the graph.

* ``mode:=publish`` re-publishes the log's scenario messages byte for byte with the QoS they were
  recorded with (``offered_qos_profiles``), at the recorded pace times ``rate`` (0 = at once).
* ``mode:=execute`` re-executes the log's scenarios on the sim / SUT nodes running now (a new
  run id, the same scenario ids), and writes a regression report comparing every new result with
  the recorded one (verdict, failure kind, objectives). Run a recorder beside it to log the new
  results; the report path is the ``report`` parameter.

Also available as ``ambiegen replay LOG.mcap``.
"""
from __future__ import annotations

import json
import sys
import time
import uuid
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, NamedTuple

from mcap.reader import make_reader

from ..core.attributes import ScenarioError
from ..core.scenario import Scenario
from ..problems import get_problem
from ..ros import topics
from ..ros.conversions import ScenarioMeta, outcome_from_message, safe_echo
from ..ros.mcap_log import create_file
from ..ros.qos import from_offered_qos_yaml
from ..ros.runlog import iter_messages
from ..ros.transport import create_node
from ..sims.outcome import Outcome
from .execution import RemoteExecution

SCENARIO_TOPICS = {topics.scenarios(p): p for p in topics.SCENARIO_TYPES}


class Recorded(NamedTuple):
    """What a log holds of its first run: enough to run it again the same way."""

    problem: str
    run_id: str
    scenarios: dict[int, Scenario]
    outcomes: dict[int, Outcome]  # the first recorded outcome of each scenario
    seed: int  # the run's seed: the full models' noise is seeded from it, so a replay must reuse it


def recorded_scenarios(path: str | Path) -> Recorded:
    """The first run of a log: problem, run id, scenarios and outcomes by id, and its seed."""
    problem = run_id = ""
    seed = 0
    scenarios: dict[int, Scenario] = {}
    results: list[Any] = []  # kept until the run is known: a result may be logged before its scenario
    for topic, _, _, msg in iter_messages(path, set(SCENARIO_TOPICS) | {topics.RESULTS}):
        if topic in SCENARIO_TOPICS:
            meta = msg.meta
            if not run_id:
                run_id, problem, seed = meta.run_id, SCENARIO_TOPICS[topic], int(meta.seed)
            if meta.run_id == run_id and int(meta.scenario_id) not in scenarios:
                data = Scenario.parse_json(meta.scenario_json)
                scenarios[int(meta.scenario_id)] = Scenario(data["problem"], data["elements"])
        else:
            results.append(msg)
    if not scenarios:
        raise ScenarioError("log", f"{path} holds no scenario messages", ", ".join(SCENARIO_TOPICS))
    outcomes: dict[int, Outcome] = {}
    for msg in results:
        if msg.run_id == run_id and int(msg.scenario_id) not in outcomes:
            outcomes[int(msg.scenario_id)] = outcome_from_message(msg)
    return Recorded(problem, run_id, scenarios, outcomes, seed)


def compare(old: Outcome | None, new: Outcome) -> dict[str, Any]:
    """One scenario's regression entry: verdicts, kinds, objectives and whether anything changed."""
    entry = {
        "new": {"verdict": new.verdict, "failed": new.failed, "failure_kind": new.failure_kind,
                "objectives": new.objectives},
        "old": None if old is None else {"verdict": old.verdict, "failed": old.failed, "failure_kind": old.failure_kind,
                                         "objectives": old.objectives},
    }
    if old is None:
        entry["change"] = "no recorded result"
    elif old.failure_kind != new.failure_kind or old.failed != new.failed:
        entry["change"] = "verdict"
    else:
        deltas = {k: new.objectives[k] - v for k, v in old.objectives.items() if k in new.objectives}
        entry["objective_deltas"] = deltas
        moved = any(abs(d) > 1e-9 for d in deltas.values())
        # another model measures other things: "none" only when the same objectives agree
        entry["change"] = "objectives" if moved or set(old.objectives) != set(new.objectives) else "none"
    return entry


class Replay:
    def __init__(self, argv: list[str] | None = None, node=None, log: str | None = None):
        self.node = node or create_node("replay", argv=argv)
        n = self.node
        self.log = log or n.declare_parameter("log", "", "MCAP file of a recorded run")
        self.mode = n.declare_parameter("mode", "publish", "publish | execute")
        self.rate = n.declare_parameter("rate", 1.0, "publish: speed factor of the recorded pace (0 = at once)")
        self.report_path = n.declare_parameter("report", "", "execute: JSON regression report ('' = LOG.replay.json, "
                                               "or LOG.replay-<UTC time>.json when that exists)")
        self.overwrite = n.declare_parameter("overwrite", False, "replace an existing report file")
        self.min_subscribers = n.declare_parameter("min_subscribers", 1, "subscribers to wait for before publishing")
        self.subscriber_wait = n.declare_parameter("subscriber_wait", 10.0, "seconds to wait for them")
        if not self.log or not Path(self.log).exists():
            raise ScenarioError("log", f"no such MCAP file {self.log!r}")
        if self.mode not in ("publish", "execute"):
            raise ScenarioError("mode", f"unknown {self.mode!r}", "publish|execute")
        if self.mode == "execute" and self.report_path and Path(self.report_path).exists() and not self.overwrite:
            raise FileExistsError(f"report {self.report_path} already exists; refusing to overwrite it "
                                  "(another name, or overwrite:=true)")
        self.report: dict[str, Any] | None = None
        self.exit_code = 0

    # --- publish: raw bytes, recorded QoS, recorded pace -----------------------------------------
    def publish(self) -> int:
        n = self.node
        publishers: dict[str, Any] = {}
        count = 0
        first_log = first_wall = None
        with open(self.log, "rb") as fh:
            reader = make_reader(fh)
            for schema, channel, message in reader.iter_messages(topics=list(SCENARIO_TOPICS), log_time_order=True):
                if not n.ok():
                    break
                pub = publishers.get(channel.topic)
                if pub is None:
                    qos = from_offered_qos_yaml(channel.metadata.get("offered_qos_profiles", ""))
                    pub = publishers[channel.topic] = n.create_publisher(schema.name, channel.topic, qos)
                    n.wait_for_subscribers(pub, self.min_subscribers, self.subscriber_wait)
                if self.rate > 0:
                    if first_log is None:
                        first_log, first_wall = message.log_time, time.monotonic()
                    due = first_wall + (message.log_time - first_log) / 1e9 / self.rate
                    n.spin_until(lambda: time.monotonic() >= due)
                pub.publish_raw(message.data)
                count += 1
        n.spin_until(lambda: False, 0.5)  # let reliable writers deliver
        n.logger.info(f"re-published {count} scenario messages from {self.log}")
        return count

    # --- execute: new results, compared with the recorded ones -----------------------------------
    def execute(self) -> dict[str, Any]:
        problem_name, old_run, scenarios, old, seed = recorded_scenarios(self.log)
        problem = get_problem(problem_name)
        run_id = f"replay-{safe_echo(old_run)[:100]}-{uuid.uuid4().hex[:6]}"  # a logged id is not trusted as a name
        remote = RemoteExecution(self.node, problem, run_id)
        for sid, scenario in sorted(scenarios.items()):
            remote.add(problem.parse(scenario.to_dict()), ScenarioMeta(run_id, sid, seed=seed))
        self.node.wait_for_subscribers(remote.pub_scenarios, self.min_subscribers, self.subscriber_wait)
        remote.begin()
        self.node.create_timer(0.01, remote.tick)
        self.node.spin_until(remote.done)
        entries = {sid: compare(old.get(sid), outcome) for sid, outcome in sorted(remote.outcomes.items())}
        changes: dict[str, int] = {}
        for entry in entries.values():
            changes[entry["change"]] = changes.get(entry["change"], 0) + 1
        report = {
            "log": str(self.log),
            "recorded_run_id": old_run,
            "replay_run_id": run_id,
            "seed": seed,
            "problem": problem_name,
            "scenarios": len(scenarios),
            "settled": len(remote.outcomes),
            "changes": changes,
            "new_failures": sorted(s for s, e in entries.items() if e["old"] and not e["old"]["failed"] and e["new"]["failed"]),
            "fixed_failures": sorted(s for s, e in entries.items() if e["old"] and e["old"]["failed"] and not e["new"]["failed"]),
            "entries": {str(k): v for k, v in entries.items()},
        }
        path = self._write_report(json.dumps(report, indent=2) + "\n")
        report["report"] = str(path)
        self.node.logger.info(f"replayed {len(remote.outcomes)}/{len(scenarios)} scenarios; changes {changes}; report {path}")
        self.report = report
        return report

    def _write_report(self, text: str) -> Path:
        """The report never lands on an earlier one: an explicit path was checked at start-up (and is
        created exclusively here), the default name gets a UTC time when ``LOG.replay.json`` exists."""
        if self.report_path:
            path = Path(self.report_path)
        else:
            path = Path(self.log).with_suffix(".replay.json")
            if path.exists():
                stamp = datetime.now(timezone.utc).strftime("%Y%m%dT%H%M%S%fZ")
                path = Path(self.log).with_suffix(f".replay-{stamp}.json")
        with create_file(path, overwrite=bool(self.report_path) and self.overwrite) as fh:
            fh.write(text.encode())
        return path

    def run(self) -> int:
        try:
            if self.mode == "publish":
                self.publish()
            else:
                report = self.execute()
                self.exit_code = 0 if report["settled"] == report["scenarios"] else 1
        finally:
            self.node.spin_until(lambda: False, 0.3)
            self.node.shutdown()
        return self.exit_code


def main(argv: list[str] | None = None) -> int:
    from . import wants_help

    if wants_help(argv):
        print("usage: replay --ros-args -p log:=FILE.mcap [-p mode:=publish|execute] ...\n")
        print(__doc__.strip())
        return 0
    from ..deps import broken_environment

    if broken_environment("replay"):
        return 2
    try:
        replay = Replay(argv)
    except (ScenarioError, ValueError, OSError) as exc:
        print(f"replay: error: {exc}", file=sys.stderr)
        return 2
    return replay.run()


if __name__ == "__main__":
    sys.exit(main())
