"""lispsm, gmnpr, glpr: the shared warp frustum on its specific claims and on hard cases.

Every case checks: finite matrices and diagnostics (strict JSON), B contained
(every vertex inside its serving map, w > 0), the projection comes from the light
(two points on one light ray land on one texel, depth grows away from the light).
"""
import json
import math

import numpy as np
import pytest
from hypothesis import assume, given, settings, strategies as st

from addon.cli.output import setup_json
from addon.warp import Light, SceneBounds, View, WarpOptions, compute, intersection_body
from addon.warp.geometry import look_along, transform_h
from addon.warp.fit import window_matrix
from addon.warp.frame import light_frames
from addon.warp.methods.warp_frustum import (eye_depth_range, frame_warps, half_fov_towards, light_at_eye, ray_closed,
                                             rule_lispsm)
from addon.warp.types import Diagnostics

from hard_cases import HARD_CASES

WARPS = ("lispsm", "gmnpr", "glpr")
GROUND = [[-50.0, -50.0, -0.1], [50.0, 50.0, 0.0]]
PILLARS = [[[x, y, 0.0], [x + 1.0, y + 1.0, 3.0]] for x in (-12.0, 0.0, 12.0) for y in (5.0, 20.0, 35.0)]
SCENE = SceneBounds.from_boxes([GROUND] + PILLARS)


def camera(eye, forward, up=(0.0, 0.0, 1.0), fov_deg=60.0, near=0.1, far=70.0, aspect=16 / 9, res=(1280, 720)):
    c2w = np.linalg.inv(look_along(np.asarray(eye, float), np.asarray(forward, float), np.asarray(up, float)))
    return View.perspective(c2w, math.radians(fov_deg), aspect, near, far, res)


def sun(direction):
    return Light("SUN", direction=np.asarray(direction, float))


def rotation(axis, angle):
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * k @ k


def ndc(matrix, points):
    h = transform_h(matrix, points)
    return h[:, :3] / h[:, 3:4], h[:, 3]


def check(setup, view, light, body):
    """The invariants every warp setup must satisfy."""
    for m in setup.maps:
        assert np.all(np.isfinite(m.matrix))
        assert m.depth_test == "LESS"
        if m.depth_row is not None:
            assert np.all(np.isfinite(m.depth_row))
    json.dumps(setup_json(setup), allow_nan=False)
    pts = body.vertices
    if not light.is_directional:
        # B = hull(R ∪ light) has the light as a vertex when it is inside; the light's own
        # frames cannot hold points nearer than 1e-6 of the scene scale (frame.perspective_frame)
        pts = pts[np.linalg.norm(pts - light.position, axis=1) > 1e-5 * body.scale]
    idx = setup.map_index(pts, tol=1e-7)
    assert np.all(idx >= 0), f"B vertices outside every map: {pts[idx < 0][:3]}"
    for i, m in enumerate(setup.maps):
        sel = idx == i
        if sel.any():
            _, w = ndc(m.matrix, pts[sel])
            assert np.all(w > 0)
    # the projection comes from the light: points on one light ray share x, y; depth grows along the ray
    rng = np.random.default_rng(0)
    wts = rng.dirichlet(np.ones(len(pts)), 40)
    inner = wts @ pts
    step = 1e-3 * body.scale
    if light.is_directional:
        further = inner + step * light.direction
    else:
        d = inner - light.position
        further = inner + step * d / np.linalg.norm(d, axis=1, keepdims=True)
    for i, m in enumerate(setup.maps):
        sel = setup.map_index(inner, tol=1e-7) == i
        if not sel.any():
            continue
        a, wa = ndc(m.matrix, inner[sel])
        b, wb = ndc(m.matrix, further[sel])
        assert np.all(wa > 0) and np.all(wb > 0)
        assert np.allclose(a[:, :2], b[:, :2], atol=1e-7), "a light ray does not land on one texel"
        assert np.all(b[:, 2] > a[:, 2]), "depth does not grow away from the light"
        if m.depth_row is not None:
            za = np.c_[inner[sel], np.ones(sel.sum())] @ m.depth_row
            zb = np.c_[further[sel], np.ones(sel.sum())] @ m.depth_row
            assert np.all(zb > za)


PAPERS = WarpOptions(lambda_guard="off")
"""Every λ exactly as its paper gives it (no λ guard)."""


def run(method, view, light, scene=SCENE, options=None):
    body = intersection_body(view, light, scene)
    setup = compute(method, view, light, scene, options or WarpOptions(), body=body)
    check(setup, view, light, body)
    return setup, body


