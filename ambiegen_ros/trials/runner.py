"""Running trials: per configuration, a stack session, the missing runs, a row each.

Each configuration gets a session (``session.StackSession``: its stack, watched and kept alive,
and a bag of its own under ``<bags>/<label>_<UTC time>/`` with the nodes' logs and the params).
Scenarios go one at a time, each configuration's runs round-robin (every scenario once, then
again), so a run cut short leaves balanced counts, and the next invocation runs only what is
missing (``rows.TrialLog.done``). A run during which a process of the stack died or hung is
FAIL(sut_crashed) (the adapter's verdict, certified), and the same scenario runs once more on the
fresh stack the session started: the row says whether the crash came back. A run during which a
part of ours died is an error record, and runs again once the part is back. Every row and every
restart is said as it happens. After ``max_errors`` errors of ours in a row, or a stack that does
not come back, the configuration stops with one line naming the logs.
"""
from __future__ import annotations

import math
import re
import sys
import time
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Callable, NamedTuple

from .configs import Prepared
from .faults import Fault, Injector
from .reruns import Reruns
from .rows import TrialLog, counted, utc_stamp
from .session import StackSession, StackStopped
from .suite import Entry, Suite

DEFAULT_START_TIMEOUT = 120.0  # s the adapter waits for a stack this command starts


@dataclass
class TrialSettings:
    stack: str  # nd | bringup | ours | external
    results: Path
    bags: Path
    repeat: int = 3
    time_scale: float = 1.0
    seed: int = 0
    domain_id: int | None = None
    known_failures: str | None = None
    fault_speed: float | None = None  # m/s: a contact with a person below it is not charged (None: the default)
    early_verdicts: bool = False
    map_upsample: int = 5
    start_timeout: float | None = None  # s the adapter waits for the stack (None: 600 for external, where you
    # start it yourself, else 120; a value given holds for every stack)
    ready_timeout: float = 300.0  # s for the stack's nodes to come up (and back, after a restart)
    hang_after: float = 30.0  # s of silence or of a node not scheduled while a run is on: hung (0: not watched)
    max_errors: int = 3
    faults: list[Fault] = field(default_factory=list)  # injected on purpose (``faults``)
    budget_s: float | None = None  # wall seconds of sending: no run starts after it (None: all runs)
    extra_env: dict[str, str] = field(default_factory=dict)
    our_transport: str | None = None  # dds: the world and the recorder on Cyclone DDS from PyPI (``lean_parts``)
    robot: str = ""  # the robot profile the world drives and the adapter judges, as the nodes take it
    # (``launch_logic.node_robot``: a shipped name or an absolute path; '': Stage's Pioneer)

    def __post_init__(self) -> None:
        if self.start_timeout is None:
            from ..launch_logic import EXTERNAL_START_TIMEOUT

            self.start_timeout = EXTERNAL_START_TIMEOUT if self.stack == "external" else DEFAULT_START_TIMEOUT


def _number(value: Any) -> float | None:
    try:
        out = float(value)
    except (TypeError, ValueError):
        return None
    return out if math.isfinite(out) else None


