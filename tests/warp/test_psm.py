"""The psm method (Stamminger & Drettakis 2002): coverage of B, one light ray ->
one texel, depth order for normal / inverted / directional PPS lights, the
awkward configurations (near 1e-3, far 1e4, 1e5 offsets, flat scenes, a camera
1 cm above the ground), continuity through the camera-plane switch, and the
fallbacks (light inside B, orthographic camera)."""
import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from addon.cli.config import parse_config
from addon.warp import Light, SceneBounds, View, WarpOptions, compute, focused_body, intersection_body
from addon.warp.diagnostics import Diagnostics
from addon.warp.frame import light_frames
from addon.warp.geometry import look_along
from addon.warp.methods.psm import GUARD_TOLERANCE, psm
from addon.warp.methods.warp_frustum import eye_depth_range, guard_lambda, half_fov_towards, light_at_eye, map_lambda
from addon.warp.post_perspective import min_norm_point, pps_light_matrix, smallest_cone, virtual_camera

SIZE = 2048
TEXEL_TOL = 1e-3
"""Allowed x/y difference (in texels) between points on one light ray."""


# ----------------------------------------------------------------------------- scenes

def camera(pos, target, *, fov=60.0, near=0.1, far=100.0, up=(0.0, 0.0, 1.0), res=(1280, 720)):
    pos = np.asarray(pos, dtype=float)
    c2w = np.linalg.inv(look_along(pos, np.asarray(target, dtype=float) - pos, up))
    return View.perspective(c2w, math.radians(fov), res[0] / res[1], near, far, res)


def town(offset=(0.0, 0.0, 0.0), flat=False):
    """A 100 m ground slab and a grid of 3 m boxes (or flat tiles)."""
    o = np.asarray(offset, dtype=float)
    boxes = [[[-50, -50, -0.1], [50, 50, 0.0]]]
    top = 0.0 if flat else 3.0
    for x in range(-20, 21, 8):
        for y in range(-5, 36, 8):
            boxes.append([[x, y, 0.0], [x + 1, y + 1, top]])
    return SceneBounds.from_boxes(np.asarray(boxes, dtype=float) + o)


def sun(direction):
    return Light("SUN", direction=np.asarray(direction, dtype=float), name="Sun")


def point(position):
    return Light("POINT", position=np.asarray(position, dtype=float), name="Lamp")


def spot(position, direction, angle_deg=70.0):
    return Light("SPOT", position=np.asarray(position, dtype=float), direction=np.asarray(direction, dtype=float),
                 spot_angle=math.radians(angle_deg), name="Spot")


def run(view, light, scene, size=SIZE):
    """The paper's PSM (the λ guard off: test_the_lambda_guard_... checks it)."""
    body = intersection_body(view, light, scene)
    return psm(view, light, body, WarpOptions(shadow_map_size=(size, size), lambda_guard="off")), body


# ----------------------------------------------------------------------------- checks

def ndc(matrix, points):
    h = np.hstack([points, np.ones((len(points), 1))]) @ matrix.T
    return h[:, :3] / h[:, 3:4], h[:, 3]


def interior_points(body, n=300, seed=0):
    """Random points inside B (convex combinations of its vertices)."""
    rng = np.random.default_rng(seed)
    w = rng.dirichlet(np.full(len(body.vertices), 0.3), size=n)
    return w @ body.vertices


def towards_light(light, points):
    return -light.rays_to(points)


def assert_finite_and_covering(setup, body, view):
    assert setup.maps, "no maps"
    for m in setup.maps:
        assert np.all(np.isfinite(m.matrix))
        assert m.depth_test in ("LESS", "GREATER")
    idx = setup.map_index(body.vertices, view, tol=1e-9)
    assert np.all(idx >= 0), f"{np.sum(idx < 0)} B vertices not covered"
    for i, m in enumerate(setup.maps):
        sel = idx == i
        if sel.any():
            _, w = ndc(m.matrix, body.vertices[sel])
            assert np.all(w > 0)