def assert_continuous(make, method, perturbations, pts):
    """A tiny change moves B's vertices in NDC only a little, and ten times less for
    a ten times smaller change (continuity, not a fixed threshold: a jump at a
    threshold would not shrink)."""
    s0 = make(None)
    for p in perturbations:
        big = max_ndc_change(s0, make((p, 1e-7)), pts)
        small = max_ndc_change(s0, make((p, 1e-9)), pts)
        assert big < 2e-3, (method, p, big)
        assert small < big / 10 + 1e-6, (method, p, big, small)


def max_ndc_change(s0, s1, pts):
    """Largest NDC move of the points each map of s0 serves (same maps in s1)."""
    assert [m.role for m in s0.maps] == [m.role for m in s1.maps]
    idx = s0.map_index(pts, tol=1e-7)
    out = 0.0
    for i, (a, b) in enumerate(zip(s0.maps, s1.maps)):
        if not np.any(idx == i):
            continue
        na, _ = ndc(a.matrix, pts[idx == i])
        nb, _ = ndc(b.matrix, pts[idx == i])
        out = max(out, float(np.max(np.abs(na - nb))))
    return out


HORIZONTAL = dict(eye=[0.0, -10.0, 2.0], forward=[0.0, 1.0, -0.15])


# ---------------------------------------------------------------- the construction's claims

@pytest.mark.parametrize("method", WARPS)
def test_light_exactly_parallel_to_the_view_gives_the_uniform_map(method):
    view = camera([0.0, 0.0, 30.0], [0.0, 0.0, -1.0], up=[0.0, 1.0, 0.0])
    light = sun([0.0, 0.0, -1.0])
    s, body = run(method, view, light)
    u = compute("uniform", view, light, SCENE, body=body)
    assert np.allclose(s.maps[0].matrix, u.maps[0].matrix, rtol=1e-12, atol=1e-12)
    assert any("uniform limit" in w for w, _ in s.diagnostics.fallbacks)
    assert s.diagnostics.extra["warp_strength_mu"] == 0.0


@pytest.mark.parametrize("method", WARPS)
def test_light_anti_parallel_to_the_view(method):
    view = camera([0.0, 0.0, 30.0], [0.0, 0.0, -1.0], up=[0.0, 1.0, 0.0])
    s, body = run(method, view, sun([0.0, 0.0, 1.0]))
    assert s.diagnostics.theta == pytest.approx(0.0, abs=1e-12)
    assert s.diagnostics.extra["warp_strength_mu"] == 0.0


@pytest.mark.parametrize("method", WARPS)
def test_light_perpendicular_and_axis_aligned_to_the_view(method):
    view = camera([0.0, -10.0, 2.0], [0.0, 1.0, 0.0])
    s, body = run(method, view, sun([0.0, 0.0, -1.0]))
    d = s.diagnostics
    assert d.gamma == pytest.approx(math.pi / 2)
    assert np.allclose(d.extra["v_p"], [0.0, 1.0, 0.0], atol=1e-12)
    assert d.extra["warp_strength_mu"] > 1.0          # a real perspective warp


@pytest.mark.parametrize("method", WARPS)
def test_the_warp_converges_continuously_to_uniform_as_the_light_turns_parallel(method):
    view = camera([0.0, 0.0, 30.0], [0.0, 0.0, -1.0], up=[0.0, 1.0, 0.0])
    light0 = sun([0.0, 0.0, -1.0])
    body = intersection_body(view, light0, SCENE)
    uni = compute("uniform", view, light0, SCENE, body=body)
    devs = []
    for ang in (1e-2, 1e-4, 1e-6, 1e-8):
        light = sun([math.sin(ang), 0.0, -math.cos(ang)])
        b = intersection_body(view, light, SCENE)
        s = compute(method, view, light, SCENE, body=b)
        devs.append(max_ndc_change(s, uni, body.vertices))
    assert devs == sorted(devs, reverse=True)
    assert devs[-1] < 1e-5


