"""The intersection body B (Scherzer §4.1): it contains every visible receiver
point and every caster point that can shadow one, it is closed, deterministic,
relative to the scene's scale, and empty bodies are reported with the reason.

Every named hard case of ``hard_cases.py`` is checked."""
import math

import numpy as np
import pytest
from hypothesis import assume, given, settings, strategies as st

from addon.warp import EmptyBodyError, Light, SceneBounds, View, intersection_body
from addon.warp.polyhedron import COINCIDENT, ConvexPolytope

from hard_cases import EMPTY_CASES, HARD_CASES, NONEMPTY_CASES, camera, point, spot, sun, town

CONTAIN_TOL = 1e-9
"""Containment slack, relative to B's scale."""


def in_view(view: View, pts: np.ndarray) -> np.ndarray:
    h = np.hstack([pts, np.ones((len(pts), 1))]) @ view.world_to_clip.T
    w = h[:, 3]
    ok = w > 0
    ndc = h[:, :3] / np.where(ok, w, 1.0)[:, None]
    return ok & np.all(np.abs(ndc) <= 1.0, axis=1)


def in_light_cone(light: Light, pts: np.ndarray) -> np.ndarray:
    """The exact spot cone (B uses a circumscribed pyramid, so this is tighter)."""
    if light.type != "SPOT":
        return np.ones(len(pts), dtype=bool)
    d = pts - light.position
    n = np.linalg.norm(d, axis=1)
    return d @ light.direction >= np.cos(light.spot_angle / 2) * n


