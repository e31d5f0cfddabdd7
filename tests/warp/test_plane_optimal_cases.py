"""plane_optimal hard cases (Chong & Gortler §2 Fig. 5, §3), each a named test.

Every case checks: the plane map (if the plane can have one) is exactly the
identity from screen pixels to texels on the plane, up to a whole-texel shift
(every pixel centre a lixel centre); every point of B is served
by some map and lies in its clip volume (w > 0, NDC in [-1, 1]); a plane that
cannot have a map is left out with a recorded reason and the fallback serves it.
"""
import math

import numpy as np
import pytest

from addon.warp import SceneBounds, WarpOptions, compute
from hard_cases import HARD_CASES
from plane_optimal_helpers import (FLOOR_PLANE, ray_plane_points, assert_pixel_centres_are_lixel_centres, body_samples, check_coverage, camera, camera_yaw_pitch, homography_jacobian, ndc,
                                   pixel_to_texel_homography, plane_maps, point, region_pixels, run, scene, sun,
                                   sun_at)


def check_exact(view, setup):
    maps = plane_maps(setup)
    assert maps, setup.diagnostics.fallbacks
    for idx, m in maps:
        g = pixel_to_texel_homography(view, m, m.region.normal, m.region.normal * m.region.offset)
        pts, px = region_pixels(view, m, count=300)
        j = homography_jacobian(g, px)
        assert np.max(np.abs(j - np.eye(2)[None])) <= 1e-9
        assert np.all(setup.map_index(pts, view) == idx)
        d, w = ndc(m.matrix, pts)
        assert np.all(w > 0) and np.all(np.abs(d) <= 1)
    assert_pixel_centres_are_lixel_centres(view, setup)


def check_covers_b(view, setup, body):
    """Every visible point served, casters and B's points on its shadow ray in its map; the fallback last."""
    light, sc = setup.inputs
    check_coverage(view, light, sc, setup, body)
    assert setup.maps[-1].role.startswith("fallback")


def fallback_reasons(setup):
    return " | ".join(f"{w}: {r}" for w, r in setup.diagnostics.fallbacks)


def test_light_perpendicular_to_the_plane_sun_straight_overhead():
    view = camera_yaw_pitch([0, -15, 5], 0, -20)
    setup, body = run(view, sun([0, 0, -1.0]))
    check_exact(view, setup)
    check_covers_b(view, setup, body)
    assert not setup.diagnostics.fallbacks


def test_light_behind_the_camera():
    view = camera_yaw_pitch([0, -15, 5], 0, -20)
    light = sun([0.0, math.cos(math.radians(20)), -math.sin(math.radians(20))])   # along the view direction
    assert light.direction @ view.direction > 0.99
    setup, body = run(view, light)
    check_exact(view, setup)
    check_covers_b(view, setup, body)


def test_sun_on_the_horizon():
    view = camera_yaw_pitch([0, -15, 5], 0, -20)
    setup, body = run(view, sun([1.0, 0.3, 0.0]))
    assert [m.role for m in setup.maps] == ["fallback"]
    assert "plane:0" in fallback_reasons(setup) and "grazes" in fallback_reasons(setup)
    check_covers_b(view, setup, body)
    # just above the horizon the plane map exists and is exact
    setup, body = run(view, sun_at(0.5, 70))
    check_exact(view, setup)
    check_covers_b(view, setup, body)


def test_camera_one_centimetre_above_the_plane():
    view = camera_yaw_pitch([0, -15, 0.01], 0, -5)
    setup, body = run(view, sun_at(30, 150))
    check_exact(view, setup)
    check_covers_b(view, setup, body)
    info = setup.diagnostics.extra["planes"][0]
    assert info["residual"] < 1e-12 and info["condition"] > 1e-8


def test_plane_seen_edge_on():
    view = camera_yaw_pitch([0, -15, 0.0], 0, 5)          # the camera in the floor's plane
    setup, body = run(view, sun_at(40, 150))
    assert [m.role for m in setup.maps] == ["fallback"]
    assert "edge-on" in fallback_reasons(setup)
    check_covers_b(view, setup, body)


def test_plane_behind_the_camera():
    view = camera_yaw_pitch([0, -15, 3], 0, -10)
    behind = ((0.0, -30.0, 0.0), (0.0, 1.0, 0.0))         # a wall 15 m behind the camera
    setup, body = run(view, sun_at(40, 150), planes=(behind, FLOOR_PLANE))
    assert [m.role for m in setup.maps] == ["plane:1", "fallback"]
    assert "plane:0" in fallback_reasons(setup) and "no visible part" in fallback_reasons(setup)
    check_exact(view, setup)
    check_covers_b(view, setup, body)


def test_vanishing_line_inside_the_view():
    view = camera_yaw_pitch([0, -20, 1.7], 0, 0)            # horizontal camera: the horizon mid-screen
    pi = np.array([0, 0, 1.0, 0])
    corners = ray_plane_points(view.world_to_clip, pi, [(-1, -1), (-1, 1), (1, 1), (1, -1)])
    depth = corners @ view.world_to_clip[3]
    assert (depth * np.sign(corners[:, 3]) < 0).any() and (depth * np.sign(corners[:, 3]) > 0).any()  # Q straddles infinity
    for light in (sun_at(25, 200), point([3, 0, 6])):
        setup, body = run(view, light)
        check_exact(view, setup)
        check_covers_b(view, setup, body)
        m = setup.maps[0]
        # the region stops at the far plane, well below the horizon (screen-space half height)
        _, px = region_pixels(view, m)
        assert px[:, 1].max() <= view.resolution[1] / 2 + 1e-6


