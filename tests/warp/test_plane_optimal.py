"""plane_optimal (Chong & Gortler, "A Lixel for every Pixel"): exactness on the
plane, coverage, the five point solve, the budget, the twist and the default plane.

Exactness is measured independently of the implementation: the composite map
screen pixel -> point of the plane -> texel is built from the View, the map's
matrix and size, and the plane only (``plane_optimal_helpers``).
"""
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from addon.warp import WarpError, WarpOptions
from addon.warp.plane_map import (PlaneOfInterest, five_point_matrix, min_area_twist, plane_light_matrix,
                                  polygon_area, rotation2d)
from addon.warp.polyhedron import ConvexPolytope, plane_section
from plane_optimal_helpers import (FLOOR_PLANE, default_plane, ray_plane_points, assert_pixel_centres_are_lixel_centres, check_coverage, camera, camera_yaw_pitch, homography_jacobian, ndc,
                                   pixel_to_texel_homography, plane_maps, plane_scale, point, region_pixels, run, scene,
                                   sun, sun_at, try_run)

ROOT = Path(__file__).resolve().parents[2]
HYPO = settings(max_examples=60, deadline=None, derandomize=True,
                suppress_health_check=[HealthCheck.filter_too_much, HealthCheck.too_slow])


def assert_uniform_on_plane(view, setup, expect_scale=None, rel=1e-9):
    """Every plane map: the pixel -> texel Jacobian over its region is the same
    similarity s·R(θ) at every pixel (the identity when s = 1 and θ = 0), to ``rel``."""
    maps = plane_maps(setup)
    assert maps, "no plane map"
    for _, m in maps:
        g = pixel_to_texel_homography(view, m, m.region.normal, m.region.normal * m.region.offset)
        _, px = region_pixels(view, m)
        j = homography_jacobian(g, px)
        s = math.sqrt(abs(np.linalg.det(j[0])))
        if expect_scale is not None:
            assert s == pytest.approx(expect_scale, rel=rel)
        ref = j[0]
        # a similarity: orthogonal columns of equal length
        assert np.allclose(ref.T @ ref, s * s * np.eye(2), rtol=0, atol=rel * s * s)
        assert np.max(np.abs(j - ref[None])) <= rel * s
        if expect_scale == 1.0 and abs(math.atan2(ref[1, 0], ref[0, 0])) < 1e-12:
            assert np.max(np.abs(j - np.eye(2)[None])) <= rel


# ---------------------------------------------------------------- exactness

@HYPO
@given(x=st.floats(-20, 20), y=st.floats(-30, 0), h=st.floats(0.3, 25), yaw=st.floats(-60, 60),
       pitch=st.floats(-85, 5), fov=st.floats(25, 100), elev=st.floats(8, 90), azim=st.floats(0, 360))
def test_every_pixel_centre_is_a_lixel_centre_sun(x, y, h, yaw, pitch, fov, elev, azim):
    view = camera_yaw_pitch([x, y, h], yaw, pitch, fov_deg=fov)
    setup, _ = try_run(view, sun_at(elev, azim), plane_budget=1.0, shadow_map_size=(4096, 4096))
    assume(setup is not None and plane_maps(setup))
    assert_uniform_on_plane(view, setup, expect_scale=plane_scale(setup))
    assert_pixel_centres_are_lixel_centres(view, setup)


@HYPO
@given(x=st.floats(-20, 20), y=st.floats(-30, 0), h=st.floats(0.3, 25), yaw=st.floats(-60, 60),
       pitch=st.floats(-85, 5), fov=st.floats(25, 100), lx=st.floats(-30, 30), ly=st.floats(-30, 40),
       lh=st.floats(0.5, 40))
def test_every_pixel_centre_is_a_lixel_centre_point_light(x, y, h, yaw, pitch, fov, lx, ly, lh):
    view = camera_yaw_pitch([x, y, h], yaw, pitch, fov_deg=fov)
    setup, _ = try_run(view, point([lx, ly, lh]), plane_budget=1.0, shadow_map_size=(4096, 4096))
    assume(setup is not None and plane_maps(setup))
    assert_uniform_on_plane(view, setup, expect_scale=plane_scale(setup))
    assert_pixel_centres_are_lixel_centres(view, setup)


