"""Nearness Diagram method and Player-style driver: hand-made scenes with outcomes known from the method.

Points are in the robot frame (x ahead, y left). The robot is Stage's pioneer2dx rectangle as
Player's driver sees it: 0.18 m to the front, 0.26 m to the back, 0.19 m to either side.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from ambiegen_ros.sims import robot
from ambiegen_ros.sims.nearness_diagram import NDDriver, NDParams, NearnessDiagram, wrap


@pytest.fixture(scope="module")
def nd():
    return NearnessDiagram(NDParams.player(0.44, 0.38, -0.04))


def wall(x0, y0, x1, y1, step=0.02):
    """Points every ``step`` along a segment (a laser's view of a wall, densely)."""
    n = max(2, int(math.hypot(x1 - x0, y1 - y0) / step) + 1)
    return np.column_stack([np.linspace(x0, x1, n), np.linspace(y0, y1, n)])


def test_player_parameters_and_robot_shape(nd):
    p = nd.p
    assert (p.front, p.back, p.left) == pytest.approx((0.18, 0.26, 0.19))
    assert (p.dsmax, p.dsmin, p.enlarge, p.discontinuity) == pytest.approx((0.4, 0.1, 0.02, 0.38))
    ahead, left, behind = nd.sector_of(0.0), nd.sector_of(math.pi / 2), nd.sector_of(math.pi)
    assert nd.E[ahead] == pytest.approx(0.18) and nd.E[left] == pytest.approx(0.19)
    assert nd.E[behind] == pytest.approx(0.26)
    # security zone: dsmin behind, the frontal arc (|corner| + dsmax) ahead, in between at the sides
    assert nd.ds[behind] == pytest.approx(0.1, abs=1e-6)
    assert nd.ds[ahead] == pytest.approx(math.hypot(0.18, 0.19) + 0.4 - 0.18, abs=1e-3)
    assert 0.1 < nd.ds[left] < nd.ds[ahead]
    assert np.allclose(nd.ds, nd.ds[(-np.arange(nd.n)) % nd.n])  # symmetric about the x axis
    # Stage's body fits inside the rectangle the driver uses, and touches all four sides
    fp = robot.PIONEER2DX
    assert fp[:, 0].min() == pytest.approx(-0.26) and fp[:, 0].max() == pytest.approx(0.18)
    assert np.abs(fp[:, 1]).max() == pytest.approx(0.19)


def test_free_space_heads_straight_for_the_goal(nd):
    out = nd.step(np.zeros((0, 2)), (3.0, 1.0))
    assert out.situation == "HSGR"
    theta = math.atan2(1.0, 3.0)
    assert out.direction == pytest.approx(theta)
    assert out.v == pytest.approx(0.3 * math.cos(theta)) and out.w == pytest.approx(math.radians(30) * math.sin(theta))
    behind = nd.step(np.zeros((0, 2)), (-3.0, -0.5))  # beyond 90 deg: turn on the spot, right
    assert behind.v == pytest.approx(0.0, abs=1e-12) and behind.w < 0


def test_obstacle_close_in_front_is_an_emergency_stop(nd):
    out = nd.step(np.array([[0.24, 0.0]]), (5.0, 0.0))
    assert out.situation == "emergency_stop" and out.stopped
    # the same point beside the robot is no emergency (outside the front corners' cone)
    assert not nd.step(np.array([[0.0, 0.24]]), (5.0, 0.0)).stopped


def test_wall_with_a_door_goes_for_the_door(nd):
    """A wall 2 m ahead across the goal with a 1 m door 1.5 m to the left: the goal is not in
    sight, the door is the nearest navigable gap. A 0.3 m door (narrower than the robot) is not
    navigable: it heads for an end of the wall instead."""
    wide = np.concatenate([wall(2.0, -4.0, 2.0, 1.0), wall(2.0, 2.0, 2.0, 4.0)])
    out = nd.step(wide, (5.0, 0.0))
    assert not out.stopped and out.situation in ("HSWR", "HSNR", "LS1")
    door = math.atan2(1.5, 2.0)
    assert abs(out.direction - door) < math.radians(25) and out.w > 0  # towards the door, turning left
    narrow = np.concatenate([wall(2.0, -4.0, 2.0, 1.35), wall(2.0, 1.65, 2.0, 4.0)])
    around = nd.step(narrow, (5.0, 0.0))
    assert not around.stopped and abs(around.direction - door) > math.radians(20)
    assert abs(around.direction) > math.radians(55)  # the wall's ends lie beyond +-63 deg


def test_enclosed_robot_finds_no_region_unless_there_is_an_opening(nd):
    ring = 1.5 * np.column_stack([np.cos(np.linspace(-np.pi, np.pi, 720, endpoint=False)),
                                  np.sin(np.linspace(-np.pi, np.pi, 720, endpoint=False))])
    assert nd.step(ring, (5.0, 0.0)).situation == "no_region"
    angles = np.arctan2(ring[:, 1], ring[:, 0])
    opening = ring[np.abs(angles - math.radians(60)) > math.radians(20)]  # a 1 m opening at +60 deg
    out = nd.step(opening, (5.0, 0.0))
    assert not out.stopped and out.w > 0 and abs(out.direction - math.radians(60)) < math.radians(35)


def test_goal_behind_a_gap_too_narrow_is_not_navigable(nd):
    """Two posts 0.3 m apart straight ahead with the goal just behind them: the goal is in sight
    but the robot (0.38 m wide) does not fit between them, so it must go around."""
    posts = np.array([[1.0, 0.15], [1.0, -0.15]])
    out = nd.step(posts, (2.0, 0.0))
    assert out.situation != "HSGR" and abs(out.direction) > math.radians(5)
    apart = nd.step(np.array([[1.0, 0.4], [1.0, -0.4]]), (2.0, 0.0))
    assert apart.situation == "HSGR" and apart.direction == pytest.approx(0.0)


def test_low_safety_turns_away_from_the_nearer_side(nd):
    """One wall close on the left (LSG: turn right, slower); walls on both sides, nearer on the
    right (LS2: turn left); the deeper inside the security zone, the slower."""
    left_wall = wall(-0.5, 0.35, 3.0, 0.35)
    one = nd.step(left_wall, (5.0, 0.0))
    assert one.situation == "LSG" and one.direction < 0 and one.w < 0 and one.v < 0.3
    closer = nd.step(wall(-0.5, 0.27, 3.0, 0.27), (5.0, 0.0))
    assert closer.direction < one.direction and closer.v < one.v
    both = nd.step(np.concatenate([wall(-0.5, 0.45, 3.0, 0.45), wall(-0.5, -0.3, 3.0, -0.3)]), (5.0, 0.0))
    assert both.situation == "LS2" and both.direction > 0 and both.w > 0


def test_gaps_and_regions_in_the_diagram(nd):
    """PND of a wall with a door: one sector per point, nearest kept, gaps at the door's edges."""
    pts = np.concatenate([wall(2.0, -4.0, 2.0, 1.0), wall(2.0, 2.0, 2.0, 4.0), [[0.1, 0.0]]])
    d, a = nd.diagram(pts)
    ahead = nd.sector_of(0.0)
    assert d[ahead] == pytest.approx(nd.E[ahead] + 0.01)  # a point inside the rectangle is pushed out
    k = nd.sector_of(math.atan2(-1.0, 2.0))
    assert d[k] == pytest.approx(math.hypot(2.0, 1.0), abs=0.03)
    door = [nd.sector_of(math.atan2(y, 2.0)) for y in (1.1, 1.5, 1.9)]
    assert np.isinf(d[door]).all()  # nothing seen through the door (points beyond it were not given)
    assert np.all(np.abs(wrap(a[np.isfinite(d)] - nd.centres[np.isfinite(d)])) <= nd.width / 2 + 1e-9)


def driver(**kw):
    return NDDriver(NearnessDiagram(NDParams.player(0.44, 0.38, -0.04)), **kw)


def test_driver_minimum_speeds_and_goal_tolerance():
    d = driver()
    d.set_goal((5.0, 0.0), 0.0, (0.0, 0.0, 0.0))
    d.add_scan(wall(-0.5, 0.27, 3.0, 0.27))  # deep in the security zone: ND asks for less than 0.1 m/s
    v, w = d.command(0.1, (0.0, 0.0, 0.0))
    assert v == pytest.approx(0.1) and w < 0
    d = driver()
    d.set_goal((-3.0, -0.1), 0.0, (0.0, 0.0, 0.0))  # straight behind: a turn on the spot
    v, w = d.command(0.1, (0.0, 0.0, 0.0))
    assert v == 0.0 and math.radians(10) - 1e-12 <= abs(w) <= math.radians(30) + 1e-12
    d.set_goal((0.05, 0.0), 0.2, (0.0, 0.0, 0.0))
    assert d.command(0.3, (0.0, 0.0, 0.0)) == (0.0, 0.0) and d.gave_up is None  # within 0.1 m: arrived


def test_driver_gives_up_when_stuck_and_a_new_goal_clears_it():
    d = driver(stuck_time=5.0, stuck_distance=0.15, stuck_angle=math.radians(10))
    d.set_goal((5.0, 0.0), 0.0, (0.0, 0.0, 0.0))
    t = 0.0
    while d.gave_up is None and t < 20:  # the robot does not move, whatever is commanded
        t += 0.1
        d.command(t, (0.01, 0.0, math.radians(3)))
    assert d.gave_up == "no_progress" and t == pytest.approx(5.1, abs=0.11)
    assert d.command(t + 0.1, (0.0, 0.0, 0.0)) == (0.0, 0.0)  # stays stopped
    d.set_goal((5.0, 1.0), t, (0.0, 0.0, 0.0))
    assert d.gave_up is None and d.command(t + 0.1, (0.0, 0.0, 0.0))[0] > 0
    # moving 0.2 m every 4 s is progress: no give-up
    d = driver()
    d.set_goal((50.0, 0.0), 0.0, (0.0, 0.0, 0.0))
    for k in range(1, 200):
        d.command(0.1 * k, (0.05 * (k // 40) * 4, 0.0, 0.0))
    assert d.gave_up is None
    # an obstacle inside the front corners: the driver gives up with the method's reason
    d.add_scan(np.array([[0.2, 0.0]]))
    assert d.command(30.0, (0.0, 0.0, 0.0)) == (0.0, 0.0) and d.gave_up == "emergency_stop"
