"""The robot's reference among people (issue 48): a patient robot that knows every person's motion.

A failure counts only when a reference passes the same scenario. With walking people the static
check (a clearance route exists) is not enough: a person may stand on the only corridor for ever.
So the reference *drives*: the pioneer2dx footprint (or a robot profile's, issue 69) along the clearance route of the true world
(walls and the unmapped obstacles, which it keeps 0.36 m from), turning on the spot at each corner
and at the goal to the goal's yaw, no faster than the robot under test (``cruise_speed``,
``nd_turn_rate_deg``). Before each step it looks ``HORIZON`` seconds ahead along its own plan
against every person's known path: if any would come within ``MARGIN`` of its body, it waits
(a space-time check, the "patient robot" of the issue). It never moves towards a contact, so by
the fault rule (``sims.obstacles.robot_at_fault``) a person who walks into it while it waits is
not its fault: recorded, not counted.

It passes when it reaches the goal within the scenario's time limit; else the scenario is an
invalid test ("people block the route": a person standing on it for ever, say).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..robot_world import PIONEER2DX, _polygon_signed_distance

HORIZON = 2.0  # [s] how far ahead the reference checks its plan against the people
MARGIN = 0.05  # [m] it waits rather than pass a person closer than this


@dataclass
class PatientRun:
    """What the patient reference did: passed, when, how long it waited, contacts it suffered."""

    passed: bool
    time: float
    waited: float
    contacts_not_at_fault: int
    reason: str = ""
    poses: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))  # (N, 3) x, y, yaw every dt


def plan_poses(route: np.ndarray, start_yaw: float, goal_yaw: float | None, speed: float, turn_rate: float,
               dt: float) -> np.ndarray:
    """Poses (N, 3) every ``dt`` of the route driven at ``speed``, turning on the spot at
    ``turn_rate`` to each leg's direction and at the end to ``goal_yaw`` (None: no final turn)."""
    out = [(float(route[0, 0]), float(route[0, 1]), float(start_yaw))]

    def turn_to(yaw: float) -> None:
        x, y, now = out[-1]
        delta = (yaw - now + math.pi) % (2 * math.pi) - math.pi
        steps = int(math.ceil(abs(delta) / (turn_rate * dt) - 1e-9))
        for k in range(1, steps + 1):
            out.append((x, y, now + delta * k / steps))

    for a, b in zip(route[:-1], route[1:]):
        seg = b - a
        length = math.hypot(*seg)
        if length <= 0:
            continue
        turn_to(math.atan2(seg[1], seg[0]))
        yaw = out[-1][2]
        steps = int(math.ceil(length / (speed * dt) - 1e-9))
        for k in range(1, steps + 1):
            p = a + seg * (k / steps)
            out.append((float(p[0]), float(p[1]), yaw))
    if goal_yaw is not None:
        turn_to(goal_yaw)
    return np.asarray(out)


def _people_clearance(poses: np.ndarray, centres: np.ndarray, radii: np.ndarray,
                      footprint: np.ndarray) -> np.ndarray:
    """Signed distance between the body at each pose (N, 3) and each person (N, M, 2 centres at the
    pose's time; radii (M,)): (N, M), <= 0 is contact."""
    dx = centres[:, :, 0] - poses[:, 0:1]
    dy = centres[:, :, 1] - poses[:, 1:2]
    c, s = np.cos(poses[:, 2:3]), np.sin(poses[:, 2:3])
    qx, qy = dx * c + dy * s, dy * c - dx * s  # into the body frame
    d = _polygon_signed_distance(qx.ravel(), qy.ravel(), footprint).reshape(qx.shape)
    return d - radii[None, :]


def patient_run(route: np.ndarray, people: tuple, start_yaw: float, goal_yaw: float | None, config: Any,
                time_limit: float, footprint: np.ndarray = PIONEER2DX, plan: np.ndarray | None = None) -> PatientRun:
    """Drive the plan, waiting whenever the next ``HORIZON`` seconds of it would meet a person.
    ``plan``: poses every ``dt`` to drive instead of the route's (a car's rounded path, issue 69)."""
    dt = float(config.dt)
    if plan is None:
        plan = plan_poses(np.asarray(route, dtype=float), start_yaw, goal_yaw, float(config.cruise_speed),
                          math.radians(float(config.nd_turn_rate_deg)), dt)
    ahead = max(1, int(round(HORIZON / dt)))
    radii = np.array([p.radius for p in people], dtype=float)
    far = float(config.cruise_speed) * HORIZON + 1.0 + (float(radii.max()) if len(radii) else 0.0)
    i, k, waited, contacts = 0, 0, 0.0, 0
    touching = np.zeros(len(people), dtype=bool)
    n_max = int(math.ceil(time_limit / dt - 1e-9))
    while i < len(plan) - 1:
        if k >= n_max:
            return PatientRun(False, k * dt, waited, contacts,
                              f"the patient reference robot, knowing every person's path, did not reach the goal "
                              f"within {time_limit:.0f} s (it waited {waited:.0f} s: people block the route)",
                              plan[: i + 1])
        t = k * dt
        move = True
        if len(people):
            now = np.array([p.position(t) for p in people])
            near = np.hypot(now[:, 0] - plan[i, 0], now[:, 1] - plan[i, 1]) < far
            if near.any():
                idx = np.flatnonzero(near)
                steps = np.arange(1, ahead + 1)
                future = plan[np.minimum(i + steps, len(plan) - 1)]
                times = t + steps * dt
                centres = np.stack([people[j].position(times) for j in idx], axis=1)  # (ahead, m, 2)
                move = bool((_people_clearance(future, centres, radii[idx], footprint) > MARGIN).all())
        if move:
            i += 1
        else:
            waited += dt
        k += 1
        if len(people):  # who touches the body now (at the new time): never its fault, it moved only when clear
            at = np.array([p.position(k * dt) for p in people])[None]
            touch = _people_clearance(plan[i:i + 1], at, radii, footprint)[0] <= 0.0
            contacts += int((touch & ~touching).sum())
            touching = touch
    return PatientRun(True, k * dt, waited, contacts, "", plan)


__all__ = ["HORIZON", "MARGIN", "PatientRun", "patient_run", "plan_poses"]