def test_one_lixel_per_pixel_is_the_identity_up_to_renumbering():
    """At one lixel per pixel: texel = pixel - (i0, j0), a whole number of texels."""
    view, light = CONFIGS["sun_oblique"]
    setup, _ = run(view, light, shadow_map_size=(1024, 1024))
    assert plane_scale(setup) == 1.0
    _, m = plane_maps(setup)[0]
    g = pixel_to_texel_homography(view, m, (0, 0, 1.0), (0, 0, 0.0))
    g = g / g[2, 2]
    assert np.allclose(g[:2, :2], np.eye(2), atol=1e-9) and np.allclose(g[2, :2], 0, atol=1e-12)
    assert np.allclose(g[:2, 2], np.round(g[:2, 2]), atol=1e-6)


def test_plane_maps_take_one_lixel_per_pixel_and_the_fallback_the_rest():
    """One lixel per pixel samples every pixel's point (§2); more would sample
    the same points again, so a larger budget refines the fallback only."""
    view, light = CONFIGS["sun_oblique"]
    last_fallback = 0
    for size in (512, 1024, 2048, 4096, 8192):
        setup, _ = run(view, light, shadow_map_size=(size, size))
        budget = setup.diagnostics.extra["budget"]
        total, need = size * size, budget["one_lixel_texels"]
        fallback = setup.maps[-1].size[0] * setup.maps[-1].size[1]
        assert need <= 0.75 * total and plane_scale(setup) == 1.0
        assert budget["plane_texels"] == need and total - need - 2 * size < fallback <= total - need
        assert fallback > last_fallback
        last_fallback = fallback


@HYPO
@given(h=st.floats(0.5, 20), yaw=st.floats(-60, 60), pitch=st.floats(-80, 0), elev=st.floats(10, 90),
       azim=st.floats(0, 360), budget=st.floats(0.02, 0.3), is_point=st.booleans())
def test_uniform_scale_on_the_plane_at_a_smaller_budget(h, yaw, pitch, elev, azim, budget, is_point):
    view = camera_yaw_pitch([0, -10, h], yaw, pitch, resolution=(1280, 720))
    light = point([3, 5, 15]) if is_point else sun_at(elev, azim)
    setup, _ = try_run(view, light, plane_budget=budget, shadow_map_size=(1024, 1024), plane_twist="off")
    assume(setup is not None and plane_maps(setup))
    s = plane_scale(setup)
    need = setup.diagnostics.extra["planes"][0]["pixel_area"]
    if need > budget * 1024 * 1024:
        assert s < 1.0
    assert_uniform_on_plane(view, setup, expect_scale=s)
    assert setup.diagnostics.extra["budget"]["plane_texels"] <= budget * 1024 * 1024


def test_twist_turns_the_map_to_a_turned_table_and_buys_more_lixels_per_pixel():
    """A square table turned 30° on screen (seen from straight above): its
    pixels' tightest rectangle is turned 15° (mod 90°) from the screen axes.
    With the twist the map turns by that angle, the sampling stays a uniform
    similarity, and the same budget buys more lixels per pixel."""
    turn = math.radians(30.0)
    table = [(3 * math.cos(turn + k * math.pi / 2), 3 * math.sin(turn + k * math.pi / 2), 0.0) for k in range(4)]
    plane = ((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), table)
    view = camera([0.0, 0.0, 12.0], [0.0, 0.0, 0.0], up=(0.0, 1.0, 0.0), resolution=(1280, 720))
    light = sun_at(50, 30)
    kw = dict(planes=(plane,), plane_budget=0.05, shadow_map_size=(1024, 1024))
    off, _ = run(view, light, plane_twist="off", **kw)
    on, _ = run(view, light, plane_twist="on", **kw)
    assert_uniform_on_plane(view, on, expect_scale=plane_scale(on))
    twist = on.diagnostics.extra["planes"][0]["twist_deg"]
    assert abs((twist - 15.0 + 45.0) % 90.0 - 45.0) < 1e-6
    assert off.diagnostics.extra["planes"][0]["twist_deg"] == 0.0
    assert plane_scale(on) > 1.1 * plane_scale(off)


def test_min_area_twist_finds_the_rotation_of_a_rotated_rectangle():
    rect = np.array([[0, 0], [4, 0], [4, 1], [0, 1.0]])
    for angle in (0.3, -0.6, 0.1):
        q = rect @ rotation2d(angle).T
        t = min_area_twist(q)
        r = q @ rotation2d(t).T
        assert np.prod(np.ptp(r, axis=0)) == pytest.approx(4.0, rel=1e-9)