def row_of(outcome: Any, entry: Entry, suite: Suite, prepared: Prepared, settings: TrialSettings, repeat: int,
           run_id: str, sid: int, bag: Path, wall: float, started_ns: int, extra: dict | None = None) -> dict:
    """One run as a row of the results file (see ``rows``)."""
    import numpy as np

    from ..core.runs import versions
    from ..sims.obstacles import contact_speeds

    m = outcome.metrics or {}
    traj = outcome.trajectory
    return {
        **prepared.record(), "stack": settings.stack, "time_scale": settings.time_scale, "seed": settings.seed,
        **({"robot": settings.robot} if settings.robot else {}),  # '' (the Pioneer): rows as before issue 69
        "scenario_name": entry.name, "key": entry.key, "repeat": repeat, "scenario": entry.scenario,
        "problem": suite.problem, "problem_config": suite.problem_config,
        "verdict": outcome.verdict, "failure_kind": outcome.failure_kind, "failed": bool(outcome.failed),
        "detail": outcome.detail, "known_failure": m.get("known_failure") or None,
        "time_s": _number(m.get("time")), "recoveries": _number(m.get("nav2_recoveries")),
        "nav2_status": m.get("nav2_status"), "nav2_error_code": _number(m.get("nav2_error_code")),
        "nav2_error_msg": m.get("nav2_error_msg"), "early_verdict": m.get("early_verdict"),
        "contact": contact_speeds(outcome.detail) if outcome.failed else None,
        "contacts_not_at_fault": _number(m.get("contacts_not_at_fault")),
        "reference_check": m.get("reference_check"),
        "failure_point": list(outcome.failure_point) if outcome.failure_point is not None else None,
        "trajectory_every_10": np.asarray(traj)[::10, :2].round(3).tolist() if traj is not None and len(traj) else None,
        "metrics": {str(k): v if isinstance(v, (str, int, float, bool)) or v is None else str(v) for k, v in m.items()},
        "wall_s": round(wall, 2), "run_id": run_id, "scenario_id": sid, "bag": str(bag),
        "wall_start_ns": started_ns, "wall_end_ns": time.time_ns(),
        "when": datetime.now(timezone.utc).isoformat(timespec="seconds"), "versions": versions(),
        "command": sys.argv, **(extra or {}),
    }


def run_trials(suite: Suite, prepared: list[Prepared], settings: TrialSettings,
               say: Callable[[str], None] = print) -> dict[str, int]:
    """Every configuration's missing runs, appended to the results file as they finish. Returns the
    runs made per label. ``KeyboardInterrupt`` stops the stack and is raised again."""
    log = TrialLog(settings.results)
    for p in prepared:
        log.check_label(p.config.label, p.digest)
    plans = []
    for p in prepared:
        done = log.done(p.config.label)
        todo = [(r, e) for r in range(1, settings.repeat + 1) for e in suite.entries if done[e.key] < r]
        plans.append((p, todo))
    total = sum(len(t) for _, t in plans)
    say(f"{len(suite.entries)} scenarios x {settings.repeat} runs x {len(prepared)} configuration"
        f"{'s' * (len(prepared) != 1)}: {total} runs to make"
        + (f" ({sum(len(suite.entries) * settings.repeat for _ in prepared) - total} already in {settings.results})"
           if total < len(suite.entries) * settings.repeat * len(prepared) else ""))
    made: dict[str, int] = {}
    clock = {"count": 0, "start": time.monotonic(), "total": total}
    injector = Injector(settings.faults, say)
    for p, todo in plans:
        if todo:
            made[p.config.label] = _run_configuration(suite, p, todo, settings, log, injector, clock, say)
    return made


class Feed:
    """Runs that are not known in advance (a search's batches): ``more()`` gives the next entries once
    the queue is empty (none: the runs end), ``took(entry, outcome)`` the verdict each entry earned
    (its first counted run; a crash's rerun on a fresh stack is not asked for again)."""

    def more(self) -> list[Entry]:
        return []

    def took(self, entry: Entry, outcome: Any) -> None:
        pass


def run_feed(suite: Suite, prepared: Prepared, settings: TrialSettings, feed: "Feed",
             say: Callable[[str], None] = print) -> int:
    """Run what ``feed`` gives on one supervised stack until it gives nothing or ``settings.budget_s``
    is spent; rows go to ``settings.results``. Returns the runs made."""
    log = TrialLog(settings.results)
    log.check_label(prepared.config.label, prepared.digest)
    clock = {"count": 0, "start": time.monotonic(), "total": 0}
    return _run_configuration(suite, prepared, [], settings, log, Injector(settings.faults, say), clock, say, feed)


class _Ran(NamedTuple):
    """One run as filed, and what followed it."""

    row: dict
    outcome: Any
    wall: float
    deaths: list
    restarts: list[dict]
    stopped: StackStopped | None  # a part that never came back: the run is filed, then the configuration stops


