"""Discovery scope as ROS 2 Jazzy has it: ROS_AUTOMATIC_DISCOVERY_RANGE, ROS_STATIC_PEERS, ROS_DOMAIN_ID.

The mapping onto Cyclone settings is checked against what rmw_cyclonedds_cpp (Jazzy) writes; then
real node processes on hosts made of network namespaces (test/helpers/netns.py) show that the
scope holds on the wire: LOCALHOST nodes meet each other on their host and nobody else, OFF nodes
meet nobody, and with multicast off on the network only ROS_STATIC_PEERS connects two hosts.
The namespace tests need root; they run for the DDS backend and, where a ROS 2 Jazzy install
with rclpy is found (as for test/real_ros), for rclpy: Jazzy's own rmw must honour the same
variables the same way, also in a graph that mixes rclpy and DDS-backend nodes.
Domain ids 74..78 and 96..98 inside the namespaces (each test's own network: nothing else can meet
them); the tests in the machine's own network take theirs from ``ros_domain``. Probes stop on
events (each has heard whom it expects); only "hears nobody" needs a listening window.
"""
from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
for p in (REPO, REPO / "test" / "helpers"):
    if str(p) not in sys.path:
        sys.path.insert(0, str(p))

import pytest  # noqa: E402

import netns  # noqa: E402
from ambiegen_ros.ros.transport.base import TransportError  # noqa: E402
from ambiegen_ros.ros.transport.discovery import (DiscoveryOptions, cyclone_fragment,  # noqa: E402
                                                  options_from_env)

# A node that says its name on /probe and reports whom it heard. It prints UP once its node exists,
# GOT once it has heard every name it expects (argv[2]), and runs until its stdin closes, so that
# no probe leaves before its peers have heard it; then it prints HEARD with every name it heard.
PROBE = r"""
import sys, threading
from ambiegen_ros.ros.transport import create_node
from ambiegen_ros.ros.qos import DEFAULT
me, expect = sys.argv[1], set(filter(None, sys.argv[2].split(",")))
node = create_node("probe_" + me, argv=[])
heard = set()
def on(msg):
    if msg.data != me:
        heard.add(msg.data)
node.create_subscription("std_msgs/msg/String", "/probe", on, DEFAULT)
pub = node.create_publisher("std_msgs/msg/String", "/probe", DEFAULT)
print("UP", flush=True)
done = threading.Event()
threading.Thread(target=lambda: (sys.stdin.read(), done.set()), daemon=True).start()
said = False
while not done.is_set():
    pub.publish(node.new_message("std_msgs/msg/String", data=me))
    node.spin_once(0.1)
    if expect and not said and expect <= heard:
        print("GOT", flush=True)
        said = True
print("HEARD", ",".join(sorted(heard)), "BACKEND", node.backend_name, flush=True)
node.shutdown()
"""
# Probes that expect names stop waiting when they have heard them (an event). Probes that must hear
# nobody listen this long once every probe is up: a window a busy machine can only make pass
# wrongly (discovery too slow to be seen), never fail wrongly.
LISTEN_S = 6.0
PATIENCE = 180.0  # s: the bound of every wait that ends on an event (a hung probe)
BACKENDS = [
    "dds",
    pytest.param("rclpy", marks=pytest.mark.skipif(bool(netns.rclpy_unavailable_reason()),
                                                   reason=str(netns.rclpy_unavailable_reason()))),
]


# --- the mapping, without a network -----------------------------------------------------------------
def test_ranges_and_peers_are_read_as_rcl_reads_them():
    assert options_from_env({}) == DiscoveryOptions("SUBNET", ())
    for rng in ("SUBNET", "LOCALHOST", "OFF", "SYSTEM_DEFAULT"):
        assert options_from_env({"ROS_AUTOMATIC_DISCOVERY_RANGE": rng}).range == rng
    got = options_from_env({"ROS_STATIC_PEERS": "10.0.0.2; robot.lab ;;[fe80::1]:7410"})
    assert got.static_peers == ("10.0.0.2", "robot.lab", "[fe80::1]:7410")
    # the deprecated ROS_LOCALHOST_ONLY=1 still wins, as in Jazzy's rcl, and drops the peers
    assert options_from_env({"ROS_LOCALHOST_ONLY": "1", "ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET",
                             "ROS_STATIC_PEERS": "10.0.0.2"}) == DiscoveryOptions("LOCALHOST", ())
    for bad in ("subnet", "LAN", "localhost only"):
        with pytest.raises(TransportError, match="ROS_AUTOMATIC_DISCOVERY_RANGE"):
            options_from_env({"ROS_AUTOMATIC_DISCOVERY_RANGE": bad})
    with pytest.raises(TransportError, match="ROS_STATIC_PEERS"):
        options_from_env({"ROS_STATIC_PEERS": "a\"/><Peer address=\"b"})