def assert_rays_and_depth_order(setup, body, view, light, n=300, seed=0):
    """For pairs (p, q) in B on one light ray, q nearer to the light: same texel,
    and q's depth wins the map's depth test against p's."""
    p = interior_points(body, n, seed)
    u = towards_light(light, p)
    # the longest step (halving from B's size) that stays in B, and without passing a point light
    reach = np.zeros(len(p))
    for t in body.scale * 2.0 ** -np.arange(0, 40):
        q = p + t * u
        ok = body.contains(q) & (reach == 0)
        if not light.is_directional:
            ok &= np.linalg.norm(light.position - p, axis=1) > 1.5 * t
        reach[ok] = t
    pairs = 0
    for frac in (0.05, 0.5, 1.0):
        q = p + (frac * reach)[:, None] * u
        ok = (reach > 0) & body.contains(q) & np.any(q != p, axis=1)
        ip = setup.map_index(p, view)
        iq = setup.map_index(q, view)
        ok &= (ip >= 0) & (ip == iq)
        for i, m in enumerate(setup.maps):
            sel = ok & (ip == i)
            if not sel.any():
                continue
            a, _ = ndc(m.matrix, p[sel])
            b, _ = ndc(m.matrix, q[sel])
            texels = np.abs(a[:, :2] - b[:, :2]) * np.asarray(m.size) / 2
            assert texels.max() < TEXEL_TOL, f"one light ray spans {texels.max()} texels"
            if m.depth_test == "LESS":
                assert np.all(b[:, 2] < a[:, 2]), "the caster nearer the light must have the smaller depth"
            else:
                assert np.all(b[:, 2] > a[:, 2]), "the caster nearer the light must have the larger depth"
            pairs += int(sel.sum())
    assert pairs >= 20, f"only {pairs} ray pairs inside B"


def check_all(view, light, scene, kind=None, applied=True):
    setup, body = run(view, light, scene)
    assert_finite_and_covering(setup, body, view)
    assert_rays_and_depth_order(setup, body, view, light)
    d = setup.diagnostics
    assert d.theta is not None and 0 <= d.theta <= math.pi / 2 + 1e-12
    assert d.gamma is not None and 0 <= d.gamma <= math.pi + 1e-12
    assert d.extra["psm_applied"] is applied
    if applied:
        assert not d.fallbacks, d.fallbacks
        if kind is not None:
            assert d.extra["pps_light_kind"] == kind
        assert d.extra["virtual_shift"] >= 0
    return setup, body


VIEW = dict(pos=(0.0, -10.0, 2.0), target=(0.0, 10.0, 2.0))       # horizontal, looking along +y


# ----------------------------------------------------------------------------- the PPS light cases (§3)

def test_sun_from_the_front_is_a_point_light_in_pps():
    check_all(camera(**VIEW), sun([0.2, -0.6, -0.5]), town(), kind="point")


def test_sun_from_behind_the_camera_is_an_inverted_light_with_a_correct_depth_order():
    setup, body = check_all(camera(**VIEW), sun([0.2, 0.6, -0.5]), town(), kind="inverted")
    # casters behind the camera (the box rows at y = -5) can shadow the view: B reaches behind the eye
    view = camera(**VIEW)
    assert view.eye_depth(body.vertices).min() < 0
    assert setup.diagnostics.extra["virtual_shift"] > 0


def test_sun_perpendicular_to_the_view_is_directional_in_pps():
    check_all(camera(**VIEW), sun([0.6, 0.0, -0.8]), town(), kind="directional")


def test_sun_exactly_along_and_against_the_view_direction():
    view = camera((0, -10, 20), (0, 10, 0))
    check_all(view, sun(view.direction), town(), kind="inverted")
    check_all(view, sun(-view.direction), town(), kind="point")


TOP_DOWN = dict(pos=(0.0, 0.0, 10.0), target=(0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0))
"""Straight down onto a flat scene: nothing in B is nearer than the visible
ground (but for B's 1e-7 box padding), so the virtual camera is the real one
moved back by ~1e-5 and the plane z = 10 + shift is the PPS plane at infinity."""


