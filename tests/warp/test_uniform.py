"""The uniform method (focused standard shadow maps, Scherzer §4.1) and the light
frames it stands on: an orthographic sun map along the light, fitted tightly to
B; a point light's single perspective map or cube faces; texel snapping that
keeps every world point on its texel while the camera moves; the frame's
continuity near light ∥ view and at the single-map / cube-face switch.

(Coverage, light rays and continuity on every hard case run for every method
in test_invariants.py.)"""
import math

import numpy as np
import pytest

from addon.warp import View, WarpOptions, compute, focused_body, intersection_body
from addon.warp.frame import (PARALLEL_BLEND, image_up, light_angles, light_cone,
                              point_frames)
from addon.warp.methods.common import SNAP_STEPS_PER_OCTAVE, snapped_window
from addon.warp.methods.uniform import uniform

from hard_cases import HARD_CASES, image_up_singularity

OPTIONS = WarpOptions(shadow_map_size=(1024, 1024))


def ndc(m, pts):
    h = np.hstack([pts, np.ones((len(pts), 1))]) @ m.T
    return h[:, :3] / h[:, 3:4], h[:, 3]


def moved(view: View, offset=(0.0, 0.0, 0.0), rot=None) -> View:
    c2w = view.camera_to_world.copy()
    c2w[:3, 3] += offset
    if rot is not None:
        c2w[:3, :3] = rot @ c2w[:3, :3]
    return View(c2w, view.projection, view.near, view.far, view.resolution)


