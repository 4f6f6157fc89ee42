"""Running an experiment: what is left to do, a process pool, per-run records, progress.

Each run is one task (algorithm, k) with seed ``seed + k``; its file is written the moment it
ends, so ``--resume`` skips it. Task functions are top-level, so a spawn pool can pickle them.
"""
from __future__ import annotations

import json
import math
import multiprocessing
import os
import signal
import sys
import time
import traceback
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from .pipeline import full_model_run, warm_up
from .records import load_record, run_path, write_atomic
from .spec import ExperimentError, ExperimentSpec, differences, resolve, run_identity
from .summary import summarize


def _settings_for(identity: dict[str, Any], algorithm: str, seed: int):
    from ..core.search import SearchSettings

    return SearchSettings(**{**identity["settings"][algorithm], "seed": seed})


def run_task(task: dict[str, Any]) -> dict[str, Any]:
    """Run one (algorithm, k) and write its file at once; returns the record."""
    from ..problems import get_problem

    identity = task["identity"]
    algorithm, k = task["algorithm"], task["run"]
    seed = identity["seed"] + k
    problem = get_problem(identity["problem"], identity["problem_config"])
    settings = _settings_for(identity, algorithm, seed)
    executor = None
    if "full_model" in identity:
        from ..sims.full_model import FullModelExecutor
        from ..sims.full_model import sim_config

        executor = FullModelExecutor(problem, sim_config(problem.name, identity["full_model"]["simulator"]))
    warm_up(problem, executor)
    record: dict[str, Any] = {
        "problem": problem.name,
        "profile": problem.profile,
        "algorithm": algorithm,
        "run": k,
        "seed": seed,
        "identity": run_identity(identity, algorithm),
    }
    if executor is None:
        record.update(_surrogate_run(problem, settings))
    else:
        record.update(full_model_run(problem, settings, executor, identity["full_model"], seed))
    record["finished"] = datetime.now(timezone.utc).isoformat(timespec="seconds")
    write_atomic(Path(task["path"]), json.dumps(record, indent=1) + "\n")
    return record


def _run_task_guarded(task: dict[str, Any]) -> dict[str, Any]:
    """A run that raises is reported (and retried by --resume) instead of stopping the others."""
    try:
        return run_task(task)
    except Exception:
        return {"algorithm": task["algorithm"], "run": task["run"], "error": traceback.format_exc()}