def virtual_camera_plane_height():
    view, scene = camera(**TOP_DOWN), town(flat=True)
    z = 10.0
    for _ in range(3):
        setup, _ = run(view, point([30.0, 5.0, z]), scene)
        z = 10.0 + setup.diagnostics.extra["virtual_shift"]
    assert z - 10.0 < 1e-4
    return z


def test_point_light_in_the_camera_plane_is_directional_in_pps():
    check_all(camera(**TOP_DOWN), point([30.0, 5.0, virtual_camera_plane_height()]), town(flat=True),
              kind="directional")


def test_point_light_in_the_real_camera_plane_is_a_point_light_when_the_virtual_camera_moved_back():
    setup, body = check_all(camera(**VIEW), point([6.0, -10.0, 9.0]), town(), kind="point")
    assert setup.diagnostics.extra["virtual_shift"] > 0


def test_point_light_behind_the_camera_is_inverted():
    check_all(camera(**VIEW), point([3.0, -25.0, 12.0]), town(), kind="inverted")


def test_point_light_inside_the_view_outside_b_uses_psm():
    view = camera((0, -10, 2), (0, 0, 3))
    light = point([0.0, 5.0, 8.0])
    assert np.all(np.abs(np.asarray(ndc(view.world_to_clip, light.position[None])[0])) <= 1)
    check_all(view, light, town(), kind="point")


def test_point_light_inside_b_falls_back_to_uniform_cube_faces_and_still_covers():
    view = camera(**VIEW)
    light = point([0.5, 8.0, 1.5])                          # among the boxes, in the view
    setup, body = check_all(view, light, town(), applied=False)
    assert any(what == "light inside B" for what, _ in setup.diagnostics.fallbacks)
    assert len(setup.maps) > 1


def test_spot_light_over_a_board():
    view = camera((0, -6, 4), (0, 0, 0), fov=45, near=0.5, far=30)
    check_all(view, spot([2, 2, 6], [-0.3, -0.3, -1]), town(), kind="point")


def test_orthographic_camera_gives_the_uniform_map():
    persp = camera(**VIEW)
    from addon.warp.geometry import ortho_matrix
    ortho = View(persp.camera_to_world, ortho_matrix(-20, 20, -12, 12, 0.1, 100), 0.1, 100, (1280, 720), True)
    light = sun([0.2, 0.6, -0.5])
    setup, body = check_all(ortho, light, town(), applied=False)
    base = compute("uniform", ortho, light, town(), WarpOptions(shadow_map_size=(SIZE, SIZE)), body=body)
    assert np.allclose(setup.maps[0].matrix, base.maps[0].matrix)
    assert setup.diagnostics.fallbacks[0][0] == "orthographic camera"


# ----------------------------------------------------------------------------- awkward ranges and scenes

@pytest.mark.parametrize("near,far", [(1e-3, 1e2), (0.1, 1e4)])
@pytest.mark.parametrize("direction", [[0.2, -0.6, -0.5], [0.2, 0.6, -0.5], [0.6, 0.0, -0.8]])
def test_extreme_clip_ranges(near, far, direction):
    view = camera((0, -10, 2), (0, 10, 1.5), near=near, far=far)
    check_all(view, sun(direction), town())


def test_scene_offset_by_1e5_gives_the_same_map():
    off = np.array([1e5, -1e5, 1e5])
    base = camera((0, -10, 2), (0, 10, 1))
    moved = camera(off + [0, -10, 2], off + [0, 10, 1])
    for light, moved_light in ((sun([0.2, 0.6, -0.5]), sun([0.2, 0.6, -0.5])),
                               (point([3, -25, 12]), point(off + [3, -25, 12]))):
        a, body = check_all(base, light, town())
        b, _ = check_all(moved, moved_light, town(off))
        pa, _ = ndc(a.maps[0].matrix, body.vertices)
        pb, _ = ndc(b.maps[0].matrix, body.vertices + off)
        assert np.abs(pa - pb).max() < 1e-6