def rot_z(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


# ----------------------------------------------------------------------------- suns

def test_sun_map_is_orthographic_along_the_light_and_tight():
    view, light, scene = HARD_CASES["sun_behind_camera"]
    body = intersection_body(view, light, scene)
    setup = uniform(view, light, body, OPTIONS)
    (m,) = [s.matrix for s in setup.maps]
    assert np.allclose(m[3], [0, 0, 0, 1])                       # affine: orthographic
    p, _ = ndc(m, body.vertices)
    q, _ = ndc(m, body.vertices + 3.0 * light.direction)
    assert np.allclose(p[:, :2], q[:, :2], atol=1e-12)           # rays along the light keep x, y
    assert np.all(q[:, 2] > p[:, 2])                             # depth grows away from the light: LESS
    assert setup.maps[0].depth_test == "LESS"
    # Focused: B fills [-1, 1]^3 up to the fit's padding.
    assert np.allclose(p.min(axis=0), -1, atol=1e-6) and np.allclose(p.max(axis=0), 1, atol=1e-6)
    theta, gamma = light_angles(view, light.direction)
    assert setup.diagnostics.theta == theta and setup.diagnostics.gamma == gamma
    assert np.array_equal(setup.diagnostics.body_vertices, body.vertices)


@pytest.mark.parametrize("name", ["sun_parallel_top_down", "sun_parallel_to_view", "sun_antiparallel_to_view"])
def test_parallel_light_uses_the_camera_up(name):
    """Exactly parallel light and view: V_P vanishes and the map's +y is the
    camera's up (projected across the light), not an arbitrary axis."""
    view, light, scene = HARD_CASES[name]
    up = image_up(view.direction, view.up, light.direction)
    pu = view.up - (view.up @ light.direction) * light.direction
    assert np.allclose(up, pu / np.linalg.norm(pu))
    body = intersection_body(view, light, scene)
    m = uniform(view, light, body, OPTIONS).maps[0].matrix
    assert m[1, :3] @ up > 0 and abs(m[0, :3] @ up) < 1e-12 * np.abs(m[0, :3]).max()


def test_image_up_turns_smoothly_through_parallel():
    """Pitching a camera through the light direction (sun straight down, camera
    through nadir) turns the map's +y continuously: no step bigger than the
    blend allows (δ / (PARALLEL_BLEND / 2) radians for a step δ)."""
    light_dir = np.array([0.0, 0.0, -1.0])
    steps = np.linspace(-math.radians(3), math.radians(3), 6001)
    ups = []
    for p in steps:
        d = np.array([0.0, math.sin(p), -math.cos(p)])          # through nadir at p = 0
        u = np.array([0.0, math.cos(p), math.sin(p)])
        ups.append(image_up(d, u, light_dir))
    ups = np.array(ups)
    angle = np.arccos(np.clip((ups[1:] * ups[:-1]).sum(axis=1), -1, 1))
    step = steps[1] - steps[0]
    assert angle.max() <= 4 * step / PARALLEL_BLEND
    # Far from parallel it is V_P: the view direction projected across the light.
    assert np.allclose(ups[0], [0, -1, 0]) and np.allclose(ups[-1], [0, 1, 0])


def _tilted(r, angle_deg, light_dir=np.array([0.0, 0.0, -1.0])):
    """A top-down camera (up +Y, right +X) tilted by sin⁻¹ r towards ``angle_deg`` (from +X)."""
    a = math.radians(angle_deg)
    pv = r * np.array([math.cos(a), math.sin(a), 0.0])
    d = pv + light_dir * math.sqrt(1 - r * r)
    up = np.array([0.0, 1.0, 0.0]) - d[1] * d
    return d, up / np.linalg.norm(up), light_dir


def test_image_up_singular_point_is_off_plain_pitch_and_pan_paths():
    """The unavoidable singular point sits inside the blend in a diagonal
    direction; plain pitches and pans through the light direction stay far
    from it, and outside the blend the measure is 1."""
    b = PARALLEL_BLEND
    grid = [(r, a) for r in np.linspace(0, b, 120) for a in np.arange(-180, 180, 0.5)]
    values = np.array([image_up_singularity(*_tilted(r, a)) for r, a in grid])
    r, a = grid[int(values.argmin())]
    assert values.min() < 0.01
    assert 0.3 < r / b < 0.9 and 110 < abs(a) < 170
    for angle in (90.0, -90.0, 0.0, 180.0):
        assert min(image_up_singularity(*_tilted(r, angle)) for r in np.linspace(0, b, 200)) > 0.3
    assert image_up_singularity(*_tilted(2 * b, 37.0)) == pytest.approx(1.0)
    view, light, _ = HARD_CASES["sun_behind_camera"]
    assert image_up_singularity(view.direction, view.up, light.direction) == pytest.approx(1.0)


# ----------------------------------------------------------------------------- texel snapping

@pytest.mark.parametrize("name", ["sun_behind_camera", "scene_offset_1e5", "sun_parallel_top_down"])
def test_texel_snapping_keeps_world_points_on_their_texels(name):
    """Moving and turning the camera shifts a snapped map by whole texels only
    (while B's extent stays on one ladder step), so shadow edges do not crawl."""
    view, light, scene = HARD_CASES[name]
    size = 1024
    opts = WarpOptions(shadow_map_size=(size, size), texel_snapping=True)
    probe = focused_body(view, light, scene, opts).vertices.mean(axis=0)[None]
    base = compute("uniform", view, light, scene, opts)
    t0 = (ndc(base.maps[0].matrix, probe)[0][0, :2] + 1) / 2 * size
    same_scale = 0
    rng = np.random.default_rng(2)
    for k in range(12):
        v2 = moved(view, rng.normal(size=3) * 0.05, rot_z(rng.normal() * 0.01))
        s2 = compute("uniform", v2, light, scene, opts)
        m = s2.maps[0].matrix
        body2 = focused_body(v2, light, scene, opts)
        assert s2.maps[0].contains(body2.vertices, 1e-9).all()
        if not np.allclose(m[:2, :3], base.maps[0].matrix[:2, :3], rtol=1e-12, atol=0):
            # A ladder step: the scale changed by 2^(k/8).
            ratio = np.abs(m[0, :3]).max() / np.abs(base.maps[0].matrix[0, :3]).max()
            assert abs(math.log2(ratio) * SNAP_STEPS_PER_OCTAVE - round(math.log2(ratio) * SNAP_STEPS_PER_OCTAVE)) < 1e-6
            continue
        same_scale += 1
        t1 = (ndc(m, probe)[0][0, :2] + 1) / 2 * size
        assert np.allclose(t1 - t0, np.round(t1 - t0), atol=1e-4 * (1 + np.abs(t1 - t0).max())), t1 - t0
    assert same_scale >= 6


def test_snapped_window_is_size_texels_from_the_world_lattice_wherever_b_wanders():
    """Texel snapping keeps a static scene from shimmering under a moving camera: as B's window wanders and breathes
    (a random walk, near every ladder step), the snapped window holds it, is exactly ``size`` texels of a ladder
    step wide and starts on a whole texel of the world-fixed lattice, never with texels added on one side."""
    rng = np.random.default_rng(16)
    size = (1024, 256)
    lo, extent = np.array([-3.0, 7.0, 0.0]), np.array([40.0, 25.0, 10.0])
    for _ in range(4000):
        lo = lo + rng.normal(size=3) * 0.05
        extent = extent * 2.0 ** (rng.normal(size=3) * 0.01)
        s_lo, s_hi = snapped_window(lo, lo + extent, size)
        for axis, texels in enumerate(size):
            width = s_hi[axis] - s_lo[axis]
            step = math.log2(width) * SNAP_STEPS_PER_OCTAVE
            assert abs(step - round(step)) < 1e-9, (axis, width)                # a ladder step, no texels added
            texel = 2.0 ** (round(step) / SNAP_STEPS_PER_OCTAVE) / texels
            assert abs(s_lo[axis] / texel - round(s_lo[axis] / texel)) < 1e-6      # on the lattice
            assert s_lo[axis] <= lo[axis] and s_hi[axis] >= lo[axis] + extent[axis] - 1e-12 * width
        assert (s_lo[2], s_hi[2]) == (lo[2], lo[2] + extent[2])


# ----------------------------------------------------------------------------- point and spot lights

def test_point_light_high_above_gets_one_perspective_map():
    view, light, scene = HARD_CASES["point_light_high_above"]
    body = intersection_body(view, light, scene)
    setup = uniform(view, light, body, OPTIONS)
    assert [m.role for m in setup.maps] == ["main"]
    m = setup.maps[0].matrix
    # Perspective from the light: the light itself maps to w = 0.
    assert abs(m[3] @ np.append(light.position, 1.0)) < 1e-9 * np.abs(m[3]).max() * np.linalg.norm(light.position)
    assert setup.maps[0].contains(body.vertices, 1e-9).all()


def test_point_light_inside_b_gets_the_cube_faces_it_needs():
    view, light, scene = HARD_CASES["point_light_inside_view"]
    body = intersection_body(view, light, scene)
    assert body.contains(light.position[None])[0]
    setup = uniform(view, light, body, OPTIONS)
    roles = [m.role for m in setup.maps]
    assert len(roles) >= 2 and all(r.startswith("cube") for r in roles)
    near = np.linalg.norm(body.vertices - light.position, axis=1) > 1e-5 * body.scale
    assert (setup.map_index(body.vertices[near], view, 1e-6) >= 0).all()
    # Each face is a 90° frustum: its own quarter of directions, nothing behind it.
    for m in setup.maps:
        assert m.matrix[3] @ np.append(light.position, 1.0) == pytest.approx(0.0, abs=1e-9)


def test_light_inside_b_declares_the_near_plane():
    view, light, scene = HARD_CASES["camera_inside_scene_box_point"]
    body = intersection_body(view, light, scene)
    setup = uniform(view, light, body, OPTIONS)
    on_light = np.linalg.norm(body.vertices - light.position, axis=1) <= 1e-6 * body.scale
    if on_light.any():
        assert any("near plane" in w for w, _ in setup.diagnostics.fallbacks)


@pytest.mark.parametrize("margin", [-1e-6, 1e-6])
def test_single_map_and_cube_faces_meet_at_the_threshold(margin):
    """Either side of max_frustum_angle both setups cover B; the switch is
    exactly where B's cone from the light is max_frustum_angle wide."""
    view, light, scene = HARD_CASES["point_light_high_above"]
    body = intersection_body(view, light, scene)
    axis, half = light_cone(body.vertices, light.position)
    opts = WarpOptions(shadow_map_size=(1024, 1024), max_frustum_angle=2 * half + margin)
    roles = [f.role for f in point_frames(view, light, body, opts)]
    assert roles == ["main"] if margin > 0 else all(r.startswith("cube") for r in roles)
    setup = uniform(view, light, body, opts)
    assert (setup.map_index(body.vertices, view, 1e-6) >= 0).all()


def test_light_cone_ignores_vertex_splits_and_the_apex():
    """The cone axis depends on B as a set: doubling a vertex or adding the apex
    itself (B's vertex at the light) does not move it."""
    view, light, scene = HARD_CASES["point_light_high_above"]
    body = intersection_body(view, light, scene)
    a1, h1 = light_cone(body.vertices, light.position)
    a2, h2 = light_cone(np.concatenate([body.vertices, body.vertices[:3]]), light.position)
    a3, h3 = light_cone(np.concatenate([body.vertices, light.position[None] + 1e-13]), light.position)
    assert np.allclose(a1, a2) and np.allclose(a1, a3) and h1 == h2 == h3


def test_point_cube_frames_move_continuously_with_the_camera():
    """The lamp in a room (B surrounds the light): a tiny camera turn moves every
    cube face's image of B only a little (the cube axis used to jump)."""
    view, light, scene = HARD_CASES["camera_inside_scene_box_point"]
    body = intersection_body(view, light, scene)
    base = uniform(view, light, body, OPTIONS)
    v2 = moved(view, rot=rot_z(1e-7))
    b2 = intersection_body(v2, light, scene)
    s2 = uniform(v2, light, b2, OPTIONS)
    pts = body.vertices[np.linalg.norm(body.vertices - light.position, axis=1) > 1e-5 * body.scale]
    idx = base.map_index(pts, view, 1e-6)
    for i, m in enumerate(base.maps):
        other = [x for x in s2.maps if x.role == m.role]
        if not other or not (idx == i).any():
            continue
        a, _ = ndc(m.matrix, pts[idx == i])
        b, _ = ndc(other[0].matrix, pts[idx == i])
        assert np.abs(a - b).max() < 1e-4


@pytest.mark.parametrize("name", ["point_light_inside_view", "camera_inside_scene_box_point", "spot_179deg",
                                  "point_light_in_camera_plane"])
def test_each_cube_face_sees_exactly_its_part_of_b(name):
    """A cube face's section points hold every vertex of B ∩ C_f (C_f the
    face's 90° pyramid from the light) and nothing outside it; a face whose
    part of B has no volume gets none."""
    from addon.warp.frame import CUBE_FACES, cube_basis, cube_sections
    view, light, scene = HARD_CASES[name]
    body = intersection_body(view, light, scene)
    poly = body.polytope_from(light.position)
    axis, _ = light_cone(body.vertices, light.position)
    basis = cube_basis(axis.tolist(), image_up(view.direction, view.up, axis).tolist())
    parts = {f: points for f, points, _, _ in cube_sections(poly, basis)}
    assert len(parts) >= 2
    for f, (face, k, sign) in enumerate(CUBE_FACES):
        forward, others = sign * basis[k], [basis[j] for j in range(3) if j != k]
        sides = np.array([s * o - forward for o in others for s in (1.0, -1.0)]) / math.sqrt(2.0)
        part = poly.clip(sides, np.zeros(4))
        if part is None or f not in parts:
            assert part is None or np.ptp(part.vertices @ sides.T, axis=0).min() < 1e-6 * body.scale, face
            continue
        # (The section is taken within B's tolerance, 1e-10 of the scale; where a side
        # meets a facet of B at a grazing angle that moves a corner along the facet.)
        own = parts[f]
        gap = np.linalg.norm(part.vertices[:, None] - own[None], axis=2).min(axis=1)
        assert gap.max() <= 1e-8 * body.scale and part.contains(own, 1e-8 * body.scale).all(), face
