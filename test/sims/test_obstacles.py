"""Obstacles beside the grid (``sims.obstacles``): posts, boxes and walking people.

Known answers come from hand geometry; the rest is checked against brute force that shares no code
with the module: sphere tracing for the laser, a densely sampled body outline for the clearance,
sampled obstacle outlines for the planner's distance.
"""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from ambiegen_ros.core.attributes import ScenarioError
from ambiegen_ros.sims.obstacles import Obstacles, Person, contact_point, placed_footprint, robot_at_fault
from ambiegen_ros.sims.robot_world import PIONEER2DX

FRONT = float(PIONEER2DX[:, 0].max())  # 0.18: the body's tip, on the x axis
SIDE = float(PIONEER2DX[:, 1].max())  # 0.19: its flat left side


def walker(**kw) -> Person:
    """Along +x for 2 m, then +y for 2 m, at 1 m/s after standing 1 s: the corner at t = 3."""
    args = dict(path=[[0, 0], [2, 0], [2, 2]], speed=1.0, delay=1.0, radius=0.3) | kw
    return Person(**args)


# --- people --------------------------------------------------------------------------------------
def test_person_stands_walks_turns_and_stops():
    p = walker()
    assert p.end_time == pytest.approx(5.0)
    cases = {0.5: ((0, 0), (0, 0)),  # before the delay: standing at the start
             1.0: ((0, 0), (1, 0)),  # leaving now
             2.5: ((1.5, 0), (1, 0)),  # mid-segment
             3.0: ((2, 0), (0, 1)),  # at the corner: the next segment's velocity
             4.0: ((2, 1), (0, 1)),
             5.0: ((2, 2), (0, 0)),  # arrived: standing for ever
             60.0: ((2, 2), (0, 0))}
    for t, (pos, vel) in cases.items():
        np.testing.assert_allclose(p.position(t), pos, atol=1e-12, err_msg=f"t={t}")
        np.testing.assert_allclose(p.velocity(t), vel, atol=1e-12, err_msg=f"t={t}")
    times = np.array(list(cases))
    assert p.position(times).shape == p.velocity(times).shape == (len(times), 2)
    np.testing.assert_allclose(p.position(times), [c[0] for c in cases.values()], atol=1e-12)
    np.testing.assert_allclose(p.velocity(times), [c[1] for c in cases.values()], atol=1e-12)


def test_person_walks_over_a_repeated_point_without_stopping():
    p = Person(path=[[0, 0], [1, 0], [1, 0], [1, 3]], speed=0.5, delay=0.0, radius=0.2)
    np.testing.assert_allclose(p.velocity(2.0), [0, 0.5])  # at the repeated point: already turning
    np.testing.assert_allclose(p.position(4.0), [1, 1])


# --- the laser -----------------------------------------------------------------------------------
def test_rays_against_a_post_hand_computed():
    obs = Obstacles(posts=[[5.0, 0.0, 1.0]])
    assert obs.ray_ranges(0, 0, [0.0, math.pi], 10, 0).tolist() == [4.0, np.inf]
    assert obs.ray_ranges(0, 0, [0.0], 3.9, 0)[0] == np.inf  # beyond max_range
    assert obs.ray_ranges(0, 0, [0.0], 4.0, 0)[0] == 4.0  # exactly at max_range still reads
    assert obs.ray_ranges(5.5, 0.2, [0.0, 2.0], 10, 0).tolist() == [0.0, 0.0]  # from inside
    assert obs.ray_ranges(0, 1, [0.0], 10, 0)[0] == pytest.approx(5.0)  # tangent: grazing counts
    assert obs.ray_ranges(0, 1.001, [0.0], 10, 0)[0] == np.inf  # just above: a miss
    # 45 degrees up from (0, -5): the ray runs through the centre, 5 sqrt(2) away, and enters 1 m before
    assert obs.ray_ranges(0, -5, [math.pi / 4], 10, 0)[0] == pytest.approx(5 * math.sqrt(2) - 1)


