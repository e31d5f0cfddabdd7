"""Texel footprint on analytic cases."""
import dataclasses
import math

import numpy as np
import pytest

from addon.measure.footprint import footprint_stats, setup_footprints
from addon.warp.geometry import look_along, ortho_matrix
from addon.warp.types import Diagnostics, Region, ShadowMap, ShadowSetup, View


def _top_down_view(height, fov_y_deg, res):
    c2w = np.linalg.inv(look_along([0.0, 0.0, height], [0, 0, -1], [0, 1, 0]))
    return View.perspective(c2w, math.radians(fov_y_deg), res[0] / res[1], 0.1, 100.0, res)


def _uniform_sun_map(half_extent, size):
    # a sun straight down: light eye at z = 50 looking down -Z, ortho window [-a, a]^2
    w2l = look_along([0.0, 0.0, 50.0], [0, 0, -1], [0, 1, 0])
    return ortho_matrix(-half_extent, half_extent, -half_extent, half_extent, 1.0, 100.0) @ w2l


@pytest.mark.parametrize("height,fov,res,a,size", [(10.0, 60, (640, 480), 20.0, 1024),
                                                     (3.0, 40, (320, 320), 8.0, 256)])
def test_top_down_sun_over_a_plane_with_a_uniform_map_has_constant_known_footprint(height, fov, res, a, size):
    view = _top_down_view(height, fov, res)
    rng = np.random.default_rng(0)
    half_h = height * math.tan(math.radians(fov) / 2)
    pts = np.column_stack([rng.uniform(-half_h * res[0] / res[1], half_h * res[0] / res[1], 500),
                           rng.uniform(-half_h, half_h, 500), np.zeros(500)])
    normals = np.tile([0.0, 0.0, 1.0], (500, 1))
    setup = ShadowSetup([ShadowMap(_uniform_sun_map(a, size), (size, size))], Diagnostics("uniform"))
    lin, area = setup_footprints(view, setup, pts, normals)
    texel = 2 * a / size                     # world length of a texel
    pixel = 2 * half_h / res[1]               # world length of a pixel at depth `height`
    assert np.allclose(lin, texel / pixel, rtol=1e-9)
    assert np.allclose(area, (texel / pixel) ** 2, rtol=1e-9)


def test_oblique_receiver_footprint_is_the_worst_direction():
    # camera looks straight down; the map's sun travels at 60 degrees from vertical along +x:
    # texels stretch by 1/cos(60) = 2 along x on the ground, so the linear footprint doubles.
    view = _top_down_view(10.0, 60, (400, 400))
    t = math.radians(60)
    d = np.array([math.sin(t), 0.0, -math.cos(t)])
    w2l = look_along(-50 * d, d, [0, 1, 0])
    m = ortho_matrix(-10, 10, -10, 10, 1, 100) @ w2l
    pts = np.array([[0.5, -1.0, 0.0], [2.0, 3.0, 0.0]])
    setup = ShadowSetup([ShadowMap(m, (500, 500))], Diagnostics("uniform"))
    lin, area = setup_footprints(view, setup, pts, np.tile([0, 0, 1.0], (2, 1)))
    pixel = 2 * 10 * math.tan(math.radians(30)) / 400
    texel = 20 / 500
    assert np.allclose(lin, 2 * texel / pixel, rtol=1e-9)
    assert np.allclose(area, 2 * (texel / pixel) ** 2, rtol=1e-9)


def test_setup_footprints_uses_the_serving_map_and_nan_elsewhere():
    view = _top_down_view(10.0, 60, (200, 200))
    m = ShadowMap(_uniform_sun_map(5.0, 100), (100, 100))
    setup = ShadowSetup([m], Diagnostics("uniform"))
    pts = np.array([[0.0, 0.0, 0.0], [7.0, 0.0, 0.0]])   # the second is outside the map window
    lin, _ = setup_footprints(view, setup, pts, np.tile([0, 0, 1.0], (2, 1)))
    assert np.isfinite(lin[0]) and np.isnan(lin[1])


def test_footprint_stats():
    s = footprint_stats(np.array([0.5, 1.0, 2.0, np.inf, np.nan]))
    assert s.max == np.inf and s.count == 4
    assert s.frac_above_1 == pytest.approx(0.5)
    assert s.mean == pytest.approx(3.5 / 3)
    m = footprint_stats(np.array([0.5, 3.0]), mask=np.array([True, False]))
    assert (m.max, m.count, m.frac_above_1) == (0.5, 1, 0.0)


