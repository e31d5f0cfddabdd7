"""plane_optimal's faster paths give what the general computations give:
R's section by P walked over R's facet loops equals the section of R's
vertices; the five points from the view frustum's corners give the matrix the
inverse viewer matrix gives; clipping by an extent's edges in plain floats
equals clipping by each edge's Plane; the texel rectangles, the depth fit from
the stored homogeneous points and the fallback cube faces fitted at once equal
the numpy and per-map formulas they replace."""
from __future__ import annotations

import dataclasses
import importlib
import math

import numpy as np
import pytest

from addon.warp import EmptyBodyError, Light, SceneBounds, View, WarpOptions, intersection_body
from addon.warp.fit import ndc_bounds, window_matrix
from addon.warp.frame import light_frames
from addon.warp.geometry import homogeneous, look_along, ortho_matrix, translation
from addon.warp.methods.common import frame_maps
from addon.warp.plane_map import (VIEW_CORNER_RAYS, PlaneOfInterest, clip_polygon, clip_to_polygon,
                                  convex_polygon_on_plane, line_plane_points, plane_light_matrix, plane_light_rows,
                                  plane_section, rotation2d)
from addon.warp.geometry import cross
from addon.warp.polyhedron import Plane
from addon.warp.types import Diagnostics, WarpError

plane_optimal = importlib.import_module("addon.warp.methods.plane_optimal")


def _scene(rng) -> SceneBounds:
    n = int(rng.integers(5, 300))
    centre = rng.uniform(-50, 50, size=(n, 2))
    half = rng.uniform(0.2, 3.0, size=(n, 2))
    height = rng.uniform(0.5, 12.0, size=n)
    boxes = np.stack([np.column_stack([centre - half, np.zeros(n)]), np.column_stack([centre + half, height])], axis=1)
    ground = np.array([[[-60.0, -60.0, -0.2], [60.0, 60.0, 0.0]]])
    return SceneBounds.from_boxes(np.concatenate([ground, boxes]))


def _view(rng, orthographic=False) -> View:
    eye = np.array([*rng.uniform(-60, 60, 2), rng.uniform(0.5, 40)])
    target = np.array([*rng.uniform(-40, 40, 2), rng.uniform(-2, 5)])
    cam_to_world = np.linalg.inv(look_along(eye, target - eye, [0.0, 0.0, 1.0]))
    if orthographic:
        half = float(rng.uniform(5, 40))
        return View(cam_to_world, ortho_matrix(-half, half, -half * 0.6, half * 0.6, 0.1, 150.0), 0.1, 150.0,
                    (1280, 768), orthographic=True)
    return View.perspective(cam_to_world, math.radians(float(rng.uniform(20, 100))), 1.6, 0.1,
                            float(rng.uniform(20, 200)), (1280, 800))


def _light(rng, kind: int) -> Light:
    if kind == 0:
        return Light("SUN", direction=rng.normal(size=3) - [0, 0, 1.5])
    if kind == 1:
        return Light("POINT", position=[*rng.uniform(-60, 60, 2), rng.uniform(1, 50)])
    return Light("SPOT", position=[*rng.uniform(-60, 60, 2), rng.uniform(5, 50)],
                 direction=rng.normal(size=3) - [0, 0, 1], spot_angle=float(rng.uniform(0.3, 2.5)))


def _frame(seed: int, orthographic=False):
    """A random view, light and B: the first draw of ``seed``'s stream whose B is not empty."""
    for draw in range(100):
        rng = np.random.default_rng([seed, draw])
        view, light = _view(rng, orthographic), _light(rng, seed % 3)
        try:
            return rng, view, light, intersection_body(view, light, _scene(rng))
        except EmptyBodyError:
            continue
    raise AssertionError(f"seed {seed}: 100 draws without a body")


def _same_loop(a: np.ndarray, b: np.ndarray, tol: float) -> bool:
    """The same polygon, perhaps starting at another vertex."""
    return len(a) == len(b) and any(np.allclose(np.roll(a, r, axis=0), b, rtol=0, atol=tol) for r in range(len(a)))


@pytest.mark.parametrize("seed", range(30))
def test_section_walked_over_the_facet_loops_is_the_section_of_the_vertices(seed):
    rng, view, _, body = _frame(seed)
    r = body.visible_polytope
    vertices = np.array(r.vertices)
    for _ in range(10):
        n = rng.normal(size=3)
        n /= np.linalg.norm(n)
        h = vertices @ n
        off = float(rng.uniform(h.min(), h.max()))
        walked = plane_section(r.vertices, n, off, body.tolerance, r.loops)
        general = plane_section(vertices, n, off, body.tolerance)
        assert (walked is None) == (general is None)
        if walked is not None:
            assert _same_loop(walked, general, 1e-9 * body.scale)


@pytest.mark.parametrize("seed", range(30))
def test_the_five_points_from_the_frustum_corners_give_the_matrix_of_the_inverse_viewer_matrix(seed):
    rng, view, light, body = _frame(seed, orthographic=seed % 5 == 4)
    origin = view.position
    l_h = light.homogeneous_from(origin)
    ends = homogeneous(view.corners() - origin)
    for _ in range(5):
        n = rng.normal(size=3)
        n /= np.linalg.norm(n)
        pi = np.append(n, -float(rng.uniform(-20, 5)))
        try:
            expected, _ = plane_light_rows(view.world_to_clip @ translation(origin), pi, l_h, body.scale)
        except WarpError:
            continue
        p = line_plane_points(ends[VIEW_CORNER_RAYS[0], :], ends[VIEW_CORNER_RAYS[1], :], pi)
        got, _ = plane_light_matrix(p, l_h, body.scale)
        # (the null vector of the DLT is defined up to sign and scale)
        unit = lambda m: m / np.linalg.norm(m) * np.sign(m.flat[np.argmax(np.abs(m))])
        assert np.allclose(unit(got), unit(expected), rtol=0, atol=1e-7)


