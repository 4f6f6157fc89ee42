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
    keep_all: bool = False
    """KEEP_ALL history (``depth`` unused): a slow reader buffers instead of losing the oldest samples."""


DEFAULT = Qos()
"""Scenarios, results, status: reliable, volatile, depth 10."""

LATCHED = Qos(reliable=True, transient_local=True, depth=1)
"""Maps, roads and the run config: the last sample is kept for late subscribers."""

STREAM = Qos(reliable=True, transient_local=False, depth=1000)
"""High-rate reliable topics (scenario/result bursts) where a deep queue avoids loss."""


# rmw's RMW_DURATION_INFINITE ({INT64_MAX / 1e9 s, remainder ns}): what Jazzy RMWs report for an
# unset deadline, lifespan and liveliness lease, and what rosbag2 writes into its bags.
_INFINITE_SEC = 9223372036
_INFINITE_NSEC = 854775807


def to_offered_qos_yaml(qos: Qos) -> str:
    """rosbag2's ``offered_qos_profiles`` text for one publisher offering ``qos`` (Jazzy form).

    Jazzy (bag metadata version 9) writes policies as lower-case names and durations as
    ``{sec, nsec}``, serialised by yaml-cpp as a block sequence without a trailing newline.
    ``ros2 bag play`` rebuilds the publisher from it (history/depth are reset to its default, the
    rest is kept), which is what makes a replayed map latched again.
    """
    infinite = f"\n    sec: {_INFINITE_SEC}\n    nsec: {_INFINITE_NSEC}"
    return (
        "- history: keep_last"
        f"\n  depth: {int(qos.depth)}"
        f"\n  reliability: {'reliable' if qos.reliable else 'best_effort'}"
        f"\n  durability: {'transient_local' if qos.transient_local else 'volatile'}"
        f"\n  deadline:{infinite}"
        f"\n  lifespan:{infinite}"
        "\n  liveliness: automatic"
        f"\n  liveliness_lease_duration:{infinite}"
        "\n  avoid_ros_namespace_conventions: false"
    )


def from_offered_qos_yaml(text: str) -> Qos:
    """The first profile of an ``offered_qos_profiles`` text back as a ``Qos`` (for replay).

    Accepts the lower-case names Jazzy writes and the numeric enums of older rosbag2 versions
    (reliability 1 = reliable, 2 = best effort; durability 1 = transient local, 2 = volatile).
    """
    import yaml

    profiles = yaml.safe_load(text) or []
    if not profiles:
        return DEFAULT
    first = profiles[0]
    reliability = first.get("reliability", "reliable")
    durability = first.get("durability", "volatile")
    depth = int(first.get("depth") or DEFAULT.depth)
    return Qos(
        reliable=reliability in ("reliable", 1, "system_default", 0),
        transient_local=durability in ("transient_local", 1),
        depth=max(depth, 1),
    )