def test_cyclone_fragment_matches_rmw_cyclonedds():
    subnet = cyclone_fragment(DiscoveryOptions("SUBNET", ("10.0.0.2",)))
    assert "AllowMulticast" not in subnet
    assert "<ParticipantIndex>auto</ParticipantIndex><MaxAutoParticipantIndex>32</MaxAutoParticipantIndex>" in subnet
    assert '<Peers><Peer address="10.0.0.2"/></Peers>' in subnet
    local = cyclone_fragment(DiscoveryOptions("LOCALHOST", ("10.0.0.2",)))
    assert "<AllowMulticast>false</AllowMulticast>" in local
    assert '<Peers><Peer address="localhost"/><Peer address="10.0.0.2"/></Peers>' in local
    off = cyclone_fragment(DiscoveryOptions("OFF", ("10.0.0.2",)))
    assert "<AllowMulticast>false</AllowMulticast>" in off and "Peer" not in off
    assert f"<ParticipantIndex>none</ParticipantIndex><Tag>ros_discovery_off_{os.getpid()}</Tag>" in off
    assert cyclone_fragment(DiscoveryOptions("SYSTEM_DEFAULT", ("10.0.0.2",))) == ""


def test_domain_config_puts_the_users_file_after_the_scope(monkeypatch):
    from ambiegen_ros.ros.transport.dds_backend import domain_config

    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    monkeypatch.setenv("CYCLONEDDS_URI", "file:///etc/my_cyclone.xml")
    parts = domain_config().split(",")
    assert "<AllowMulticast>false</AllowMulticast>" in parts[0]
    assert parts[1] == "file:///etc/my_cyclone.xml"  # the user's settings override ours, as with rmw
    monkeypatch.setenv("ROS_STATIC_PEERS", "no-such-host.invalid")
    with pytest.raises(TransportError, match="cannot resolve peer 'no-such-host.invalid'"):
        domain_config()  # Cyclone itself would abort the process


@pytest.mark.parametrize("env", [{"ROS_AUTOMATIC_DISCOVERY_RANGE": "subnet"},
                                 {"ROS_STATIC_PEERS": "no-such-host.invalid"}])
def test_a_node_with_a_bad_scope_exits_with_one_clear_line(env, ros_domain):
    proc = subprocess.run(
        [sys.executable, "-m", "sim_nodes.thermostat_sim", "--ros-args", "-p", "model:=surrogate"],
        cwd=REPO, env=netns.node_env(ros_domain, AMBIEGEN_TRANSPORT="dds", **env), capture_output=True, text=True,
        timeout=120,
    )
    assert proc.returncode == 2, proc.stderr[-2000:]
    assert list(env)[0] in proc.stderr and "Traceback" not in proc.stderr


def test_campaign_defaults_to_localhost_and_rejects_remote_workers_without_a_wider_scope(tmp_path, ros_domain):
    from ambiegen_ros.campaign import Campaign, CampaignSpec, discovery_scope

    assert discovery_scope(None, {}) == "LOCALHOST"
    assert discovery_scope("subnet", {"ROS_LOCALHOST_ONLY": "1"}) == "SUBNET"
    assert discovery_scope(None, {"ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET"}) == "SUBNET"  # the user's choice
    campaign = Campaign(CampaignSpec(problem="thermostat", out=tmp_path / "c"))
    assert campaign.env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"
    proc = subprocess.run(
        [sys.executable, "-m", "ambiegen_ros", "campaign", "--problem", "thermostat", "--workers", "0",
         "--remote-workers", "2", "--out", str(tmp_path / "r")],
        cwd=REPO, env=netns.node_env(ros_domain), capture_output=True, text=True, timeout=120,
    )
    assert proc.returncode == 2 and "--discovery-range subnet" in proc.stderr, proc.stderr
    assert not (tmp_path / "r").exists()


# --- on the wire, between namespaces ----------------------------------------------------------------
@pytest.fixture
def network():
    reason = netns.unavailable_reason()
    if reason:
        pytest.skip(f"no test network: {reason}")
    net = netns.TestNetwork(("a", "b")).create()
    yield net
    net.destroy()


def _probes(net, backend: str, specs: list[tuple]) -> dict[str, tuple[set, str]]:
    """Run probes (name, host, domain, env, expected names[, backend]) at once, until each has heard
    the names it expects and every probe has listened LISTEN_S; name -> (names it heard, backend)."""
    import threading

    procs, lines, expects, readers = {}, {}, {}, {}
    for name, host, domain, env, expect, *own_backend in specs:
        args, penv = netns.node_process(["-c", PROBE, name, ",".join(sorted(expect))], domain,
                                        *own_backend or [backend], **env)
        procs[name] = net.popen(host, args, cwd=REPO, env=penv, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                stderr=subprocess.STDOUT, text=True)
        lines[name], expects[name] = [], set(expect)
        readers[name] = threading.Thread(target=lambda p=procs[name], out=lines[name]: out.extend(p.stdout), daemon=True)
        readers[name].start()

    def wait(what: str, ready) -> None:
        deadline = time.monotonic() + PATIENCE
        while not ready():
            dead = [n for n, p in procs.items() if p.poll() is not None]
            assert not dead, f"probe {dead[0]} ended early:\n{''.join(lines[dead[0]])[-3000:]}"
            assert time.monotonic() < deadline, f"no {what} after {PATIENCE:g} s: " + str(
                {n: "".join(out)[-500:] for n, out in lines.items()})
            time.sleep(0.05)

    try:
        wait("UP from every probe", lambda: all("UP\n" in out for out in lines.values()))
        listen_until = time.monotonic() + LISTEN_S
        wait("GOT from every probe that expects names",
             lambda: all("GOT\n" in lines[n] for n, e in expects.items() if e) and time.monotonic() >= listen_until)
    finally:
        for proc in procs.values():
            proc.stdin.close()
    heard = {}
    for name, proc in procs.items():
        proc.wait(timeout=PATIENCE)
        readers[name].join(PATIENCE)  # the rest of its output, to the end
        out = "".join(lines[name])
        line = next((ln for ln in out.splitlines() if ln.startswith("HEARD")), None)
        assert line is not None and proc.returncode == 0, f"probe {name} failed:\n{out[-3000:]}"
        _, names, _, ran_on = line.split(" ")
        heard[name] = (set(filter(None, names.split(","))), ran_on)
    return heard


