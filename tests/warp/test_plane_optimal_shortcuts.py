"""The shortcuts in plane_optimal equal the plain constructions.

* R's section by P, walked from facet to facet across the crossed edges
  (``plane_map._walk_section``), is the hull of the crossing points
  (``_section_hull``), on random planes and on planes through R's vertices
  (where the walk declines and the hull answers).
* The caster cone's section of B from C's facets and edges
  (``plane_optimal._cone_section``) holds the same points as
  ``ConvexPolytope.section`` by C's facets, for suns, point and spot lights,
  lights inside B and regions from P ∩ R.
* The five-point solve with the plane map's equation coefficients made once
  gives ``five_point_matrix``'s matrix and report bit for bit.
* p^1..p^4, the light's position and the viewer's clip w in plain floats
  (Cramer's rule for an affine camera matrix) equal ``line_plane_points``,
  ``Light.homogeneous_position`` and ``View.world_to_clip``; the plane map's 2D
  affine maps composed in floats equal the matrix product.
"""
import importlib

import numpy as np
import pytest

from addon.warp import View, plane_map
from addon.warp.geometry import homogeneous, look_along
from addon.warp.plane_map import (_FIVE_POINT_COEFFICIENTS, _FIVE_POINT_TARGETS, VIEW_CORNER_RAYS, _section_hull,
                                  _solve_five_points, _walk_section, five_point_matrix, line_plane_points, offset_steps,
                                  plane_section)

from test_plane_optimal_speed_equivalence import _frame, _same_loop

plane_optimal = importlib.import_module("addon.warp.methods.plane_optimal")


def _heights(vertices: list, n, off: float) -> list:
    return [float(np.dot(n, v)) - off for v in vertices]


@pytest.mark.parametrize("seed", range(30))
def test_the_walked_section_is_the_hull_of_the_crossings(seed):
    rng, _, _, body = _frame(seed)
    r = body.visible_polytope
    vertices = r.vertices
    walked_count = 0
    for trial in range(12):
        n = rng.normal(size=3)
        n /= np.linalg.norm(n)
        h = np.array(vertices) @ n
        if trial % 4 == 3:                                   # through a vertex: the walk declines
            off = float(h[rng.integers(len(h))])
        else:
            off = float(rng.uniform(h.min(), h.max()))
        heights = _heights(vertices, n, off)
        hull = _section_hull(vertices, heights, r.loops, n, body.tolerance)
        got = plane_section(vertices, n, off, body.tolerance, r.loops)
        assert (got is None) == (hull is None)
        if got is not None:
            assert _same_loop(got, hull, 1e-12 * body.scale)
        if min(map(abs, heights)) > body.tolerance:
            walked = _walk_section(vertices, heights, r.loops, *n.tolist(), body.tolerance)
            if walked is not None:
                walked_count += 1
                assert _same_loop(walked, hull, 1e-12 * body.scale)
        else:
            assert trial % 4 == 3
    assert walked_count >= 6                                 # (the walk answers the plain crossings)


def test_the_walk_declines_a_section_with_a_turn_within_the_tolerance():
    # A box cut just above one corner: that corner's crossings are within 1e-9 of each other.
    box = [(x, y, z) for x in (0.0, 1.0) for y in (0.0, 1.0) for z in (0.0, 1.0)]
    loops = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    n = np.array([1.0, 1.0, 1.0]) / np.sqrt(3)
    off = float(n @ [1.0, 1.0, 1.0]) - 1e-9
    heights = _heights(box, n, off)
    assert _walk_section(box, heights, loops, *n.tolist(), 1e-8) is None
    got = plane_section(box, n, off, 1e-8, loops)
    hull = _section_hull(box, heights, loops, n, 1e-8)
    assert (got is None) == (hull is None)


def _cone(rng, body, view, light, origin, tol):
    """C over a region from P ∩ R for a random plane through R: (corners, height, l_h), or None."""
    r = body.visible_polytope
    vertices = np.array(r.vertices)
    n = rng.normal(size=3)
    n /= np.linalg.norm(n)
    off = float(rng.uniform(*np.quantile(vertices @ n, [0.2, 0.8])))
    poly = plane_section(r.vertices, n, off, body.tolerance, r.loops)
    if poly is None:
        return None
    l_h = light.homogeneous_from(origin)
    light_side = float(np.append(n, -off) @ l_h)
    if abs(light_side) < 1e-6:
        return None
    height = np.sign(light_side) * np.append(n, -off)
    vertices = poly.tolist()
    outwards = offset_steps(vertices, n)
    grow = tol * float(rng.choice([2.0, 5.0, 1e3]))
    corners = [tuple(float(c) for c in p + grow * np.array(d)) for p, d in zip(poly, outwards)]
    return corners, height, l_h


def _same_hull(a: np.ndarray, b: np.ndarray, atol: float) -> bool:
    """The same convex hull: equal support values in many directions."""
    d = np.random.default_rng(0).normal(size=(300, 3))
    return np.allclose((a @ d.T).max(axis=0), (b @ d.T).max(axis=0), rtol=0, atol=atol)


def _both_sections(poly, cone, tol):
    """C's facets, and B ∩ C from them and C's edges (``_cone_section``) and by the facets alone (``section``)."""
    corners, height, l_h = cone
    h = height.tolist()
    normals, offsets = plane_optimal._cone_facets(corners, h, l_h, tol)
    got = plane_optimal._cone_section(poly, normals, offsets, *plane_optimal._cone_edges(corners, h, l_h, tol))
    return normals, offsets, got, poly.section(np.array(normals), np.array(offsets))