def test_perspective_footprint_removes_the_surface_orientation():
    # top-down camera, sun straight down, uniform map: on the ground the perspective factor
    # equals the plain footprint; on a wall (normal along x) the plain footprint is infinite
    # (texels edge-on) but the perspective factor is finite and matches Lloyd's density ratio.
    from addon.measure.footprint import perspective_footprints
    from addon.warp.types import Light
    view = _top_down_view(10.0, 60, (400, 400))
    setup = ShadowSetup([ShadowMap(_uniform_sun_map(20.0, 512), (512, 512))], Diagnostics("uniform"))
    sun = Light("SUN", direction=[0, 0, -1])
    ground = np.array([[1.0, 2.0, 0.0]])
    wall = np.array([[1.0, 2.0, 4.0]])
    lin, _ = setup_footprints(view, setup, ground, np.array([[0, 0, 1.0]]))
    persp = perspective_footprints(view, sun, setup, np.vstack([ground, wall]))
    assert persp[0] == pytest.approx(lin[0], rel=1e-9)
    lin_wall, _ = setup_footprints(view, setup, wall, np.array([[1.0, 0, 0]]))
    assert not np.isfinite(lin_wall[0]) or lin_wall[0] > 1e6
    # at eye depth 6 the needed pixel density is (10/6)^2 times that at depth 10
    assert persp[1] == pytest.approx(lin[0] * 10 / 6, rel=1e-9)


def test_across_edge_width_is_the_texels_screen_width_across_the_edge():
    # camera straight down, a sun 60 degrees from vertical along +x: on the ground a texel is
    # 2 texel widths long along x and 1 along y, so an edge running along y (normal along x) moves
    # by twice what an edge along x moves; σ_max is the larger of the two.
    from addon.measure.footprint import setup_across_edge_width
    view = _top_down_view(10.0, 60, (400, 400))
    t = math.radians(60)
    d = np.array([math.sin(t), 0.0, -math.cos(t)])
    setup = ShadowSetup([ShadowMap(ortho_matrix(-10, 10, -10, 10, 1, 100) @ look_along(-50 * d, d, [0, 1, 0]),
                                   (500, 500))], Diagnostics("uniform"))
    pts = np.array([[0.5, -1.0, 0.0], [2.0, 3.0, 0.0], [-1.0, 0.0, 0.0]])
    up = np.tile([0, 0, 1.0], (3, 1))
    ratio = (20 / 500) / (2 * 10 * math.tan(math.radians(30)) / 400)   # texel / pixel widths
    width = setup_across_edge_width(view, setup, pts, up, np.array([[1.0, 0.0], [0.0, 1.0], [0.6, -0.8]]))
    assert width == pytest.approx([2 * ratio, ratio, math.hypot(0.6 * 2, 0.8) * ratio], rel=1e-9)
    lin, _ = setup_footprints(view, setup, pts, up)
    assert np.all(width <= lin * (1 + 1e-12))


def test_an_edge_along_a_texel_axis_has_grid_angle_zero_and_one_across_the_diagonal_45_degrees():
    # camera straight down; a sun straight down whose map is turned 30 degrees about the vertical: an edge
    # along that map's texel rows (or columns) is at 0, one along its diagonal at 45
    from bench.edge_footprint import grid_angle
    view = _top_down_view(10.0, 60, (400, 400))
    turn = math.radians(30)
    m = ShadowMap(ortho_matrix(-10, 10, -10, 10, 1, 100) @ look_along([0, 0, 50.0], [0, 0, -1],
                                                                      [-math.sin(turn), math.cos(turn), 0]), (512, 512))
    pts = np.array([[0.5, -1.0, 0.0], [2.0, 3.0, 0.0], [-1.0, 0.0, 0.0], [1.0, 1.0, 0.0]])
    normals = [turn, turn + math.pi / 2, turn + math.pi / 4, turn + math.radians(10)]
    edge = np.array([[math.cos(a), math.sin(a)] for a in normals])
    got = grid_angle(view, m, pts, np.tile([0, 0, 1.0], (4, 1)), edge)
    assert got == pytest.approx([0.0, 0.0, 45.0, 10.0], abs=1e-7)


@pytest.mark.parametrize("radius", [1, 4])
@pytest.mark.parametrize("normal", [(1.0, 0.0), (0.0, -1.0), (math.sqrt(0.5), math.sqrt(0.5))])
def test_shadow_edge_normals_point_into_the_shadow_across_a_straight_edge(normal, radius):
    from addon.measure.errors import dilate, shadow_edges
    from addon.measure.footprint import shadow_edge_normals
    n = np.array(normal)
    y, x = np.mgrid[0:40, 0:60]
    truth = (x - 30.3) * n[0] + (y - 20.2) * n[1] > 0                 # row 0 at the bottom: y up
    valid = np.ones_like(truth)
    valid[:, :3] = False
    got = shadow_edge_normals(truth, valid, radius)
    edges = shadow_edges(truth, valid)
    inner = edges & (x > 3 + radius) & (x < 59 - radius) & (y >= radius) & (y < 40 - radius)
    assert inner.sum() > 20
    assert np.allclose(got[inner], n, atol=1e-12)
    assert np.all(np.isnan(got[~valid])) and np.all(np.isnan(got[~dilate(edges, radius)]))