def _run_once(session: StackSession, entry: Entry, extra: dict, run_no: int, repeat: int, suite: Suite,
              p: Prepared, settings: TrialSettings) -> _Ran:
    """One run on the session: what died before it restarted, the run, what died during it restarted."""
    before = session.between_runs()
    bag = session.bags[-1]
    outcome, sid, wall, w0, deaths = session.run(entry, run_no)
    stopped = None
    try:
        restarts = session.recover(deaths) if deaths else []
    except StackStopped as exc:
        restarts, stopped = [{"event": "restart", "process": None, "why": str(exc), "ok": False}], exc
    events = [{"process": d.process, "part": d.part, "what": d.what} for d in deaths]
    row = row_of(outcome, entry, suite, p, settings, repeat, session.run_id, sid, bag, wall, w0,
                 {**extra, "events": events, "restarts": before + restarts, "cpu": session.cpu})
    return _Ran(row, outcome, wall, deaths, restarts, stopped)


def _run_configuration(suite: Suite, p: Prepared, todo: list[tuple[int, Entry]], settings: TrialSettings,
                       log: TrialLog, injector: Injector, clock: dict, say: Callable[[str], None],
                       feed: Feed | None = None) -> int:
    """One configuration's runs on one session, with the reruns that crashes and our errors call for
    (``reruns.Reruns``). The session's processes stop however this ends."""
    label = p.config.label
    made, errors = 0, 0
    queue: list[tuple[Entry, dict]] = [(entry, {}) for _, entry in todo]
    feed = feed or Feed()
    with StackSession(settings, suite, p, say, injector) as session:
        say(f"[{label}] stack {settings.stack}" + (f", robot {settings.robot}" if settings.robot else "")
            + f", params {p.path or '(defaults)'}; bag {session.bag}")
        if not session.ready():
            raise StackStopped(f"[{label}] the stack's nodes did not come up in {settings.ready_timeout:.0f} s "
                               f"(logs: {session.dir / 'logs'})")
        policy = Reruns(settings.max_errors, label, str(session.dir / "logs"))
        done = log.done(label)
        while not (settings.budget_s is not None and time.monotonic() - clock["start"] > settings.budget_s):
            if not queue:
                queue = [(entry, {}) for entry in feed.more()]
                clock["total"] += len(queue)
                if not queue:
                    break
            entry, extra = queue.pop(0)
            made += 1
            repeat = done[entry.key] + 1
            ran = _run_once(session, entry, extra, made, repeat, suite, p, settings)
            log.append(ran.row)
            clock["count"] += 1
            step = policy.after(ran.row, ran.deaths, ran.restarts, extra, errors)
            errors = step.errors
            if step.count:
                done[entry.key] += 1
            if step.tell:
                feed.took(entry, ran.outcome)
            _say_run(say, clock, label, entry, repeat, settings.repeat, ran.outcome, ran.row, ran.wall)
            if ran.stopped is not None:
                raise ran.stopped
            if step.again is not None:
                queue.insert(0, (entry, step.again))
                clock["total"] += 1
            if step.stop is not None:
                raise StackStopped(step.stop)
    return made


def _say_run(say: Callable[[str], None], clock: dict, label: str, entry: Entry, repeat: int, of: int, outcome: Any,
             row: dict, wall: float) -> None:
    count, total = clock["count"], clock["total"]
    eta = (time.monotonic() - clock["start"]) / count * max(total - count, 0)
    rerun = row.get("crash_rerun_of")
    which = f"run {repeat}/{of}" if repeat <= of else f"run {repeat} (one more)"
    say(f"[{count}/{total}] {label} {entry.name} {which}: {outcome.verdict[:90]}"
        + (f" ({outcome.detail[:120]})" if outcome.failed or not counted(row) else "")
        + (f" (the crash's rerun on a fresh stack: {crash_again(rerun['detail'], outcome)})" if rerun else "")
        + f"  {wall:.0f} s" + (f", about {eta / 60:.0f} min left" if count < total else ""))


def crash_again(first: str, outcome: Any) -> str:
    """Did the crash come back: the same process and the same death, another one, or none."""
    if outcome.failure_kind != "sut_crashed":
        return "it did not come back"
    what = re.compile(r"the stack crashed: (.+?), [0-9.]+ s into the run")
    was, now = what.search(first), what.search(outcome.detail)
    if was and now and was.group(1) != now.group(1):
        return f"the stack crashed again, differently: {now.group(1)} (first {was.group(1)})"
    return "it came back"


__all__ = ["Feed", "StackStopped", "TrialSettings", "row_of", "run_feed", "run_trials", "utc_stamp"]