def test_flat_scene():
    view = camera((0, -10, 2), (0, 10, 0))
    for light in (sun([0.2, 0.6, -0.5]), sun([0.2, -0.6, -0.5]), point([3, -25, 12])):
        check_all(view, light, town(flat=True))


def test_flat_scene_seen_straight_down():
    view = camera((0, 0, 10), (0, 0, 0), up=(0, 1, 0))
    check_all(view, sun([0.3, 0.2, -1.0]), town(flat=True))


@pytest.mark.parametrize("direction", [[0.2, -0.6, -0.5], [0.2, 0.6, -0.5], [0.6, 0.0, -0.8]])
def test_camera_one_centimetre_above_the_ground(direction):
    view = camera((0.5, -3, 0.01), (0.5, 10, 0.01), near=0.005, far=200)
    check_all(view, sun(direction), town())


# ----------------------------------------------------------------------------- continuity

def _rotated(d, axis, angle):
    d, k = np.asarray(d, float), np.asarray(axis, float) / np.linalg.norm(axis)
    return d * math.cos(angle) + np.cross(k, d) * math.sin(angle) + k * (k @ d) * (1 - math.cos(angle))


def _max_ndc_change(view, scene, la, lb, points):
    a, _ = run(view, la, scene)
    b, _ = run(view, lb, scene)
    pa, _ = ndc(a.maps[0].matrix, points)
    pb, _ = ndc(b.maps[0].matrix, points)
    return np.abs(pa - pb).max(), a, b


@pytest.mark.parametrize("base", [[0.2, -0.6, -0.5], [0.2, 0.6, -0.5], [0.5, 0.3, -0.4], [0.05, 0.9, -0.4]])
def test_small_sun_rotations_move_the_map_a_little(base):
    view = camera((0, -10, 2), (0, 10, 1))
    scene = town()
    _, body = run(view, sun(base), scene)
    pts = body.visible_vertices
    for axis in ([1, 0, 0], [0, 0, 1], [0.3, 0.5, 0.8]):
        change, _, _ = _max_ndc_change(view, scene, sun(base), sun(_rotated(base, axis, 1e-6)), pts)
        assert change < 1e-3


def test_sun_crossing_the_camera_plane_is_continuous():
    """The paper's inverted-light switch (§3.1): a sun crossing the plane
    perpendicular to the view direction. Lixel's inverted depth axis keeps the
    map continuous (same depth test on both sides)."""
    view = camera(**VIEW)
    scene = town()
    _, body = run(view, sun([0.6, 0.0, -0.8]), scene)
    pts = body.visible_vertices
    for eps in (1e-4, 1e-6, 1e-9):
        la, lb = sun([0.6, -eps, -0.8]), sun([0.6, eps, -0.8])
        change, a, b = _max_ndc_change(view, scene, la, lb, pts)
        assert a.diagnostics.extra["pps_light_kind"] == "point"
        assert b.diagnostics.extra["pps_light_kind"] == "inverted"
        assert a.maps[0].depth_test == b.maps[0].depth_test == "LESS"
        assert change < 50 * eps + 1e-7, (eps, change)


def test_point_light_crossing_the_camera_plane_is_continuous_and_covering():
    view = camera(**TOP_DOWN)
    scene = town(flat=True)
    z = virtual_camera_plane_height()
    _, body = run(view, point([30.0, 5.0, z]), scene)
    pts = body.visible_vertices
    for eps in (1e-3, 1e-6):
        la, lb = point([30.0, 5.0, z - eps]), point([30.0, 5.0, z + eps])
        change, a, b = _max_ndc_change(view, scene, la, lb, pts)
        assert (a.diagnostics.extra["pps_light_kind"], b.diagnostics.extra["pps_light_kind"]) == ("point", "inverted")
        assert change < 50 * eps
        for light in (la, lb):
            check_all(view, light, scene)


