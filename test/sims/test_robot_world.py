"""The robot's world (``sims.robot_world``) on its own: the body stops at walls, the laser reads
exact ranges with noise only on returns, and the run loop of ``sims.robot`` drives it unchanged.

Known answers come from geometry: a robot in a box knows how far its walls are.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from ambiegen_ros.sims import robot, robot_world
from ambiegen_ros.sims.robot_world import WORLD_FIELDS, RobotWorld


def box(n: int = 11) -> np.ndarray:
    g = np.zeros((n, n), dtype=bool)
    g[0, :] = g[-1, :] = g[:, 0] = g[:, -1] = True
    return g


def test_world_fields_are_config_fields():
    """The world reads only fields that the run's config has, so one config drives both."""
    names = {f.name for f in dataclasses.fields(robot.RobotSimConfig)}
    assert set(WORLD_FIELDS) <= names


def test_the_world_names_stay_importable_from_sims_robot():
    """Code written against ``sims.robot`` before the split keeps working with the same objects."""
    for name in ("PIONEER2DX", "WallGeometry", "cast_rays", "clearances", "pad_grid", "wall_distance", "ENGINES"):
        assert getattr(robot, name) is getattr(robot_world, name), name
        assert name in robot.__all__


def test_laser_reads_the_walls_of_a_box_exactly():
    """From the centre of a 9 m box (walls 1 m thick), facing +x: 4.5 m ahead, left and right;
    beams that reach nothing within ``laser_range`` read the range itself."""
    cfg = robot.RobotSimConfig(laser_noise=0.0, beams=181, fov_deg=180.0)
    world = RobotWorld(box(), 1.0, cfg, (5.5, 5.5, 0.0))
    ranges, hits = world.scan()
    assert hits.all()
    assert ranges[90] == pytest.approx(4.5) and ranges[0] == pytest.approx(4.5) and ranges[-1] == pytest.approx(4.5)
    short = RobotWorld(box(), 1.0, dataclasses.replace(cfg, laser_range=3.0), (5.5, 5.5, 0.0))
    ranges, hits = short.scan()
    assert not hits.any() and np.all(ranges == 3.0)


def test_laser_noise_only_on_returns_and_follows_the_seed():
    cfg = robot.RobotSimConfig(laser_noise=0.05, laser_range=5.0)
    exact = RobotWorld(box(), 1.0, dataclasses.replace(cfg, laser_noise=0.0), (5.5, 5.5, 0.3)).scan()[0]

    def noisy(seed):
        return RobotWorld(box(), 1.0, cfg, (5.5, 5.5, 0.3), np.random.default_rng(seed)).scan()

    (a, hits), (b, _), (c, _) = noisy(1), noisy(1), noisy(2)
    assert 0 < hits.sum() < len(hits)  # the corners of the box lie beyond 5 m
    assert np.array_equal(a, b) and not np.array_equal(a, c)
    assert np.array_equal(a[~hits], exact[~hits]) and np.all(a[~hits] == 5.0)
    assert np.all(a[hits] != exact[hits]) and np.abs(a[hits] - exact[hits]).max() < 0.3


def test_body_stops_at_the_wall_it_drives_into():
    """Full speed at the +x wall: the body ends touching it (clearance <= 0, within the bisection's
    resolution), stopped, never inside; the pioneer2dx's nose is 0.18 m ahead of its centre."""
    cfg = robot.RobotSimConfig(max_accel=100.0, max_speed=0.8)
    world = RobotWorld(box(), 1.0, cfg, (8.5, 5.5, 0.0))
    clearances = []
    while not world.contact and len(clearances) < 50:
        clearances.append(world.step(0.8, 0.0))
    assert world.contact and world.v == 0.0 and world.w == 0.0
    assert -1e-3 < clearances[-1] <= 0.0 and all(c > 0 for c in clearances[:-1])
    nose = robot.PIONEER2DX[:, 0].max()
    assert world.x + nose == pytest.approx(10.0, abs=1e-3) and world.x + nose <= 10.0 + 1e-9
    x = world.x
    world.step(0.8, 0.0)  # pushing on: the body stays at the wall
    assert world.x <= x + 1e-3 and world.contact


def test_step_limits_acceleration_and_integrates_a_turn():
    cfg = robot.RobotSimConfig()
    world = RobotWorld(box(30), 1.0, cfg, (3.0, 15.0, 0.0))
    world.step(5.0, 0.0)
    assert world.v == pytest.approx(cfg.max_accel * cfg.dt)
    for _ in range(25):  # 1.6 s to top speed, about 14 m of room ahead
        world.step(5.0, 0.0)
    assert world.v == pytest.approx(cfg.max_speed)  # the command is capped at the base's top speed
    spin = RobotWorld(box(30), 1.0, cfg, (15.0, 15.0, 0.0))
    for _ in range(100):
        spin.step(0.0, 0.5)
    assert (spin.x, spin.y) == (15.0, 15.0)  # turning on the spot
    turned = cfg.dt * (0.2 + 0.4 + 0.5 * 98)  # w ramps 0.2, 0.4, then 0.5 rad/s (2 rad/s^2)
    assert spin.yaw == pytest.approx(math.remainder(turned, 2 * math.pi), abs=1e-9)