def test_rays_against_a_box_hand_computed():
    obs = Obstacles(boxes=[[2.0, -1.0, 3.0, 1.0]])
    r = obs.ray_ranges(0, 0, np.array([0.0, math.pi, math.pi / 2]), 10, 0)
    assert r.tolist() == [2.0, np.inf, np.inf]
    assert obs.ray_ranges(2.5, -3, [math.pi / 2], 10, 0)[0] == pytest.approx(2.0)  # from below
    assert obs.ray_ranges(5, 0, [math.pi], 10, 0)[0] == pytest.approx(2.0)  # from the far side
    assert obs.ray_ranges(2.5, 0.5, [1.0, -2.0], 10, 0).tolist() == [0.0, 0.0]  # from inside
    assert obs.ray_ranges(0, 1, [0.0], 10, 0)[0] == 2.0  # along the top face: grazing counts
    assert obs.ray_ranges(0, 1.001, [0.0], 10, 0)[0] == np.inf
    corner = Obstacles(boxes=[[2.0, 2.0, 3.0, 3.0]])
    assert corner.ray_ranges(0, 0, [math.pi / 4], 10, 0)[0] == pytest.approx(2 * math.sqrt(2))  # through a corner
    assert corner.ray_ranges(0, 0, [math.pi / 4], 2.8, 0)[0] == np.inf
    grid = obs.ray_ranges(0, 0, np.zeros((2, 3)), 10, 0)
    assert grid.shape == (2, 3) and (grid == 2.0).all()  # the angles' shape is kept


def test_rays_see_a_person_where_they_are_at_t():
    obs = Obstacles(people=(Person(path=[[10, 0], [10, 10]], speed=1.0, delay=0.0, radius=0.5),))
    assert obs.ray_ranges(0, 5, [0.0], 20, t=5.0)[0] == pytest.approx(9.5)
    assert obs.ray_ranges(0, 5, [0.0], 20, t=0.0)[0] == np.inf  # still at (10, 0)


def _sdf(px, py, circles, boxes):
    """Signed distance to the union of circles and boxes, written out again for the references."""
    d = np.full(np.shape(px), np.inf)
    for cx, cy, r in circles:
        d = np.minimum(d, np.hypot(px - cx, py - cy) - r)
    for x0, y0, x1, y1 in boxes:
        qx, qy = np.abs(px - (x0 + x1) / 2) - (x1 - x0) / 2, np.abs(py - (y0 + y1) / 2) - (y1 - y0) / 2
        d = np.minimum(d, np.hypot(np.maximum(qx, 0), np.maximum(qy, 0)) + np.minimum(np.maximum(qx, qy), 0))
    return d


def random_scene(rng, n_posts=4, n_boxes=3, n_people=3) -> Obstacles:
    boxes = []
    for _ in range(n_boxes):
        x0, y0 = rng.uniform(-4, 3, 2)
        boxes.append([x0, y0, x0 + rng.uniform(0.1, 1.5), y0 + rng.uniform(0.1, 1.5)])
    people = tuple(Person(path=rng.uniform(-4, 4, (3, 2)), speed=rng.uniform(0.3, 1.5), delay=rng.uniform(0, 2),
                          radius=rng.uniform(0.15, 0.4)) for _ in range(n_people))
    posts = np.column_stack([rng.uniform(-4, 4, (n_posts, 2)), rng.uniform(0.02, 0.5, n_posts)])
    return Obstacles(posts=posts, boxes=boxes, people=people)


def test_rays_agree_with_sphere_tracing_on_random_scenes():
    """Sphere tracing marches each ray by the distance to the nearest surface, which can never step
    over one; it stops within 1e-10 of the first surface the ray meets."""
    rng = np.random.default_rng(1)
    hits = misses = 0
    for _ in range(20):
        obs = random_scene(rng)
        x, y, t, max_range = *rng.uniform(-3, 3, 2), rng.uniform(0, 6), 6.0
        angles = np.linspace(-math.pi, math.pi, 181)
        got = obs.ray_ranges(x, y, angles, max_range, t)
        circles = obs.circles_at(t)
        s = np.zeros(len(angles))
        done = np.zeros(len(angles), dtype=bool)
        for _ in range(20000):
            d = _sdf(x + s * np.cos(angles), y + s * np.sin(angles), circles, obs.boxes)
            done |= (d <= 1e-10) | (s > max_range)
            if done.all():
                break
            s = np.where(done, s, s + np.maximum(d, 0))
        assert done.all()
        want = np.where(s <= max_range, s, np.inf)
        finite = np.isfinite(want)
        np.testing.assert_array_equal(np.isfinite(got), finite)
        np.testing.assert_allclose(got[finite], want[finite], atol=1e-8)
        hits, misses = hits + finite.sum(), misses + (~finite).sum()
    assert hits > 500 and misses > 500  # both kinds of ray were tested


# --- the body ------------------------------------------------------------------------------------
def sampled_outline(x, y, yaw, n=5000) -> np.ndarray:
    """The placed body's boundary, ``n`` points per edge, the vertices included."""
    poly = placed_footprint(PIONEER2DX, x, y, yaw)
    u = np.linspace(0, 1, n)[:, None, None]
    return (poly + u * (np.roll(poly, -1, axis=0) - poly)).reshape(-1, 2)


