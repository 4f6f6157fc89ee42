"""Shared bits of the benchmark scripts: where results go and how they are stamped."""
from __future__ import annotations

import json
import os
import platform
from datetime import datetime, timezone
from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "results"


def write_result(name: str, figures: dict) -> Path:
    """Write ``bench/results/<name>.json`` with the machine and package versions beside the figures."""
    from ambiegen_ros.core.runs import versions

    RESULTS.mkdir(parents=True, exist_ok=True)
    doc = {
        "benchmark": name,
        "when": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "machine": {"cpus": os.cpu_count(), "platform": platform.platform()},
        "versions": versions(),
        "figures": figures,
    }
    path = RESULTS / f"{name}.json"
    path.write_text(json.dumps(doc, indent=2) + "\n")
    return path


def report(name: str, tag: str, figures: dict) -> Path:
    """Write ``<name>[_<tag>].json`` (``write_result``) and print the figures and where they went."""
    path = write_result(name + (f"_{tag}" if tag else ""), figures)
    print(figures)
    print(f"written: {path}")
    return path


def read_rows(path: Path) -> list[dict]:
    """Every row of a JSON-lines results file, oldest first (none when it does not exist yet)."""
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()] if path.exists() else []


def append_row(path: Path, row: dict) -> None:
    """Add one row to a JSON-lines results file: appended, never rewritten."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "a") as fh:
        fh.write(json.dumps(row) + "\n")


def seed_list(text: str) -> list[int]:
    """Seeds from the command line: ``100-119`` or ``100,101,105`` (or one seed)."""
    if "-" in text and "," not in text:
        low, high = (int(v) for v in text.split("-"))
        return list(range(low, high + 1))
    return [int(v) for v in text.split(",")]


NAV2_LOOP_MISSED = "Control loop missed its desired rate"  # Nav2 controller_server's own warning


def nav2_loop_misses(log: Path) -> int | None:
    """How often Nav2's controller missed its loop rate, by its warnings in a log (None: no log)."""
    return log.read_text(errors="replace").count(NAV2_LOOP_MISSED) if log.exists() else None