def test_point_light_approaching_b_switches_to_uniform_finite_and_covering_on_both_sides():
    """The switch PSM cannot avoid: a point light coming close to B needs a PPS
    frustum wider than max_frustum_angle and, inside B, no single frustum at
    all (§3.3); Lixel hands over to the uniform map's cube faces. Every step
    is finite and covers B, and the fallback is recorded."""
    view = camera(**VIEW)
    scene = town()
    kinds = []
    for z in (40.0, 12.0, 6.0, 3.5, 3.0 + 1e-3, 3.0 - 1e-3, 1.5):
        light = point([0.5, 8.0, z])
        setup, _ = run(view, light, scene)
        assert_finite_and_covering(setup, intersection_body(view, light, scene), view)
        applied = setup.diagnostics.extra["psm_applied"]
        setup, _ = check_all(view, light, scene, applied=applied)
        if not applied:
            assert {w for w, _ in setup.diagnostics.fallbacks} & {"PPS light frustum", "light inside B"}
        kinds.append(applied)
    assert kinds[0] and not kinds[-1]
    assert kinds == sorted(kinds, reverse=True), kinds      # one switch, no flicker back


# ----------------------------------------------------------------------------- generated configurations

@settings(max_examples=40, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(yaw=st.floats(-math.pi, math.pi), pitch=st.floats(-1.2, 0.3), height=st.floats(0.05, 30.0),
       az=st.floats(-math.pi, math.pi), el=st.floats(0.05, 1.5), use_point=st.booleans(),
       dist=st.floats(5.0, 80.0))
def test_generated_configurations_cover_b_and_keep_rays_and_depth_order(yaw, pitch, height, az, el, use_point, dist):
    pos = np.array([0.0, -10.0, height])
    forward = np.array([math.cos(pitch) * math.sin(yaw), math.cos(pitch) * math.cos(yaw), math.sin(pitch)])
    view = camera(pos, pos + forward, near=0.05, far=150)
    towards = np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
    light = point(pos + dist * towards + [0, 0, 4]) if use_point else sun(-towards)
    scene = town()
    try:
        body = intersection_body(view, light, scene)
    except Exception as exc:                                  # nothing visible: not PSM's business
        assert "receiver" in str(exc) or "scene" in str(exc)
        return
    setup = psm(view, light, body, WarpOptions(shadow_map_size=(SIZE, SIZE)))
    assert_finite_and_covering(setup, body, view)
    assert_rays_and_depth_order(setup, body, view, light, n=200)
    if not setup.diagnostics.extra["psm_applied"]:
        assert use_point and setup.diagnostics.fallbacks


# ----------------------------------------------------------------------------- construction pieces

def test_virtual_camera_puts_b_in_front_and_fills_the_unit_cube():
    view = camera(**VIEW)
    light = sun([0.2, 0.6, -0.5])
    body = intersection_body(view, light, town())
    cam = virtual_camera(view, body)
    p, w = ndc(cam.to_pps, body.vertices - view.position)
    assert np.all(w > 0) and w.min() == pytest.approx(cam.near)
    assert np.allclose(p.min(axis=0), -1, atol=1e-5) and np.allclose(p.max(axis=0), 1, atol=1e-5)
    # the shift: B's nearest point is as far from the virtual eye as R's nearest from the real one
    assert cam.near == pytest.approx(view.eye_depth(body.visible_vertices).min(), rel=1e-9)
    assert cam.shift == pytest.approx(cam.near - view.eye_depth(body.vertices).min(), rel=1e-9)
    # B' is B in PPS
    assert np.abs(cam.points - p).max() <= 1e-12


def test_min_norm_point_matches_brute_force():
    rng = np.random.default_rng(3)
    for _ in range(30):
        pts = rng.normal(size=(rng.integers(1, 25), 3)) + rng.normal(size=3) * rng.uniform(0, 4)
        x = min_norm_point(pts)
        # optimality: x is in the hull (checked via the support inequality) and no point beats it
        assert np.all(pts @ x >= x @ x - 1e-9 * max(1.0, (pts ** 2).sum(axis=1).max()))
        w = rng.dirichlet(np.ones(len(pts)), size=4000)
        assert np.linalg.norm(x) <= np.linalg.norm(w @ pts, axis=1).min() + 1e-9


def _cone(rng, n: int, half: float, spanning: int) -> np.ndarray:
    """n unit directions in a cone of half-angle ``half`` spanned by ``spanning``
    of them on its rim (two opposite, or three 120° apart), in a random frame."""
    a = rng.uniform(0, 2 * math.pi) + np.arange(spanning) * 2 * math.pi / spanning
    rim = np.column_stack([math.sin(half) * np.cos(a), math.sin(half) * np.sin(a), np.full(spanning, math.cos(half))])
    tilt, turn = rng.uniform(0, half * 0.5, n - spanning), rng.uniform(0, 2 * math.pi, n - spanning)
    inner = np.column_stack([np.sin(tilt) * np.cos(turn), np.sin(tilt) * np.sin(turn), np.cos(tilt)])
    frame, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return np.concatenate([rim, inner]) @ frame.T


def test_the_smallest_cone_is_spanned_by_its_rim():
    """The narrowest cone around the directions has every direction within
    its half-angle and the spanning ones on its rim (two or three of them),
    its axis towards the hull's point nearest the origin."""
    rng = np.random.default_rng(41)
    for t in range(400):
        spanning, half = 2 + t % 2, rng.uniform(0.01, 1.5)
        d = _cone(rng, int(rng.integers(spanning, 30)), half, spanning)
        k, margin = smallest_cone(d)
        assert margin == pytest.approx(math.cos(half), abs=1e-9)
        assert np.all(d @ k >= margin - 1e-12) and np.allclose(d[:spanning] @ k, margin, atol=1e-9)
        x = min_norm_point(d)
        assert np.allclose(k, x / np.linalg.norm(x), atol=1e-9)
    opposite = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])
    assert smallest_cone(opposite)[1] == pytest.approx(0.0, abs=1e-12)     # they surround the origin: no cone