def test_matrix_equals_the_closed_form_shadow_projection_on_every_point():
    """Independent derivation: the light image of any point is the viewer image
    of its shadow on P (M_v·S with S = (π·l)I - lπ^T) - the x, y, w rows agree up to scale."""
    view = camera_yaw_pitch([1, -12, 4], 10, -20)
    for light in (sun_at(40, 120), point([4, 6, 9])):
        pi = np.array([0, 0, 1.0, 0])
        l_h = np.array(light.homogeneous_from(np.zeros(3)))
        s = (pi @ l_h) * np.eye(4) - np.outer(l_h, pi)
        closed = (view.world_to_clip @ s)[[0, 1, 3]]
        m, info = plane_light_matrix(ray_plane_points(view.world_to_clip, pi, [(-1, -1), (-1, 1), (1, 1), (1, -1)]), l_h, 10.0)
        solved = m[[0, 1, 3]]
        k = np.sum(closed * solved) / np.sum(solved * solved)
        assert np.allclose(k * solved, closed, atol=1e-10 * np.abs(closed).max())
        assert info["residual"] < 1e-12
        assert info["condition"] > 1e-6


def test_five_point_solve_meets_its_constraints_and_rejects_coplanar_points():
    rng = np.random.default_rng(3)
    m_true = rng.normal(size=(4, 4))
    src = np.column_stack([rng.normal(size=(5, 3)), np.ones(5)])
    dst = src @ m_true.T
    m, info = five_point_matrix(src, dst)
    k = np.sum(m * m_true) / np.sum(m * m)
    assert np.allclose(k * m, m_true, atol=1e-9)
    flat = src.copy()
    flat[:4, 2] = 0.0          # four coplanar points
    with pytest.raises(WarpError, match="degenerate"):
        five_point_matrix(flat, dst)


def test_plane_section_of_a_cube():
    cube = ConvexPolytope.box([0.0, 0.0, 0.0], [1.0, 1.0, 1.0], 1e-12)
    poly = plane_section(cube, np.array([0, 0, 1.0]), 0.5)
    assert len(poly) == 4 and np.allclose(poly[:, 2], 0.5)
    assert polygon_area(poly, [0, 0, 1.0]) == pytest.approx(1.0)
    assert plane_section(cube, np.array([0, 0, 1.0]), 2.0) is None
    top = plane_section(cube, np.array([0, 0, 1.0]), 1.0)        # a facet lying on the plane is the section
    assert len(top) == 4 and np.allclose(top[:, 2], 1.0)


# ---------------------------------------------------------------- sign, depth, coverage

CONFIGS = {
    "sun_oblique": (camera_yaw_pitch([0, -15, 5], 5, -15), sun_at(35, 200)),
    "sun_behind_camera": (camera_yaw_pitch([0, -15, 5], 0, -15), sun([0.05, 0.9, -0.4])),
    "point_light": (camera_yaw_pitch([2, -12, 3], -10, -10), point([0, 6, 8])),
    "spot_light": (camera_yaw_pitch([2, -12, 3], -10, -10), None),
    "horizon_in_view": (camera_yaw_pitch([0, -20, 1.7], 0, 0), sun_at(20, 60)),
}


def _light(name, light):
    if light is None:
        from addon.warp import Light
        return Light("SPOT", position=np.array([0.0, 0.0, 10.0]), direction=np.array([0.1, 0.3, -1.0]),
                     spot_angle=math.radians(80))
    return light


@pytest.mark.parametrize("name", sorted(CONFIGS))
def test_coverage_region_casters_and_the_rest_of_b(name):
    view, light = CONFIGS[name]
    light = _light(name, light)
    setup, body = run(view, light)
    maps = plane_maps(setup)
    assert maps, setup.diagnostics.fallbacks
    roles = [m.role for m in setup.maps]
    assert roles[0] == "plane:0" and roles[-1].startswith("fallback")
    idx, m = maps[0]
    # the needed region: all of it served by the plane map, inside its clip volume
    pts, _ = region_pixels(view, m, count=600)
    assert np.all(setup.map_index(pts, view) == idx)
    d, w = ndc(m.matrix, pts)
    assert np.all(w > 0) and np.all(np.abs(d) <= 1)
    # points within the tolerance of the plane too
    off = pts + np.outer(np.where(np.arange(len(pts)) % 2 == 0, 0.9, -0.9) * m.region.tolerance, m.region.normal)
    assert np.all(setup.map_index(off, view) == idx)
    # casters: points of B between the light and the region are in the plane map (depth grows away from the light)
    rng = np.random.default_rng(5)
    ts = rng.uniform(0, 1, size=len(pts))
    if light.is_directional:
        reach = body.vertices[:, 2].max() / abs(light.direction[2])     # up to the top of B
        cast = pts - (ts * reach)[:, None] * light.direction
        near = np.ones(len(pts), dtype=bool)
    else:
        cast = light.position + ts[:, None] * (pts - light.position)
        near = np.linalg.norm(cast - light.position, axis=1) > 1e-4 * body.scale
    sel = body.contains(cast, tol=0.0) & near
    assert sel.sum() > 20
    dc, wc = ndc(m.matrix, cast[sel])
    assert np.all(wc > 0) and np.all(np.abs(dc) <= 1 + 1e-12)
    dr, _ = ndc(m.matrix, pts[sel])
    assert np.all(dc[:, 2] <= dr[:, 2] + 1e-12)                         # caster nearer the light
    assert np.allclose(dc[:, :2], dr[:, :2], atol=1e-9)                 # on the same texel ray
    # every visible point served, its casters and the points of B on its shadow ray in the same map
    check_coverage(view, light, scene(), setup, body)


