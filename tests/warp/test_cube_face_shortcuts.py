"""The shortcuts in the point light's cube faces equal the plain constructions.

* ``frame.ray_interval`` (reductions with ``where=``, the parallel-facet test
  only when some ray is parallel to a facet) equals the interval written out
  facet by facet, also for rays parallel to a facet inside or outside it.
* ``frame.pyramid_sections`` for pyramids that share nothing (a reshape of the
  planes' distances) equals the same pyramids with their planes shuffled (the
  gathered path).
* ``ray_closed``'s window corner rays (the directions a map sends to
  (±1, ±1, 1)) are the cross products of the window's sides, turned to w > 0.
* ``fit.window_matrices`` (per-axis float helper) equals the box fitted axis by axis.
* ``frame.point_frames`` (each face's perspective written out in floats) equals
  ``perspective_of`` on the face's ``look_along`` view.
"""
import math

import numpy as np
import pytest

from addon.warp import WarpOptions, intersection_body
from addon.warp.fit import NDC_PAD, window_matrices
from addon.warp.frame import (CUBE_FACES, Pyramids, image_up, light_cone, near_far, perspective_of, point_frames,
                              pyramid_sections, ray_interval, separate_pyramids)
from addon.warp.geometry import look_along
from addon.warp.methods.warp_frustum import _WINDOW_CORNERS, _WINDOW_SIDES, _XYW
from addon.warp.polyhedron import ConvexPolytope

from hard_cases import HARD_CASES
from test_cube_faces_speed_equivalence import MULTI_MAP_CASES, _case, random_basis, random_bodies, same_points


def plain_ray_interval(poly, rays):
    """Facet by facet: n . (t r) <= o for t >= 0."""
    t_lo, t_hi, hit = [], [], []
    for r in rays:
        lo, hi, ok = 0.0, math.inf, True
        for n, o in zip(poly.normals, poly.offsets):
            rate = float(n @ r)
            if rate > 0:
                hi = min(hi, o / rate)
            elif rate < 0:
                lo = max(lo, o / rate)
            elif o < 0:
                ok = False
        t_lo.append(lo)
        t_hi.append(hi)
        hit.append(ok and lo <= hi and math.isfinite(hi))
    return np.array(t_lo), np.array(t_hi), np.array(hit)


@pytest.mark.parametrize("seed", range(4))
def test_ray_interval_equals_facet_by_facet(seed):
    rng = np.random.default_rng(400 + seed)
    checked = 0
    for basis, poly, _ in random_bodies(rng, 30):
        rays = rng.normal(size=(8, 3))
        # Some rays exactly parallel to a facet (a box facet: a zero coordinate), on both sides of it.
        rays[:3, rng.integers(3)] = 0.0
        lo, hi, hit = ray_interval(poly, rays)
        plo, phi, phit = plain_ray_interval(poly, rays)
        assert np.array_equal(hit, phit)
        assert np.allclose(lo[hit], plo[hit], rtol=1e-12, atol=1e-12)
        assert np.allclose(hi[hit], phi[hit], rtol=1e-12, atol=1e-12)
        checked += int(hit.sum())
    assert checked > 100


@pytest.mark.parametrize("seed", range(3))
def test_separate_pyramids_reshape_equals_gather(seed):
    rng = np.random.default_rng(500 + seed)
    for basis, poly, edges in random_bodies(rng, 25):
        k = int(rng.integers(1, 5))
        planes = rng.normal(size=(4 * k, 3))
        planes /= np.linalg.norm(planes, axis=1)[:, None]
        rays = rng.normal(size=(4 * k, 3))
        pts, member, _ = pyramid_sections(poly, edges, planes, rays, separate_pyramids(k))
        assert separate_pyramids(k).separate
        shuffle = rng.permutation(4 * k)                     # plane shuffle[i] is the old plane i
        place = np.argsort(shuffle)
        mixed = Pyramids(place.reshape(k, 4), np.ones((k, 4)), np.eye(k, dtype=bool).repeat(4, axis=0))
        assert not mixed.separate
        pts2, member2, _ = pyramid_sections(poly, edges, planes[shuffle], rays, mixed)
        for j in range(k):
            assert member[:, j].any() == member2[:, j].any()
            if member[:, j].any():
                assert same_points(pts[member[:, j]], pts2[member2[:, j]])


