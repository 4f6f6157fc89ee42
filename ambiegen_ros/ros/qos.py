"""The few QoS profiles AmbieGen uses, in one backend-neutral form.

ROS 2 defaults are RELIABLE + VOLATILE + KEEP_LAST(10); "latched" topics (maps, run config) are
RELIABLE + TRANSIENT_LOCAL + KEEP_LAST(1) so late joiners (a recorder, Nav2's map server client)
still receive the last sample.
"""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Qos:
    reliable: bool = True
    transient_local: bool = False
    depth: int = 10


DEFAULT = Qos()
"""Scenarios, results, status: reliable, volatile, depth 10."""

LATCHED = Qos(reliable=True, transient_local=True, depth=1)
"""Maps, roads and the run config: the last sample is kept for late subscribers."""

STREAM = Qos(reliable=True, transient_local=False, depth=1000)
"""High-rate reliable topics (scenario/result bursts) where a deep queue avoids loss."""