def test_selection_order_and_budget_report():
    view, light = CONFIGS["sun_oblique"]
    planes = (FLOOR_PLANE, ((0.0, 20.0, 0.0), (0.0, -1.0, 0.0)))
    sc = scene(extra=[np.array([[-30, 20, 0], [30, 20.5, 10]])])
    setup, _ = run(view, light, sc, planes=planes)
    roles = [m.role for m in setup.maps]
    assert roles == ["plane:0", "plane:1", "fallback"]
    budget = setup.diagnostics.extra["budget"]
    assert budget["plane_budget"] == 0.75
    total = 2048 * 2048
    assert budget["plane_texels"] == sum(m.size[0] * m.size[1] for m in setup.maps[:2])
    assert budget["plane_texels"] <= 0.75 * total
    fb = setup.maps[-1].size
    assert fb[0] * fb[1] <= total - budget["plane_texels"]
    assert_pixel_centres_are_lixel_centres(view, setup)
    wall = setup.maps[1]
    assert np.allclose(np.abs(wall.region.normal), [0, 1, 0])


def test_default_plane_is_the_top_of_the_widest_thinnest_box():
    boxes = np.array([[[-5, -5, -1], [5, 5, 0]], [[-50, -40, -0.2], [50, 40, 0.3]], [[0, 0, 0], [60, 2, 30]],
                      [[-3, -3, 0.3], [3, 3, 0.4]]])
    plane = default_plane(boxes)
    assert np.allclose(plane.normal, [0, 0, 1]) and plane.offset == pytest.approx(0.3)
    assert np.allclose(np.ptp(plane.extent, axis=0), [100, 80, 0])
    assert default_plane(np.array([[[0, 0, 0], [1, 1, 1.0]]])) is None


def test_default_plane_is_used_without_planes_and_limited_to_that_face():
    view, light = CONFIGS["sun_oblique"]
    setup, _ = run(view, light, planes=())
    assert [m.role for m in setup.maps] == ["plane:0", "fallback"]
    region = setup.maps[0].region
    assert np.allclose(region.normal, [0, 0, 1]) and region.offset == pytest.approx(0.0)
    assert np.all(np.abs(region.polygon[:, :2]) <= 50 + 1e-9)
    assert_pixel_centres_are_lixel_centres(view, setup)


def test_plane_extent_limits_the_region():
    view, light = CONFIGS["sun_oblique"]
    table = ((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), np.array([[-2, -2, 0], [2, -2, 0], [2, 2, 0], [-2, 2, 0.0]]))
    setup, _ = run(view, light, planes=(table,))
    region = setup.maps[0].region
    assert np.all(np.abs(region.polygon[:, :2]) <= 2 + 1e-9)
    assert not region.contains(np.array([[5.0, 5.0, 0.0]]))[0]


def test_cube_face_fallbacks_share_the_plane_maps_texels():
    """A point light's n fallback faces take, together with the plane maps,
    the n·T texels of the uniform method's n faces: each face gives up
    1/n of the plane maps' texels, not all of them."""
    view, light = CONFIGS["point_light"]
    setup, _ = run(view, light, shadow_map_size=(512, 512))
    budget, faces = setup.diagnostics.extra["budget"], [m for m in setup.maps if m.role.startswith("fallback")]
    total, n = 512 * 512, len(faces)
    assert n > 1 and budget["plane_texels"] > 0.1 * total
    for m in faces:
        assert total - budget["plane_texels"] / n - 2 * 512 < m.size[0] * m.size[1] <= total - budget["plane_texels"] / n


def test_linear_z_depth_row_grows_away_from_the_light_and_is_constant_on_the_plane():
    view, light = CONFIGS["point_light"]
    setup, body = run(view, light, linear_z=True)
    m = setup.maps[0]
    assert m.depth_row is not None
    pts, _ = region_pixels(view, m)
    z = np.column_stack([pts, np.ones(len(pts))]) @ m.depth_row
    assert np.ptp(z) < 1e-9 and np.all(np.abs(z) <= 1)
    above = pts + np.array([0, 0, 0.5])
    za = np.column_stack([above, np.ones(len(above))]) @ m.depth_row
    assert np.all(za < z)