def test_lowest_in_boxes_is_the_least_vertex_of_each_clipped_region():
    from addon.warp.polyhedron import ConvexPolytope
    from addon.warp.post_perspective import lowest_in_boxes
    rng = np.random.default_rng(0)
    for _ in range(4):
        normals = rng.normal(size=(int(rng.integers(5, 14)), 3))
        normals /= np.linalg.norm(normals, axis=1)[:, None]
        region = ConvexPolytope.from_halfspaces(normals, rng.uniform(1.0, 3.0, len(normals)), 1e-9)
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        centre, half = rng.uniform(-3, 3, size=(40, 3)), rng.uniform(0.05, 2.5, size=(40, 3))
        lo, hi = centre - half, centre + half
        got = lowest_in_boxes(region, lo, hi, axis)
        eye = np.eye(3)
        for i in range(len(lo)):
            part = region.clip(np.concatenate([eye, -eye]), np.concatenate([hi[i], -lo[i]]))
            if part is None:                     # nothing with volume in common (at most a touch)
                assert got[i] >= float(np.where(axis > 0, lo[i], hi[i]) @ axis) - 1e-9
            else:
                assert got[i] == pytest.approx(float((part.vertices @ axis).min()), abs=1e-9)


def test_smallest_cone_is_exact_for_a_symmetric_cone():
    axis = np.array([0.3, -0.4, 0.866])
    axis /= np.linalg.norm(axis)
    u = np.cross(axis, [1.0, 0, 0])
    u /= np.linalg.norm(u)
    v = np.cross(axis, u)
    half = math.radians(35)
    dirs = [math.cos(half) * axis + math.sin(half) * (math.cos(t) * u + math.sin(t) * v)
            for t in np.linspace(0, 2 * math.pi, 7, endpoint=False)]
    dirs.append(axis)
    k, margin = smallest_cone(np.array(dirs))
    assert np.allclose(k, axis, atol=1e-12)
    assert margin == pytest.approx(math.cos(half), abs=1e-12)


