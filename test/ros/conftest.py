"""Fixtures of the process tests: ``graph`` (node subprocesses + a driver node on the test's own domain),
``dds_env`` (in-process DDS nodes, for the transport tests in and between processes) and ``nodes_factory``,
``test_node`` (node subprocesses of a test, and a node in this process: the node tests)."""
import os
import sys
from pathlib import Path

import pytest

TEST = Path(__file__).resolve().parents[1]
if str(TEST) not in sys.path:
    sys.path.insert(0, str(TEST))

from helpers.node_runs import nodes_factory, test_node  # noqa: E402,F401  (fixtures, found here by pytest)
from helpers.sut_graph import graph  # noqa: E402,F401  (a fixture, found here by pytest)

from ambiegen_ros.ros import transport  # noqa: E402


@pytest.fixture
def dds_env(monkeypatch):
    """In-process DDS nodes in their own domain, always shut down afterwards."""
    made = []

    def make(domain: int, name: str = "t", **kw):
        monkeypatch.setenv("ROS_DOMAIN_ID", str(domain))
        node = transport.create_node(name, backend="dds", **kw)
        made.append(node)
        return node

    yield make
    for n in made:
        n.shutdown()


@pytest.fixture
def session_env(monkeypatch):
    """A trials session's driver in this process sets ROS_DOMAIN_ID and ROS_AUTOMATIC_DISCOVERY_RANGE
    in ``os.environ``: both as they were after the test."""
    for key in ("ROS_DOMAIN_ID", "ROS_AUTOMATIC_DISCOVERY_RANGE"):
        was = os.environ.get(key)
        monkeypatch.setenv(key, was or "0")
        if was is None:
            monkeypatch.delenv(key)
    return monkeypatch