@pytest.mark.parametrize("backend", BACKENDS)
def test_localhost_and_off_keep_nodes_home(network, backend):
    local = {"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    off = {"ROS_AUTOMATIC_DISCOVERY_RANGE": "OFF"}
    heard = _probes(network, backend, [
        ("a_local1", "a", 74, local, {"a_local2"}), ("a_local2", "a", 74, local, {"a_local1"}),
        ("b_subnet", "b", 74, {}, set()),
        ("a_off1", "a", 75, off, set()), ("a_off2", "a", 75, off, set()),
        ("a_default", "a", 76, {"ROS_AUTOMATIC_DISCOVERY_RANGE": "SYSTEM_DEFAULT"}, {"b_default"}),
        ("b_default", "b", 76, {}, {"a_default"}),
        ("a_other_domain", "a", 77, local, set()),
    ])
    assert all(ran_on == backend for _, ran_on in heard.values())
    assert heard["a_local1"][0] == {"a_local2"} and heard["a_local2"][0] == {"a_local1"}
    assert heard["b_subnet"][0] == set()  # LOCALHOST on host A is not discovered from host B
    assert heard["a_off1"][0] == set() and heard["a_off2"][0] == set()
    assert heard["a_default"][0] == {"b_default"} and heard["b_default"][0] == {"a_default"}
    assert heard["a_other_domain"][0] == set()  # ROS_DOMAIN_ID separates


@pytest.mark.parametrize("backend", BACKENDS)
def test_static_peers_connect_hosts_without_multicast(network, backend):
    network.set_multicast(False)
    a, b = network.address("a"), network.address("b")
    heard = _probes(network, backend, [
        ("a_alone", "a", 77, {}, set()), ("b_alone", "b", 77, {}, set()),
        ("a_peer", "a", 78, {"ROS_STATIC_PEERS": b}, {"b_peer"}), ("b_peer", "b", 78, {"ROS_STATIC_PEERS": a}, {"a_peer"}),
    ])
    assert heard["a_alone"][0] == set() and heard["b_alone"][0] == set()  # no multicast: no discovery
    assert heard["a_peer"][0] == {"b_peer"} and heard["b_peer"][0] == {"a_peer"}


@pytest.mark.skipif(bool(netns.rclpy_unavailable_reason()), reason=str(netns.rclpy_unavailable_reason()))
def test_rclpy_and_dds_nodes_meet_only_as_the_scope_allows(network):
    """A mixed graph, as users run it: rclpy (Jazzy's rmw_cyclonedds_cpp) and DDS-backend nodes
    with multicast off. Static peers connect them across hosts; LOCALHOST nodes of both kinds
    meet on their host; without peers nobody crosses."""
    network.set_multicast(False)
    a, b = network.address("a"), network.address("b")
    local = {"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    heard = _probes(network, "dds", [
        ("a_rclpy_peer", "a", 96, {"ROS_STATIC_PEERS": b}, {"b_dds_peer"}, "rclpy"),
        ("b_dds_peer", "b", 96, {"ROS_STATIC_PEERS": a}, {"a_rclpy_peer"}),
        ("a_rclpy_local", "a", 97, local, {"a_dds_local"}, "rclpy"), ("a_dds_local", "a", 97, local, {"a_rclpy_local"}),
        ("a_rclpy_alone", "a", 98, {}, set(), "rclpy"), ("b_dds_alone", "b", 98, {}, set()),
    ])
    assert {name: ran_on for name, (_, ran_on) in heard.items()} == {
        "a_rclpy_peer": "rclpy", "b_dds_peer": "dds", "a_rclpy_local": "rclpy", "a_dds_local": "dds",
        "a_rclpy_alone": "rclpy", "b_dds_alone": "dds"}
    assert heard["a_rclpy_peer"][0] == {"b_dds_peer"} and heard["b_dds_peer"][0] == {"a_rclpy_peer"}
    assert heard["a_rclpy_local"][0] == {"a_dds_local"} and heard["a_dds_local"][0] == {"a_rclpy_local"}
    assert heard["a_rclpy_alone"][0] == set() and heard["b_dds_alone"][0] == set()
