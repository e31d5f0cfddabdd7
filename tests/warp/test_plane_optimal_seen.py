"""plane_optimal's default plane of interest is chosen by what the camera sees (issue 12): the flat receiver top
that holds most of the seen surface, and its map is made only when the pixels it makes exact ("a lixel for every
pixel", Chong-Gortler §2) are worth the texels the fallback gives up for it."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from addon.measure.box_scene import pixel_rays, ray_boxes, visible_points
from addon.warp import SceneBounds, WarpOptions, compute, focused_body, intersection_body
from addon.warp.methods.plane_optimal import worth_its_texels
from addon.warp.plane_map import default_plane, top_shares
from addon.warp.visibility import BOX_SAMPLES, SURFACE_SAMPLES, surface_from_window_depth
from plane_optimal_helpers import camera, sun_at

TABLE = np.array([[-12.0, -12.0, -0.3], [12.0, 12.0, 0.0]])
BOARD = np.array([[-4.0, -4.0, 0.0], [4.0, 4.0, 0.06]])
PIECES = np.array([[[x - 0.3, y - 0.3, 0.05], [x + 0.3, y + 0.3, 1.2]]
                   for x in np.arange(-3.5, 4.0) for y in (0.5, 1.5, 2.5, 3.5)])
TOL = 1e-9


def _board():
    """A board on a wider table, pieces on its far half, seen from close by (the chess sample scene's kind)."""
    return (SceneBounds.from_boxes(np.array([TABLE, BOARD, *PIECES])),
            camera((0.0, -6.0, 2.5), (0.0, 0.5, 0.0), fov_deg=70.0), sun_at(50.0, 30.0))


def test_the_default_plane_is_the_flat_top_the_camera_sees_most():
    sc, view, light = _board()
    body = focused_body(view, light, sc)
    boxes = body.culled.receivers.boxes
    shares = top_shares(boxes, body.visible.surface, TOL)
    plane, share = default_plane(boxes, body.visible.surface, TOL)
    assert plane.offset == pytest.approx(0.06) and share == shares.max() > shares[0] > 0     # the board, not the table
    assert default_plane(boxes)[0].offset == pytest.approx(0.0)     # without a seen surface: the widest top, the table


def test_a_seen_share_is_the_share_of_the_camera_rays_that_end_on_the_top():
    sc, view, light = _board()
    body = focused_body(view, light, sc)
    points, _ = visible_points(view, sc, BOX_SAMPLES)              # (the CLI's ray grid)
    on_board = (np.abs(points[:, 2] - 0.06) < 1e-9) & (np.abs(points[:, :2]) <= 4.0).all(axis=1)
    shares = top_shares(body.culled.receivers.boxes, body.visible.surface, TOL)
    assert len(body.visible.surface) == len(points)
    assert shares[1] == pytest.approx(on_board.mean(), abs=1.0 / len(points))


def test_a_plane_map_is_made_only_when_what_it_makes_exact_outweighs_what_the_fallback_loses():
    # errors even over the pixels and as wide as a texel: (1 - σ)·√(T / (T - texels)) of uniform's are left, σ the
    # share made exact: all of it at one lixel per pixel, none below
    assert worth_its_texels(0.5, 1.0, 50, 100) and not worth_its_texels(0.2, 1.0, 50, 100)
    assert not worth_its_texels(0.99, 0.95, 1, 100)
    assert worth_its_texels(None, 0.5, 99, 100)                     # the share unknown: the paper's budget
    sc, view, light = _board()
    body = focused_body(view, light, sc)
    small, large = (compute("plane_optimal", view, light, sc, WarpOptions(shadow_map_size=(n, n)), body=body)
                    for n in (256, 2048))
    uniform = compute("uniform", view, light, sc, WarpOptions(shadow_map_size=(256, 256)), body=body)
    assert [m.role for m in small.maps] == ["fallback"] and "plane:0" in dict(small.diagnostics.fallbacks)
    assert np.allclose(small.maps[0].matrix, uniform.maps[0].matrix) and small.maps[0].size == (256, 256)
    assert [m.role for m in large.maps] == ["plane:0", "fallback"]
    assert large.diagnostics.extra["budget"]["lixels_per_pixel"] == 1.0


def _edge_samples(view, sc, light):
    """Which of the CLI's ray-grid samples (``body.visible.surface``'s order) have a seen neighbour in the other
    state of light (the first look's shadow edges, exactly), and the samples' points."""
    o, d, length = pixel_rays(view, BOX_SAMPLES)
    t, _, n = ray_boxes(o, d, length, sc.receivers)
    hit = np.isfinite(t)
    p = o[hit] + t[hit, None] * d[hit]
    lit = np.full(hit.shape, np.nan)
    lit[hit] = ~np.isfinite(ray_boxes(p + 1e-6 * n[hit], np.broadcast_to(-light.direction, p.shape),
                                      np.full(len(p), np.inf), sc.casters)[0])
    grid = lit.reshape(BOX_SAMPLES[::-1])
    edge = np.zeros(grid.shape, dtype=bool)
    edge[1:] |= np.abs(grid[1:] - grid[:-1]) == 1
    edge[:, 1:] |= np.abs(grid[:, 1:] - grid[:, :-1]) == 1
    return edge.reshape(-1)[hit], p


def test_a_plane_wholly_in_shadow_with_none_of_the_views_shadow_edges_gets_no_map_its_texels_go_to_the_fallback():
    """Shadow aliasing is at the shadow edges (Chong-Gortler §1): a ground wholly in a wall's shadow under a 5° sun,
    most of what is seen, holds none of the edges (they run across the towers' lit faces above it), so making it
    exact gains nothing; priced by its seen share alone it took the texels from the fallback (gen62_08_low_sun)."""
    ground, wall = np.array([[-40.0, -40.0, -0.5], [40.0, 40.0, 0.0]]), np.array([[-40.0, -31.0, 0.0], [40.0, -30.0, 8.0]])
    towers = [np.array([[x - 1.0, 8.0, 0.0], [x + 1.0, 10.0, 20.0]]) for x in (-8.0, -3.0, 3.0, 8.0)]
    sc, light = SceneBounds.from_boxes(np.array([ground, wall, *towers])), sun_at(5.0, 180.0)
    view = camera((0.0, -14.0, 6.0), (0.0, 6.0, 3.0), fov_deg=70.0)
    body = focused_body(view, light, sc)
    at_edge, p = _edge_samples(view, sc, light)
    on_ground = np.abs(p[:, 2]) < TOL
    shadowed = np.isfinite(ray_boxes(p + 1e-6 * np.array([0.0, 0.0, 1.0]), np.broadcast_to(-light.direction, p.shape),
                                np.full(len(p), np.inf), sc.casters)[0])
    assert len(body.visible.surface) == len(p) and on_ground.mean() > 0.8 and shadowed[on_ground].all()
    assert at_edge.sum() >= 4 and not at_edge[on_ground].any()
    looked = dataclasses.replace(body, visible=dataclasses.replace(
        body.visible, edge_directions=np.where(at_edge[:, None], (1.0, 0.0, 0.0), 0.0)))
    options = WarpOptions(shadow_map_size=(1024, 1024))
    assert [m.role for m in compute("plane_optimal", view, light, sc, options, body=body).maps] == ["plane:0", "fallback"]
    setup = compute("plane_optimal", view, light, sc, options, body=looked)
    uniform = compute("uniform", view, light, sc, options, body=looked)
    assert [m.role for m in setup.maps] == ["fallback"] and setup.maps[0].size == (1024, 1024)
    assert np.allclose(setup.maps[0].matrix, uniform.maps[0].matrix) and "plane:0" in dict(setup.diagnostics.fallbacks)


def test_a_plane_holding_most_of_the_shadow_edges_is_priced_by_them_not_by_its_seen_pixels():
    """The errors a plane map makes exact are the uniform map's on the plane, and they lie at its shadow edges (§1):
    σ is the plane's share of the edges, more than its share of the pixels where the rest of the view is wholly lit.
    Posts' shadows on a ground that fills 18 % of the view, under a wall in full sun, make 70 % of the edges; at 384²
    its map takes t/B = 0.48, and (1 - 0.70)·√(B / (B - t)) = 0.42 of uniform's errors are left (seen share alone:
    (1 - 0.18)·1.39 = 1.14, no map)."""
    ground, wall = np.array([[-30.0, -30.0, -0.5], [30.0, 30.0, 0.0]]), np.array([[-30.0, 14.0, 0.0], [30.0, 15.0, 12.0]])
    posts = [np.array([[x - 0.4, y - 0.4, 0.0], [x + 0.4, y + 0.4, 1.0]]) for x in (-4.0, -1.5, 1.5, 4.0)
             for y in (2.0, 5.0, 8.0)]
    sc, light = SceneBounds.from_boxes(np.array([ground, wall, *posts])), sun_at(25.0, 250.0)
    view = camera((0.0, -4.0, 2.0), (0.0, 14.0, 5.0), fov_deg=60.0)
    body = focused_body(view, light, sc)
    at_edge, p = _edge_samples(view, sc, light)
    on_ground = np.abs(p[:, 2]) < TOL
    assert len(body.visible.surface) == len(p) and on_ground.mean() < 0.2 and at_edge.sum() >= 50
    assert on_ground[at_edge].mean() > 0.65
    looked = dataclasses.replace(body, visible=dataclasses.replace(
        body.visible, edge_directions=np.where(at_edge[:, None], (1.0, 0.0, 0.0), 0.0)))
    options = WarpOptions(shadow_map_size=(384, 384))
    assert [m.role for m in compute("plane_optimal", view, light, sc, options, body=body).maps] == ["fallback"]
    setup = compute("plane_optimal", view, light, sc, options, body=looked)
    assert [m.role for m in setup.maps] == ["plane:0", "fallback"]
    assert setup.diagnostics.extra["seen_share"] == pytest.approx(on_ground[at_edge].mean())
    budget = setup.diagnostics.extra["budget"]
    assert budget["lixels_per_pixel"] == 1.0 and 0.4 < budget["plane_texels"] / budget["total_texels"] < 0.55

def test_without_a_seen_surface_the_plane_map_keeps_the_papers_budget():
    sc, view, light = _board()
    setup = compute("plane_optimal", view, light, sc, WarpOptions(shadow_map_size=(256, 256)),
                    body=intersection_body(view, light, sc))
    assert [m.role for m in setup.maps] == ["plane:0", "fallback"]


def test_the_seen_surface_of_a_depth_buffer_straddles_each_sampled_point():
    """Each sample of a depth buffer (float32 window depths of a floor, as read back) is the segment of its ray
    that the buffer's precision allows; the floor crosses every one, and undrawn pixels give none."""
    view = camera((0.0, -10.0, 3.0), (0.0, 10.0, 0.0), near=0.1, far=500.0, resolution=(400, 300))
    y, x = np.mgrid[0:300, 0:400]
    ndc = np.stack([(x + 0.5) / 200 - 1, (y + 0.5) / 150 - 1], axis=-1).reshape(-1, 2)
    inverse = np.linalg.inv(view.world_to_clip)
    ends = np.concatenate([ndc, np.full((len(ndc), 1), -1.0), np.ones((len(ndc), 1))], axis=1) @ inverse.T
    far = np.concatenate([ndc, np.ones((len(ndc), 2))], axis=1) @ inverse.T
    a, b = ends[:, :3] / ends[:, 3:], far[:, :3] / far[:, 3:]
    t = a[:, 2] / (a[:, 2] - b[:, 2])                              # where each ray meets z = 0
    floor = a + t[:, None] * (b - a)
    h = np.append(floor, np.ones((len(floor), 1)), axis=1) @ view.world_to_clip.T
    window = np.where((t > 0) & (t < 1), (h[:, 2] / h[:, 3] + 1) / 2, 1.0).reshape(300, 400).astype(np.float32)
    surface, _ = surface_from_window_depth(view, window)
    drawn = (window < 1).sum()
    assert SURFACE_SAMPLES // 4 < len(surface) <= SURFACE_SAMPLES and len(surface) < drawn
    assert (surface[:, :, 2].min(axis=1) <= 1e-9).all() and (surface[:, :, 2].max(axis=1) >= -1e-9).all()


def test_a_tops_share_counts_each_sample_whose_depths_meet_it_inside_its_rectangle():
    """top_shares against the definition, box by box, on a tiled floor (many tops at one height) and slabs."""
    rng = np.random.default_rng(5)
    x, y = np.meshgrid(np.arange(-10.0, 10.0), np.arange(-10.0, 10.0))
    tiles = np.stack([np.c_[x.ravel(), y.ravel(), np.zeros(x.size)], np.c_[x.ravel() + 1, y.ravel() + 1,
                                                                          np.full(x.size, 0.02)]], axis=1)
    slabs = np.array([[[-3.0, -3.0, 0.02], [3.0, 3.0, 0.5]], [[4.0, 4.0, 0.02], [6.0, 9.0, 0.5]]])
    boxes = np.concatenate([tiles, slabs])
    points = np.c_[rng.uniform(-10, 10, (3000, 2)), rng.choice([0.02, 0.5, 0.3], 3000)]
    surface = points[:, None] + rng.uniform(-1e-3, 1e-3, (3000, 2, 1)) * np.array([0.0, 0.0, 1.0])
    shares = top_shares(boxes, surface, TOL)
    for i, (lo, hi) in enumerate(boxes):
        meets = (surface[:, :, 2].min(axis=1) <= hi[2] + TOL) & (surface[:, :, 2].max(axis=1) >= hi[2] - TOL)
        mid = surface.mean(axis=1)
        inside = ((mid[:, :2] >= lo[:2] - TOL) & (mid[:, :2] <= hi[:2] + TOL)).all(axis=1)
        assert shares[i] == (meets & inside).mean()


GROUND = np.array([[-30.0, -30.0, -1.0], [30.0, 30.0, 0.0]])
POSTS = np.array([[[x - 0.2, y - 0.2, 0.0], [x + 0.2, y + 0.2, 1.5]] for x in (-3.0, 0.0, 3.0) for y in (2.0, 5.0)])


def test_the_default_plane_gets_a_map_only_where_one_lixel_per_pixel_fits():
    """A ground filling 98 % of the view needs 232k texels at one lixel per pixel; 512² at the default budget gives
    s = 0.92. Below one lixel per pixel no lixel samples a pixel's own point (Chong-Gortler §2's exactness is the
    identity of the two lattices), and such a map renders worse than the uniform one (docs/papers.md): the fallback
    takes the whole budget, and says why. A plane the user gives keeps the paper's budget."""
    sc = SceneBounds.from_boxes(np.array([GROUND, *POSTS]))
    view, light = camera((0.0, -4.0, 6.0), (0.0, 3.0, 0.0), fov_deg=60.0), sun_at(50.0, 30.0)
    body = focused_body(view, light, sc)

    def run(n, **kw):
        return compute("plane_optimal", view, light, sc, WarpOptions(shadow_map_size=(n, n), **kw), body=body)

    small, large = run(512), run(1024)
    assert [m.role for m in small.maps] == ["fallback"] and small.maps[0].size == (512, 512)
    assert "0.919 lixels per pixel" in dict(small.diagnostics.fallbacks)["plane:0"]
    assert [m.role for m in large.maps] == ["plane:0", "fallback"]
    assert large.diagnostics.extra["budget"]["lixels_per_pixel"] == 1.0
    given = run(512, planes=(((0.0, 0.0, 0.0), (0.0, 0.0, 1.0)),))
    assert [m.role for m in given.maps] == ["plane:0", "fallback"]
    assert given.diagnostics.extra["budget"]["lixels_per_pixel"] == pytest.approx(0.919, abs=1e-3)