def test_pps_light_rows_vanish_at_the_light_for_all_three_kinds():
    rng = np.random.default_rng(5)
    pts = rng.uniform(-1, 1, size=(40, 3))
    for lh in ([0.3, 2.5, 4.0, 1.0], [0.3, 2.5, 4.0, -1.0], [0.3, 2.5, 4.0, 0.0]):
        pl = pps_light_matrix(np.array(lh), pts)
        img = pl.matrix @ (np.array(lh) / np.linalg.norm(lh))
        assert np.abs(img[[0, 1, 3]]).max() < 1e-12 and abs(img[2]) > 1e-3
        _, w = ndc(pl.matrix, pts)
        assert np.all(w > 0)


def _rotated_view(view, axis, angle):
    c2w = view.camera_to_world.copy()
    for j in range(3):
        c2w[:3, j] = _rotated(c2w[:3, j], axis, angle)
    return View(c2w, view.projection, view.near, view.far, view.resolution)


@pytest.mark.parametrize("direction", [[0.2, -0.6, -0.5], [0.2, 0.6, -0.5], [0.6, 0.05, -0.8]])
def test_small_camera_rotations_move_the_map_a_little(direction):
    view = camera((0, -10, 2), (0, 10, 1))
    scene, light = town(), sun(direction)
    a, body = run(view, light, scene)
    for axis in ([1, 0, 0], [0, 0, 1], [0.3, 0.5, 0.8]):
        b, _ = run(_rotated_view(view, axis, 1e-6), light, scene)
        pa, _ = ndc(a.maps[0].matrix, body.visible_vertices)
        pb, _ = ndc(b.maps[0].matrix, body.visible_vertices)
        assert np.abs(pa - pb).max() < 1e-3


def test_warp_frustum_corners_are_the_clip_volume_corners():
    from addon.warp.geometry import UNIT_CUBE_CORNERS
    for light in (sun([0.2, -0.6, -0.5]), sun([0.2, 0.6, -0.5]), point([3.0, -25.0, 12.0])):
        setup, _ = run(camera(**VIEW), light, town())
        corners = setup.diagnostics.warp_frustum_corners
        m = setup.maps[0].matrix
        pre = np.hstack([UNIT_CUBE_CORNERS, np.ones((8, 1))]) @ np.linalg.inv(m).T
        if light.is_directional:
            assert corners is not None
        if corners is None:             # the clip volume reaches infinity: a corner's preimage has w <= 0
            assert np.any(pre[:, 3] <= 0)
            continue
        assert corners.shape == (8, 3)
        p, w = ndc(m, corners)
        assert np.all(w > 0) and np.allclose(p, UNIT_CUBE_CORNERS, atol=1e-6)


def test_nearest_visible_depth_is_between_the_near_plane_and_what_is_seen():
    from addon.warp.post_perspective import nearest_visible_depth
    view = camera((0, -10, 2), (0, 10, 1))
    light = sun([0.2, 0.6, -0.5])
    body = intersection_body(view, light, town())
    d = nearest_visible_depth(view, light, body)
    # the ground is first seen along the bottom edge of the view: depth of the ray hitting z = 0
    inv = np.linalg.inv(view.world_to_clip)
    xs = np.linspace(-1, 1, 41)
    a = np.column_stack([xs, -np.ones_like(xs), -np.ones_like(xs), np.ones_like(xs)]) @ inv.T
    b = np.column_stack([xs, -np.ones_like(xs), np.ones_like(xs), np.ones_like(xs)]) @ inv.T
    a, b = a[:, :3] / a[:, 3:], b[:, :3] / b[:, 3:]
    hit = a + ((0 - a[:, 2]) / (b[:, 2] - a[:, 2]))[:, None] * (b - a)
    assert view.near < d <= view.eye_depth(hit).min() + 1e-9
    assert d == pytest.approx(view.eye_depth(hit).min(), rel=1e-3)    # the ground slab is the nearest receiver
    assert nearest_visible_depth(view, light, body, WarpOptions(visible_depth_range=(4.5, 60.0))) == 4.5


