"""Run files: one JSON per finished run, written atomically, so a kill never leaves half a result."""
from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any


def write_atomic(path: Path, text: str) -> None:
    """Write then rename: a reader (or a kill) never sees half a file."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


def run_path(out: Path, algorithm: str, run: int) -> Path:
    return Path(out) / "runs" / f"{algorithm}-{run:03d}.json"


def load_record(path: Path) -> dict[str, Any] | None:
    try:
        return json.loads(path.read_text())
    except (OSError, json.JSONDecodeError):
        return None  # a damaged file counts as not done (re-run)


__all__ = ["load_record", "run_path", "write_atomic"]