def test_point_light_on_the_plane():
    view = camera_yaw_pitch([0, -15, 5], 0, -20)
    light = point([0.0, 5.0, 0.0])
    setup, body = run(view, light)
    assert all(m.role.startswith("fallback") for m in setup.maps)
    assert "plane:0" in fallback_reasons(setup) and "lies in" in fallback_reasons(setup)
    # with no plane map the fallback is exactly the uniform method's maps over B, with the whole budget
    uni = compute("uniform", view, light, scene(), WarpOptions(shadow_map_size=(2048, 2048)), body=body)
    assert len(uni.maps) == len(setup.maps)
    for a, b in zip(uni.maps, setup.maps):
        assert np.array_equal(a.matrix, b.matrix) and a.size == b.size
    # every visible point is served. (Shadow rays along the floor graze the floor box: the judge
    # counts them as crossing it, and the uniform cube maps leave those grazing "casters" out.)
    from addon.measure.box_scene import judge
    verdict = judge(view, light, scene(), setup, (160, 90))
    assert verdict.uncovered == 0


def test_miners_lamp_point_light_at_the_camera():
    view = camera_yaw_pitch([0, -15, 5], 0, -20)
    setup, body = run(view, point(view.position))
    check_exact(view, setup)
    check_covers_b(view, setup, body)
    # Fig. 4: the light image is the viewer image for every point, not only the plane's
    m = setup.maps[0]
    rng = np.random.default_rng(2)
    pts = body_samples(body)
    pts = pts[view.eye_depth(pts) > view.near]
    lc = np.column_stack([pts, np.ones(len(pts))]) @ m.matrix.T
    vc = np.column_stack([pts, np.ones(len(pts))]) @ view.world_to_clip.T
    texel = (lc[:, :2] / lc[:, 3:4] + 1) / 2 * np.array(m.size)
    pixel = (vc[:, :2] / vc[:, 3:4] + 1) / 2 * np.array(view.resolution)
    shift = texel - pixel
    assert np.allclose(shift, np.round(shift[0]), atol=1e-7)
    del rng


@pytest.mark.parametrize("pitch", [-89.0, -45.0, 3.0])
def test_spot_light_cone_limits_the_region(pitch):
    from addon.warp import Light
    view = camera_yaw_pitch([0, -10, 6], 0, pitch)
    spot = Light("SPOT", position=np.array([0.0, 0.0, 8.0]), direction=np.array([0, 0, -1.0]),
                 spot_angle=math.radians(40))
    try:
        setup, body = run(view, spot)
    except Exception as exc:  # nothing lit in view
        assert "spot cone" in str(exc)
        return
    maps = plane_maps(setup)
    if maps:
        check_exact(view, setup)
        r = maps[0][1].region.polygon
        radius = 8.0 * math.tan(math.radians(20)) / math.cos(math.pi / 16) ** 2 + 1e-6   # the 16-sided pyramid around the cone
        assert np.all(np.linalg.norm(r[:, :2], axis=1) <= radius * 1.01)
    check_covers_b(view, setup, body)


def test_orthographic_camera():
    from addon.warp import View
    from addon.warp.geometry import ortho_matrix
    base = camera_yaw_pitch([0, -15, 8], 0, -35)
    view = View(base.camera_to_world, ortho_matrix(-8, 8, -4.5, 4.5, 0.1, 60), 0.1, 60, (640, 360), True)
    setup, body = run(view, sun_at(35, 120))
    check_exact(view, setup)
    check_covers_b(view, setup, body)


@pytest.mark.parametrize("lamp", ["single frame", "cube faces"])
def test_fallback_maps_note_the_uniform_near_plane_prefixed(lamp):
    """A point light in a lampshade box (a box reaches nearer to it than the near plane): the fallback maps record
    the uniform method's near-plane notes, named by their frames behind ``fallback:`` (one note for one concept)."""
    if lamp == "single frame":
        view, light = camera((12.0, 0.0, 3.0), (0.0, 0.0, 0.0)), point((0.0, 0.0, 30.0))
        ground, block = [[-10, -10, -0.1], [10, 10, 0.0]], [[-1, -1, 0], [1, 1, 2]]
        sc = SceneBounds(np.array([ground, block, [[-0.5, -0.5, 29.5], [0.5, 0.5, 30.5]]]), np.array([ground, block]))
    else:
        view, light, sc = HARD_CASES["camera_inside_scene_box_point"]
    opts = WarpOptions(shadow_map_size=(1024, 1024))
    uniform, plane = compute("uniform", view, light, sc, opts), compute("plane_optimal", view, light, sc, opts)
    assert ([m.role for m in uniform.maps] == ["main"]) == (lamp == "single frame")
    wanted = {f"fallback:{what}": why for what, why in uniform.diagnostics.fallbacks}
    assert wanted and {what: why for what, why in plane.diagnostics.fallbacks if what.startswith("fallback:")} == wanted
