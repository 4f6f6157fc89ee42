"""The robot world hosted for an outside controller (``sims.hosted_world``): clock, held commands,
scans, lockstep and contact, and that it is the full model's loop when a controller answers every
scan as ``sims.robot.drive`` does."""
from __future__ import annotations

import math
from pathlib import Path
import sys

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

from ambiegen_ros.sims import robot  # noqa: E402
from ambiegen_ros.sims.hosted_world import HostedWorld  # noqa: E402
from ambiegen_ros.sims.robot import RobotSimConfig, RouteFollower  # noqa: E402
from test_full_models import box  # noqa: E402


def open_world(**kw) -> HostedWorld:
    h = HostedWorld(RobotSimConfig(dt=kw.pop("dt", 0.1)), **kw)
    h.load_map(box(), 1.0)
    h.teleport(10.0, 10.0, 0.0)
    return h


def test_the_clock_only_goes_forward_and_every_reset_takes_a_step():
    h = HostedWorld(RobotSimConfig())
    assert not h.ready and h.pose == (0.0, 0.0, 0.0)
    h.step()
    assert h.k == 1  # no map: only the clock runs
    h.load_map(box(), 1.0)
    assert h.k == 2 and h.ready
    h.teleport(5.0, 6.0, 1.0)
    assert h.k == 3 and h.pose == pytest.approx((5.0, 6.0, 1.0))
    h.load_map(box(), 1.0)  # a new map keeps the last teleport's pose
    assert h.k == 4 and h.pose == pytest.approx((5.0, 6.0, 1.0)) and h.runs == 3


def test_a_command_is_held_until_its_timeout_then_the_robot_stops():
    h = open_world(cmd_timeout=0.5)
    h.command(0.3, 0.0)
    for _ in range(5):
        h.step()
    assert h.twist[0] > 0.2  # accelerating at 0.5 m/s^2 towards 0.3 m/s
    for _ in range(12):  # > 0.5 s without a new command: braking to a stop
        h.step()
    assert h.twist[0] == pytest.approx(0.0)
    x_stopped = h.pose[0]
    h.step()
    assert h.pose[0] == pytest.approx(x_stopped)
    held = open_world(cmd_timeout=0.0)  # 0: held forever
    held.command(0.3, 0.0)
    for _ in range(40):
        held.step()
    assert held.twist[0] == pytest.approx(0.3)