@pytest.mark.parametrize("degrees", [7.0, 20.0, 33.0, 63.0, 101.0, 200.0, 296.0])
def test_a_straight_shadow_edge_s_normal_is_found_within_degrees_at_any_angle(degrees):
    """The normal across a straight edge at any angle to the pixel grid is found within 2° in the median over its
    pixels and 6° at worst: the across-edge width |Jᵀn| on a receiver where a texel is long follows it (a 3 x 3
    Sobel errs by 7° to 12° in the median here, and read gen2_08_low_sun's uniform width twice what its edges show)."""
    from addon.measure.errors import shadow_edges
    from addon.measure.footprint import shadow_edge_normals
    n = np.array([math.cos(math.radians(degrees)), math.sin(math.radians(degrees))])
    y, x = np.mgrid[0:60, 0:80]
    truth = (x - 40.37) * n[0] + (y - 30.61) * n[1] > 0
    valid = np.ones_like(truth)
    got = shadow_edge_normals(truth, valid)
    inner = shadow_edges(truth, valid) & (x > 5) & (x < 74) & (y > 5) & (y < 54)
    error = np.degrees(np.arccos(np.clip(got[inner] @ n, -1.0, 1.0)))
    assert inner.sum() > 40 and error.max() < 6.0 and np.median(error) < 2.0


def test_a_grid_phase_moves_every_texel_coordinate_by_the_offset_and_keeps_the_depth_and_the_window():
    """The grid moves by the offset and grows a texel on each side (texel coordinates + 1 + offset in a map
    2 texels larger), so every point the map held it still holds: no gap opens between cube faces or splits."""
    from bench.edge_footprint import phases, shifted
    offsets = phases(12)
    assert np.array_equal(offsets[0], [0.0, 0.0]) and np.all((offsets >= 0) & (offsets < 1))
    assert len({tuple(np.round(o, 9)) for o in offsets}) == 12
    t = math.radians(60)
    d = np.array([math.sin(t), 0.0, -math.cos(t)])
    m = ShadowMap(ortho_matrix(-10, 10, -10, 10, 1, 100) @ look_along(-50 * d, d, [0, 1, 0]), (500, 400))
    pts = np.c_[np.random.default_rng(1).uniform(-5, 5, (20, 3)), np.ones(20)]
    corners = np.array([[x, y, z, 1.0] for x in (-1, 1) for y in (-1, 1) for z in (-0.5, 0.5)]) @ np.linalg.inv(m.matrix).T
    corners /= corners[:, 3:]

    def texel_and_depth(matrix, size):
        h = pts @ matrix.T
        return (h[:, :2] / h[:, 3:] * 0.5 + 0.5) * size, h[:, 2] / h[:, 3]
    for offset in ((0.25, 0.75), (0.999, 0.0)):
        moved = shifted(ShadowSetup([m], Diagnostics("uniform")), offset).maps[0]
        assert moved.size == (502, 402)
        (a, za), (b, zb) = texel_and_depth(m.matrix, [500, 400]), texel_and_depth(moved.matrix, [502, 402])
        assert np.allclose(b - a, 1.0 + np.asarray(offset), atol=1e-9) and np.allclose(za, zb, atol=0)
        assert moved.contains(corners[:, :3], tol=1e-9).all()


def test_a_grid_phase_leaves_a_plane_maps_lixels_on_their_pixels():
    """Chong-Gortler §2 places a plane map's lixels on the pixels: its grid has no free phase to move."""
    from bench.edge_footprint import shifted
    m = ShadowMap(ortho_matrix(-10, 10, -10, 10, 1, 100) @ look_along([0, 0, 50], [0, 0, -1], [0, 1, 0]), (500, 400))
    plane = dataclasses.replace(m, region=Region(np.array([0.0, 0.0, 1.0]), 0.0,
                                                 np.array([[-5.0, -5, 0], [5, -5, 0], [5, 5, 0], [-5, 5, 0]]), 1e-6))
    kept, moved = shifted(ShadowSetup([plane, m], Diagnostics("plane_optimal")), (0.5, 0.5)).maps
    assert kept is plane and not np.array_equal(moved.matrix, m.matrix)


def test_a_cascades_seams_are_its_blend_bands_as_the_shading_reads_them_and_the_pixels_by_a_change_of_map():
    """shade_frag.glsl mixes map j's shadow into a farther map's where the eye depth is within j's blend band past
    the end of j's depth range; the other seam pixels lie within two pixels of a change of serving map."""
    from types import SimpleNamespace
    from bench.edge_footprint import seams
    near = ShadowMap(np.eye(4), (64, 64), view_depth_range=(0.1, 5.0), blend_band=0.5)
    far = ShadowMap(np.eye(4), (64, 64), view_depth_range=(5.0, 20.0))
    depth = np.tile(np.linspace(1.0, 10.0, 10), (6, 1))          # columns at eye depths 1..10
    index = np.where(depth <= 5.0, 0, 1)
    band, change = seams(ShadowSetup([near, far], Diagnostics("cascade")), SimpleNamespace(map_index=index,
                                                                                       eye_depth=depth))
    assert not band.any()                                         # no pixel between 5.0 and 5.5
    depth[:, 5] = 5.25
    band, change = seams(ShadowSetup([near, far], Diagnostics("cascade")), SimpleNamespace(map_index=index,
                                                                                       eye_depth=depth))
    assert np.array_equal(np.flatnonzero(band.any(axis=0)), [5]) and band[:, 5].all()
    assert np.array_equal(np.flatnonzero(change.any(axis=0)), [2, 3, 4, 6, 7])   # 4|5 and 2 px on, less the band
