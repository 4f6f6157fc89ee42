"""The scenarios of a trial and the problem they belong to: from suite files or a campaign's log.

A suite file is JSON: ``{"suite": [{"scenario": {...}, "name": ..., "note": ...}, ...]}`` (a
search's ``suite.json``, our write-ups' ``*_suite.json``; ``"scenarios"`` is read too), a list of
such entries, or one scenario (``{"problem": ..., "elements": [...]}``). It may say the problem's
settings it was found with (``"problem_config"``); ``--config FILE.yaml`` gives them otherwise (a
hazards scenario is a hazards scenario only with ``scenario: hazards``). A campaign's MCAP gives
its certified failures (known ones left out) and the problem settings it recorded.

Each scenario is identified by ``scenario_key`` (its elements and problem settings, hashed): rows
of the results file are matched by it, so a renamed suite file still resumes.
"""
from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..core.attributes import ScenarioError
from ..core.errors import BadInput, ConfigError

SUFFIXES = ("_suite", "_scenario", "_map", "_failures")  # left off a file's stem in the names of its scenarios


def scenario_key(scenario: dict, problem_config: dict | None = None) -> str:
    """16 hex digits that name a scenario with its problem settings (``bench/nav2_maps.py``'s rows
    use the same key, so their scenarios match)."""
    data = scenario if not problem_config else {"scenario": scenario, "problem_config": problem_config}
    return hashlib.sha1(json.dumps(data, sort_keys=True).encode()).hexdigest()[:16]


@dataclass(frozen=True)
class Entry:
    name: str  # what tables call it: "<file stem>:<index>" or the entry's own "name"
    scenario: dict
    key: str
    note: str = ""


@dataclass
class Suite:
    problem: str
    problem_config: dict
    entries: list[Entry]
    sources: list[str] = field(default_factory=list)
    duplicates: int = 0  # scenarios given more than once (kept once)

    def names(self) -> dict[str, str]:
        """key -> name, in suite order."""
        return {e.key: e.name for e in self.entries}


def _stem(path: Path) -> str:
    stem = path.stem
    for suffix in SUFFIXES:
        if stem.endswith(suffix) and len(stem) > len(suffix):
            return stem[: -len(suffix)]
    return stem


def _json_entries(path: Path) -> tuple[list[dict], dict]:
    """(entries, the file's own problem settings) of a suite file."""
    try:
        data = json.loads(path.read_text())
    except OSError as exc:
        raise BadInput(f"{path}: cannot read ({exc.strerror})")
    except ValueError as exc:
        raise BadInput(f"{path}: not JSON ({exc})")
    if isinstance(data, list):
        return data, {}
    if not isinstance(data, dict):
        raise BadInput(f"{path}: a suite file holds an object or a list, not {type(data).__name__}")
    found = {k: data[k] for k in ("problem", "problem_config") if k in data}
    if "elements" in data:
        return [data], found
    for key in ("suite", "scenarios"):
        if isinstance(data.get(key), list):
            return data[key], found
    raise BadInput(f"{path}: no scenarios (a 'suite' or 'scenarios' list, or one scenario with 'elements')")


def _log_entries(path: Path) -> tuple[list[dict], dict]:
    """The certified failures of a campaign's log (known failures left out), and its problem settings."""
    from ..nodes.execution import run_profile
    from ..nodes.replay import recorded_scenarios
    from ..ros.runlog import read_metadata

    try:
        problem, run_id, scenarios, outcomes, _ = recorded_scenarios(path)
        metadata = read_metadata(path)
    except (ScenarioError, ValueError, OSError) as exc:
        raise BadInput(f"{path}: {exc}")
    try:
        config = json.loads(metadata.get("ambiegen_run", {}).get("config_json", "") or "{}")
    except ValueError:
        config = {}
    settings = dict(config.get("problem_config") or {}) if isinstance(config, dict) else {}
    profile = run_profile(metadata.get("ambiegen_run", {}).get("config_json", ""))
    if profile:
        settings["profile"] = profile
    entries = []
    for sid, outcome in sorted(outcomes.items()):
        if outcome.failed and not outcome.metrics.get("known_failure") and sid in scenarios:
            entries.append({"scenario": scenarios[sid].to_dict(), "name": f"{_stem(path)}:{sid}",
                            "note": f"{run_id} scenario {sid}: {outcome.verdict} ({outcome.detail})"})
    return entries, {"problem": problem, "problem_config": settings}


