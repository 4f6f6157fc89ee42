"""What ``sut_adapter`` says to Nav2 besides topics: its lifecycle, costmaps and action.

Written after ``nav2_simple_commander``'s ``BasicNavigator``, without blocking: every call is
asynchronous and the adapter polls from its timers, so a slow Nav2 never stalls the executor.
The clients come from the node's transport (``Node.create_client`` / ``create_action_client``):
rclpy's own on the rclpy backend, ``transport/dds_services.py`` (rmw_cyclonedds_cpp's wire format)
on the DDS backend, so the adapter can face a Nav2 on rmw_cyclonedds_cpp without rclpy's executor.
Their messages are the backend's, ``send``'s pose included (``node.new_message``).

* ``missing()``: what Nav2 has not shown yet: the ``navigate_to_pose`` action server, and each of
  ``lifecycle_nodes`` in state ``active`` (asked over ``<node>/get_state``, as
  ``waitUntilNav2Active`` does);
* ``clear_costmaps()``: both costmaps cleared entirely (``clear_entirely_*_costmap``), so marks of
  the last scenario's walls never show up in the next map;
* ``send(pose)``: the goal; its result (status succeeded | aborted | canceled, with Nav2's error
  code and message when the action has them) lands in ``result``, and the most recoveries its
  feedback reported (``number_of_recoveries``: every recovery action the behaviour tree ran, costmap
  clearings included) in ``recoveries``: a goal that succeeded after one is a near miss;
* ``cancel()``: the running goal, once our oracle has decided before Nav2 did.

A failed bringup is tried again (``manager``): Nav2's lifecycle manager gives up a bringup at the
first node that fails to activate and never tries again. One cause is ours: a costmap that
activates before our world's first ``/clock`` waits for TF until sim time 0 + 60 s, and the clock
then jumps to the world's stamps, so it fails at once. When lifecycle nodes stay inactive for
``restart_after`` s, the client asks the manager ``is_active``; the manager answers only when no
bringup of its own is running (its services share the bringup's callback group), so an answer
``false`` means it gave up: the client asks it to ``CLEANUP`` (inactive nodes back to unconfigured)
and ``STARTUP`` again, at most ``restarts`` times. A CLEANUP that fails is a restart spent, with no
STARTUP after it (its nodes are not back in the state a bringup starts from). Each request to
the manager has ``answer_within`` s to be answered, checked as ``missing()`` is polled: one
unanswered by then (a manager that died or hung with the request out) is dropped, its answer
ignored should it come, and a later attempt may follow; so is one out when ``forget_active`` runs.
"""
from __future__ import annotations

import time
from typing import Any

STATUS_NAMES = {4: "succeeded", 5: "canceled", 6: "aborted"}  # action_msgs/GoalStatus
ACTION_TYPE = "nav2_msgs/action/NavigateToPose"
GET_STATE = "lifecycle_msgs/srv/GetState"
CLEAR_COSTMAP = "nav2_msgs/srv/ClearEntireCostmap"
IS_ACTIVE = "std_srvs/srv/Trigger"
MANAGE_NODES = "nav2_msgs/srv/ManageLifecycleNodes"
TRANSITION_EVENT = "lifecycle_msgs/msg/TransitionEvent"
STARTUP, CLEANUP = 0, 6  # ManageLifecycleNodes' commands