def test_invalid_options_are_named_errors():
    with pytest.raises(WarpError, match="plane_twist"):
        WarpOptions(plane_twist="sideways")
    with pytest.raises(WarpError, match="planes\\[0\\]"):
        PlaneOfInterest.from_option(((0, 0, 0), (0, 0, 0)), 0)


def test_cli_outputs_a_map_per_plane_and_the_fallback_with_regions(tmp_path):
    cfg = json.loads((ROOT / "examples" / "outdoor_sun.json").read_text())
    cfg["planes"] = [{"point": [0, 0, 0], "normal": [0, 0, 1]}]
    path = tmp_path / "c.json"
    path.write_text(json.dumps(cfg))
    out = subprocess.run([sys.executable, "-m", "addon.warp", "--method", "plane_optimal", str(path)],
                         cwd=ROOT, capture_output=True, text=True, check=True)
    data = json.loads(out.stdout)
    roles = [m["role"] for m in data["maps"]]
    assert roles == ["plane:0", "fallback"]
    assert set(data["maps"][0]["region"]) == {"normal", "offset", "polygon", "tolerance"}
    assert data["diagnostics"]["budget"]["lixels_per_pixel"] == 1.0      # 1024², so one lixel per pixel
    out = subprocess.run([sys.executable, "-m", "addon.warp", "--method", "all", str(path)],
                         cwd=ROOT, capture_output=True, text=True, check=True)
    assert "plane_optimal" in json.loads(out.stdout)["methods"]


def test_at_most_eight_maps_largest_planes_kept():
    view, light = CONFIGS["sun_oblique"]
    planes = tuple(((0.0, 0.0, 0.4 * k), (0.0, 0.0, 1.0)) for k in range(9))   # floor and 8 levels above it
    setup, _ = run(view, light, planes=planes)
    assert len(setup.maps) == 8 and setup.maps[-1].role == "fallback"
    kept = [m.role for m in setup.maps[:-1]]
    assert kept == sorted(kept, key=lambda r: int(r.split(":")[1]))      # plane order kept
    dropped = [w for w, r in setup.diagnostics.fallbacks if "at most 8 maps" in r]
    assert len(dropped) == 2 and set(dropped).isdisjoint(kept)
    assert_uniform_on_plane(view, setup, expect_scale=plane_scale(setup))


def test_enclosing_polygon_contains_and_limits_vertices():
    from addon.warp.plane_map import enclosing_polygon, polygon_area
    from addon.warp.types import Region
    n = np.array([0, 0, 1.0])
    ang = np.linspace(0, 2 * np.pi, 50, endpoint=False)
    circle = np.column_stack([np.cos(ang), np.sin(ang), np.zeros(50)])
    e = enclosing_polygon(circle, n, 32)
    assert len(e) == 32
    assert Region(n, 0.0, e, 1e-12).contains(circle).all()
    assert polygon_area(e, n) < polygon_area(circle, n) * 1.01


def test_receivers_no_plane_describes_get_the_uniform_map_and_the_reason():
    """A hilly terrain (its box 11 % as high as wide) has no plane of interest
    (Chong-Gortler §5): plane_optimal is the uniform map with the whole budget,
    and says why and what to do."""
    terrain = np.array([[-800.0, -500.0, -30.0], [800.0, 1100.0, 150.0]])
    houses = [np.array([[x, y, 60.0], [x + 15, y + 15, 80.0]]) for x, y in ((0, 0), (40, 90), (-60, 200))]
    from addon.warp import SceneBounds, compute, intersection_body
    bounds = SceneBounds.from_boxes(np.array([terrain, *houses]))
    view = camera([-60.0, -420.0, 230.0], [0.0, 0.0, 80.0], near=1.0, far=800.0)
    light = sun([0.6, 0.35, -0.45])
    body = intersection_body(view, light, bounds)
    options = WarpOptions(shadow_map_size=(1024, 1024))
    setup = compute("plane_optimal", view, light, bounds, options, body=body)
    uniform = compute("uniform", view, light, bounds, options, body=body)
    assert [m.role for m in setup.maps] == ["fallback"]
    assert setup.maps[0].size == uniform.maps[0].size and np.array_equal(setup.maps[0].matrix, uniform.maps[0].matrix)
    (what, why), = setup.diagnostics.fallbacks
    assert what == "planes"
    assert "receiver box 0, is 11%" in why and "uniform map" in why and "give planes" in why