@pytest.mark.parametrize("seed", range(45))
def test_the_cone_section_from_facets_and_edges_is_the_section_by_the_facets(seed):
    rng, view, light, body = _frame(seed)
    origin = view.position
    tol = max(plane_optimal.REGION_TOLERANCE * body.scale, 100 * body.tolerance)
    poly = plane_optimal._polytope(body, origin)
    compared = 0
    for _ in range(6):
        cone = _cone(rng, body, view, light, origin, tol)
        if cone is None:
            continue
        normals, offsets, got, expected = _both_sections(poly, cone, tol)
        if len(normals) != len(cone[0]) + 1:
            continue
        assert (got is None) == (expected is None)
        if got is not None:
            compared += 1
            assert _same_hull(got, expected, 1e-9 * body.scale)
            # every point in B and in C within the tolerance
            assert (got @ np.array(normals).T - offsets).max() <= 10 * poly.tol
            assert (got @ poly.normals.T - poly.offsets).max() <= 10 * poly.tol
    assert compared or seed % 3 != 0, "no cone of a sun met B"


def test_the_cone_section_holds_the_light_inside_b():
    """A point light inside B: C's apex (the light) is a vertex of B ∩ C, found as the end of C's side edges."""
    for seed in range(1, 60, 3):
        rng, view, light, body = _frame(seed)
        origin = view.position
        if not body.contains(light.position[None], tol=0.0)[0]:
            continue
        tol = max(plane_optimal.REGION_TOLERANCE * body.scale, 100 * body.tolerance)
        poly = plane_optimal._polytope(body, origin)
        cone = _cone(rng, body, view, light, origin, tol)
        if cone is None:
            continue
        _, _, got, expected = _both_sections(poly, cone, tol)
        assert _same_hull(got, expected, 1e-9 * body.scale)
        assert np.abs(got - (light.position - origin)).max(axis=1).min() <= 1e-9 * body.scale
        return
    pytest.skip("no point light inside B among the seeds")


@pytest.mark.parametrize("seed", range(10))
def test_the_five_point_solve_with_the_coefficients_made_once_is_five_point_matrix(seed):
    rng = np.random.default_rng(seed)
    src = rng.normal(size=(5, 4))
    src /= np.linalg.norm(src, axis=1)[:, None]
    m, info = _solve_five_points(src.tolist(), _FIVE_POINT_TARGETS, _FIVE_POINT_COEFFICIENTS)
    m_general, info_general = five_point_matrix(src, _FIVE_POINT_TARGETS)
    assert np.array_equal(m, m_general) and info == info_general
    assert np.array_equal(_FIVE_POINT_COEFFICIENTS, plane_map._dlt_coefficients(_FIVE_POINT_TARGETS))


@pytest.mark.parametrize("seed", range(20))
def test_the_corner_ray_points_view_w_and_light_in_floats_equal_the_matrix_forms(seed):
    rng, view, light, body = _frame(seed, orthographic=seed % 5 == 4)
    origin = view.position
    n = rng.normal(size=3)
    n /= np.linalg.norm(n)
    off = float(rng.uniform(-5, 5))
    pi = np.append(n, -off)
    ends = homogeneous(view.corners() - origin)
    expected = line_plane_points(ends[VIEW_CORNER_RAYS[0], :], ends[VIEW_CORNER_RAYS[1], :], pi)
    got = np.array(plane_optimal._corner_ray_points(view, origin.tolist(), *n.tolist(), off))
    assert np.allclose(got, expected, rtol=1e-12, atol=1e-12 * np.abs(expected).max())
    l_h = light.homogeneous_position.copy()
    if l_h[3] != 0:
        l_h[:3] -= origin
    assert np.array_equal(light.homogeneous_from(origin), l_h)
    for x in rng.uniform(-50, 50, size=(5, 3)):
        w = float(view.world_to_clip[3] @ np.append(x + origin, 1.0))
        assert plane_optimal._view_w(view, *x.tolist()) == pytest.approx(w, rel=1e-12, abs=1e-12 * (1 + abs(w)))


def test_view_w_of_a_scaled_and_of_a_projective_camera_matrix():
    rng = np.random.default_rng(7)
    for k in range(20):
        eye, target = rng.uniform(-40, 40, 3), rng.uniform(-40, 40, 3)
        c2w = np.linalg.inv(look_along(eye, target - eye, [0.0, 0.0, 1.0])) @ np.diag([*rng.uniform(0.3, 3, 3), 1.0])
        if k % 4 == 3:
            c2w[3] = [1e-3, -2e-3, 1e-3, 1.0]                  # not affine: the 4x4 inverse answers
        view = View.perspective(c2w, 1.0, 1.5, 0.1, 100.0)
        x = rng.uniform(-30, 30, 3)
        w = float(view.world_to_clip[3] @ np.append(x + view.position, 1.0))
        assert plane_optimal._view_w(view, *x.tolist()) == pytest.approx(w, rel=1e-11, abs=1e-11 * (1 + abs(w)))


def test_affine_composition_in_floats_is_the_matrix_product():
    rng = np.random.default_rng(3)
    a, b = rng.normal(size=(2, 3)), rng.normal(size=(2, 3))
    full = lambda m: np.vstack([m, [0.0, 0.0, 1.0]])
    got = np.array(plane_optimal._affine_then(a.tolist(), b.tolist()))
    assert np.allclose(got, (full(a) @ full(b))[:2], rtol=1e-14, atol=1e-14)
