"""Linear depth (Scherzer §4.2) is every map's default: a depth row that grows
along every light ray, holds B in [-1, 1] and means a distance along the ray."""
from __future__ import annotations

import numpy as np
import pytest

from addon.warp import METHODS, EmptyBodyError, WarpOptions, compute, intersection_body
from addon.warp.frame import light_frames
from addon.warp.linear_depth import frame_depth_row, light_depth_row
from hard_cases import HARD_CASES, NONEMPTY_CASES

OPTIONS = WarpOptions(shadow_map_size=(1024, 1024))


def _setup(method, name, **options):
    view, light, scene = HARD_CASES[name]
    body = intersection_body(view, light, scene)
    return view, light, body, compute(method, view, light, scene, WarpOptions(shadow_map_size=(1024, 1024), **options),
                                      body=body)


def _depth(row, points):
    return np.c_[points, np.ones(len(points))] @ row


@pytest.mark.parametrize("name", NONEMPTY_CASES)
@pytest.mark.parametrize("method", sorted(METHODS))
def test_every_map_stores_a_depth_that_grows_along_the_light_rays_and_holds_B(method, name):
    view, light, body, setup = _setup(method, name)
    served = setup.map_index(body.vertices, view, 1e-6)
    for i, m in enumerate(setup.maps):
        if m.depth_row is None:
            assert any(what == "linear z" for what, _ in setup.diagnostics.fallbacks), (method, name, m.role)
            continue
        pts = body.vertices[served == i]
        if not light.is_directional:   # a perspective map cannot hold its own centre (the "near plane" exclusion)
            pts = pts[np.linalg.norm(pts - light.position, axis=1) > 1e-5 * body.scale]
        if not len(pts):
            continue
        z = _depth(m.depth_row, pts)
        assert z.min() >= -1 - 1e-6 and z.max() <= 1 + 1e-6, (m.role, z.min(), z.max())
        rays = light.rays_to(pts)
        growth = rays @ m.depth_row[:3]                      # dz per metre along each point's light ray
        assert (growth > 0).all(), (m.role, growth.min())


@pytest.mark.parametrize("method", sorted(METHODS))
def test_hyperbolic_depth_stays_an_option(method):
    for name in ("sun_behind_camera", "point_light_inside_view", "spot_over_scene"):
        _, _, _, setup = _setup(method, name, linear_z=False)
        assert all(m.depth_row is None for m in setup.maps)


@pytest.mark.parametrize("linear_z", [True, False])
@pytest.mark.parametrize("name", ["sun_behind_camera", "point_light_inside_view", "spot_over_scene"])
def test_the_stored_depth_is_the_depth_row_or_z_over_w_and_its_gradient_is_its_rate_per_metre(name, linear_z):
    _, _, body, setup = _setup("lispsm", name, linear_z=linear_z)
    for m in setup.maps:
        h = m.clip(body.vertices)
        pts = body.vertices[h[:, 3] > 1e-3 * np.abs(h[:, 3]).max()]         # (well in front of a perspective map)
        depth, gradient = m.stored_depth(pts)
        h = m.clip(pts)
        assert np.allclose(depth, _depth(m.depth_row, pts) if linear_z else h[:, 2] / h[:, 3], rtol=0, atol=1e-12)
        step = 1e-6 * body.scale
        for axis in range(3):
            ahead, behind = (m.stored_depth(pts + sign * step * np.eye(3)[axis])[0] for sign in (1, -1))
            rate = (ahead - behind) / (2 * step)
            assert np.allclose(gradient[:, axis], rate, rtol=1e-4, atol=1e-6 * np.abs(gradient).max()), (m.role, axis)