def test_window_corner_rays_are_the_sides_cross_products():
    rng = np.random.default_rng(7)
    for _ in range(200):
        m = rng.normal(size=(4, 4))
        rows = m[:, :3]
        rays = (np.linalg.inv(rows[_XYW]) @ _WINDOW_CORNERS).T
        for ray, (sx, sy) in zip(rays, [(-1, -1), (-1, 1), (1, -1), (1, 1)]):
            cross = np.cross(rows[0] - sx * rows[3], rows[1] - sy * rows[3])
            cross *= np.sign(cross @ rows[3])                # the side where w > 0
            assert np.allclose(ray / np.linalg.norm(ray), cross / np.linalg.norm(cross), atol=1e-9)
            assert ray @ rows[3] > 0
            assert np.allclose([ray @ rows[0], ray @ rows[1]], [sx * (ray @ rows[3]), sy * (ray @ rows[3])])
        sides = _WINDOW_SIDES @ rows
        assert np.all(rays @ sides.T <= 1e-9 * np.abs(rays @ sides.T).max())   # the rays bound the window


def plain_window(lo, hi):
    ext = np.maximum(np.asarray(hi) - lo, 0.0)
    m = np.eye(4)
    for i in range(3):
        pad = NDC_PAD * max(ext[i], ext.max() * 1e-6) + 1e-300
        a, b = lo[i] - pad, hi[i] + pad
        m[i, i], m[i, 3] = 2.0 / (b - a), -(b + a) / (b - a)
    return m


def test_window_matrices_equal_axis_by_axis():
    rng = np.random.default_rng(11)
    for _ in range(300):
        k = int(rng.integers(1, 6))
        lo = rng.normal(size=(k, 3)) * 10.0 ** rng.integers(-2, 3)     # (a pad below lo's ulp has no window)
        flat = rng.random((k, 3)) < 0.2                      # some axes without extent (a box's x always has one)
        flat[:, 0] = False
        hi = lo + rng.uniform(0.5, 2.0, size=(k, 3)) * ~flat * 10.0 ** rng.integers(1, 5)
        got = window_matrices(lo.tolist(), hi.tolist())
        for g, a, b in zip(got, lo, hi):
            assert np.array_equal(g, plain_window(a, b))


@pytest.mark.parametrize("name", MULTI_MAP_CASES)
def test_cube_face_perspectives_equal_perspective_of_look_along(name):
    view, light, scene = _case(name)
    body = intersection_body(view, light, scene)
    frames = point_frames(view, light, body, WarpOptions())
    assert len(frames) >= 2
    axis, _ = light_cone(body.vertices, light.position)
    up = image_up(view.direction, view.up, axis)
    from addon.warp.frame import cube_basis
    basis = cube_basis(axis.tolist(), up.tolist())
    floor = 1e-6 * body.scale
    for f in frames:
        _, k, sign = next(c for c in CUBE_FACES if "cube" + c[0] == f.role)
        forward = sign * basis[k]
        face_up = basis[2] if k == 1 else basis[1]
        eye = look_along(light.position, forward, face_up)
        depth = (f.points - light.position) @ forward
        near, far, clamped = near_far(float(depth.min()), float(depth.max()), floor)
        if f.near_clamped:                                   # the face's points start at the near floor
            near = floor
        expected = perspective_of(eye, near, far)
        scale = np.abs(expected).max()
        assert np.allclose(f.to_light, expected, rtol=1e-9, atol=1e-12 * scale), f.role