def test_lispsm_n_opt_is_scherzer_eq1_with_eye_depths_and_lambda_is_gmnpr_eq9():
    """z_n, Δz are eye depths of R = B ∩ V; with the receivers' box around the whole
    frustum they are the camera's near and far - the paper's ideal configuration -
    and λ = n_opt / (B's extent along V_P) is exactly GMNPR Eq. 9."""
    from addon.warp.aliasing import lambda_gmnpr
    from aliasing_model import lambda_lispsm
    big = SceneBounds.from_boxes([[[-300.0, -300.0, -300.0], [300.0, 300.0, 300.0]]])
    view = camera([0.0, 0.0, 0.0], [0.0, 1.0, 0.0], near=0.1, far=70.0)
    n, f, phi = 0.1, 70.0, math.radians(30.0)
    for gamma_deg in (90.0, 120.0, 60.0, 40.0, 20.0, 10.0):
        g = math.radians(gamma_deg)
        light = sun([0.0, math.cos(g), -math.sin(g)])   # in the camera's vertical plane
        s, body = run("lispsm", view, light, big, PAPERS)
        d = s.diagnostics
        theta = min(g, math.pi - g)
        assert d.extra["z_n"] == pytest.approx(n, rel=1e-9)
        assert d.extra["delta_z"] == pytest.approx(f - n, rel=1e-9)
        assert d.n_opt == pytest.approx((n + math.sqrt(n * f)) / math.sin(g), rel=1e-9)
        assert d.extra["lambda"] == pytest.approx(lambda_lispsm(theta, n, f, phi), rel=1e-6)
        sg, _ = run("gmnpr", view, light, big, PAPERS)
        assert sg.diagnostics.extra["phi"] == pytest.approx(phi, rel=1e-12)
        assert sg.diagnostics.lam == pytest.approx(lambda_gmnpr(theta, n, f, phi), rel=1e-9)


def test_lispsm_projection_centre_is_scherzer_eq2():
    """C_P = C_eye - (n_opt - z_n)·V_P in the ideal case (z_n replaced by B's near
    side along V_P in general, which equals z_n here)."""
    big = SceneBounds.from_boxes([[[-300.0, -300.0, -300.0], [300.0, 300.0, 300.0]]])
    view = camera([1.0, 2.0, 3.0], [0.0, 1.0, 0.0])
    s, body = run("lispsm", view, sun([0.0, 0.0, -1.0]), big)
    d = s.diagnostics
    v_p = d.extra["v_p"]
    assert np.allclose(v_p, [0.0, 1.0, 0.0], atol=1e-12)
    expected = view.position - (d.n_opt - view.near) * v_p
    assert np.allclose(d.extra["projection_centre"], expected, rtol=0, atol=1e-7 * d.n_opt)


def test_projection_centre_is_in_front_of_all_of_B_when_B_extends_behind_the_eye():
    # sun from behind the camera: B reaches back towards the light and below the eye's V_P position
    view = camera([0.0, 0.0, 1.5], [0.0, 1.0, -0.6])
    light = sun([0.0, 0.3, -1.0])
    for method in WARPS:
        s, body = run(method, view, light)
        c, v_p = s.diagnostics.extra["projection_centre"], s.diagnostics.extra["v_p"]
        assert np.all((body.vertices - c) @ v_p > 0)


def test_delta_z_from_the_visible_range_changes_n_opt_but_never_B():
    view = camera(**HORIZONTAL)
    light = sun([0.3, 0.2, -1.0])
    s_body, body = run("lispsm", view, light)
    opts = WarpOptions(delta_z="visible", visible_depth_range=(0.5, 20.0))
    s_vis, body2 = run("lispsm", view, light, options=opts)
    assert np.array_equal(s_vis.diagnostics.body_vertices, s_body.diagnostics.body_vertices)
    g = s_vis.diagnostics.gamma
    assert s_vis.diagnostics.extra["z_n"] == 0.5
    assert s_vis.diagnostics.extra["delta_z"] == pytest.approx(19.5)
    assert s_vis.diagnostics.n_opt == pytest.approx((0.5 + math.sqrt(0.5 * 20.0)) / math.sin(g))
    assert s_vis.diagnostics.n_opt != pytest.approx(s_body.diagnostics.n_opt)


def test_delta_z_visible_without_a_range_falls_back_to_B_and_says_so():
    view = camera(**HORIZONTAL)
    s, _ = run("lispsm", view, sun([0.3, 0.2, -1.0]), options=WarpOptions(delta_z="visible"))
    assert any(w == "delta_z" for w, _ in s.diagnostics.fallbacks)


