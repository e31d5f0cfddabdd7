"""PSM's virtual camera and nearest visible depth, as made fast, keep their results:

* the virtual camera's B' (``VirtualCamera.points``: the fit's window applied
  to B's divided raw PPS coordinates) is B transformed by ``to_pps`` and
  divided, and fills the unit cube;
* the nearest visible depth (pool kept sorted by bound, the holding test only
  for a batch starting at the coarse bound) equals the least over every
  receiver box of the nearest point of R ∩ box, on street views moved about
  the bench's city under a sun, a point light and a spot;
* a receiver box holding R's nearest vertex always has the coarse bound as
  its lower bound (why the holding test may wait for such a batch).
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from addon.warp import EmptyBodyError, intersection_body
from addon.warp.geometry import look_along, transform_points
from addon.warp.post_perspective import lowest_in_boxes, nearest_visible_depth, virtual_camera
from addon.warp.types import View
from bench.warp_speed import LIGHTS, city_scene, street_view
from hard_cases import point, spot, sun


@pytest.fixture(scope="module")
def city():
    return city_scene(10000)


def _street_views(rng, count):
    """Cameras 0.3-6 m over the bench city's streets, looking slightly down."""
    for _ in range(count):
        eye = np.array([rng.uniform(-90, 90), rng.uniform(-90, 90), rng.uniform(0.3, 6.0)])
        yaw = rng.uniform(0, 2 * math.pi)
        forward = np.array([math.cos(yaw), math.sin(yaw), -rng.uniform(0.0, 0.4)])
        cam_to_world = np.linalg.inv(look_along(eye, forward, [0.0, 0.0, 1.0]))
        yield View.perspective(cam_to_world, math.radians(rng.uniform(40, 80)), 16 / 9, 10 ** rng.uniform(-2, 0),
                               rng.uniform(60, 200))


def _lights(rng):
    return [sun(rng.normal(size=3) * [1, 1, 0.3] + [0, 0, -1]),
            point(rng.uniform(-80, 80, 3) * [1, 1, 0] + [0, 0, rng.uniform(8, 40)]),
            spot(rng.uniform(-80, 80, 3) * [1, 1, 0] + [0, 0, 40], rng.normal(size=3) * 0.3 + [0.5, 0.5, -0.7],
                 math.radians(rng.uniform(30, 90)))]


def _frames(city, seed, count):
    rng = np.random.default_rng(seed)
    for i, view in enumerate(_street_views(rng, count)):
        light = _lights(rng)[i % 3]
        try:
            yield view, light, intersection_body(view, light, city)
        except EmptyBodyError:
            continue


def test_virtual_camera_points_are_b_in_pps(city):
    bench = [(street_view(), light) for light in LIGHTS.values()]
    checked = 0
    for view, light, body in [*_frames(city, 11, 24), *((v, l, intersection_body(v, l, city)) for v, l in bench)]:
        cam = virtual_camera(view, body, nearest_visible_depth(view, light, body))
        expected = transform_points(cam.to_pps, body.vertices - view.position)
        assert np.abs(cam.points - expected).max() <= 1e-12
        assert np.allclose(cam.points.min(axis=0), -1.0, atol=1e-6) and np.allclose(cam.points.max(axis=0), 1.0, atol=1e-6)
        checked += 1
    assert checked >= 20


def _every_box(view, body):
    """The nearest visible depth by brute force over every receiver box, and the boxes' bounds."""
    origin, axis = view.position, -view.world_to_camera[2, :3]
    boxes = body.receiver_boxes
    depths = (body.visible_vertices - origin) @ axis
    coarse = max(float(depths.min()), view.near)
    each = lowest_in_boxes(body.visible_polytope, boxes[:, 0] - origin, boxes[:, 1] - origin, axis)
    least = float(each.min())
    return (max(least, coarse) if math.isfinite(least) else coarse), coarse, boxes, each


def test_nearest_visible_depth_equals_the_least_over_every_receiver_box(city):
    checked = 0
    for view, light, body in _frames(city, 23, 45):
        expected, coarse, boxes, each = _every_box(view, body)
        assert nearest_visible_depth(view, light, body) == pytest.approx(expected, rel=1e-12, abs=1e-12)
        if np.isfinite(each).any():                  # the nearest box's depth, by clipping R with it
            i = int(each.argmin())
            eye = np.eye(3)
            lo, hi = boxes[i] - view.position
            part = body.visible_polytope.clip(np.concatenate([eye, -eye]), np.concatenate([hi, -lo]))
            if part is not None:
                axis = -view.world_to_camera[2, :3]
                assert float(each[i]) == pytest.approx(float((part.vertices @ axis).min()), abs=1e-9)
        checked += 1
    assert checked >= 35


def test_a_box_holding_the_nearest_vertex_of_r_has_the_coarse_bound(city):
    """nearest_visible_depth's lower bound of a box, max(k·(nearest corner) - k·eye, coarse),
    is the coarse bound for every receiver box holding R's nearest vertex."""
    held = 0
    for view, light, body in _frames(city, 31, 45):
        origin, axis = view.position, -view.world_to_camera[2, :3]
        depths = (body.visible_vertices - origin) @ axis
        first = int(depths.argmin())
        coarse = max(float(depths[first]), view.near)
        vertex = body.visible_vertices[first]
        boxes = body.receiver_boxes
        holding = np.all((boxes[:, 0] <= vertex) & (vertex <= boxes[:, 1]), axis=1)
        k = axis.tolist()
        nearest = np.array([max(c, 0.0) for c in k] + [max(-c, 0.0) for c in k])
        shift = sum(a * b for a, b in zip(origin.tolist(), k))
        bounds = np.concatenate([boxes[holding, 0].T, -boxes[holding, 1].T])
        lower = np.maximum(nearest @ bounds - shift, coarse)
        assert np.all(lower <= coarse)
        held += int(holding.any())
    assert held >= 3
