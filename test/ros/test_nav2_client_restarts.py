"""``Nav2Client``'s restarts of a bringup that gave up, when the lifecycle manager does not play along.

On the DDS model of Jazzy's lifecycle manager (``test_dds_services.FakeLifecycleManager``, no ROS
installed): a manager that never answers ``is_active`` (it died or hung with the request out), a
CLEANUP that fails, and a stack process that dies while a request is out (``forget_active``).
The client's deadlines are checked as the adapter's tick polls ``missing()``, as ``run_until``
does here; nothing sleeps.
"""
from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_dds_services import (FakeLifecycleManager, FakeNav2, _quiet_log, pair,  # noqa: E402,F401 (a fixture)
                               run_until)

from ambiegen_ros.ros.transport import dds_backend  # noqa: E402

pytestmark = pytest.mark.skipif(not dds_backend.is_available(), reason="cyclonedds is not installed")
MANAGER = "lifecycle_manager_navigation"


class SilentManager(FakeLifecycleManager):
    """Leaves its first ``silent`` is_active requests unanswered (a manager that died or hung with the
    request out); ``answer_late(success)`` answers the oldest of them after all."""

    def __init__(self, node, nav2, silent: int):
        super().__init__(node, nav2)
        self.silent, self.unanswered = silent, []

    def on_is_active(self, request, token):
        if self.silent:
            self.silent -= 1
            self.asked += 1
            self.unanswered.append(token)
            return None
        return super().on_is_active(request, token)

    def answer_late(self, success: bool) -> None:
        self.services[0].respond(self.unanswered.pop(0), self.reg.new("std_srvs/srv/Trigger_Response",
                                                                      success=success, message=""))


def client_for(client_node, nodes: list[str], lines: list, **kw):
    from sim_nodes.nav2_client import Nav2Client

    return Nav2Client(client_node, "navigate_to_pose", nodes, [], _quiet_log(lines), manager=MANAGER, **kw)


def test_an_is_active_the_manager_never_answers_expires_and_is_asked_again(pair):
    client, server = pair
    lines: list = []
    fake = FakeNav2(server, {"controller_server": "inactive"})
    manager = SilentManager(server, fake, silent=1)
    nav2 = client_for(client, ["controller_server"], lines, restarts=2, restart_after=0.05, answer_within=0.5)
    assert run_until(client, [fake, manager], lambda: (nav2.missing(), manager.asked)[1] == 1 and nav2._restarting)
    assert run_until(client, [fake, manager], lambda: nav2.missing() == [], timeout=30), (manager.asked, lines)
    assert manager.asked == 2 and manager.commands == [6, 0] and nav2.restarts == 1
    assert sum("did not answer is_active" in m for m in lines) == 1, lines
    # the first request's answer, after its deadline: "not active" would start a restart, but it is
    # no longer the request out, so it is ignored
    manager.answer_late(False)
    assert not run_until(client, [fake, manager], lambda: (nav2.missing(), len(manager.commands))[1] > 2
                         or nav2.restarts > 1, timeout=1.0)
    assert manager.services[0].outbox == [], "the late answer went out"


def test_a_cleanup_that_fails_is_a_restart_spent_with_no_startup_after_it(pair):
    """CLEANUP fails on a node that is not inactive (here: unconfigured); a STARTUP after it would
    run a bringup on nodes in states the manager did not expect."""
    client, server = pair
    lines: list = []
    fake = FakeNav2(server, {"controller_server": "inactive", "planner_server": "unconfigured"})
    manager = FakeLifecycleManager(server, fake)
    nav2 = client_for(client, ["controller_server", "planner_server"], lines, restarts=2, restart_after=0.05)
    assert run_until(client, [fake, manager], lambda: (nav2.missing(), nav2.restarts_left)[1] == 0
                     and not nav2._restarting, timeout=30), (manager.commands, lines)
    assert manager.commands == [6, 6] and nav2.restarts == 2, "each restart ends at its failed CLEANUP"
    assert sum("CLEANUP failed" in m and "no STARTUP" in m for m in lines) == 2, lines
    assert fake.states == {"controller_server": "inactive", "planner_server": "unconfigured"}


def test_forget_active_drops_a_pending_restart_so_the_next_one_does_not_wait_for_a_dead_manager(pair):
    """A death of the stack (the manager's own, say) with is_active out: ``forget_active`` clears it,
    and the next attempt goes out long before the request's deadline would have."""
    client, server = pair
    lines: list = []
    fake = FakeNav2(server, {"controller_server": "inactive"})
    manager = SilentManager(server, fake, silent=1)
    nav2 = client_for(client, ["controller_server"], lines, restarts=2, restart_after=0.05, answer_within=3600.0)
    assert run_until(client, [fake, manager], lambda: (nav2.missing(), manager.asked)[1] == 1 and nav2._restarting)
    nav2.forget_active()
    assert not nav2._restarting and nav2.restarts == 0
    assert run_until(client, [fake, manager], lambda: nav2.missing() == [], timeout=30), (manager.asked, lines)
    assert manager.asked == 2 and manager.commands == [6, 0] and nav2.restarts == 1
    assert not any("did not answer" in m for m in lines), "no deadline passed: forget_active cleared it"