class Nav2Client:
    def __init__(self, node: Any, action_name: str, lifecycle_nodes: list[str], costmap_services: list[str],
                 logger: Any, manager: str = "", restarts: int = 0, restart_after: float = 20.0,
                 answer_within: float = 60.0):
        """``node``: the adapter's transport node (either backend); ``manager``: the lifecycle
        manager's node name ('' = never restart a failed bringup); ``answer_within``: seconds the
        manager has to answer each request (a bringup it runs meanwhile delays its answers)."""
        self.node, self.logger = node, logger
        self.action = node.create_action_client(ACTION_TYPE, action_name)
        self.action_name = action_name
        self.lifecycle_nodes = [n.strip().strip("/") for n in lifecycle_nodes if n.strip()]
        self.costmap_services = [s.strip() for s in costmap_services if s.strip()]
        self.active: set[str] = set()
        self._asking: set[str] = set()
        self._clients: dict[str, Any] = {}  # service name: its client, made once
        self.handle: Any = None
        self.result: dict[str, Any] | None = None
        self.recoveries = 0  # the current goal's, from its feedback
        self.goals = 0
        self.manager = manager.strip().strip("/")
        self.allowed_restarts, self.restart_after = int(restarts) if self.manager else 0, float(restart_after)
        self.restarts = 0  # bringups asked for so far
        self.answer_within = float(answer_within)
        self._inactive_since: float | None = None
        self._request: tuple[str, float, int] | None = None  # to the manager, unanswered: what, deadline, number
        self._requests = 0

    # --- readiness ------------------------------------------------------------------------------
    def missing(self) -> list[str]:
        """What Nav2 has not shown yet (empty: ready). Asks each inactive lifecycle node again."""
        out = []
        if not self.action.server_is_ready():
            out.append(f"Nav2's {self.action_name} action server is not up")
        for name in self.lifecycle_nodes:
            if name in self.active:
                continue
            out.append(f"Nav2 node {name} is not active")
            client = self._client(GET_STATE, f"/{name}/get_state")
            if name in self._asking or not client.service_is_ready():
                continue
            self._asking.add(name)
            future = client.call_async(client.new_request())

            def done(f, name=name):
                self._asking.discard(name)
                response = f.result()
                if response is not None and response.current_state.label == "active":
                    self.active.add(name)

            future.add_done_callback(done)
        self._restart_if_given_up(any(name not in self.active for name in self.lifecycle_nodes))
        return out

    def _client(self, srv_type: str, service: str) -> Any:
        client = self._clients.get(service)
        if client is None:
            client = self._clients[service] = self.node.create_client(srv_type, service)
        return client

    # --- a failed bringup, again ----------------------------------------------------------------
    @property
    def restarts_left(self) -> int:
        return max(0, self.allowed_restarts - self.restarts)

    @property
    def _restarting(self) -> bool:
        """A request to the manager is out (and not past its deadline)."""
        return self._request is not None

    def _restart_if_given_up(self, inactive: bool) -> None:
        """Lifecycle nodes inactive for ``restart_after`` s: ask the manager whether it gave up."""
        now = time.monotonic()
        self._expire(now)
        if not inactive or self.restarts_left <= 0:
            self._inactive_since = None
            return
        if self._inactive_since is None:
            self._inactive_since = now
        if self._restarting or now - self._inactive_since < self.restart_after:
            return
        asked = self._client(IS_ACTIVE, f"/{self.manager}/is_active")
        if not asked.service_is_ready():
            return
        self._call(asked, asked.new_request(), "is_active", self._on_is_active)

    def _call(self, client: Any, request: Any, what: str, then: Any) -> None:
        """Send ``request``; ``then(response)`` when it is answered before its deadline and while it is
        still the request out (not dropped by ``_expire`` or ``forget_active``)."""
        self._requests += 1
        number = self._requests
        self._request = (what, time.monotonic() + self.answer_within, number)

        def done(future):
            if self._request is None or self._request[2] != number:
                return  # too late: the state moved on without it
            self._request = None
            then(future.result())

        client.call_async(request).add_done_callback(done)

    def _expire(self, now: float) -> None:
        """Drop a request the manager left unanswered past its deadline: a later attempt may follow."""
        if self._request is None or now <= self._request[1]:
            return
        what = self._request[0]
        self._request, self._inactive_since = None, now
        self.logger.warning(f"{self.manager} did not answer {what} within {self.answer_within:g} s (gone, or hung?): "
                            f"dropped; asked again after {self.restart_after:g} s if nodes stay inactive "
                            f"({self.restarts_left} restart(s) left)")

    def _on_is_active(self, response: Any) -> None:
        if response is None or response.success:  # busy or active: the nodes' own states will tell
            self._inactive_since = time.monotonic()
            return
        self.restarts += 1
        inactive = [n for n in self.lifecycle_nodes if n not in self.active]
        self.logger.warning(f"Nav2's bringup gave up ({', '.join(inactive)} not active after "
                            f"{self.restart_after:g} s; {self.manager} is not active): asking it to clean up and start "
                            f"again (restart {self.restarts}, {self.restarts_left} left)")
        self._manage(CLEANUP, self._on_cleanup)

    def _manage(self, command: int, then: Any) -> None:
        client = self._client(MANAGE_NODES, f"/{self.manager}/manage_nodes")
        what = {CLEANUP: "CLEANUP", STARTUP: "STARTUP"}.get(command, f"command {command}")
        self._call(client, client.new_request(command=command), what,
                   lambda response: then(bool(response is not None and response.success)))

    def _on_cleanup(self, ok: bool) -> None:
        if ok:
            self._manage(STARTUP, self._on_startup)
            return
        self._inactive_since = time.monotonic()
        self.logger.warning(f"{self.manager}: CLEANUP failed (a node not inactive?): no STARTUP after it; restart "
                            f"{self.restarts} spent, {self.restarts_left} left")

    def _on_startup(self, ok: bool) -> None:
        self.logger.warning(f"{self.manager}: the new bringup {'succeeded' if ok else 'failed too'}")
        self.forget_active()  # every node is asked again

    def watch_transitions(self, qos: Any, on_leave: Any) -> None:
        """Each lifecycle node's ``transition_event``: a node leaving ``active`` (its manager took the
        stack down after a lost bond, or someone deactivated it) is asked again before the next goal,
        and ``on_leave(name, "active -> <state>")`` is told."""
        for name in self.lifecycle_nodes:
            self.node.create_subscription(TRANSITION_EVENT, f"/{name}/transition_event",
                                          lambda msg, name=name: self._on_transition(name, msg, on_leave), qos)

    def _on_transition(self, name: str, msg: Any, on_leave: Any) -> None:
        start, goal = str(msg.start_state.label), str(msg.goal_state.label)
        if start == "active":
            self.active.discard(name)
            on_leave(name, f"{start} -> {goal}")

    def forget_active(self) -> None:
        """A process of the stack died: its successor starts inactive, so ask every node again before the
        next goal (a goal sent to a restarting Nav2 is rejected, which is no failure of the scenario).
        A question the dead node never answered is forgotten too, or its node would never be asked again;
        so is a request to the lifecycle manager (it may be the one that died), and its answer if it comes."""
        self.active.clear()
        self._asking.clear()
        self._request, self._inactive_since = None, None

    def clear_costmaps(self) -> None:
        for service in self.costmap_services:
            client = self._client(CLEAR_COSTMAP, service)
            if client.service_is_ready():
                client.call_async(client.new_request())
            else:
                self.logger.warning(f"{service} is not available: the costmap keeps the last scenario's marks")

    # --- the goal -------------------------------------------------------------------------------
    def send(self, pose: Any) -> None:
        """Send a ``geometry_msgs/PoseStamped`` goal (the node's ``new_message``); the outcome goes to ``result``."""
        request = self.action.new_goal(pose=pose)
        self.handle, self.result, self.recoveries = None, None, 0
        self.goals += 1
        goal_number = self.goals

        def on_feedback(message):
            if goal_number == self.goals:
                self.recoveries = max(self.recoveries, int(message.feedback.number_of_recoveries))

        def on_response(future):
            handle = future.result()
            if goal_number != self.goals:  # an old scenario's goal: not ours to record
                return
            if handle is None or not handle.accepted:
                self.result = {"status": "rejected", "error_code": 0, "error_msg": "goal rejected"}
                return
            self.handle = handle
            handle.get_result_async().add_done_callback(on_result)

        def on_result(future):
            wrapped = future.result()
            result = getattr(wrapped, "result", None)
            outcome = {"status": STATUS_NAMES.get(int(wrapped.status), f"status {int(wrapped.status)}"),
                       "error_code": int(getattr(result, "error_code", 0) or 0),
                       "error_msg": str(getattr(result, "error_msg", "") or "")}
            late = goal_number != self.goals  # its scenario was decided already: logged, not recorded
            self.logger.info(f"navigate_to_pose finished: {outcome['status']} (error {outcome['error_code']}"
                             f"{': ' + outcome['error_msg'] if outcome['error_msg'] else ''})"
                             + (" after its scenario was decided" if late else ""))
            if not late:
                self.result = outcome

        self.action.send_goal_async(request, feedback_callback=on_feedback).add_done_callback(on_response)

    def cancel(self) -> None:
        if self.handle is not None and self.result is None:
            self.handle.cancel_goal_async()
        self.goals += 1  # whatever comes back for it now belongs to no scenario
        self.handle = None