def test_nearest_visible_depth_is_the_least_over_every_receiver_box():
    """Visiting the culling index's clusters nearest first and stopping early
    gives exactly the minimum over all receiver boxes of the nearest point of
    R ∩ box (seeded views over the town, every light type)."""
    from addon.warp import EmptyBodyError
    from addon.warp.post_perspective import lowest_in_boxes, nearest_visible_depth
    from hard_cases import camera as hc_camera, point as hc_point, spot as hc_spot, sun as hc_sun, town as hc_town
    rng = np.random.default_rng(7)
    checked = 0
    for _ in range(60):
        eye = np.array([rng.uniform(-30, 30), rng.uniform(-30, 30), rng.uniform(0.05, 20)])
        fwd = rng.normal(size=3)
        fwd[2] = -abs(fwd[2])
        view = hc_camera(eye, forward=fwd, near=10 ** rng.uniform(-2, 0), far=rng.uniform(30, 300))
        light = [hc_sun(rng.normal(size=3) * [1, 1, 0] + [0, 0, -1]), hc_point(rng.uniform(-30, 30, 3) + [0, 0, 35]),
                 hc_spot(rng.uniform(-30, 30, 3) + [0, 0, 35], [0.2, 0.3, -1], math.radians(rng.uniform(20, 120)))][_ % 3]
        try:
            body = intersection_body(view, light, hc_town(flat=bool(rng.integers(2))))
        except EmptyBodyError:
            continue
        origin, axis = view.position, -view.world_to_camera[2, :3]
        boxes = body.culled.receivers.boxes
        least = float(lowest_in_boxes(body.visible_polytope, boxes[:, 0] - origin, boxes[:, 1] - origin, axis).min())
        coarse = max(float(view.eye_depth(body.visible_vertices).min()), view.near)
        expected = max(least, coarse) if math.isfinite(least) else coarse
        assert nearest_visible_depth(view, light, body) == pytest.approx(expected, rel=1e-12, abs=1e-12)
        checked += 1
    assert checked >= 40


@pytest.mark.parametrize("case", ["outdoor_sun", "camera_1cm_above_ground"])
def test_the_lambda_guard_moves_the_virtual_camera_back_until_psm_is_no_worse_than_uniform(case):
    """The λ guard (docs/papers.md) on PSM: on outdoor_sun, and a camera 1 cm
    above the ground whose λ is 1/15 of the guard's, PSM's own λ, read from its
    map, is below the guard's, so the virtual camera moves back (§4.2) until it
    meets it; the map still holds B."""
    if case == "outdoor_sun":
        example = Path(__file__).parents[2] / "examples" / "outdoor_sun.json"
        view, light, scene, options = parse_config(json.loads(example.read_text()))
    else:
        from hard_cases import HARD_CASES
        (view, light, scene), options = HARD_CASES[case], WarpOptions()
    body = focused_body(view, light, scene, options)
    frame = light_frames(view, light, body, options)[0]
    at, _ = light_at_eye(view, light, options, body, view.direction)
    ctx = eye_depth_range(view, body, options, Diagnostics("psm"))
    ctx.phi = half_fov_towards(view, at.ell)

    def lam_and_guard(setup):
        axis, lam = map_lambda(setup.maps[0].matrix, frame)
        return lam, guard_lambda(0.0, at.gamma, axis, ctx)[0]

    raw = psm(view, light, body, dataclasses.replace(options, lambda_guard="off"))
    guarded = psm(view, light, body, options)
    lam, guard = lam_and_guard(raw)
    assert lam < 0.5 * guard and not raw.diagnostics.fallbacks
    lam, guard = lam_and_guard(guarded)
    assert guard <= lam <= guard * (1 + GUARD_TOLERANCE)
    assert [w for w, _ in guarded.diagnostics.fallbacks] == ["main: λ guard"]
    assert guarded.diagnostics.extra["virtual_near"] > 2 * raw.diagnostics.extra["virtual_near"]
    assert guarded.maps[0].contains(body.vertices, 1e-6).all()
    # the note's move is a ratio, in no unit ("from near 0.1 to 3.2": bare Blender units beside the panel's lengths)
    moved = guarded.diagnostics.extra["virtual_near"] / raw.diagnostics.extra["virtual_near"]
    assert guarded.diagnostics.fallbacks[0][1].startswith(f"virtual camera moved back to {moved:.3g}x its near (§4.2)")