def test_scans_read_inf_without_a_return_and_come_on_schedule():
    h = open_world(scan_every=3)
    assert h.scan_due  # right after the teleport
    ranges = h.scan()
    assert not h.scan_due
    # the box is 30 x 30 m, the laser reaches 10 m: from (10, 10) facing +x nothing is in range
    # straight ahead; the wall 9 m behind the left side is (beam +90 deg: y = 30 is 20 m away; -90: 10 m)
    assert np.isinf(ranges[len(ranges) // 2])
    assert np.isfinite(ranges).any() and (ranges[np.isfinite(ranges)] <= 10.0).all()
    h.step(), h.step()
    assert not h.scan_due
    h.step()
    assert h.scan_due


def test_lockstep_waits_for_the_answer_to_each_scan():
    h = open_world(lockstep=True)
    assert h.can_step
    h.scan()
    assert not h.can_step
    h.command(0.1, 0.0)
    assert h.can_step
    free = open_world(lockstep=False)
    free.scan()
    assert free.can_step


def test_the_body_stops_at_a_wall_and_reports_contact():
    h = open_world(cmd_timeout=0.0)
    h.teleport(27.0, 10.0, 0.0)  # 3 m from the east wall (x = 30 is wall, cells 29..)
    h.command(0.8, 0.0)
    for _ in range(200):
        h.step()
        if h.contact:
            break
    assert h.contact and h.twist == (0.0, 0.0)
    x = h.pose[0]
    assert 28.0 < x < 29.0  # the front of the body at the wall, the centre short of it
    with pytest.raises(ValueError):
        h.command(math.nan, 0.0)


def test_an_origin_shifts_the_map_not_the_robot():
    a, b = HostedWorld(RobotSimConfig()), HostedWorld(RobotSimConfig())
    a.load_map(box(), 1.0)
    b.load_map(box(), 1.0, origin=(-5.0, 2.0))
    a.teleport(10.0, 10.0, 0.3)
    b.teleport(5.0, 12.0, 0.3)
    assert np.array_equal(a.scan(), b.scan())
    assert b.pose == pytest.approx((5.0, 12.0, 0.3))


def test_answering_every_scan_is_the_in_process_run():
    """A controller that answers each scan (``RouteFollower``, as ``nd_driver`` does) in a lockstep
    world with dt = the scan period drives exactly the in-process full model's trajectory."""
    grid = box()
    grid[10:20, 14] = True  # a wall to go round
    cfg = RobotSimConfig()
    start, goal = (3, 15), (26, 15)
    waypoints, length = robot.plan_route(grid, 1.0, start, goal, cfg)
    ref = robot.navigate(grid, 1.0, start, goal, cfg, seed=4, route=waypoints)
    h = HostedWorld(cfg, seed=4, lockstep=True)
    h.load_map(grid, 1.0)
    sx, sy = waypoints[0]
    h.teleport(sx, sy, math.atan2(waypoints[1, 1] - sy, waypoints[1, 0] - sx))
    follower = RouteFollower(cfg, waypoints, h.beam_angles, h.pose)
    xs = [h.pose[:2]]
    for k in range(1, len(ref["timeline"]["t"])):
        follower.advance(k * cfg.dt, h.pose)
        ranges = h.scan()
        hits = np.isfinite(ranges)
        v, w, _ = follower.command(k * cfg.dt, h.pose, *h.twist, np.where(hits, ranges, cfg.laser_range), hits)
        h.command(v, w)
        h.step()
        xs.append(h.pose[:2])
    assert ref["outcome"] == "success"
    assert np.allclose(np.asarray(xs), np.column_stack([ref["timeline"]["x"], ref["timeline"]["y"]]), atol=1e-9)


TWO_LASERS = """name: two_lasers
base_frame: base_link
footprint: {polygon: [[-0.3, -0.25], [0.3, -0.25], [0.3, 0.25], [-0.3, 0.25]]}
drive: {kind: differential}
limits:
  max_speed: {x: 0.5, y: 0.0, theta: 1.5}
  max_accel: {x: 1.0, y: 0.0, theta: 2.0}
lasers:
  - {frame: front_laser, parent: base_link, x: 0.25, y: 0.0, yaw_deg: 0.0, fov_deg: 180.0, beams: 181,
     range: 10.0, rate: 10.0, noise: 0.0, topic: /scan}
  - {frame: rear_laser, parent: base_link, x: -0.25, y: 0.0, yaw_deg: 180.0, fov_deg: 180.0, beams: 91,
     range: 5.0, rate: 4.0, noise: 0.0, topic: /scan_rear}
"""


def test_each_laser_of_a_profile_scans_at_its_own_rate(tmp_path):
    """10 Hz and 4 Hz at 0.02 s steps: every 5 and every 12 steps (4.17 Hz, the nearest whole number
    of steps), both right away after a reset; lockstep waits on the first laser only."""
    from ambiegen_ros.sims.hosted_world import laser_steps
    from ambiegen_ros.sims.robot_profile import load_profile

    path = tmp_path / "two_lasers.yaml"
    path.write_text(TWO_LASERS)
    profile = load_profile(str(path))
    h = HostedWorld(RobotSimConfig(dt=0.02), scan_every=laser_steps(10.0, 0.02), profile=profile)
    assert h.laser_every == [5, 12] and h.laser_period(1) == pytest.approx(0.24)
    h.load_map(box(), 1.0)
    h.teleport(10.0, 10.0, 0.0)
    when: dict[int, list[int]] = {0: [], 1: []}
    for _ in range(120):
        due = h.due_lasers
        scans = h.scans(due)
        assert set(scans) == set(due)
        for laser, ranges in scans.items():
            when[laser].append(h.k)
            assert len(ranges) == (181, 91)[laser]
        h.step()
    start = when[0][0]
    assert when[1][0] == start  # both right away
    assert np.diff(when[0]).tolist() == [5] * (len(when[0]) - 1) and len(when[0]) == 24
    assert np.diff(when[1]).tolist() == [12] * (len(when[1]) - 1) and len(when[1]) == 10
    # the rear laser looks back from its own mount: the west wall's face (x = 1) 4 - 0.25 - 1 m behind
    h.teleport(4.0, 10.0, 0.0)
    rear = h.scans([1])[1]
    assert rear[45] == pytest.approx(4.0 - 0.25 - 1.0, abs=0.01) and np.isinf(rear[0]) and np.isinf(rear[-1])
    locked = HostedWorld(RobotSimConfig(dt=0.02), scan_every=5, lockstep=True, profile=profile)
    locked.load_map(box(), 1.0)
    locked.scans([1])
    assert locked.can_step  # the second laser's scan does not hold the world
    locked.scans([0])
    assert not locked.can_step
