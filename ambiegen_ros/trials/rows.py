"""The results file of trials: one JSON object per run, appended, never rewritten.

A run is one scenario on one configuration, once (``repeat`` counts them). Rows carry everything
a table or a picture needs without the bag: the scenario, the configuration (label, files, the
digest of the merged params, the world's options), Nav2's answer, the verdict and its evidence
(contact speeds, where it failed, the path every 10th pose), the versions and the bag's path.

Resuming: the runs that count are those with a verdict of the stack (``COUNTED``: a pass, a
failure, or an invalid test). An error or a lost answer is recorded too, but is not a run of the
stack: it is run again on the next invocation. A line cut short by a crash is skipped (and said),
never rewritten; the next row starts on a line of its own.
"""
from __future__ import annotations

import json
import os
import sys
from collections import Counter
from datetime import datetime, timezone
from pathlib import Path

from ..core.errors import BadInput

SCHEMA = 1
NOT_COUNTED = ("error", "sim_timeout", "invalid_scenario")  # ours, not the stack's: run again on resume


def utc_stamp() -> str:
    """The UTC time in folder names and reports (sorts as it reads)."""
    return datetime.now(timezone.utc).strftime("%Y%m%dT%H%M%SZ")


def counted(row: dict) -> bool:
    """Is this row a run of the stack (a verdict it earned), not an error of ours?"""
    return row.get("failure_kind") not in NOT_COUNTED


class TrialLog:
    """``path``: a JSON-lines file that only grows."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        self.skipped = 0  # lines that are not rows (a crash mid-line)

    def rows(self) -> list[dict]:
        if not self.path.exists():
            return []
        out, self.skipped = [], 0
        for line in self.path.read_text(errors="replace").splitlines():
            if not line.strip():
                continue
            try:
                row = json.loads(line)
            except ValueError:
                self.skipped += 1
                continue
            if isinstance(row, dict) and "key" in row and "label" in row:
                out.append(row)
            else:
                self.skipped += 1
        if self.skipped:
            print(f"{self.path}: {self.skipped} line(s) that are not rows skipped (left as they are)", file=sys.stderr)
        return out

    def done(self, label: str) -> Counter:
        """Runs of the stack per scenario key under ``label``."""
        return Counter(r["key"] for r in self.rows() if r["label"] == label and counted(r))

    def check_label(self, label: str, digest: str) -> None:
        """A label names one configuration: rows of the same label with other merged params refuse the run."""
        other = {r.get("config_digest") for r in self.rows() if r["label"] == label} - {digest, None}
        if other:
            raise BadInput(f"{self.path}: label {label!r} was run with other params (digest {sorted(other)[0]}, now "
                           f"{digest}); give this configuration another label, or another results file")

    def append(self, row: dict) -> None:
        """One row, on a line of its own, on disk before this returns."""
        self.path.parent.mkdir(parents=True, exist_ok=True)
        with open(self.path, "ab") as fh:
            if fh.tell() > 0:
                with open(self.path, "rb") as check:
                    check.seek(-1, os.SEEK_END)
                    if check.read(1) != b"\n":
                        fh.write(b"\n")  # a line cut short stays as it is; ours starts anew
            fh.write((json.dumps({"trial_schema": SCHEMA, **row}) + "\n").encode())
            fh.flush()
            os.fsync(fh.fileno())


def rows_of(path: str | Path, labels: list[str] | None = None, keys: set[str] | None = None) -> list[dict]:
    """The rows of a results file, of some labels and scenarios only when given."""
    rows = TrialLog(path).rows()
    return [r for r in rows if (labels is None or r["label"] in labels) and (keys is None or r["key"] in keys)]


__all__ = ["NOT_COUNTED", "SCHEMA", "TrialLog", "counted", "rows_of"]