def _ignore_sigint(parent: int | None = None) -> None:
    """Pool workers leave Ctrl-C and a hangup (the terminal's, sent to the whole process group) to the
    parent, which stops them with SIGTERM (a run's file is written whole or not at all); a parent
    that is gone, even by SIGKILL, stops them too (``signals.watch_parent``)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if hasattr(signal, "SIGHUP"):  # POSIX
        signal.signal(signal.SIGHUP, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    if parent is not None:
        from ..ros.transport.signals import PARENT_VAR, watch_parent

        watch_parent({PARENT_VAR: str(parent)})


def _surrogate_run(problem, settings) -> dict[str, Any]:
    """RQ1/RQ2: one search on the surrogate; best F1, diversity, the history for checkpoints."""
    from ..core.search import Search

    result = Search(problem, settings).run()
    return {
        "evaluations": result.evaluations,
        "wall_s": round(result.elapsed, 3),
        "best_f1": result.best_f1,
        "diversity": result.diversity,
        "suite_size": len(result.suite),
        "history": {key: [h[key] for h in result.history] for key in ("evaluations", "elapsed_s", "best_f1")},
        "suite": [{"f1": e["f1"], "f2": e["f2"], "scenario": e["scenario"]} for e in result.suite],
    }


def default_jobs() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


class ExperimentProgress:
    """``[#####     ] 12/90 runs  4m10s elapsed, ~20m left`` on stderr (a terminal only)."""

    def __init__(self, total: int, done: int, enabled: bool | None = None, label: str = "",
                 run_seconds: float | None = None, jobs: int = 1):
        self.total, self.done, self.start_done = total, done, done
        self.label = label
        self.run_seconds, self.jobs = run_seconds, jobs  # a clock budget per run gives an early estimate
        self.enabled = sys.stderr.isatty() if enabled is None else enabled
        self.t0 = time.monotonic()

    @staticmethod
    def _fmt(seconds: float) -> str:
        seconds = int(round(seconds))
        h, rem = divmod(seconds, 3600)
        m, s = divmod(rem, 60)
        return f"{h}h{m:02d}m" if h else (f"{m}m{s:02d}s" if m else f"{s}s")

    def eta(self) -> float | None:
        finished = self.done - self.start_done
        if finished <= 0:
            if self.run_seconds is None:
                return None
            waves = math.ceil((self.total - self.done) / self.jobs)
            return max(waves * self.run_seconds - (time.monotonic() - self.t0), 0.0)
        return (time.monotonic() - self.t0) / finished * (self.total - self.done)

    def update(self, done: int | None = None) -> None:
        if done is not None:
            self.done = done
        if not self.enabled:
            return
        frac = self.done / self.total if self.total else 1.0
        eta = self.eta()
        left = f", ~{self._fmt(eta)} left" if eta is not None else ""
        sys.stderr.write(f"\r{self.label}[{'#' * int(frac * 30):<30}] {self.done}/{self.total} runs  "
                         f"{self._fmt(time.monotonic() - self.t0)} elapsed{left}   ")
        sys.stderr.flush()

    def close(self) -> None:
        if self.enabled:
            sys.stderr.write("\n")
            sys.stderr.flush()


def prepare(spec: ExperimentSpec, out: Path, resume: bool, jobs: int) -> tuple[dict[str, Any], list[dict], list[dict]]:
    """Check DIR, write config.json; returns (config, runs already done, tasks to run)."""
    out = Path(out)
    identity = resolve(spec)
    existing = out / "config.json"
    if out.exists() and any(out.iterdir()):
        if not resume:
            raise ExperimentError(f"--out {out}: directory exists and is not empty (use --resume to continue "
                                  "that experiment, or choose a new directory)")
        if not existing.exists():
            raise ExperimentError(f"--out {out}: not an experiment directory (no config.json); refusing to write into it")
        old = json.loads(existing.read_text()).get("identity") or {}
        shared = {k: v for k, v in identity.items() if k != "settings"}
        diff = differences({k: v for k, v in old.items() if k != "settings"}, shared)
        for alg, settings in identity["settings"].items():  # an algorithm may join or stay out
            if alg in (old.get("settings") or {}):
                diff += differences(old["settings"][alg], settings, f"settings.{alg}")
        if diff:
            raise ExperimentError(f"--resume: {out} holds an experiment with a different config "
                                  f"({', '.join(diff[:5])}); use the same options or a new --out")
        identity = {**identity, "settings": {**old.get("settings", {}), **identity["settings"]}}
    done, tasks = [], []
    for k in range(spec.runs):  # interleaved: a stopped experiment leaves balanced algorithms
        for alg in spec.algorithms:
            path = run_path(out, alg, k)
            rec = load_record(path) if path.exists() else None
            if rec is not None:
                diff = differences(rec.get("identity"), run_identity(identity, alg))
                if diff:
                    raise ExperimentError(f"--resume: {path} was made with a different config ({', '.join(diff[:5])})")
                done.append(rec)
            else:
                tasks.append({"identity": identity, "algorithm": alg, "run": k, "path": str(path)})
    from ..core.runs import versions

    config = {
        "identity": identity,
        "problem": identity["problem"],
        "profile": identity["profile"],
        "seed": spec.seed,
        "algorithms": list(spec.algorithms),
        "runs": spec.runs,
        "jobs": jobs,
        "cpus": os.cpu_count(),
        "versions": versions(),
        "command": sys.argv,
        "written": datetime.now(timezone.utc).isoformat(timespec="seconds"),
    }
    write_atomic(existing, json.dumps(config, indent=2) + "\n")
    return config, done, tasks


def run_experiment(spec: ExperimentSpec, out: Path, jobs: int | None = None, resume: bool = False,
                   progress: bool | None = None) -> dict[str, Any]:
    """Run what is missing, then write the tables, statistics, report and plots."""
    out = Path(out)
    jobs = max(1, jobs or default_jobs())
    config, records, tasks = prepare(spec, out, resume, jobs)
    identity = config["identity"]
    run_seconds = (identity["full_model"]["time_budget_s"] if "full_model" in identity
                   else next(iter(identity["settings"].values()))["time_budget"])
    bar = ExperimentProgress(len(records) + len(tasks), len(records), enabled=progress,
                             label=f"{config['problem']} ({config['profile']}) ", run_seconds=run_seconds, jobs=jobs)
    bar.update()
    errors: list[dict[str, Any]] = []

    def take(rec: dict[str, Any]) -> None:
        if "error" in rec:
            errors.append(rec)
            print(f"\nambiegen experiment: run {rec['algorithm']}-{rec['run']:03d} failed (--resume retries it):\n"
                  f"{rec['error']}", file=sys.stderr)
        else:
            records.append(rec)
        bar.update(len(records) + len(errors))

    try:
        if jobs == 1 or len(tasks) <= 1:
            for task in tasks:
                take(_run_task_guarded(task))
        elif tasks:
            pool = multiprocessing.get_context("spawn").Pool(min(jobs, len(tasks)), initializer=_ignore_sigint,
                                                            initargs=(os.getpid(),))
            try:
                results = pool.imap_unordered(_run_task_guarded, tasks)
                for _ in tasks:
                    while True:
                        try:
                            rec = results.next(timeout=1.0)
                            break
                        except multiprocessing.TimeoutError:
                            bar.update()
                    take(rec)
                pool.close()
            finally:
                pool.terminate()  # on Ctrl-C or an error: the runs in flight stop (their files were never written)
                pool.join()
    finally:
        bar.close()
        if records:
            summarize(out, config, records)
    return {"config": config, "records": records, "errors": errors}


__all__ = ["ExperimentProgress", "default_jobs", "prepare", "run_experiment", "run_task"]