@pytest.mark.parametrize("seed", range(40))
def test_clipping_to_an_extent_is_clipping_by_each_of_its_edges(seed):
    rng = np.random.default_rng(seed)
    n = rng.normal(size=3)
    n /= np.linalg.norm(n)
    u = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(n, u)
    base = rng.normal(size=3) * 5

    def polygon(count, radius):
        xy = rng.normal(size=(count, 2)) * radius + rng.normal(size=2)
        return convex_polygon_on_plane(base + xy[:, :1] * u + xy[:, 1:] * v, n, 1e-9)

    poly, ext = polygon(int(rng.integers(3, 12)), 3.0), polygon(int(rng.integers(3, 8)), 2.0)
    out = cross(np.roll(ext, -1, axis=0) - ext, np.broadcast_to(n, ext.shape))
    out /= np.linalg.norm(out, axis=1)[:, None]
    expected = poly
    for o_n, o_o in zip(out, np.einsum("ij,ij->i", out, ext)):
        expected = clip_polygon(expected, Plane(o_n, float(o_o)), 1e-9)
        if len(expected) < 3:
            expected = None
            break
    got = clip_to_polygon(poly, ext, n, 1e-9)
    assert (got is None) == (expected is None)
    if got is not None:
        assert np.allclose(got, expected, rtol=0, atol=1e-12)


@pytest.mark.parametrize("seed", range(40))
def test_texel_rectangles_in_plain_floats_are_the_matrix_formula(seed):
    """The lixels whose cells (within ½ of their centres) cover s·R(θ)·(p - ½)."""
    rng = np.random.default_rng(seed)
    pixels = rng.uniform(-500, 2500, size=(int(rng.integers(3, 12)), 2))
    s, theta = float(rng.uniform(0.05, 4.0)), float(rng.uniform(-math.pi / 4, math.pi / 4)) * (seed % 3 != 0)
    q = s * (pixels - 0.5) @ rotation2d(theta).T
    lo, hi = np.floor(q.min(axis=0) + 0.5), np.floor(q.max(axis=0) + 0.5) + 1
    expected = (int(lo[0]), int(lo[1]), int(hi[0]), int(hi[1]))
    assert plane_optimal._rect([tuple(p) for p in pixels.tolist()], s, theta) == expected


def _plane_jobs(seed, **options):
    _, view, light, body = _frame(seed)
    opts = WarpOptions(shadow_map_size=(1024, 1024), **options)
    diag = Diagnostics("plane_optimal")
    tol = max(plane_optimal.REGION_TOLERANCE * body.scale, 100 * body.tolerance)
    planes = [PlaneOfInterest.through((0, 0, 0.0), (0, 0, 1.0)), PlaneOfInterest.through((0, 0, 2.0), (0.1, 0.2, 1))]
    jobs = [j for j in (plane_optimal._prepare(k, p, view, light, body, view.position, tol, diag)
                        for k, p in enumerate(planes)) if j is not None]
    assert jobs, f"seed {seed}: neither plane gets a map; choose other seeds"
    return view, light, body, opts, tol, jobs


@pytest.mark.parametrize("seed", range(20))
def test_the_depth_fit_from_the_stored_points_is_the_unit_cube_fit(seed):
    view, _, _, opts, tol, jobs = _plane_jobs(seed, linear_z=seed % 2 == 0)
    s = plane_optimal._share_budget(jobs, 0.75 * 1024 * 1024, "auto")
    for job in jobs:
        got = plane_optimal._plane_map(job, s, view.position, tol, opts)
        m = got.matrix @ translation(view.position)
        m[2] = -job.height
        points = job.fit_h[:, :3]
        lo, hi = ndc_bounds(m, points)
        win = window_matrix(np.array([-1.0, -1.0, lo[2]]), np.array([1.0, 1.0, hi[2]]))
        z_row = win[2, 2] * m[2] + win[2, 3] * m[3]
        assert np.allclose(got.matrix[2], z_row @ translation(-view.position), rtol=1e-12, atol=1e-12)
        if opts.linear_z:
            heights = np.column_stack([points, np.ones(len(points))]) @ job.height
            span = max(float(heights.max() - heights.min()), tol)
            pad, k = 1e-7 * span, 2.0 / (span + 2e-7 * span)
            row = -k * job.height + np.array([0, 0, 0, 1.0 + k * (float(heights.min()) - pad)])
            assert np.allclose(got.depth_row, row @ translation(-view.position), rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("seed", [s for s in range(30) if s % 3 == 1])
def test_the_fallback_cube_faces_fitted_at_once_are_the_frame_maps(seed):
    _, view, light, body = _frame(seed)
    options = WarpOptions(shadow_map_size=(1024, 1024))
    setup = plane_optimal.plane_optimal(view, light, body, options)
    fallbacks = [m for m in setup.maps if m.role.startswith("fallback")]
    frames = light_frames(view, light, body, options)
    assert len(fallbacks) == len(frames)
    for got, frame in zip(fallbacks, frames):
        expected = frame_maps([frame], got.size)[0]
        assert np.allclose(got.matrix, expected.matrix, rtol=1e-12, atol=1e-12 * np.abs(expected.matrix).max())