def inside_body(qx, qy, x, y, yaw) -> np.ndarray:
    """Strictly inside the placed body: in the robot frame, left of every edge."""
    c, s = math.cos(yaw), math.sin(yaw)
    rx, ry = c * (qx - x) + s * (qy - y), -s * (qx - x) + c * (qy - y)
    a, b = PIONEER2DX, np.roll(PIONEER2DX, -1, axis=0)
    cross = (b[:, 0] - a[:, 0]) * (ry[..., None] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (rx[..., None] - a[:, 0])
    return np.all(cross > 0, axis=-1)


def test_body_clearance_agrees_with_a_sampled_outline():
    """Random poses near one post or one box: separate, the distance agrees with the sampled outline
    within 1e-6; overlapping (an outline point strictly inside the obstacle, or the obstacle's
    centre or corner strictly inside the body), the clearance is negative, and only then."""
    rng = np.random.default_rng(2)
    seen = {"post": [0, 0], "box": [0, 0]}
    for _ in range(200):
        x, y, yaw = *rng.uniform(-0.3, 0.3, 2), rng.uniform(-math.pi, math.pi)
        outline = sampled_outline(x, y, yaw)
        if rng.random() < 0.5:
            cx, cy, r = *(np.array([x, y]) + rng.uniform(-0.45, 0.45, 2)), rng.uniform(0.02, 0.2)
            obs, kind = Obstacles(posts=[[cx, cy, r]]), "post"
            brute = np.hypot(outline[:, 0] - cx, outline[:, 1] - cy).min() - r
            overlap = brute < 0 or inside_body(np.array(cx), np.array(cy), x, y, yaw)
        else:
            (cx, cy), (hx, hy) = np.array([x, y]) + rng.uniform(-0.5, 0.5, 2), rng.uniform(0.025, 0.3, 2)
            box = [cx - hx, cy - hy, cx + hx, cy + hy]
            obs, kind = Obstacles(boxes=[box]), "box"
            gx = np.maximum(np.maximum(box[0] - outline[:, 0], outline[:, 0] - box[2]), 0)
            gy = np.maximum(np.maximum(box[1] - outline[:, 1], outline[:, 1] - box[3]), 0)
            brute = np.hypot(gx, gy).min()
            strictly_in = ((outline[:, 0] > box[0]) & (outline[:, 0] < box[2])
                           & (outline[:, 1] > box[1]) & (outline[:, 1] < box[3]))
            corners = np.array([[box[0], box[1]], [box[2], box[1]], [box[2], box[3]], [box[0], box[3]]])
            overlap = strictly_in.any() or inside_body(corners[:, 0], corners[:, 1], x, y, yaw).any()
        got, which = obs.body_clearance(x, y, yaw, PIONEER2DX, t=0.0)
        assert which == (kind, 0)
        if abs(got) < 1e-6:
            continue  # touching within sampling: no verdict either way
        assert (got < 0) == overlap, (x, y, yaw, obs.to_dict(), got)
        if not overlap:
            assert got == pytest.approx(brute, abs=1e-6)
        seen[kind][int(overlap)] += 1
    assert min(min(v) for v in seen.values()) >= 25, seen  # each kind both separate and overlapping


def test_a_box_corner_poking_into_the_flat_side():
    """Yaw -45 degrees: the body's flat left side faces (1, 1); a box corner on that normal 1 cm
    inside it pokes in with no body vertex inside the box: penetration depth 1 cm exactly."""
    c = (SIDE - 0.01) / math.sqrt(2)
    obs = Obstacles(boxes=[[c, c, c + 5, c + 5]])
    poly = placed_footprint(PIONEER2DX, 0, 0, -math.pi / 4)
    assert not ((poly[:, 0] > c) & (poly[:, 1] > c)).any()  # no body vertex in the box
    got, which = obs.body_clearance(0, 0, -math.pi / 4, PIONEER2DX, 0)
    assert which == ("box", 0) and got == pytest.approx(-0.01, abs=1e-12)
    c = (SIDE + 0.01) / math.sqrt(2)  # 1 cm off the side instead: the corner is 1 cm away
    got, _ = Obstacles(boxes=[[c, c, c + 5, c + 5]]).body_clearance(0, 0, -math.pi / 4, PIONEER2DX, 0)
    assert got == pytest.approx(0.01, abs=1e-12)


def test_the_body_tip_poking_into_a_box_face():
    """Only the tip vertex lies beyond x = FRONT - 2 mm: it pokes 2 mm into the box's face."""
    face = FRONT - 0.002
    assert (PIONEER2DX[:, 0] > face).sum() == 1
    got, which = Obstacles(boxes=[[face, -5, face + 5, 5]]).body_clearance(0, 0, 0, PIONEER2DX, 0)
    assert which == ("box", 0) and got == pytest.approx(-0.002, abs=1e-12)
    got, _ = Obstacles(boxes=[[FRONT + 0.05, -5, FRONT + 5, 5]]).body_clearance(0, 0, 0, PIONEER2DX, 0)
    assert got == pytest.approx(0.05, abs=1e-12)


def test_body_clearance_names_the_nearest_and_signs_a_centre_inside():
    obs = Obstacles(posts=[[3, 0, 0.1], [0, 0.05, 0.02]], boxes=[[5, 5, 6, 6]],
                    people=(Person(path=[[1, 0], [1, 1]], speed=1, delay=0, radius=0.2),))
    got, which = obs.body_clearance(0, 0, 0, PIONEER2DX, 0)
    assert which == ("post", 1)  # its centre is inside the body: 0.14 from the side, plus the radius
    assert got == pytest.approx(-(SIDE - 0.05) - 0.02)
    got, which = obs.body_clearance(1.0, -0.6, 0, PIONEER2DX, 0)  # the person, at (1, 0) at t = 0, abeam
    assert which == ("person", 0) and got == pytest.approx(0.6 - SIDE - 0.2)
    assert Obstacles().body_clearance(0, 0, 0, PIONEER2DX, 0) == (math.inf, None)


# --- the planner's view --------------------------------------------------------------------------
def test_static_distance_agrees_with_sampled_outlines():
    rng = np.random.default_rng(3)
    obs = random_scene(rng, n_posts=3, n_boxes=3, n_people=2)
    px, py = rng.uniform(-5, 5, (2, 400))
    got = obs.static_distance(px, py)
    n = 1500
    theta = np.linspace(0, 2 * math.pi, n, endpoint=False)
    rims = [np.column_stack([cx + r * np.cos(theta), cy + r * np.sin(theta)]) for cx, cy, r in obs.posts]
    u = np.linspace(0, 1, n)[:, None]
    for x0, y0, x1, y1 in obs.boxes:
        rims += [np.array([x0, y0]) + u * [x1 - x0, 0], np.array([x0, y1]) + u * [x1 - x0, 0],
                 np.array([x0, y0]) + u * [0, y1 - y0], np.array([x1, y0]) + u * [0, y1 - y0]]
    rim = np.concatenate(rims)
    brute = np.hypot(px[:, None] - rim[:, 0], py[:, None] - rim[:, 1]).min(axis=1)
    brute[_sdf(px, py, obs.posts, obs.boxes) <= 0] = 0.0
    inside = brute == 0
    assert 0 < inside.sum() < len(px)
    spacing = max(2 * math.pi * obs.posts[:, 2].max(), np.ptp(obs.boxes[:, [0, 2]], axis=1).max(),
                  np.ptp(obs.boxes[:, [1, 3]], axis=1).max()) / (n - 1)
    assert (got[inside] == 0).all()
    assert (brute - got >= -1e-9).all() and (brute - got <= spacing).all()  # sampling only overestimates
    assert got.shape == px.shape
    assert obs.static_distance(px.reshape(20, 20), 0.0).shape == (20, 20)  # broadcast
    assert np.isinf(Obstacles(people=obs.people).static_distance(px, py)).all()  # people are not static


def test_occupancy_marks_cells_that_share_area():
    obs = Obstacles(posts=[[2.5, 2.5, 0.6]], boxes=[[1.0, 0.0, 2.0, 1.0]],
                    people=(Person(path=[[0.5, 4.5], [4.5, 4.5]], speed=1, delay=0, radius=0.3),))
    grid = obs.occupancy((5, 5), 1.0)
    want = np.zeros((5, 5), dtype=bool)
    want[0, 1] = True  # the box fills one cell exactly; its neighbours only touch it
    want[2, 2] = want[1, 2] = want[3, 2] = want[2, 1] = want[2, 3] = True  # a plus: the corners are 0.707 away
    np.testing.assert_array_equal(grid, want)
    want[4, 0] = True  # the person at (0.5, 4.5) at t = 0
    np.testing.assert_array_equal(obs.occupancy((5, 5), 1.0, t=0.0), want)
    shifted = obs.occupancy((5, 5), 1.0, origin=(1.0, 0.0))
    assert shifted[0, 0] and not shifted[0, 1]  # the box is now the first column


# --- who hit whom --------------------------------------------------------------------------------
@pytest.mark.parametrize("yaw, v, at_fault", [
    (0.0, 0.0, False),  # standing still
    (0.0, 0.005, False),  # creeping below min_speed
    (0.0, 0.5, True),  # driving towards it
    (math.pi, 0.5, False),  # driving away
    (math.pi, -0.5, True),  # reversing into it
    (0.0, -0.5, False),  # reversing away
    (math.pi / 2, 0.5, False),  # passing sideways: no component towards it
])
def test_robot_at_fault(yaw, v, at_fault):
    assert robot_at_fault((1.0, 1.0), yaw, v, (2.0, 1.0)) is at_fault


def test_contact_points_lie_on_the_surface_facing_the_body():
    obs = Obstacles(posts=[[1.0, 0.0, 0.1]], boxes=[[-3, -1, -1, 1]])
    np.testing.assert_allclose(contact_point(0, 0, 0, PIONEER2DX, "post", 0, obs, 0), [0.9, 0.0])
    np.testing.assert_allclose(contact_point(0, 0, 0, PIONEER2DX, "box", 0, obs, 0), [-1.0, 0.0])  # body's tail
    np.testing.assert_allclose(contact_point(0.85, 0.0, 0, PIONEER2DX, "post", 0, obs, 0), [0.9, 0.0])  # overlapping
    np.testing.assert_allclose(contact_point(-0.9, 0.0, 0, PIONEER2DX, "box", 0, obs, 0), [-1.0, 0.0])  # overlapping
    np.testing.assert_allclose(contact_point(-1.2, 0.5, 0, PIONEER2DX, "box", 0, obs, 0), [-1.0, 0.5])  # centre inside
    corner = Obstacles(boxes=[[1, 1, 2, 2]])
    np.testing.assert_allclose(contact_point(0, 0, 0, PIONEER2DX, "box", 0, corner, 0), [1.0, 1.0])
    with pytest.raises(ValueError, match="index"):
        contact_point(0, 0, 0, PIONEER2DX, "post", 3, obs, 0)
    with pytest.raises(ValueError, match="obstacle_kind"):
        contact_point(0, 0, 0, PIONEER2DX, "wall", 0, obs, 0)


# --- files and checks ----------------------------------------------------------------------------
def test_round_trip_through_json():
    obs = random_scene(np.random.default_rng(4))
    d = json.loads(json.dumps(obs.to_dict()))
    assert set(d["people"][0]) == {"path", "speed", "delay", "radius"}
    back = Obstacles.from_dict(d)
    assert back == obs and back.to_dict() == obs.to_dict()
    np.testing.assert_array_equal(back.boxes, obs.boxes)
    assert Obstacles.from_dict({}) == Obstacles() and Obstacles().empty() and not obs.empty()


@pytest.mark.parametrize("build, field", [
    (lambda: Obstacles(posts=[[0, 0, -1]]), "posts[0].radius"),
    (lambda: Obstacles(posts=[[0, 0, 1], [0, np.nan, 1]]), "posts[1]"),
    (lambda: Obstacles(posts=[[0, 0]]), "posts"),
    (lambda: Obstacles(posts=[[0, 0, 1], [0, 1]]), "posts"),
    (lambda: Obstacles(boxes=[[0, 0, 1, 1], [2, 0, 1, 1]]), "boxes[1]"),
    (lambda: Obstacles(boxes=[[0, 1, 1, 1]]), "boxes[0]"),
    (lambda: Obstacles(people=({"path": [[0, 0], [1, 1]]},)), "people[0]"),
    (lambda: walker(speed=0.0), "speed"),
    (lambda: walker(delay=-1.0), "delay"),
    (lambda: walker(radius=0.0), "radius"),
    (lambda: walker(speed=math.inf), "speed"),
    (lambda: walker(path=[[0, 0]]), "path"),
    (lambda: walker(path=[[1, 1], [1, 1]]), "path"),
    (lambda: walker(path=[[0, 0], [math.inf, 0]]), "path[1]"),
    (lambda: Obstacles.from_dict({"people": [{"path": [[0, 0], [1, 0]], "speed": -1, "radius": 0.2}]}),
     "people[0].speed"),
    (lambda: Obstacles.from_dict({"post": []}), "obstacles"),
])
def test_validation_names_the_field(build, field):
    with pytest.raises(ScenarioError) as info:
        build()
    assert info.value.field == field
    assert isinstance(info.value, ValueError)