def visible_receiver_points(view, light, scene, n=4000, seed=0) -> np.ndarray:
    """Random points of V ∩ L inside receiver boxes (plus the boxes' corners that are)."""
    rng = np.random.default_rng(seed)
    boxes = scene.receivers
    # Sample inside the receivers that meet the view's bounding box (big scenes: skip the rest).
    corners = view.corners()
    lo, hi = corners.min(axis=0), corners.max(axis=0)
    near = np.all((boxes[:, 0] <= hi) & (boxes[:, 1] >= lo), axis=1)
    boxes = boxes[near]
    if len(boxes) == 0:
        return np.zeros((0, 3))
    b = np.stack([np.maximum(boxes[:, 0], lo), np.minimum(boxes[:, 1], hi)], axis=1)
    which = rng.integers(0, len(b), n)
    u = rng.random((n, 3))
    pts = b[which, 0] + u * (b[which, 1] - b[which, 0])
    # Points on the boxes' faces too (flat scenes have only faces).
    face = rng.integers(0, 3, n // 2)
    side = rng.integers(0, 2, n // 2)
    pts2 = pts[: n // 2].copy()
    pts2[np.arange(n // 2), face] = b[which[: n // 2], side, face]
    cube = np.array([[i & 1, (i >> 1) & 1, (i >> 2) & 1] for i in range(8)])
    cpts = (b[:, None, 0] + cube[None] * (b[:, None, 1] - b[:, None, 0])).reshape(-1, 3)
    pts = np.concatenate([pts, pts2, cpts, lit_receiver_points(light, boxes, rng)])
    return pts[in_view(view, pts) & in_light_cone(light, pts)]


def lit_receiver_points(light, boxes, rng, n=3000) -> np.ndarray:
    """Where rays from a spot (inside its cone) first enter a receiver box: a
    narrow cone would be missed by sampling the boxes."""
    if light.type != "SPOT":
        return np.zeros((0, 3))
    a = light.direction
    u = np.cross(a, np.eye(3)[int(np.argmin(np.abs(a)))])
    u /= np.linalg.norm(u)
    w = np.cross(a, u)
    cos_max = math.cos(light.spot_angle / 2)
    c = rng.uniform(cos_max, 1.0, n)
    phi = rng.uniform(0, 2 * math.pi, n)
    sn = np.sqrt(1 - c * c)
    d = c[:, None] * a + (sn * np.cos(phi))[:, None] * u + (sn * np.sin(phi))[:, None] * w
    with np.errstate(divide="ignore", invalid="ignore"):
        t0 = (boxes[None, :, 0] - light.position) / d[:, None]          # (n, boxes, 3)
        t1 = (boxes[None, :, 1] - light.position) / d[:, None]
    enter = np.nanmax(np.minimum(t0, t1), axis=2)
    leave = np.nanmin(np.maximum(t0, t1), axis=2)
    hit = (enter <= leave) & (leave >= 0)
    t = np.where(hit, np.maximum(enter, 0), np.inf).min(axis=1)
    ok = np.isfinite(t)
    return light.position + t[ok, None] * d[ok]


def shadowing_caster_points(light, scene, receivers_pts, steps=64) -> np.ndarray:
    """Points inside caster boxes on the segments from visible receiver points towards the light."""
    p = receivers_pts[:, None, :]
    t = np.linspace(0.0, 1.0, steps)[None, :, None]
    if light.is_directional:
        span = 2.0 * scene.scale()
        q = p - t * span * light.direction
    else:
        q = p + t * (light.position - p)
    q = q.reshape(-1, 3)
    c = scene.casters
    inside = np.zeros(len(q), dtype=bool)
    for box in c:
        inside |= np.all((q >= box[0]) & (q <= box[1]), axis=1)
    return q[inside]


def assert_contains(body, pts, what):
    if len(pts) == 0:
        return
    tol = CONTAIN_TOL * max(body.scale, float(np.abs(body.origin).max()))
    ok = body.contains(pts, tol)
    assert ok.all(), f"{(~ok).sum()} of {len(pts)} {what} outside B, e.g. {pts[~ok][:3].tolist()}"


def hausdorff(a, b) -> float:
    d = np.linalg.norm(a[:, None] - b[None], axis=2)
    return float(max(d.min(axis=0).max(), d.min(axis=1).max()))


def assert_closed(body):
    """Every edge of every face is shared by exactly two faces; Euler V - E + F = 2; faces planar."""
    tol = 10 * body.tolerance
    verts = body.vertices
    def vid(p):
        d = np.linalg.norm(verts - p, axis=1)
        assert d.min() <= tol
        return int(d.argmin())
    count = {}
    for f in body.faces:
        assert len(f) >= 3
        ids = [vid(p) for p in f]
        n = np.cross(f[1] - f[0], f[2] - f[0])
        for k in range(len(ids)):
            e = tuple(sorted((ids[k], ids[(k + 1) % len(ids)])))
            count[e] = count.get(e, 0) + 1
        c = f.mean(axis=0)
        # Planar: distance to the face's best plane below the tolerance.
        u, s, vt = np.linalg.svd(f - c)
        assert s[-1] <= 1e-6 * max(body.scale, 1e-9) * math.sqrt(len(f))
    assert all(v == 2 for v in count.values()), "open body: an edge is not shared by exactly two faces"
    assert len(verts) - len(count) + len(body.faces) == 2


# ----------------------------------------------------------------------------- the hard cases

@pytest.mark.parametrize("name", NONEMPTY_CASES)
def test_hard_case_body_contains_what_the_view_needs(name):
    view, light, scene = HARD_CASES[name]
    body = intersection_body(view, light, scene)
    assert np.all(np.isfinite(body.vertices)) and len(body.vertices) >= 4
    recv = visible_receiver_points(view, light, scene)
    assert len(recv) > 0, "the case should show some receiver"
    assert_contains(body, recv, "visible receiver points")
    assert_contains(body, shadowing_caster_points(light, scene, recv[:400]), "shadowing caster points")
    assert_closed(body)


@pytest.mark.parametrize("name", ["sun_behind_camera", "spot_over_scene", "point_light_inside_view", "theta_equals_phi"])
def test_when_the_face_walk_gives_up_vertex_enumeration_builds_the_same_body(name, monkeypatch):
    """Every face-loop cut refusing (OpenCut, as on a cut too degenerate to
    order), and the light hull's loops too (B may need no cut after it), sends
    B through vertex enumeration: the same body, still holding what the view
    needs."""
    from addon.warp import polyhedron
    from addon.warp.light_hull import LightHull
    view, light, scene = HARD_CASES[name]
    walked = intersection_body(view, light, scene)
    enumerations = []

    def refuse(*args, **kwargs):
        enumerations.append(1)
        raise polyhedron.OpenCut("refused for the test")
    monkeypatch.setattr(polyhedron, "_cut", refuse)
    monkeypatch.setattr(LightHull, "polytope", refuse)
    enumerated = intersection_body(view, light, scene)
    assert enumerations                              # built by enumeration
    tol = 10 * walked.tolerance
    assert enumerated.contains(walked.vertices, tol).all() and walked.contains(enumerated.vertices, tol).all()
    recv = visible_receiver_points(view, light, scene)
    assert_contains(enumerated, recv, "visible receiver points")
    assert_contains(enumerated, shadowing_caster_points(light, scene, recv[:400]), "shadowing caster points")


@pytest.mark.parametrize("name", sorted(EMPTY_CASES))
def test_hard_case_empty_body_raises_with_a_reason(name):
    view, light, scene = HARD_CASES[name]
    with pytest.raises(EmptyBodyError, match="receiver"):
        intersection_body(view, light, scene)


def test_empty_scene_is_reported():
    view, light, _ = HARD_CASES["sun_behind_camera"]
    with pytest.raises(EmptyBodyError, match="no shadow casters or receivers"):
        intersection_body(view, light, SceneBounds.from_boxes(np.zeros((0, 2, 3))))


@pytest.mark.parametrize("name", NONEMPTY_CASES)
def test_deterministic(name):
    view, light, scene = HARD_CASES[name]
    a = intersection_body(view, light, scene)
    b = intersection_body(view, light, SceneBounds(scene.casters.copy(), scene.receivers.copy()))
    assert np.array_equal(a.vertices, b.vertices)
    assert len(a.faces) == len(b.faces) and all(np.array_equal(f, g) for f, g in zip(a.faces, b.faces))
    assert np.array_equal(a.culled.casters.mask, b.culled.casters.mask)
    assert np.array_equal(a.culled.receivers.mask, b.culled.receivers.mask)
    assert all(np.array_equal(p, q) for p, q in zip(a.hull_halfspaces, b.hull_halfspaces))


def test_a_point_sized_receiver_gives_a_closed_body():
    """A box of zero size 30 m away: the padding must exceed the tolerance
    (which grows with the distance from the camera), or B comes out empty."""
    view, light, _ = HARD_CASES["sun_behind_camera"]
    point_box = SceneBounds.from_boxes([[[0.0, 10.0, 0.0], [0.0, 10.0, 0.0]]])
    body = intersection_body(view, light, point_box)
    assert_closed(body)
    assert_contains(body, np.array([[0.0, 10.0, 0.0]]), "the point receiver")


def test_flat_scene_gives_a_closed_body_of_positive_volume():
    view, light, scene = HARD_CASES["flat_scene"]
    body = intersection_body(view, light, scene)
    assert_closed(body)
    z = body.vertices[:, 2]
    assert z.max() - z.min() > 0


# ----------------------------------------------------------------------------- scale and translation

@pytest.mark.parametrize("factor", [1e-3, 1e3])
def test_tolerances_are_relative_to_the_scene_scale(factor):
    """Scaling the whole configuration scales B (same vertex count, same shape)."""
    base = intersection_body(*HARD_CASES["sun_behind_camera"])
    view, light, scene = HARD_CASES["sun_behind_camera"]
    c2w = view.camera_to_world.copy()
    c2w[:3, 3] *= factor
    scaled_view = View.perspective(c2w, view.fov_y, view.projection[1, 1] / view.projection[0, 0],
                                   view.near * factor, view.far * factor)
    scaled = intersection_body(scaled_view, light, SceneBounds.from_boxes(scene.casters * factor))
    assert len(scaled.vertices) == len(base.vertices)
    assert hausdorff(scaled.vertices / factor, base.vertices) <= 1e-9 * base.scale
    assert scaled.tolerance == pytest.approx(base.tolerance * factor, rel=1e-9)


def test_translation_by_1e5_gives_the_same_body():
    off = np.array([1e5, -1e5, 1e5])
    a = intersection_body(camera([0.0, -20.0, 5.0], [0.0, 10.0, 0.0]), sun([0.4, 0.3, -0.6]), town())
    view, light, scene = HARD_CASES["scene_offset_1e5"]
    b = intersection_body(view, light, scene)
    assert len(a.vertices) == len(b.vertices)
    assert hausdorff(b.vertices - off, a.vertices) <= 1e-9 * a.scale + 1e5 * 4e-16


def test_the_culling_keeps_the_receivers_in_view_and_the_casters_that_can_shadow_them():
    view, light, scene = HARD_CASES["sun_behind_camera"]
    body = intersection_body(view, light, scene)
    receivers = body.culled.receivers.mask
    assert receivers.shape == (len(scene.receivers),) and receivers.any()
    # A caster far outside the light-extruded view is dropped; one between the view and the sun is kept.
    behind = np.array([[[-300.0, -300.0, 0.0], [-299.0, -299.0, 1.0]]])
    above = body.visible_vertices.mean(axis=0) - 10.0 * light.direction
    over = np.array([[above - 0.5, above + 0.5]])
    s2 = SceneBounds(np.concatenate([scene.casters, behind, over]), scene.receivers)
    b2 = intersection_body(view, light, s2)
    assert not b2.culled.casters.mask[-2] and b2.culled.casters.mask[-1]
    assert_contains(b2, over[0], "the caster between the view and the sun")


# ----------------------------------------------------------------------------- the culling index

def test_polytope_clip_matches_brute_force():
    rng = np.random.default_rng(5)
    for _ in range(50):
        poly = ConvexPolytope.box([-1, -2, -3], [2, 1, 3], 1e-12)
        n = rng.normal(size=(rng.integers(1, 8), 3))
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        o = rng.uniform(0.1, 2.0, len(n))
        out = poly.clip(n, o)
        pts = rng.uniform([-1, -2, -3], [2, 1, 3], (4000, 3))
        inside = np.all(pts @ n.T <= o, axis=1)
        assert out is not None
        assert np.array_equal(out.contains(pts, 0.0), inside)
        # Vertices lie inside every half-space and on at least three facets.
        assert np.all(out.vertices @ out.normals.T - out.offsets <= 1e-9)
        assert np.all(out.incidence.sum(axis=1) >= 3)


# ----------------------------------------------------------------------------- generated configurations

@st.composite
def configurations(draw):
    f = st.floats
    eye = np.array([draw(f(-30, 30)), draw(f(-30, 30)), draw(f(0.05, 30))])
    yaw = draw(f(0, 2 * math.pi))
    pitch = draw(f(-1.4, 0.3))
    fwd = np.array([math.cos(pitch) * math.cos(yaw), math.cos(pitch) * math.sin(yaw), math.sin(pitch)])
    near = 10 ** draw(f(-3, 0))
    far = near * 10 ** draw(f(1.5, 4))
    view = camera(eye, forward=fwd, fov=draw(f(20, 100)), near=near, far=far)
    kind = draw(st.sampled_from(["SUN", "POINT", "SPOT"]))
    d = np.array([draw(f(-1, 1)), draw(f(-1, 1)), draw(f(-1, -0.02))])
    pos = np.array([draw(f(-40, 40)), draw(f(-40, 40)), draw(f(0.5, 40))])
    light = {"SUN": lambda: sun(d), "POINT": lambda: point(pos),
             "SPOT": lambda: spot(pos, d, math.radians(draw(f(10, 170))))}[kind]()
    return view, light, town(flat=draw(st.booleans()))


@settings(derandomize=True, database=None, max_examples=120, deadline=None)
@given(configurations())
def test_generated_bodies_contain_what_the_view_needs(config):
    view, light, scene = config
    try:
        body = intersection_body(view, light, scene)
    except EmptyBodyError:
        assert len(visible_receiver_points(view, light, scene, n=2000)) == 0
        return
    recv = visible_receiver_points(view, light, scene, n=1500)
    assert_contains(body, recv, "visible receiver points")
    assert_contains(body, shadowing_caster_points(light, scene, recv[:200], steps=32), "shadowing caster points")
    assert_closed(body)


BOX_LO, BOX_HI = np.array([-1.0, -2.0, -3.0]), np.array([2.0, 1.0, 3.0])
BOX_CORNERS = np.array([[x, y, z] for x in (-1.0, 2.0) for y in (-2.0, 1.0) for z in (-3.0, 3.0)])


def awkward_cuts(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """1 to 6 half-spaces that are hard on vertex enumeration: through a corner
    of the box, tilted 1e-9 to 1e-3 rad from one of its faces, at random, or
    repeating the previous plane exactly or within 1e-14."""
    planes = []
    for _ in range(int(rng.integers(1, 7))):
        kind = rng.choice(["corner", "face_tilt", "random", "repeat"])
        if kind == "corner":
            n = rng.uniform(-1, 1, 3)
            if not np.any(np.abs(n) > 1e-3):
                n = np.ones(3)
            planes.append((n, float(n @ BOX_CORNERS[rng.integers(8)])))
        elif kind == "face_tilt":
            axis, sign = int(rng.integers(3)), float(rng.choice([-1.0, 1.0]))
            n = np.zeros(3)
            n[axis] = sign
            n[(axis + 1) % 3] = 10 ** rng.uniform(-9, -3) * rng.choice([-1.0, 1.0])
            bound = BOX_HI[axis] if sign > 0 else -BOX_LO[axis]
            planes.append((n, bound - rng.uniform(0, 0.5) * rng.choice([0.0, 1.0])))
        elif kind == "random":
            n = rng.uniform(-1, 1, 3)
            if not np.any(np.abs(n) > 1e-3):
                n = np.array([0.0, 0.0, 1.0])
            planes.append((n, rng.uniform(0.05, 2.0) * np.linalg.norm(n)))
        elif planes:
            n, o = planes[-1]
            planes.append((n * (1 + rng.uniform(0, 1e-14)), o * (1 + rng.uniform(0, 1e-14))))
    if not planes:
        planes.append((np.ones(3), 1.0))
    return np.array([p[0] for p in planes]), np.array([p[1] for p in planes])


AWKWARD_SAMPLES = 600


def test_polytope_clip_is_exact_on_awkward_cuts():
    """Clipping on degenerate cuts (a fixed, seeded sample, so every run checks
    the same cases): a clip is never falsely empty, its vertices satisfy every
    half-space to the flatness scale, it holds exactly the sample points that
    satisfy them (away from the boundary), and its faces close (Euler) on at
    least 99% of the cuts. The face walk (``polyhedron._cut``) closes them by
    construction; a cut it cannot order falls back to vertex enumeration,
    whose faces may not close on thin wedges between planes a few 1e-6 rad
    apart (B's light hull then takes its planes from shared vertices, see
    ``body.light_hull``)."""
    rng = np.random.default_rng(20261122)
    tol = 1e-10 * 6.0            # as in body.py: 1e-10 of the scale
    pts = np.random.default_rng(0).uniform(BOX_LO, BOX_HI, (3000, 3))
    box = ConvexPolytope.box(BOX_LO, BOX_HI, tol)
    open_faces = 0
    for _ in range(AWKWARD_SAMPLES):
        n, o = awkward_cuts(rng)
        unit = n / np.linalg.norm(n, axis=1, keepdims=True)
        offset = o / np.linalg.norm(n, axis=1)
        out = box.clip(unit, offset)
        d = (pts @ unit.T - offset).max(axis=1)
        if out is None:
            assert not np.any(d < -1e-9), (n.tolist(), o.tolist())
            continue
        # Exact to the flatness scale: a cut within COINCIDENT tolerances of a facet over the
        # whole solid is that facet (conservatively looser), and B is padded by that much.
        flat = COINCIDENT * tol
        assert np.all(out.vertices @ unit.T - offset <= flat), (n.tolist(), o.tolist())
        # A solid thinner than the flatness scale (B is padded to it) is flat within the tolerance.
        thickness = float((out.offsets[:, None] - out.normals @ out.vertices.T).max(axis=1).min())
        if thickness <= COINCIDENT * tol:
            continue
        clear = np.abs(d) > flat
        assert np.array_equal(out.contains(pts[clear], 0.0), d[clear] < 0), (n.tolist(), o.tolist())
        edges = out.edges
        open_faces += len(out.vertices) - len(edges) + len(out.normals) != 2
    assert open_faces <= AWKWARD_SAMPLES // 100


def test_two_cuts_nearly_along_a_face_leave_nearly_the_whole_box():
    """Planes through one line of a face, tilted 1e-6 and 1e-7 rad from it, are
    distinct facets over a 6 m box (they part by 3e-6 there, thousands of
    tolerances): the clip is the box less two thin wedges, never empty."""
    tol = 1e-10 * 6.0
    box = ConvexPolytope.box([-1, -2, -3], [2, 1, 3], tol)
    n = np.array([[0.0, -1.0, -1e-6], [0.0, -1.0, 1e-7]])
    length = np.linalg.norm(n, axis=1)
    out = box.clip(n / length[:, None], np.array([2.0, 2.0]) / length)
    assert out is not None
    assert np.allclose(out.vertices.min(axis=0), [-1, -2, -3]) and np.allclose(out.vertices.max(axis=0), [2, 1, 3])
    edges = out.edges
    assert len(out.vertices) - len(edges) + len(out.normals) == 2