def test_z_n_is_the_nearest_visible_eye_depth():
    # only a far box is visible: z_n is its nearest eye depth, not the camera's near plane
    scene = SceneBounds.from_boxes([[[-5.0, 30.0, -1.0], [5.0, 40.0, 1.0]]])
    view = camera([0.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    s, _ = run("lispsm", view, sun([0.0, 0.0, -1.0]), scene)
    assert s.diagnostics.extra["z_n"] == pytest.approx(30.0, rel=1e-6)
    assert s.diagnostics.extra["delta_z"] == pytest.approx(10.0, rel=1e-5)


@pytest.mark.parametrize("method", WARPS)
def test_middle_vector_option_sets_V_P_towards_the_middle_of_B(method):
    view = camera(**HORIZONTAL)
    light = sun([0.4, 0.3, -0.6])
    s, body = run(method, view, light, options=WarpOptions(middle_vector=True))
    mv = body.volume_centroid - view.position
    ell = light.direction
    expected = mv - (mv @ ell) * ell
    expected /= np.linalg.norm(expected)
    assert np.allclose(s.diagnostics.extra["v_p"], expected, atol=1e-9)
    plain, _ = run(method, view, light)
    assert not np.allclose(plain.diagnostics.extra["v_p"], expected, atol=1e-3)


@pytest.mark.parametrize("method", WARPS)
def test_linear_z_depth_row_spans_B(method):
    for light in (sun([0.4, 0.3, -0.6]), Light("POINT", position=np.array([3.0, 10.0, 15.0]))):
        view = camera(**HORIZONTAL)
        s, body = run(method, view, light, options=WarpOptions(linear_z=True))
        for i, m in enumerate(s.maps):
            assert m.depth_row is not None
            z = np.c_[body.vertices, np.ones(len(body.vertices))] @ m.depth_row
            if len(s.maps) == 1:
                assert z.min() == pytest.approx(-1.0, abs=1e-5)
                assert z.max() == pytest.approx(1.0, abs=1e-5)


def test_warp_frustum_corners_are_the_clip_volume_of_the_map():
    view = camera(**HORIZONTAL)
    s, body = run("lispsm", view, sun([0.4, 0.3, -0.6]))
    c = s.diagnostics.warp_frustum_corners
    assert c.shape == (8, 3) and np.all(np.isfinite(c))
    got, _ = ndc(s.maps[0].matrix, c)
    from addon.warp.geometry import UNIT_CUBE_CORNERS
    assert np.allclose(got, UNIT_CUBE_CORNERS, atol=1e-6)


def test_orthographic_camera_gets_the_uniform_map_and_says_why():
    from addon.warp.geometry import ortho_matrix
    c2w = np.linalg.inv(look_along(np.array([0.0, -10.0, 5.0]), np.array([0.0, 1.0, -0.5]), np.array([0, 0, 1.0])))
    view = View(c2w, ortho_matrix(-8, 8, -4.5, 4.5, 0.1, 70.0), 0.1, 70.0, (1280, 720), orthographic=True)
    light = sun([0.4, 0.3, -0.6])
    for method in WARPS:
        s, body = run(method, view, light)
        u = compute("uniform", view, light, SCENE, body=body)
        assert np.allclose(s.maps[0].matrix, u.maps[0].matrix)
        assert any("orthographic" in r for _, r in s.diagnostics.fallbacks)


# ---------------------------------------------------------------- continuity

@pytest.mark.parametrize("method", WARPS)
@pytest.mark.parametrize("gamma_deg", [0.0, 1.0, 30.0, 60.0, 90.0, 150.0, 179.0])
def test_tiny_camera_and_light_rotations_change_the_map_only_a_little(method, gamma_deg):
    view = camera([0.0, -10.0, 2.0], [0.0, 1.0, 0.0])
    g = math.radians(gamma_deg)
    base = np.array([0.0, math.cos(g), -math.sin(g)])
    body = intersection_body(view, sun(base), SCENE)
    axes = ([1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.3, 0.5, 0.8])

    def light_turned(p):
        return run(method, view, sun(base if p is None else rotation(p[0], p[1]) @ base))[0]

    def camera_turned(p):
        if p is None:
            return run(method, view, sun(base))[0]
        c2w = view.camera_to_world.copy()
        c2w[:3, :3] = rotation(p[0], p[1]) @ c2w[:3, :3]
        return run(method, View(c2w, view.projection, view.near, view.far, view.resolution), sun(base))[0]

    assert_continuous(light_turned, method, axes, body.vertices)
    assert_continuous(camera_turned, method, axes, body.vertices)


@pytest.mark.parametrize("method", WARPS)
def test_theta_equal_to_phi_exactly_and_at_plus_minus_1e_9(method):
    view = camera([0.0, -10.0, 2.0], [0.0, 1.0, 0.0])
    phi = half_fov_towards(view, np.array([0.0, 0.0, -1.0]))
    assert phi == pytest.approx(math.radians(30.0), rel=1e-12)
    setups = []
    for eps in (-1e-9, 0.0, 1e-9):
        g = phi + eps
        s, body = run(method, view, sun([0.0, math.cos(g), -math.sin(g)]))
        setups.append(s)
    lams = [s.diagnostics.lam if s.diagnostics.lam is not None else s.diagnostics.extra["lambda"] for s in setups]
    assert all(lam > 0 for lam in lams)
    assert lams[0] == pytest.approx(lams[1], rel=1e-6) and lams[2] == pytest.approx(lams[1], rel=1e-6)
    for s in (setups[0], setups[2]):
        assert max_ndc_change(setups[1], s, body.vertices) < 1e-5


def test_gmnpr_lambda_at_theta_phi_is_sqrt_fn_over_2f():
    view = camera([0.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    big = SceneBounds.from_boxes([[[-300.0, -300.0, -300.0], [300.0, 300.0, 300.0]]])
    g = math.radians(30.0)
    s, _ = run("gmnpr", view, sun([0.0, math.cos(g), -math.sin(g)]), big)
    assert s.diagnostics.lam == pytest.approx(math.sqrt(0.1 * 70.0) / (2 * 70.0), rel=1e-6)


@settings(max_examples=25, derandomize=True, deadline=None)
@given(yaw=st.floats(-math.pi, math.pi), pitch=st.floats(-1.4, 0.3), lat=st.floats(-1.55, -0.02),
       lon=st.floats(-math.pi, math.pi), method=st.sampled_from(WARPS), mid=st.booleans())
def test_generated_sun_configurations(yaw, pitch, lat, lon, method, mid):
    fwd = [math.cos(pitch) * math.sin(yaw), math.cos(pitch) * math.cos(yaw), math.sin(pitch)]
    view = camera([1.0, -3.0, 2.0], fwd)
    d = [math.cos(lat) * math.cos(lon), math.cos(lat) * math.sin(lon), math.sin(lat)]
    s, body = run(method, view, sun(d), options=WarpOptions(middle_vector=mid))
    c0 = body.volume_centroid
    for eps in (1e-7, 1e-9):
        b1 = intersection_body(view, sun(rotation([0.2, 0.9, 0.1], eps) @ np.array(d)), SCENE)
        # B itself jumps when a caster box starts to touch hull(R ∪ light) (S_c grows by a whole
        # box): the warp cannot be continuous across that and it is not the warp's doing
        assume(np.linalg.norm(b1.volume_centroid - c0) < 1e-4 * body.scale)

    def turned(p):
        light = sun(d if p is None else rotation(p[0], p[1]) @ np.array(d))
        return run(method, view, light, options=WarpOptions(middle_vector=mid))[0]

    assert_continuous(turned, method, ([0.2, 0.9, 0.1],), body.vertices)


# ---------------------------------------------------------------- hard cases

@pytest.mark.parametrize("method", WARPS)
def test_light_behind_the_camera(method):
    view = camera([0.0, -10.0, 2.0], [0.0, 1.0, -0.2])
    s, body = run(method, view, sun([0.1, 0.8, -0.3]))
    assert s.diagnostics.gamma < math.pi / 2


@pytest.mark.parametrize("method", WARPS)
def test_sun_one_degree_above_the_horizon(method):
    view = camera(**HORIZONTAL)
    e = math.radians(1.0)
    for az in (0.0, 1.0, 2.5):
        run(method, view, sun([math.cos(e) * math.sin(az), math.cos(e) * math.cos(az), -math.sin(e)]))


@pytest.mark.parametrize("method", WARPS)
@pytest.mark.parametrize("near,far", [(1e-3, 1e2), (0.1, 1e4)])
def test_extreme_near_far_ratios(method, near, far):
    big = SceneBounds.from_boxes([[[-2e4, -2e4, -1.0], [2e4, 2e4, 0.0]], [[2.0, 5.0, 0.0], [3.0, 6.0, 2.0]]])
    view = camera([0.0, 0.0, 1.7], [0.0, 1.0, -0.1], near=near, far=far)
    for d in ([0.3, 0.2, -1.0], [0.0, 0.0, -1.0], [0.0, 0.99, -0.1]):
        s, _ = run(method, view, sun(d), big)
        assert s.diagnostics.extra["z_n"] >= near


@pytest.mark.parametrize("method", WARPS)
def test_whole_scene_offset_by_1e5(method):
    off = np.array([1e5, -1e5, 1e5])
    scene = SceneBounds.from_boxes([np.asarray(b) + off for b in [GROUND] + PILLARS])
    view0 = camera(**HORIZONTAL)
    view = camera(np.array(HORIZONTAL["eye"]) + off, HORIZONTAL["forward"])
    light = sun([0.4, 0.3, -0.6])
    s, body = run(method, view, light, scene)
    s0, body0 = run(method, view0, light)
    # the same configuration translated: the same map up to translation
    a, _ = ndc(s.maps[0].matrix, body0.vertices + off)
    b, _ = ndc(s0.maps[0].matrix, body0.vertices)
    assert np.max(np.abs(a - b)) < 1e-6


@pytest.mark.parametrize("method", WARPS)
def test_flat_scene(method):
    flat = SceneBounds.from_boxes([[[-50.0, -50.0, 0.0], [50.0, 50.0, 0.0]]])
    view = camera(**HORIZONTAL)
    for d in ([0.4, 0.3, -0.6], [0.0, 0.0, -1.0], [0.0, 1.0, -0.05]):
        run(method, view, sun(d), flat)


@pytest.mark.parametrize("method", WARPS)
def test_camera_inside_the_scene_box(method):
    room = SceneBounds.from_boxes([[[-5.0, -5.0, 0.0], [5.0, 5.0, 3.0]], [[-1.0, 1.0, 0.0], [0.0, 2.0, 1.0]]])
    view = camera([0.5, -3.0, 1.5], [0.1, 1.0, -0.2], far=20.0)
    for d in ([0.4, 0.3, -0.6], [0.0, -1.0, -0.2]):
        run(method, view, sun(d), room)
    run(method, view, Light("POINT", position=np.array([0.0, 0.0, 2.8])), room)


@pytest.mark.parametrize("method", WARPS)
def test_camera_one_centimetre_above_the_ground(method):
    view = camera([0.0, 0.0, 0.01], [0.0, 1.0, -0.05])
    for d in ([0.4, 0.3, -0.6], [0.0, 0.0, -1.0], [0.0, -1.0, -0.3]):
        run(method, view, sun(d))


@pytest.mark.parametrize("method", WARPS)
def test_point_light_in_the_camera_plane(method):
    view = camera([0.0, -10.0, 2.0], [0.0, 1.0, 0.0])
    s, _ = run(method, view, Light("POINT", position=np.array([0.0, -10.0, 12.0])))
    assert s.maps


@pytest.mark.parametrize("method", WARPS)
def test_point_light_behind_the_camera(method):
    view = camera([0.0, -10.0, 2.0], [0.0, 1.0, -0.1])
    s, _ = run(method, view, Light("POINT", position=np.array([1.0, -20.0, 8.0])))
    assert s.maps


@pytest.mark.parametrize("method", WARPS)
def test_point_light_inside_the_view(method):
    view = camera([0.0, -10.0, 2.0], [0.0, 1.0, -0.1])
    s, _ = run(method, view, Light("POINT", position=np.array([0.0, 10.0, 2.0])))
    assert len(s.maps) >= 2                # several cube faces
    # frames that cannot be warped are uniform and say so
    roles = {m.role for m in s.maps}
    for what, _ in s.diagnostics.fallbacks:
        assert what.split(":")[0] in roles


@pytest.mark.parametrize("method", WARPS)
def test_point_light_at_the_eye_falls_back_to_uniform(method):
    view = camera([0.0, -10.0, 2.0], [0.0, 1.0, -0.1])
    s, _ = run(method, view, Light("POINT", position=view.position.copy()))
    assert any("at the light" in r for _, r in s.diagnostics.fallbacks)


@pytest.mark.parametrize("method", WARPS)
def test_spot_cone_that_barely_contains_the_view(method):
    view = camera([0.0, -10.0, 2.0], [0.0, 1.0, -0.15])
    tx, ty = 1 / view.projection[0, 0], 1 / view.projection[1, 1]
    half = math.atan(math.hypot(tx, ty))
    spot = Light("SPOT", position=view.position - 0.01 * view.direction, direction=view.direction,
                 spot_angle=2 * half + math.radians(0.5))
    s, body = run(method, view, spot)
    # the view's every visible point is served
    assert np.all(s.map_index(body.visible_vertices, view, tol=1e-7) >= 0)


@pytest.mark.parametrize("method", WARPS)
@pytest.mark.parametrize("y", [-10.5, -10.0, -9.97, -9.5])
def test_point_light_near_the_eye_plane_changes_the_map_continuously(method, y):
    """Frames whose light plane passes near the eye fade to uniform instead of jumping."""
    view = camera([0.0, -10.0, 2.0], [0.0, 1.0, -0.1])
    pos = np.array([0.0, y, 12.0])
    body = intersection_body(view, Light("POINT", position=pos), SCENE)

    def moved(p):
        shift = np.zeros(3) if p is None else 10.0 * p[1] * np.asarray(p[0])
        return run(method, view, Light("POINT", position=pos + shift))[0]

    assert_continuous(moved, method, ([0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.6, 0.8]), body.vertices)


# ----------------------------------------------------------------------------- GLPR's guard

def _glpr_inputs(setup):
    d = setup.diagnostics
    z_n, z_f = d.extra["z_n"], d.extra["z_n"] + d.extra["delta_z"]
    return d.theta, z_n, z_f, d.extra["phi"]


def test_glprs_guard_acts_reports_and_keeps_the_warp_no_stronger_than_it():
    """A view over far-reaching ground: GLPR's own λ (F ~ z) over-warps; the
    guard raises it (a fallback note says from what to what and why) to at
    least the λ at which the worst aliasing matches the uniform map's."""
    from addon.warp import aliasing as al
    view = camera([0.0, -10.0, 6.0], [0.0, 1.0, -0.25])
    light = sun([0.3, 0.5, -0.6])
    guarded = compute("glpr", view, light, SCENE, WarpOptions(shadow_map_size=1024))
    raw = compute("glpr", view, light, SCENE, WarpOptions(shadow_map_size=1024, lambda_guard="off"))
    theta, z_n, z_f, phi = _glpr_inputs(raw)
    assert raw.diagnostics.lam == pytest.approx(al.lambda_glpr(theta, z_n, z_f, phi))
    assert not any("λ guard" in what for what, _ in raw.diagnostics.fallbacks)
    notes = [why for what, why in guarded.diagnostics.fallbacks if what == "main: λ guard"]
    assert len(notes) == 1 and "λ raised from" in notes[0]
    lam = guarded.diagnostics.lam if guarded.diagnostics.lam is not None else math.inf
    assert lam >= al.lambda_no_worse_than_uniform(theta, z_n, z_f, phi) * (1 - 1e-12)
    assert lam > raw.diagnostics.lam


def test_a_forced_lambda_is_not_guarded():
    view = camera([0.0, -10.0, 6.0], [0.0, 1.0, -0.25])
    setup = compute("glpr", view, sun([0.3, 0.5, -0.6]), SCENE, WarpOptions(shadow_map_size=1024, lam=1e-4))
    assert setup.diagnostics.lam == pytest.approx(1e-4)
    assert not any("λ guard" in what for what, _ in setup.diagnostics.fallbacks)


@pytest.mark.parametrize("method", WARPS)
def test_where_warps_lose_on_average_the_guarded_warp_is_nearly_the_uniform_map(method):
    """Looking across a floor at a wall (most pixels far along V_P): no strong
    warp's texels are smaller there, so the guard leaves (nearly, or exactly:
    λ = ∞) the uniform map, where the warp's own λ would warp hard."""
    view = camera([0.0, -3.0, 1.5], [0.0, 1.0, -0.05], near=0.1, far=30.0)
    wall = [[-20.0, 4.0, 0.0], [20.0, 4.5, 12.0]]
    scene = SceneBounds.from_boxes([GROUND, wall])
    light = sun([0.2, 0.6, -0.7])
    guarded = compute(method, view, light, scene, WarpOptions(shadow_map_size=1024))
    raw = compute(method, view, light, scene, WarpOptions(shadow_map_size=1024, lambda_guard="off"))

    def lam(setup):
        d = setup.diagnostics
        value = d.extra["lambda"] if method == "lispsm" else d.lam
        return math.inf if value is None else value
    assert lam(raw) < 1.5
    assert lam(guarded) > 10.0 and guarded.diagnostics.extra["warp_strength_mu"] < 0.1
    assert any(what == "main: λ guard" for what, _ in guarded.diagnostics.fallbacks)
    assert not any("uniform limit" in what for what, _ in guarded.diagnostics.fallbacks)


def test_the_guard_can_be_kept_to_glpr():
    """lambda_guard="glpr": GMNPR's and LiSPSM's λ are their papers' (Eq. 8, Eq. 1) again."""
    from addon.warp import aliasing as al
    view = camera([0.0, -3.0, 1.5], [0.0, 1.0, -0.05], near=0.1, far=30.0)
    scene = SceneBounds.from_boxes([GROUND, [[-20.0, 4.0, 0.0], [20.0, 4.5, 12.0]]])
    light = sun([0.2, 0.6, -0.7])
    options = WarpOptions(shadow_map_size=1024, lambda_guard="glpr")
    g = compute("gmnpr", view, light, scene, options).diagnostics
    z_n, z_f = g.extra["z_n"], g.extra["z_n"] + g.extra["delta_z"]
    assert g.lam == pytest.approx(al.lambda_gmnpr(g.theta, z_n, z_f, g.extra["phi"]))
    assert not any("λ guard" in what for what, _ in g.fallbacks)
    glpr = compute("glpr", view, light, scene, options).diagnostics
    assert any(what == "main: λ guard" for what, _ in glpr.fallbacks)


def _maps_before_closure(view, light, scene, options):
    """A point light's warped cube-face maps as ``warped_setup`` hands them to ``ray_closed``."""
    body = intersection_body(view, light, scene)
    frames = light_frames(view, light, body, options)
    if len(frames) < 2:
        return body, []
    ctx = eye_depth_range(view, body, options, Diagnostics("lispsm"))
    at, reason = light_at_eye(view, light, options, body, body.volume_centroid - view.position)
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
def test_a_ray_closed_map_holds_b_within_its_window(name):
    """A warped cube-face map's window reaches past its face: ray closure
    widens its depth to hold all of B ∩ window (the window's sides as
    half-spaces through the light, clipped from B here)."""
    view, light, scene = _case(name)
    body, matrices = _maps_before_closure(view, light, scene, WarpOptions())
    assert len(matrices) >= 2, f"{name} no longer gives several warped maps: choose another case"
    poly = body.polytope_from(light.position)
    compared = 0
    for m, (closed, note, held) in zip(matrices, ray_closed(matrices, body, light.position)):
        # The window |x| <= w, |y| <= w as half-spaces through the light.
        sides = np.array([m[0] - m[3], -m[0] - m[3], m[1] - m[3], -m[1] - m[3]])[:, :3]
        part = poly.clip(sides / np.linalg.norm(sides, axis=1)[:, None], np.zeros(4))
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


@pytest.mark.parametrize("method", ["lispsm", "gmnpr", "glpr", "psm"])
def test_where_shadow_edges_fall_only_far_away_the_guard_warps_less(method):
    """The λ guard's screen bound is weighed by where shadow edges fall on what is seen, where that is known
    (``TileDepths.edges``): the wrong pixels lie along them. Edges only in the farthest tiles keep the map nearer
    the uniform one than the visible pixels alone would (a weaker warp: a larger λ); edges spread as the pixels
    are give the same map."""
    import dataclasses
    from addon.warp.visibility import region_from_boxes
    view = camera([0.0, -30.0, 6.0], [0.0, 1.0, -0.2], near=0.1, far=80.0)
    scene = SceneBounds.from_boxes([[[-60.0, -60.0, -0.1], [60.0, 60.0, 0.0]], [[-3.0, 10.0, 0.0], [3.0, 12.0, 5.0]]])
    light = sun([0.9, 0.1, -0.5])
    region = region_from_boxes(view, scene)
    t = region.tiles
    far = np.where(t.seen & (t.far >= np.quantile(t.far[t.seen], 0.9)), t.samples, 0)

    def strength(tiles):
        setup = compute(method, view, light, scene, WarpOptions(shadow_map_size=1024),
                        visible=dataclasses.replace(region, tiles=tiles))
        return setup.maps[0].matrix, setup.diagnostics
    plain, _ = strength(t)
    spread, _ = strength(dataclasses.replace(t, edges=t.samples))
    np.testing.assert_allclose(spread, plain, rtol=1e-9, atol=1e-12)
    edged, diag = strength(dataclasses.replace(t, edges=far))
    assert any("shadow edges" in why for what, why in diag.fallbacks if "λ guard" in what)
    body = intersection_body(view, light, scene, region)
    assert warp_lambda(edged, view, light, body) > warp_lambda(plain, view, light, body) * 1.1


def warp_lambda(matrix, view, light, body):
    """λ = (h_min - h_0)/D read from the map (``map_lambda``), in its sun frame (∞: unwarped)."""
    from addon.warp.methods.warp_frustum import map_lambda
    return map_lambda(matrix, light_frames(view, light, body, WarpOptions())[0])[1]
