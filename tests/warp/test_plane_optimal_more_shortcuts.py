"""More of plane_optimal's shortcuts equal the plain constructions.

* The five-point matrix as the map between the two sides' projective frames
  (``plane_map.projective_frame``) is the null vector of the 15x16 DLT
  system (its last right singular vector) up to scale, for random points
  and for the plane map's own five points.
"""
import importlib

import numpy as np
import pytest

from addon.warp import plane_map
from addon.warp.plane_map import (_EQUATION_POINT, _FIVE_POINT_FRAME, _FIVE_POINT_TARGETS, _dlt_coefficients,
                                  _solve_five_points, five_point_matrix, projective_frame)
from addon.warp.types import WarpError

from test_plane_optimal_speed_equivalence import _frame

plane_optimal = importlib.import_module("addon.warp.methods.plane_optimal")


def _dlt_null_vector(src, dst) -> np.ndarray:
    """The plain solve: the last right singular vector of the DLT system, as a 4x4."""
    a = (_dlt_coefficients(dst)[:, :, None] * src[_EQUATION_POINT][:, None, :]).reshape(15, 16)
    return np.linalg.svd(a)[2][-1].reshape(4, 4)


def _same_up_to_scale(m, expected, rtol) -> bool:
    k = float(np.sum(m * expected) / np.sum(m * m))
    return np.allclose(k * m, expected, rtol=0, atol=rtol * np.abs(expected).max())


@pytest.mark.parametrize("seed", range(40))
def test_the_frame_map_is_the_dlt_null_vector(seed):
    rng = np.random.default_rng(seed)
    src = rng.normal(size=(5, 4))
    dst = _FIVE_POINT_TARGETS if seed % 2 else rng.normal(size=(5, 4))
    m, info = five_point_matrix(src, dst)
    assert _same_up_to_scale(m, _dlt_null_vector(src, np.asarray(dst)), 1e-10)
    assert info["residual"] < 1e-12


def test_the_target_frame_is_made_once_and_maps_the_canonical_basis():
    assert np.array_equal(_FIVE_POINT_FRAME, projective_frame(_FIVE_POINT_TARGETS))
    basis = np.vstack([np.eye(4), np.ones(4)])
    images = basis @ _FIVE_POINT_FRAME.T
    for got, want in zip(images, _FIVE_POINT_TARGETS):
        assert np.allclose(np.cross(got[:3], want[:3]) if want[3] == 0 else got * want[3] - want * got[3], 0, atol=1e-14)
    assert np.allclose(images[4], _FIVE_POINT_TARGETS[4], atol=1e-15)


def test_coplanar_points_have_no_frame():
    rng = np.random.default_rng(5)
    flat = np.column_stack([rng.normal(size=(5, 2)), np.zeros(5), np.ones(5)])
    with pytest.raises(WarpError, match="degenerate"):
        projective_frame(flat)


@pytest.mark.parametrize("seed", range(30))
def test_the_plane_maps_five_points_solve_to_the_dlt_null_vector(seed, monkeypatch):
    rng, view, light, body = _frame(seed)
    origin = view.position
    n = rng.normal(size=3)
    n /= np.linalg.norm(n)
    points = plane_optimal._corner_ray_points(view, origin.tolist(), *n.tolist(), float(rng.uniform(-3, 3)))
    solved = []

    def keep(src, dst, coefficients, dst_frame=None):
        solved.append((np.array(src), _solve_five_points(src, dst, coefficients, dst_frame)))
        return solved[-1][1]

    monkeypatch.setattr(plane_map, "_solve_five_points", keep)
    try:
        plane_map.plane_light_matrix(points, light.homogeneous_from(origin), body.scale)
    except WarpError:
        return
    src, (m, info) = solved[0]
    assert _same_up_to_scale(m, _dlt_null_vector(src, _FIVE_POINT_TARGETS), 1e-10)
    assert info["residual"] < 1e-12


def _box_prism(lo, hi, z0, z1):
    """An axis-aligned box [lo, hi] x [z0, z1] given as facets (normals with -0.0 entries, as -np.eye) and edges."""
    normals = np.concatenate([-np.eye(3), np.eye(3)])
    offsets = [-lo[0], -lo[1], -z0, hi[0], hi[1], z1]
    corners = [(lo[0], lo[1]), (hi[0], lo[1]), (hi[0], hi[1]), (lo[0], hi[1])]
    base = [(x, y, z0) for x, y in corners]
    up = [(0.0, 0.0, z1 - z0)] * 4
    along = [(bx - ax, by - ay, 0.0) for (ax, ay, _), (bx, by, _) in zip(base, base[1:] + base[:1])]
    top = [(x, y, z1) for x, y in corners]
    return normals.tolist(), offsets, base + base + top, up + along + along, [1.0] * 12


@pytest.mark.parametrize("seed", range(40))
def test_the_cone_section_of_boxes_is_the_section_by_the_facets(seed):
    """Axis-aligned boxes: edges exactly parallel to facets (rates of +0 and -0), edges lying in the other's
    facets and vertices on them; the one clip of both edge sets gives the hull ``ConvexPolytope.section`` gives."""
    from addon.warp.polyhedron import ConvexPolytope
    from test_plane_optimal_shortcuts import _same_hull
    rng = np.random.default_rng(seed)
    # (whole coordinates, often shared: coplanar facets, vertices on facets)
    lo, hi = rng.integers(-3, 1, size=3).astype(float), rng.integers(1, 4, size=3).astype(float)
    poly = ConvexPolytope.box(lo, hi, 1e-9)
    clo, chi = rng.integers(-4, 1, size=2).astype(float), rng.integers(0, 5, size=2).astype(float)
    chi = np.maximum(chi, clo + 1)
    z0, z1 = float(rng.integers(-4, 2)), float(rng.integers(0, 5))
    z1 = max(z1, z0 + 1)
    normals, offsets, starts, steps, ends = _box_prism(clo, chi, z0, z1)
    got = plane_optimal._cone_section(poly, normals, offsets, starts, steps, ends)
    expected = poly.section(np.array(normals), np.array(offsets))
    if expected is None or got is None:
        # (section answers None only when nothing is left; the clip may keep a touching face or edge)
        inter_lo, inter_hi = np.maximum(lo, [clo[0], clo[1], z0]), np.minimum(hi, [chi[0], chi[1], z1])
        assert expected is None and (inter_hi - inter_lo).min() <= 0
        return
    assert _same_hull(got, expected, 1e-12)
