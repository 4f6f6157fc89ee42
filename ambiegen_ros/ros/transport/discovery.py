"""Discovery scope from Jazzy's environment variables, and the Cyclone XML that enforces it.

ROS 2 Jazzy reads ``ROS_AUTOMATIC_DISCOVERY_RANGE`` (``SUBNET`` when unset, ``LOCALHOST``,
``OFF``, ``SYSTEM_DEFAULT``), ``ROS_STATIC_PEERS`` (``;``-separated hosts) and the deprecated
``ROS_LOCALHOST_ONLY=1`` (which, when set, wins and means ``LOCALHOST`` without static peers)
in rcl; rmw_cyclonedds_cpp turns them into a Cyclone configuration fragment placed *before* the
user's ``CYCLONEDDS_URI``. ``cyclone_fragment`` builds the same fragment, so a node on our DDS
backend reaches exactly the peers an rclpy node would. With rclpy the RMW does this itself; we
only validate the values first (``options_from_env``) so a typo is an error, not a silent
fallback (rcl would warn and assume ``LOCALHOST``).

What each range does (as rmw_cyclonedds_cpp, Jazzy):
* SUBNET: multicast discovery as usual, plus unicast discovery of the static peers;
* LOCALHOST: no multicast; unicast discovery of ``localhost`` and the static peers only;
* OFF: no multicast, no peers, and a per-process discovery tag: only nodes of this process meet;
* SYSTEM_DEFAULT: Cyclone's own settings untouched (static peers ignored).
"""
from __future__ import annotations

import ipaddress
import os
import socket
from dataclasses import dataclass
from xml.sax.saxutils import quoteattr

from .base import TransportError

RANGES = ("SUBNET", "LOCALHOST", "OFF", "SYSTEM_DEFAULT")
RANGE_VAR = "ROS_AUTOMATIC_DISCOVERY_RANGE"
PEERS_VAR = "ROS_STATIC_PEERS"
LOCALHOST_ONLY_VAR = "ROS_LOCALHOST_ONLY"
# Peers rmw_cyclonedds_cpp probes per host (one port pair per participant index): roughly the
# number of ROS processes per machine it can discover by unicast.
MAX_AUTO_PARTICIPANT_INDEX = 32
PEER_MAX_LENGTH = 255  # RMW_DISCOVERY_OPTIONS_STATIC_PEERS_MAX_LENGTH - 1


@dataclass(frozen=True)
class DiscoveryOptions:
    range: str = "SUBNET"
    static_peers: tuple[str, ...] = ()


def options_from_env(env: dict[str, str] | None = None) -> DiscoveryOptions:
    """The discovery options rcl would derive from ``env`` (default ``os.environ``).

    Raises TransportError for an unknown range or an unusable peer, naming the variable.
    """
    env = os.environ if env is None else env
    localhost_only = env.get(LOCALHOST_ONLY_VAR, "").strip()
    raw = env.get(RANGE_VAR, "").strip()
    if raw and raw not in RANGES:
        raise TransportError(f"{RANGE_VAR}={raw!r}: use one of {', '.join(RANGES)} (unset = SUBNET)")
    peers = tuple(p.strip() for p in env.get(PEERS_VAR, "").split(";") if p.strip())
    for peer in peers:
        if len(peer) > PEER_MAX_LENGTH or any(c in peer for c in "<>\"' \t"):
            raise TransportError(f"{PEERS_VAR}: {peer!r} is not a host name or address")
    if localhost_only == "1":  # deprecated, but rcl still lets it win
        return DiscoveryOptions("LOCALHOST", ())
    return DiscoveryOptions(raw or "SUBNET", peers)


def check_peers_resolve(options: DiscoveryOptions) -> None:
    """Every static peer must resolve: Cyclone aborts the whole process on an unknown one."""
    for peer in options.static_peers:
        host = peer
        if host.startswith("[") and "]" in host:  # [v6]:port
            host = host[1:host.index("]")]
        elif host.count(":") == 1 and host.rsplit(":", 1)[1].isdigit():  # host:port
            host = host.rsplit(":", 1)[0]
        try:
            ipaddress.ip_address(host)
            continue
        except ValueError:
            pass
        try:
            socket.getaddrinfo(host, None)
        except OSError as exc:
            raise TransportError(f"{PEERS_VAR}: cannot resolve peer {peer!r} ({exc})") from None


def cyclone_fragment(options: DiscoveryOptions) -> str:
    """The ``<CycloneDDS>`` fragment rmw_cyclonedds_cpp puts before ``CYCLONEDDS_URI`` ('' = none)."""
    rng = options.range
    if rng == "SYSTEM_DEFAULT":
        return ""
    peers = list(options.static_peers) if rng in ("SUBNET", "LOCALHOST") else []
    if rng == "LOCALHOST":
        peers.insert(0, "localhost")
    xml = "<CycloneDDS><Domain Id=\"any\">"
    if rng in ("LOCALHOST", "OFF"):
        xml += "<General><AllowMulticast>false</AllowMulticast></General>"
    if rng == "OFF":
        # a tag no other process uses: automatic discovery can never match anyone else
        xml += f"<Discovery><ParticipantIndex>none</ParticipantIndex><Tag>ros_discovery_off_{os.getpid()}</Tag>"
    else:
        xml += ("<Discovery><ParticipantIndex>auto</ParticipantIndex>"
                f"<MaxAutoParticipantIndex>{MAX_AUTO_PARTICIPANT_INDEX}</MaxAutoParticipantIndex>")
    if peers:
        xml += "<Peers>" + "".join(f"<Peer address={quoteattr(p)}/>" for p in peers) + "</Peers>"
    return xml + "</Discovery></Domain></CycloneDDS>"