def _row_entries(path: Path) -> tuple[list[dict], dict]:
    """The failures of a results file (``rerun``, ``compare``, ``stack-search``: JSON lines), once each
    scenario (by its key), named as their rows name them; the rows' problem settings."""
    from .rows import TrialLog

    try:
        rows = TrialLog(path).rows()
    except (OSError, ValueError) as exc:
        raise BadInput(f"{path}: cannot read its rows ({exc})") from None
    entries, seen = [], set()
    for row in rows:
        if row.get("failed") and not row.get("known_failure") and row.get("key") not in seen:
            seen.add(row.get("key"))
            entries.append({"scenario": row["scenario"], "name": row.get("scenario_name") or row.get("key"),
                            "note": f"{row.get('verdict', '')} ({row.get('detail', '')})"})
    found = {k: rows[0][k] for k in ("problem", "problem_config") if rows and k in rows[0]}
    return entries, found


def load_suite(paths: list[str], config_file: str | None = None, profile: str | None = None) -> Suite:
    """The scenarios of ``paths`` (suite files, campaign logs, and the failures of a results file),
    checked by their problem, with one problem setting for all: ``config_file``'s, else the files'
    own (they must agree)."""
    from ..core.config import load_config_file
    from ..problems import get_problem

    if not paths:
        raise BadInput("no suite: name a suite file or a campaign's MCAP")
    given = load_config_file(config_file) if config_file else None
    raw: list[tuple[str, dict]] = []
    settings: list[tuple[str, dict]] = []
    for name in paths:
        path = Path(name)
        if not path.is_file():
            raise BadInput(f"{name}: no such file")
        read = {".mcap": _log_entries, ".jsonl": _row_entries}.get(path.suffix, _json_entries)
        entries, found = read(path)
        if not entries:
            raise BadInput(f"{name}: no scenarios" + {".mcap": " (no certified failures in this log)",
                                                       ".jsonl": " (no failure in these rows)"}.get(path.suffix, ""))
        settings.append((name, found))
        for i, entry in enumerate(entries):
            if not isinstance(entry, dict):
                raise BadInput(f"{name}: entry {i} is not an object")
            scenario = entry.get("scenario", entry)
            label = str(entry.get("name") or f"{_stem(path)}:{i}")
            note = str(entry.get("note") or entry.get("detail") or "")
            raw.append((label, {"scenario": scenario, "note": note, "source": name}))
    if given is not None:
        problem = given.get("problem") or "robot"
        problem_config = dict(given.get("problem_config") or {})
    else:
        problems = {s.get("problem") for _, s in settings if s.get("problem")}
        configs = {json.dumps(s.get("problem_config") or {}, sort_keys=True) for _, s in settings}
        if len(problems) > 1 or len(configs) > 1:
            raise BadInput("the suites were found with different problem settings: run them apart, or give one with "
                           "--config FILE.yaml")
        problem = problems.pop() if problems else None
        problem_config = json.loads(configs.pop()) if configs else {}
    if profile:
        problem_config = {**problem_config, "profile": profile}
    problem = problem or str(raw[0][1]["scenario"].get("problem") or "")
    try:
        case = get_problem(problem, problem_config)
    except (ConfigError, ScenarioError, TypeError, ValueError, KeyError) as exc:
        raise BadInput(f"problem {problem!r} with {problem_config}: {exc}")
    entries: list[Entry] = []
    seen: set[str] = set()
    duplicates = 0
    for label, item in raw:
        scenario = item["scenario"]
        try:
            parsed = case.parse(scenario)
        except ScenarioError as exc:
            raise BadInput(f"{item['source']}: scenario {label}: {exc}")
        data = parsed.to_dict()
        key = scenario_key(data, problem_config)
        if key in seen:
            duplicates += 1
            continue
        seen.add(key)
        entries.append(Entry(label, data, key, item["note"]))
    return Suite(problem, problem_config, entries, list(paths), duplicates)


def problem_of(suite: Suite) -> Any:
    from ..problems import get_problem

    return get_problem(suite.problem, suite.problem_config)


__all__ = ["Entry", "Suite", "load_suite", "problem_of", "scenario_key"]
