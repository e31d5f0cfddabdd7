"""The point light's cube faces and the ray closure of its warped maps, computed
the fast way, equal the plain constructions.

* The six faces' pyramids share their 6 planes (x = ±y, y = ±z, z = ±x in the
  cube's basis) and 8 corner rays (``frame.CUBE_PYRAMIDS``): the sections found
  once per plane and ray equal each face's own construction
  (``pyramid_section_points``) and the 24 planes handled separately, on random
  polytopes around the apex, some with a facet on a cube plane.
* ``ray_closed`` (all windows at once, each map fitted on its own run of
  candidates) equals B clipped by each map's window and fitted.
"""
import math

import numpy as np
import pytest

from addon.warp import WarpOptions, intersection_body
from addon.warp.fit import window_matrix
from addon.warp.frame import (_CUBE_PLANES, _CUBE_SIGNS, CUBE_FACES, CUBE_PYRAMIDS, cube_section_points,
                              light_frames, pyramid_section_points, pyramid_sections, separate_pyramids)
from addon.warp.methods.warp_frustum import (eye_depth_range, frame_warps, half_fov_towards, light_at_eye,
                                             ray_closed, rule_lispsm, volume_centroid)
from addon.warp.polyhedron import ConvexPolytope
from addon.warp.types import Diagnostics

from hard_cases import HARD_CASES


def random_basis(rng) -> np.ndarray:
    """A random right-handed orthonormal basis (rows)."""
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return q.T * np.sign(np.linalg.det(q))


def random_polytope(rng, basis, tol=1e-9):
    """A random convex polytope near the origin (sometimes around it), and now and
    then with a facet on one of the cube's diagonal planes."""
    centre = rng.normal(size=3) * rng.choice([0.0, 0.5, 2.0])
    half = rng.uniform(0.3, 2.0, size=3)
    normals = [np.eye(3), -np.eye(3)]
    offsets = [centre + half, half - centre]
    cuts = rng.normal(size=(rng.integers(0, 6), 3))
    normals.append(cuts)
    offsets.append(cuts @ centre + rng.uniform(0.2, 1.5, size=len(cuts)) * np.linalg.norm(cuts, axis=1))
    if rng.random() < 0.3:                                   # a facet on a cube plane
        plane = _CUBE_PLANES[rng.integers(6)] * rng.choice([-1.0, 1.0])
        normals.append((plane @ basis)[None])
        offsets.append([0.0])
    return ConvexPolytope.from_halfspaces(np.concatenate(normals), np.concatenate(offsets), tol)


def same_points(a, b) -> bool:
    a, b = np.unique(np.round(a, 8), axis=0), np.unique(np.round(b, 8), axis=0)
    return a.shape == b.shape and np.allclose(a, b, atol=1e-7)


def random_bodies(rng, draws: int):
    """(cube basis, polytope, its edges) for each of ``draws`` random draws that gives a polytope."""
    for _ in range(draws):
        basis = random_basis(rng)
        poly = random_polytope(rng, basis)
        if poly is not None:
            yield basis, poly, poly.edges()


@pytest.mark.parametrize("seed", range(6))
def test_shared_cube_planes_equal_each_face_alone(seed):
    rng = np.random.default_rng(seed)
    checked = 0
    for basis, poly, edges in random_bodies(rng, 40):
        together = cube_section_points(poly, edges, basis)
        for (face, k, sign), pts in zip(CUBE_FACES, together):
            alone = pyramid_section_points(poly, edges, sign * basis[k], [basis[j] for j in range(3) if j != k])
            assert (alone is None) == (pts is None), face
            if pts is not None:
                assert same_points(alone, pts), face
                checked += 1
    assert checked >= 40


