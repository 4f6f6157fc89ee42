"""The choices a user names (algorithms, F2 references, fidelity profiles) as plain tuples.

Importable without numpy or pymoo, so the command line can list them in ``--help`` at once.
"""
from __future__ import annotations

ALGORITHMS = ("ga", "nsga2", "random")
"""ga: one objective (F1); nsga2: F1 + diversity (F2); random: the baseline."""
REFERENCES = ("parent", "front")
"""What F2 measures the distance to: the parent (the paper) or the nearest front member."""
PROFILES = ("replication", "refined")
"""replication: the authors' code, which made the paper's tables; refined: the paper's text."""
DEFAULT_PROFILE = "replication"
"""The profile a run uses unless told otherwise."""

__all__ = ["ALGORITHMS", "DEFAULT_PROFILE", "PROFILES", "REFERENCES"]
