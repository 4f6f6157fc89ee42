"""pytest wiring of the real-ROS suite (the helpers and why they work so: jazzy_env.py).

Every test here is skipped, naming the reason, unless a ROS 2 Jazzy install is found:
``$AMBIEGEN_ROS_SETUP`` if set (it replaces the default; a path that does not exist switches the
suite off), else ``/opt/ros/jazzy/setup.bash``, and ``import rclpy`` must work under it.
"""
from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import pytest

HERE = Path(__file__).resolve().parent
if str(HERE) not in sys.path:
    sys.path.insert(0, str(HERE))

from jazzy_env import Graph, probe, working_tree_install  # noqa: E402


def pytest_collection_modifyitems(config, items):
    here = Path(__file__).parent
    mine = [item for item in items if here in Path(str(item.fspath)).parents]
    if not mine:
        return
    info = probe()
    if "skip" in info:
        for item in mine:
            item.add_marker(pytest.mark.skip(reason=info["skip"]))


@pytest.fixture(scope="session")
def jazzy() -> dict[str, Any]:
    info = probe()
    if "skip" in info:
        pytest.skip(info["skip"])
    return info


@pytest.fixture
def graph(tmp_path):
    made: list[Graph] = []

    def make(label: str = "logs") -> Graph:
        g = Graph(tmp_path / label)
        made.append(g)
        return g

    yield make
    for g in made:
        g.cleanup()


@pytest.fixture(scope="session")
def workspace(jazzy, tmp_path_factory) -> Path:
    """The working tree (uncommitted changes included) built with colcon; returns its install dir."""
    return working_tree_install(tmp_path_factory.mktemp("ws"))