@pytest.mark.parametrize("seed", range(4))
def test_shared_planes_equal_separate_planes(seed):
    """``pyramid_sections`` with the cube's 6 shared planes and 8 rays gives each
    face the same points as with its own 4 planes and 4 rays."""
    rng = np.random.default_rng(100 + seed)
    for basis, poly, edges in random_bodies(rng, 30):
        planes = (_CUBE_PLANES @ basis) / math.sqrt(2.0)
        rays = _CUBE_SIGNS @ basis
        pts, member, _ = pyramid_sections(poly, edges, planes, rays, CUBE_PYRAMIDS)
        own_planes = planes[CUBE_PYRAMIDS.sides] * CUBE_PYRAMIDS.signs[..., None]          # (6, 4, 3)
        own_rays = np.stack([rays[CUBE_PYRAMIDS.corners[:, f]] for f in range(6)])         # (6, 4, 3)
        pts6, member6, _ = pyramid_sections(poly, edges, own_planes.reshape(-1, 3), own_rays.reshape(-1, 3),
                                            separate_pyramids(6))
        for f in range(6):
            assert member[:, f].any() == member6[:, f].any()
            if member[:, f].any():
                assert same_points(pts[member[:, f]], pts6[member6[:, f]])


def _maps_before_closure(view, light, scene, options):
    """A point light's warped cube-face maps as ``warped_setup`` hands them to ``ray_closed``."""
    body = intersection_body(view, light, scene)
    frames = light_frames(view, light, body, options)
    if len(frames) < 2:
        return body, []
    ctx = eye_depth_range(view, body, options, Diagnostics("lispsm"))
    at, reason = light_at_eye(view, light, options, body, volume_centroid(body) - view.position)
    if at is None:
        return body, []
    warps = frame_warps(frames, view, at, reason, rule_lispsm, ctx, half_fov_towards(view, at.ell), options, body)
    return body, [w.matrix for w in warps if w.geo is not None]


def _case(name):
    if name == "bench_point":                                # the bench's point light over a smaller city
        from bench.warp_speed import LIGHTS, city_scene, street_view
        return street_view(), LIGHTS["point"], city_scene(2000)
    return HARD_CASES[name]


MULTI_MAP_CASES = ("point_light_offset_1e5", "flat_scene_point", "camera_inside_scene_box_point",
                   "point_light_in_camera_plane", "point_light_inside_view", "spot_179deg", "bench_point")
"""The cases whose light gets several warped cube-face maps (the others need no ray closure)."""


@pytest.mark.parametrize("name", MULTI_MAP_CASES)
def test_ray_closed_equals_b_clipped_by_each_window(name):
    view, light, scene = _case(name)
    body, matrices = _maps_before_closure(view, light, scene, WarpOptions())
    assert len(matrices) >= 2, f"{name} no longer gives several warped maps: choose another case"
    poly = body.polytope_from(light.position)
    compared = 0
    for m, (closed, note, held) in zip(matrices, ray_closed(matrices, body, light.position)):
        # The window |x| <= w, |y| <= w as half-spaces through the light.
        sides = np.array([m[0] - m[3], -m[0] - m[3], m[1] - m[3], -m[1] - m[3]])[:, :3]
        part = poly.clip(sides, np.zeros(4))
        if part is None:
            continue
        h = np.hstack([part.vertices + light.position, np.ones((len(part.vertices), 1))]) @ m.T
        compared += 1
        if closed is None:                                   # B ∩ window reaches the light (w = 0)
            assert h[:, 3].min() <= 1e-6 * np.abs(h[:, 3]).max(), name
            continue
        ndc = h[:, :3] / h[:, 3:]
        lo, hi = ndc.min(axis=0), ndc.max(axis=0)
        if lo.min() >= -1.0 - 1e-9 and hi.max() <= 1.0 + 1e-9:
            expected = m
        else:
            expected = window_matrix(lo, hi) @ m
        scale = np.abs(expected).max()
        assert np.allclose(closed, expected, rtol=1e-6, atol=1e-6 * scale), name
        # The points it reports hold B ∩ window: the same NDC box.
        hh = np.hstack([held, np.ones((len(held), 1))]) @ m.T
        held_ndc = hh[:, :3] / hh[:, 3:]
        assert np.allclose(held_ndc.min(axis=0), lo, atol=1e-6) and np.allclose(held_ndc.max(axis=0), hi, atol=1e-6)
    assert compared > 0
