"""Fixtures of the process tests: ``graph`` (node subprocesses + a driver node on the test's own domain)."""
import sys
from pathlib import Path

TEST = Path(__file__).resolve().parents[1]
if str(TEST) not in sys.path:
    sys.path.insert(0, str(TEST))

from helpers.sut_graph import graph  # noqa: E402,F401  (a fixture, found here by pytest)
