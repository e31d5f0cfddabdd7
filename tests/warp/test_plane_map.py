"""plane_map's searches: without a seen surface the default plane is the widest
flat top of the selected receiver boxes; a polygon accepted as already convex is
its own hull."""
from __future__ import annotations

import math

import numpy as np
import pytest

from addon.warp import EmptyBodyError, Light, SceneBounds, View, intersection_body
from addon.warp.geometry import look_along
from addon.warp.plane_map import default_plane, is_convex_polygon
from addon.warp.polyhedron import convex_polygon_on_plane
from plane_optimal_helpers import default_plane as reference_default_plane


def _city(rng, n: int, flat: bool) -> SceneBounds:
    centre = rng.uniform(-50, 50, size=(n, 2))
    half = rng.uniform(0.2, 3.0, size=(n, 2))
    height = rng.uniform(0.05, 0.5, size=n) if flat else rng.uniform(5.0, 12.0, size=n)
    boxes = np.stack([np.column_stack([centre - half, np.zeros(n)]), np.column_stack([centre + half, height])], axis=1)
    boxes = np.concatenate([boxes, boxes[:7]])                 # equal boxes: ties broken by the lowest index
    return SceneBounds.from_boxes(boxes)


@pytest.mark.parametrize("seed", range(40))
def test_default_plane_without_a_seen_surface_is_the_widest_flat_top(seed):
    for draw in range(100):                      # the first draw whose view sees a receiver
        rng = np.random.default_rng([seed, draw])
        scene = _city(rng, int(rng.integers(1, 1500)), flat=seed % 4 != 3)
        eye = np.array([*rng.uniform(-60, 60, 2), rng.uniform(1, 40)])
        target = np.array([*rng.uniform(-40, 40, 2), 0.0])
        view = View.perspective(np.linalg.inv(look_along(eye, target - eye, [0.0, 0.0, 1.0])), math.radians(60), 1.5,
                                0.1, float(rng.uniform(10, 200)))
        try:
            body = intersection_body(view, Light("SUN", direction=[0.3, 0.2, -1.0]), scene)
            break
        except EmptyBodyError:
            continue
    else:
        raise AssertionError(f"seed {seed}: 100 draws without a receiver in view")
    boxes = body.culled.receivers.boxes
    expected, (got, share) = reference_default_plane(boxes), default_plane(boxes)
    assert share is None
    assert (expected is None) == (got is None)
    if expected is not None:
        assert got.name == expected.name and got.offset == expected.offset
        assert np.array_equal(got.extent, expected.extent)


def test_a_convex_extent_is_its_own_hull():
    rng = np.random.default_rng(1)
    accepted = 0
    for trial in range(3000):
        n = rng.normal(size=3)
        n /= np.linalg.norm(n)
        u = np.cross(n, [1.0, 0, 0] if abs(n[0]) < 0.9 else [0, 1.0, 0])
        u /= np.linalg.norm(u)
        v = np.cross(n, u)
        angles = rng.uniform(0, 2 * np.pi, int(rng.integers(3, 9)))
        if trial % 3:
            angles = np.sort(angles)[:: 1 if trial % 3 == 1 else -1]
        flat = 10 ** rng.uniform(-7, 1)
        pts = np.outer(np.cos(angles), u) * 10 + np.outer(np.sin(angles), v) * flat + rng.normal(size=3)
        tol = 10 ** rng.uniform(-9, -3)
        if is_convex_polygon(pts, n, tol):
            accepted += 1
            hull = convex_polygon_on_plane(pts, n, tol)
            assert hull is not None and len(hull) == len(pts)
            assert any(np.array_equal(np.roll(pts, s, axis=0), hull) for s in range(len(pts)))
    assert accepted > 300
    square = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0.0]])
    assert is_convex_polygon(square, [0, 0, 1.0], 1e-9)
    assert not is_convex_polygon(square[::-1], [0, 0, 1.0], 1e-9)             # clockwise
    assert not is_convex_polygon(np.concatenate([square, square]), [0, 0, 1.0], 1e-9)    # around twice


@pytest.mark.parametrize("seed", range(10))
def test_a_plane_maps_region_holds_the_points_within_its_tolerance_of_the_plane_over_its_polygon(seed):
    from addon.warp import Region
    from addon.warp.geometry import normalize, perpendicular
    rng = np.random.default_rng(seed)
    n = normalize(rng.normal(size=3))
    u = perpendicular(n)
    axes = np.array([u, np.cross(n, u)])
    offset, tol = float(rng.normal() * 10), 10.0 ** rng.uniform(-6, -2)
    corners = np.sort(rng.uniform(0, 2 * math.pi, int(rng.integers(3, 12))))
    flat = np.column_stack([np.cos(corners), np.sin(corners)]) * rng.uniform(0.5, 50)
    polygon = offset * n + flat @ axes
    region = Region(n, offset, polygon, tol)
    inside = rng.dirichlet(np.ones(len(polygon)), 500) @ polygon
    assert region.contains(inside + np.outer(rng.uniform(-0.9, 0.9, 500) * tol, n)).all()
    assert not region.contains(inside + np.outer(rng.choice([-1, 1], 500) * rng.uniform(1.1, 3, 500) * tol, n)).any()
    edges = np.roll(flat, -1, axis=0) - flat                         # in the plane's axes, CCW about n
    out = np.column_stack([edges[:, 1], -edges[:, 0]]) / np.linalg.norm(edges, axis=1)[:, None]
    middle = (flat + np.roll(flat, -1, axis=0)) / 2
    for reach, expected in ((0.9 * tol, True), (1.5 * tol, False), (1.0, False)):
        assert (region.contains(offset * n + (middle + reach * out) @ axes) == expected).all(), (reach, expected)