@pytest.mark.parametrize("name", ["sun_behind_camera", "point_light_high_above", "point_light_inside_view"])
def test_a_frames_depth_is_its_distance_along_the_light(name):
    """A sun's frame stores light-space z and a point light's its axis distance
    (the perspective's w): one metre along a ray is the same step everywhere."""
    view, light, scene = HARD_CASES[name]
    body = intersection_body(view, light, scene)
    for frame in light_frames(view, light, body, OPTIONS):
        row = frame_depth_row(frame)
        along = frame.to_light[2] if frame.directional else frame.to_light[3]
        k = (row[:3] @ along[:3]) / (along[:3] @ along[:3])
        assert k > 0 and np.allclose(row[:3], k * along[:3], rtol=1e-9, atol=1e-12 * abs(k))
        z = _depth(row, frame.points)
        assert z.min() == pytest.approx(-1.0, abs=1e-6) and z.max() == pytest.approx(1.0, abs=1e-6)


def test_a_point_lights_depth_axis_is_acute_to_every_ray_of_B():
    """Without a frame (PSM's map), the axis is chosen among the light cone's
    and B's light-facing facets' so that depth grows along every ray of B."""
    for name in NONEMPTY_CASES:
        view, light, scene = HARD_CASES[name]
        if light.is_directional:
            continue
        try:
            body = intersection_body(view, light, scene)
        except EmptyBodyError:
            continue
        if body.contains(light.position[None])[0]:
            continue
        row = light_depth_row(light, body)
        if row is None:
            continue
        assert (light.rays_to(body.vertices) @ row[:3] > 0).all(), name


@pytest.mark.parametrize("name", ["point_light_inside_view", "spot_at_eye_aimed_aside"])
def test_hyperbolic_cube_faces_start_at_the_nearest_box_and_keep_their_precision(name):
    """With hyperbolic depth a point light's cube faces (the light inside B)
    put their near plane at the nearest box that matters, not at the light:
    no box point a face holds is nearer than it, and one float32 step of the
    stored depth is under 1e-4 of the distance at every box corner served (at
    1e-6 of the scene scale it was decimetres at 30 m)."""
    view, light, scene = HARD_CASES[name]
    body = intersection_body(view, light, scene)
    assert body.contains(light.position[None])[0]
    setup = compute("uniform", view, light, scene, WarpOptions(shadow_map_size=(1024, 1024), linear_z=False), body=body)
    assert not any("near plane" in what for what, _ in setup.diagnostics.fallbacks)
    boxes = np.concatenate([scene.casters, scene.receivers])
    corners = boxes[:, [[0, 0, 0], [0, 0, 1], [0, 1, 0], [0, 1, 1], [1, 0, 0], [1, 0, 1], [1, 1, 0], [1, 1, 1]],
                    [0, 1, 2]].reshape(-1, 3)
    rng = np.random.default_rng(4)
    inner = (boxes[:, 0][:, None] + rng.random((len(boxes), 16, 3)) * (boxes[:, 1] - boxes[:, 0])[:, None]).reshape(-1, 3)
    pts = np.concatenate([corners, inner])
    pts = pts[body.contains(pts)]
    for m in setup.maps:
        h = np.c_[pts, np.ones(len(pts))] @ m.matrix.T
        ahead = h[:, 3] > 0
        ndc = h[ahead, :3] / h[ahead, 3:]
        window = (np.abs(ndc[:, :2]) <= 1).all(axis=1)
        assert (ndc[window, 2] >= -1 - 1e-9).all(), m.role
        served = pts[ahead][window & (ndc[:, 2] <= 1)]
        if not len(served):
            continue
        rays = light.rays_to(served)
        eps = 1e-4
        ahead_pts = served + eps * rays

        def window_depth(p):
            hh = np.c_[p, np.ones(len(p))] @ m.matrix.T
            return 0.5 * hh[:, 2] / hh[:, 3] + 0.5

        rate = (window_depth(ahead_pts) - window_depth(served)) / eps      # stored depth per metre along the ray
        step = np.spacing(np.float32(1.0)) / rate                           # metres per float32 step near 1
        distance = np.linalg.norm(served - light.position, axis=1)
        assert (step < 1e-4 * distance).all(), (m.role, float((step / distance).max()))
